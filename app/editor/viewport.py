"""The 3D viewport, drawn with moderngl into an offscreen framebuffer the window shows: voxels, ground, light, render camera.

Voxels are quads (renderer/voxel_faces.py) placed by each object's placement matrix,
shaded by the direction to the light plus ambient. Each quad's four corners are stored as
vertices of their own rather than drawn as instances: Mesa's software OpenGL shades long
vertex arrays in wide batches but instances of four vertices one by one (the demo chair's
viewport is quicker). Faces turned away from the viewer
are dropped in the vertex shader. While the user drags, an object finer than MOTION_RESOLUTION voxels a side is
drawn from its voxels merged in blocks (a block is occupied if any of its voxels is): the product's 200^3 voxels have
four times the faces of 100^3, which slows a drag's frames in software OpenGL (docs/editor.md). At rest every voxel is drawn. A paint stroke or the bucket's preview rewrites only the faces'
colors (`recolor`). The ground is the floor (square or disk, its color or texture) with a faint grid, the light is its square seen as a glowing
rectangle with a line down to the floor, and the render camera is drawn as its viewing frustum.
"""

from __future__ import annotations

import math

import moderngl
import numpy as np

from app.editor.orbit_view import frustum_corners, view_projection
from app.editor.window import upload_image
from renderer.camera import Camera
from renderer.color import linear_to_srgb
from renderer.environment import scene_sun_direction
from renderer.errors import InputError
from renderer.floor_texture import FloorTexture, floor_texture
from renderer.grid import pool_voxels
from renderer.scene import FLOOR_DISK_RADIUS, FLOOR_HALF_SIZE, LIGHT_SIZE, LOOK_AT, OBJECT_SIZE, Scene
from renderer.surface import grid_from_world
from renderer.transform import OBJECT_BOX_MAX, OBJECT_BOX_MIN, apply_transform, object_to_world
from renderer.voxel_faces import exposed_faces

BACKGROUND = (0.16, 0.17, 0.19)
LIGHT_COLOR = (1.0, 0.93, 0.55)
SUN_COLOR = (1.0, 0.75, 0.2)
SUN_DISTANCE = 20.0  # the viewport lights its voxels from this far along the sun
LIGHT_ACTIVE_COLOR = (1.0, 0.6, 0.2)
FRUSTUM_COLOR = (0.55, 0.58, 0.64)  # grey, as Blender draws a camera: orange marks the selected object
BOX_COLOR = (0.9, 0.9, 0.95)
SELECTED_BOX_COLOR = (1.0, 0.62, 0.15)  # the selected object's box, when there are several (Blender's outline)
SELECTED_BOX_MARGIN = 0.03  # of the box's side, on each side
PICK_COLOR = (1.0, 1.0, 1.0)
GROUND_OFFSET = -0.003  # the ground is drawn a hair below y = 0 so lines on the floor do not flicker into it
FRUSTUM_DEPTH = 0.9  # depth of the drawn camera pyramid, world units
MOTION_RESOLUTION = 100  # voxels a side at most while the user drags (finer objects are drawn merged in blocks)
MIN_MOTION_RESOLUTION = 32  # ... and never coarser than this, however many objects

_VOXEL_VS = """
#version 330
in vec2 corner;
in vec4 cell;   // i, j, k, face id
in vec3 color;
uniform mat4 view_projection;
uniform mat4 object_to_world;
uniform mat3 normal_to_world;
uniform vec3 eye;
uniform float voxel_size;
uniform vec3 box_min;
out vec3 v_color;
out vec3 v_normal;
out vec3 v_world;
void main() {
    int face = int(cell.w + 0.5);
    int axis = face / 2;
    float side = (face % 2 == 0) ? 1.0 : 0.0;
    vec3 p = cell.xyz;
    vec3 n = vec3(0.0);
    if (axis == 0) { p += vec3(side, corner.x, corner.y); n.x = side * 2.0 - 1.0; }
    else if (axis == 1) { p += vec3(corner.y, side, corner.x); n.y = side * 2.0 - 1.0; }
    else { p += vec3(corner.x, corner.y, side); n.z = side * 2.0 - 1.0; }
    vec4 world = object_to_world * vec4(box_min + p * voxel_size, 1.0);
    v_world = world.xyz;
    v_normal = normalize(normal_to_world * n);
    v_color = color;
    gl_Position = view_projection * world;
    if (dot(v_normal, eye - world.xyz) <= 0.0) gl_Position = vec4(2.0, 2.0, 2.0, 1.0);  // faces away: outside the clip volume
}
"""

_SHADED_FS = """
#version 330
in vec3 v_color;
in vec3 v_normal;
in vec3 v_world;
uniform vec3 light_position;
out vec4 frag;
void main() {
    vec3 to_light = normalize(light_position - v_world);
    float diffuse = max(dot(normalize(v_normal), to_light), 0.0);
    frag = vec4(v_color * (0.38 + 0.72 * diffuse), 1.0);
}
"""

_GROUND_VS = """
#version 330
in vec3 position;
uniform mat4 view_projection;
out vec3 v_world;
void main() { v_world = position; gl_Position = view_projection * vec4(position, 1.0); }
"""

_GROUND_FS = """
#version 330
in vec3 v_world;
uniform vec3 floor_color;
uniform vec3 light_position;
uniform float disk_radius;  // 0: the square floor
uniform sampler2D floor_texture;
uniform float texture_repeat;  // world units one repeat spans; 0: the plain color
uniform float half_size;
out vec4 frag;
void main() {
    if (disk_radius > 0.0 && length(v_world.xz) > disk_radius) discard;
    vec3 to_light = normalize(light_position - v_world);
    vec3 albedo = floor_color;
    if (texture_repeat > 0.0)  // placed as renderer/floor_texture.py places it
        albedo = texture(floor_texture, vec2(v_world.x + half_size, half_size - v_world.z) / texture_repeat).rgb;
    vec3 shaded = albedo * (0.38 + 0.72 * max(to_light.y, 0.0));
    vec2 cell = abs(fract(v_world.xz * 2.0 + 0.5) - 0.5) / fwidth(v_world.xz * 2.0);
    float line = 1.0 - min(min(cell.x, cell.y), 1.0);
    frag = vec4(mix(shaded, shaded * 0.8, line * 0.6), 1.0);
}
"""

_FLAT_VS = """
#version 330
in vec3 position;
uniform mat4 view_projection;
void main() { gl_Position = view_projection * vec4(position, 1.0); }
"""

_FLAT_FS = """
#version 330
uniform vec3 color;
out vec4 frag;
void main() { frag = vec4(color, 1.0); }
"""

_QUAD_CORNERS = np.array([[0, 0], [1, 0], [0, 1], [1, 1]], dtype=np.float32)
_QUAD_TRIANGLES = np.array([0, 1, 2, 2, 1, 3], dtype=np.uint32)  # corners of the quad's two triangles


class ViewportRenderer:
    """Owns the GL objects of the viewport; `draw` renders a scene into a framebuffer of the requested size."""

    def __init__(self, ctx: moderngl.Context):
        self.ctx = ctx
        self._voxel_program = ctx.program(vertex_shader=_VOXEL_VS, fragment_shader=_SHADED_FS)
        self._ground_program = ctx.program(vertex_shader=_GROUND_VS, fragment_shader=_GROUND_FS)
        self._flat_program = ctx.program(vertex_shader=_FLAT_VS, fragment_shader=_FLAT_FS)
        self._objects: list[_ObjectFaces | None] = []  # per object of the scene, in order (None: nothing to draw)
        h, y = FLOOR_HALF_SIZE, GROUND_OFFSET
        ground = np.array([[-h, y, -h], [h, y, -h], [h, y, h], [-h, y, -h], [h, y, h], [-h, y, h]], dtype=np.float32)
        self._ground_vao = ctx.vertex_array(self._ground_program, [(ctx.buffer(ground.tobytes()), "3f", "position")])
        self._lines = ctx.buffer(reserve=4096)
        self._lines_vao = ctx.vertex_array(self._flat_program, [(self._lines, "3f", "position")])
        self._fbo: moderngl.Framebuffer | None = None
        self._ground_texture: tuple[FloorTexture, moderngl.Texture] | None = None  # the floor's, and its GL copy
        self._voxels_version = 0
        self._drawn = None  # what the framebuffer shows; an unchanged frame is not drawn again
        self.version = 0  # counts the frames drawn into the framebuffer, so the window knows when it changed

    def _floor_texture_of(self, scene: Scene) -> moderngl.Texture | None:
        """The scene's floor texture as a mip-mapped GL texture (uploaded when it changes), or None."""
        try:
            texture = floor_texture(scene)
        except InputError:
            texture = None  # the edit that named it said why
        if texture is None:
            return None
        if self._ground_texture is None or self._ground_texture[0] is not texture:
            if self._ground_texture is not None:
                self._ground_texture[1].release()
            gl = upload_image(self.ctx, None, linear_to_srgb(texture.albedo))
            gl.build_mipmaps()
            gl.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
            self._ground_texture = (texture, gl)
        return self._ground_texture[1]

    def set_voxels(self, rgba: np.ndarray, index: int = 0) -> int:
        """Upload object `index`'s visible faces, one group per face direction (and those of its merged blocks, drawn
        in motion, if it is finer than MOTION_RESOLUTION); returns how many quads there are at rest."""
        self._voxels_version += 1
        self.keep_objects(max(len(self._objects), index + 1))
        if self._objects[index] is not None:
            self._objects[index].release()
        self._objects[index] = _ObjectFaces(self.ctx, self._voxel_program, rgba)
        return self._objects[index].levels[0].quads

    def recolor(self, rgba: np.ndarray, overrides: tuple[np.ndarray, np.ndarray] | None = None, index: int = 0) -> None:
        """Show new colors on the faces set_voxels made for object `index`: `rgba` must have the same occupancy
        (paint never changes it). `overrides`: (sorted flat voxel indices, their colors (K, 3)) shown instead of
        rgba's (the bucket's preview tint). Only the faces' colors are written: finding the faces is slow at 200^3,
        and the bucket's previews and strokes would pay it at each voxel the bucket rests on."""
        faces = self._objects[index] if index < len(self._objects) else None
        if faces is None or rgba.shape[0] != faces.resolution:
            raise ValueError("recolor needs the voxels set_voxels was given, with other colors")
        self._voxels_version += 1
        faces.recolor(rgba, overrides)

    def keep_objects(self, count: int) -> None:
        """Hold faces for `count` objects: those past them are released, new places are empty."""
        for faces in self._objects[count:]:
            if faces is not None:
                faces.release()
        self._objects = self._objects[:count] + [None] * (count - len(self._objects))
        self._voxels_version += 1

    def forget(self, index: int) -> None:
        """Draw nothing for object `index` (its voxels could not be loaded)."""
        if index < len(self._objects) and self._objects[index] is not None:
            self._objects[index].release()
            self._objects[index] = None
            self._voxels_version += 1

    @property
    def quads_in_motion(self) -> int:
        """How many faces a frame draws while the user drags (0 before any voxels are set)."""
        return sum(level.quads for _, _, level in self._levels(moving=True))

    def _levels(self, moving: bool) -> list[tuple[int, _ObjectFaces, _FaceLevel]]:
        """(object index, its faces, the level a frame draws). While the user drags, merged blocks: at most
        MOTION_RESOLUTION a side for one object, fewer for several, so that a drag's frame draws about as many
        faces whatever the objects (a face count grows with the square of the side)."""
        shown = [(i, faces) for i, faces in enumerate(self._objects) if faces is not None]
        most = max(MIN_MOTION_RESOLUTION, int(MOTION_RESOLUTION / math.sqrt(max(len(shown), 1))))
        return [(i, faces, faces.motion_level(most) if moving else faces.levels[0]) for i, faces in shown]

    def draw(self, width: int, height: int, view: Camera, scene: Scene, floor_color, light_active: bool = False,
             picked_voxel: tuple[int, int, int] | None = None, moving: bool = False,
             selected: int = 0, hidden: frozenset[int] = frozenset()) -> moderngl.Framebuffer:
        """Render the scene seen by `view` (already sized width x height) into the returned framebuffer; `moving`: a
        drag is in progress (a fine object is drawn in merged blocks); `selected`: the object outlined by its box
        (`picked_voxel` is one of its voxels); `hidden`: objects not drawn (the object list's eye).

        llvmpipe (software OpenGL) needs tens of milliseconds for a frame, so a frame identical
        to the last one is not drawn again.
        """
        levels = [level for level in self._levels(moving) if level[0] not in hidden]
        drawn = (width, height, view, scene, tuple(floor_color), light_active, picked_voxel, self._voxels_version,
                 tuple(level.block for _, _, level in levels), selected, hidden)
        if drawn == self._drawn:
            return self._fbo
        self._drawn = drawn
        self.version += 1
        fbo = self._framebuffer(width, height)
        self._render(fbo, view, scene, floor_color, light_active, picked_voxel, levels, selected)
        return fbo

    def image(self, width: int, height: int, view: Camera, scene: Scene, floor_color) -> np.ndarray:
        """The viewport as an (H, W, 3) uint8 image, top row first, drawn in a framebuffer of its own (for exports)."""
        size = (width, height)
        attachments = (self.ctx.renderbuffer(size, 4), self.ctx.depth_renderbuffer(size))
        fbo = self.ctx.framebuffer(*attachments)
        try:
            self._render(fbo, view, scene, floor_color, levels=self._levels(moving=False))
            pixels = fbo.read(components=3)
        finally:
            fbo.release()
            for attachment in attachments:
                attachment.release()
        return np.frombuffer(pixels, dtype=np.uint8).reshape(height, width, 3)[::-1].copy()

    def _render(self, fbo: moderngl.Framebuffer, view: Camera, scene: Scene, floor_color, light_active: bool = False,
                picked_voxel: tuple[int, int, int] | None = None,
                levels: list[tuple[int, _ObjectFaces, _FaceLevel]] = (), selected: int = 0) -> None:
        width, height = fbo.size
        fbo.use()
        ctx = self.ctx
        ctx.viewport = (0, 0, width, height)
        ctx.clear(*BACKGROUND, 1.0, depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        vp = _gl_matrix(view_projection(view))
        light = tuple(float(c) for c in _shading_light(scene))

        self._ground_program["view_projection"].write(vp)
        self._ground_program["floor_color"].value = tuple(float(c) for c in floor_color)
        self._ground_program["light_position"].value = light
        self._ground_program["disk_radius"].value = FLOOR_DISK_RADIUS if scene.floor.shape == "disk" else 0.0
        self._ground_program["half_size"].value = FLOOR_HALF_SIZE
        texture = self._floor_texture_of(scene)
        self._ground_program["texture_repeat"].value = 0.0 if texture is None else float(scene.floor.texture_scale)
        if texture is not None:
            texture.use(0)
            self._ground_program["floor_texture"].value = 0
        self._ground_vao.render()

        p = self._voxel_program
        p["view_projection"].write(vp)
        p["eye"].value = tuple(float(c) for c in view.position)
        p["box_min"].value = tuple(float(c) for c in OBJECT_BOX_MIN)
        p["light_position"].value = light
        for index, faces, level in levels:
            if index >= len(scene.objects) or not level.groups:
                continue
            placement = object_to_world(scene.objects[index])
            p["object_to_world"].write(_gl_matrix(placement))
            p["normal_to_world"].write(np.linalg.inv(placement[:3, :3]).T.astype("f4").tobytes(order="F"))
            p["voxel_size"].value = OBJECT_SIZE / faces.resolution * level.block
            eye_grid = apply_transform(grid_from_world(placement, faces.resolution), view.position) / level.block
            for group in level.groups:
                if group.may_face(eye_grid):
                    group.vao.render(moderngl.TRIANGLES)

        light_color = LIGHT_ACTIVE_COLOR if light_active else LIGHT_COLOR
        shapes = [(moderngl.LINES, _frustum_lines(Camera.from_scene(scene)), FRUSTUM_COLOR)]
        if selected < len(scene.objects):
            chosen = object_to_world(scene.objects[selected])
            if len(scene.objects) == 1:
                shapes.append((moderngl.LINES, _box_lines(chosen, OBJECT_BOX_MIN, OBJECT_BOX_MAX), BOX_COLOR))
            else:  # a little outside the box, so that it shows on an object that fills its box
                margin = SELECTED_BOX_MARGIN * (OBJECT_BOX_MAX - OBJECT_BOX_MIN)
                shapes.append((moderngl.LINES, _box_lines(chosen, OBJECT_BOX_MIN - margin, OBJECT_BOX_MAX + margin),
                               SELECTED_BOX_COLOR))
            faces = self._objects[selected] if selected < len(self._objects) else None
            if picked_voxel is not None and faces is not None:
                side = OBJECT_SIZE / faces.resolution
                lo = OBJECT_BOX_MIN + np.asarray(picked_voxel) * side
                shapes.append((moderngl.LINES, _box_lines(chosen, lo, lo + side), PICK_COLOR))
        if scene.light.enabled:
            shapes.append((moderngl.LINES, _light_lines(scene), light_color))
            shapes.append((moderngl.TRIANGLES, _light_corners(scene)[[0, 1, 2, 0, 2, 3]],
                           tuple(0.5 * c + 0.5 for c in light_color)))
        sun = scene_sun_direction(scene)
        if sun is not None:
            shapes.append((moderngl.LINES, _sun_lines(sun), SUN_COLOR))
        self._flat_program["view_projection"].write(vp)
        self._draw_flat(shapes)
        ctx.disable(moderngl.DEPTH_TEST)

    def _framebuffer(self, width: int, height: int) -> moderngl.Framebuffer:
        if self._fbo is None or self._fbo.size != (width, height):
            if self._fbo is not None:
                for attachment in (*self._fbo.color_attachments, self._fbo.depth_attachment):
                    attachment.release()
                self._fbo.release()
            size = (width, height)
            self._fbo = self.ctx.framebuffer(self.ctx.renderbuffer(size, 4), self.ctx.depth_renderbuffer(size))
        return self._fbo

    def _draw_flat(self, shapes: list[tuple[int, np.ndarray, tuple[float, float, float]]]) -> None:
        """Draw (mode, points, color) shapes in one color each, from one upload: with software OpenGL, writing
        a buffer that an earlier draw of the frame reads makes the driver finish that draw first."""
        data = np.ascontiguousarray(np.concatenate([points for _, points, _ in shapes]), dtype=np.float32)
        if data.nbytes > self._lines.size:
            self._lines.orphan(data.nbytes)
        self._lines.write(data.tobytes())
        first = 0
        for mode, points, color in shapes:
            self._flat_program["color"].value = color
            self._lines_vao.render(mode, vertices=len(points), first=first)
            first += len(points)


class _ObjectFaces:
    """One object's faces: every voxel's, then (for an object finer than the motion resolution) its merged blocks'
    for frames drawn while the user drags, made on the first drag (the bucket's previews upload the voxels at every
    voxel it rests on)."""

    def __init__(self, ctx: moderngl.Context, program: moderngl.Program, rgba: np.ndarray):
        self.ctx, self.program = ctx, program
        self.resolution = rgba.shape[0]
        self.levels = [_FaceLevel(ctx, program, rgba, 1)]
        self._rgba = rgba  # the voxels the merged blocks are made from

    def recolor(self, rgba: np.ndarray, overrides: tuple[np.ndarray, np.ndarray] | None) -> None:
        for level in self.levels[1:]:  # the merged blocks' colors are made again on the next drag
            level.release()
        self.levels = self.levels[:1]
        self.levels[0].recolor(rgba, overrides)
        self._rgba = rgba

    def motion_level(self, most: int = MOTION_RESOLUTION) -> _FaceLevel:
        """What a frame draws while the user drags: merged blocks at most `most` a side, else every voxel."""
        block = -(-self.resolution // most)
        if block == 1:
            return self.levels[0]
        if self.levels[-1].block != block:
            for level in self.levels[1:]:
                level.release()
            self.levels = [self.levels[0], _FaceLevel(self.ctx, self.program, pool_voxels(self._rgba, (block,) * 3),
                                                      block)]
        return self.levels[-1]

    def release(self) -> None:
        for level in self.levels:
            level.release()


class _FaceLevel:
    """The exposed faces of voxels merged in blocks of `block`^3 (1: every voxel), by face direction."""

    def __init__(self, ctx: moderngl.Context, program: moderngl.Program, rgba: np.ndarray, block: int):
        self.block = block
        cells, colors = exposed_faces(rgba)
        self.quads = len(cells)
        self.groups = []
        for face in range(6):
            mine = cells[:, 3] == face
            if mine.any():
                self.groups.append(_FaceGroup(ctx, program, face, cells[mine], colors[mine], rgba.shape[:3]))

    def recolor(self, rgba: np.ndarray, overrides: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        """Write each face's color from its voxel in `rgba` (see ViewportRenderer.recolor)."""
        flat = np.asarray(rgba).reshape(-1, rgba.shape[-1])
        for group in self.groups:
            colors = flat[group.voxels, :3]
            if overrides is not None and len(overrides[0]):
                indices, override_colors = overrides
                slot = np.minimum(np.searchsorted(indices, group.voxels), len(indices) - 1)
                hit = indices[slot] == group.voxels
                colors[hit] = override_colors[slot[hit]]
            group.write_colors(colors)

    def release(self) -> None:
        for group in self.groups:
            group.release()


class _FaceGroup:
    """The exposed faces of one direction: their vertex buffers (four corners a face; the colors in a buffer of their
    own, so a paint stroke rewrites only them), the flat index of each face's voxel, and the planes they lie on."""

    def __init__(self, ctx: moderngl.Context, program: moderngl.Program, face: int, cells: np.ndarray,
                 colors: np.ndarray, shape: tuple[int, int, int]):
        self.axis, self.positive = face // 2, face % 2 == 0
        planes = cells[:, self.axis] + (1.0 if self.positive else 0.0)  # grid coordinate of each face's plane
        self.bound = float(planes.min() if self.positive else planes.max())
        self.voxels = np.ravel_multi_index(tuple(cells[:, :3].astype(np.int64).T), shape)
        count = len(cells)
        geometry = np.concatenate([np.tile(_QUAD_CORNERS, (count, 1)), np.repeat(cells, 4, axis=0)],
                                  axis=1).astype(np.float32)
        triangles = (4 * np.arange(count, dtype=np.uint32)[:, None] + _QUAD_TRIANGLES).ravel()
        self._buffers = (ctx.buffer(geometry.tobytes()), ctx.buffer(reserve=count * 4 * 3 * 4),
                         ctx.buffer(triangles.tobytes()))
        self.write_colors(colors)
        self.vao = ctx.vertex_array(program, [(self._buffers[0], "2f 4f", "corner", "cell"),
                                              (self._buffers[1], "3f", "color")],
                                    index_buffer=self._buffers[2], index_element_size=4)

    def write_colors(self, colors: np.ndarray) -> None:
        """Set the faces' colors (F, 3), sRGB, clipped to [0, 1]."""
        clipped = np.clip(np.asarray(colors, dtype=np.float32), 0.0, 1.0)
        self._buffers[1].write(np.repeat(clipped, 4, axis=0).tobytes())

    def may_face(self, eye_grid: np.ndarray) -> bool:
        """Whether any face of the group can turn its front to an eye at `eye_grid` (object grid coordinates).

        A +x face on the plane x = c faces the eye only if the eye has x > c; so when the eye is
        behind every plane of the group, none of its faces can be seen (about half of all faces).
        """
        e = float(eye_grid[self.axis])
        return e > self.bound if self.positive else e < self.bound

    def release(self) -> None:
        self.vao.release()
        for buffer in self._buffers:
            buffer.release()


def _gl_matrix(m: np.ndarray) -> bytes:
    """A 4x4 numpy matrix as the column-major float32 bytes GLSL expects."""
    return np.asarray(m, dtype="f4").tobytes(order="F")


def _shading_light(scene: Scene) -> np.ndarray:
    """Where the viewport's voxels are lit from: the area light, or far along the sun when only a sky lights them."""
    sun = scene_sun_direction(scene)
    if scene.light.enabled or sun is None:
        return np.asarray(scene.light.position, dtype=np.float64)
    return np.asarray(LOOK_AT) + SUN_DISTANCE * sun


def _sun_lines(sun: np.ndarray) -> np.ndarray:
    """An arrow from the sun's side of the scene towards its centre, and a cross (the sun) at its tail."""
    centre = np.asarray(LOOK_AT, dtype=np.float64)
    tail, head = centre + 2.2 * sun, centre + 1.0 * sun
    side = np.cross(sun, [0.0, 1.0, 0.0])
    side = side / np.linalg.norm(side) if np.linalg.norm(side) > 1e-6 else np.array([1.0, 0.0, 0.0])
    up = np.cross(side, sun)
    back = head + 0.15 * sun
    lines = [tail, head, head, back + 0.06 * side, head, back - 0.06 * side, head, back + 0.06 * up, head, back - 0.06 * up]
    for a, b in ((side, up), (up, -side), (-side, -up), (-up, side)):
        lines += [tail + 0.12 * a, tail + 0.12 * b]
    return np.array(lines)


def _light_corners(scene: Scene) -> np.ndarray:
    x, y, z = scene.light.position
    h = 0.5 * LIGHT_SIZE
    return np.array([[x - h, y, z - h], [x + h, y, z - h], [x + h, y, z + h], [x - h, y, z + h]])


def _light_lines(scene: Scene) -> np.ndarray:
    """The light square's outline, a line down to the floor and a cross where it lands."""
    c = _light_corners(scene)
    x, y, z = scene.light.position
    outline = [c[0], c[1], c[1], c[2], c[2], c[3], c[3], c[0]]
    drop = [(x, y, z), (x, 0.0, z), (x - 0.15, 0.0, z), (x + 0.15, 0.0, z), (x, 0.0, z - 0.15), (x, 0.0, z + 0.15)]
    return np.array(outline + [np.array(p) for p in drop])


def _frustum_lines(camera: Camera) -> np.ndarray:
    """The render camera as a pyramid (centre to image corners), an 'up' triangle, and its line of sight."""
    eye = camera.position
    far = frustum_corners(camera, FRUSTUM_DEPTH)
    lines = [eye, np.asarray(camera.target)]
    for i in range(4):
        lines += [eye, far[i], far[i], far[(i + 1) % 4]]
    top_mid = 0.5 * (far[0] + far[1])
    up = camera.camera_to_world()[:3, 1] * 0.15 * np.linalg.norm(far[1] - far[0])
    lines += [far[0] + 0.3 * (far[1] - far[0]), top_mid + up, top_mid + up, far[0] + 0.7 * (far[1] - far[0])]
    return np.array(lines)


def _box_lines(matrix: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The 12 edges of the box [lo, hi] (object coordinates) placed by `matrix`."""
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    world = apply_transform(matrix, corners)
    edges = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]
    return np.array([world[i] for edge in edges for i in edge])
