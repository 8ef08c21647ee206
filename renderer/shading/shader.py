"""The voxel shader: a physically based image of the network's inputs, in three cacheable stages.

The stages live in geometry.py, surface.py and lighting.py, each with its compiled loops; quality.py holds the
tuned values, buffers.py what a network reads, staged.py the chain with its cache. shade_scene runs them all at once.

From the object's voxels, where the scene places them, the light position, the camera elevation and the floor color
(what the network reads), and the scene's fixed constants (renderer/scene.py), it draws what the path tracer would,
approximately. It draws the object's own voxels, merged as for the grid it stands in for
(renderer.grid.shader_pool_factors: none on the 256^3 grid at the data's scales, in pairs on the network's 128^3 one);
lengths below in voxels are those merged voxels.

1. object_geometry (depends on the voxels' occupancy alone, in the object's own frame; `placed` puts the result where
   the scene has the object and sets the camera, so paint and every placement and camera edit keep this stage): the
   object's occupied voxels, cropped to their box; the distance to the nearest occupied voxel
   (the surface is where it equals SURFACE_LEVEL, a little inside the voxel hull, which is fatter
   than the mesh; thin parts stay as tubes); the gradient of that distance smoothed, at full and half resolution,
   for normals; the occupancy smoothed broadly for ambient occlusion, and its blocked lines per block of 4-32 voxels
   for the sky a hollow hides; the shadows' occluders (the occupied voxels' mean centre in each block of about
   1 / OCCLUDER_CELLS of the object box).
2. visible_surface (adds the image size): per pixel, the first surface point a camera ray meets
   (sphere tracing the distance), anti-aliased at silhouettes by 2 x 2 rays (ShaderQuality), its normal (averaged over the
   surface around it where the surface is flat), albedo (the voxels' colors averaged over the pixel's footprint)
   and ambient occlusion (near, and cones traced into the far sky); the floor points, and how much of their sky the object blocks; these as
   images too (SurfaceImages), shared by every light's shaded image. floor_reflection: the same, coarser, of the
   object mirrored in the floor, where the floor shows (for the shader's own image, not a network's input).
3. shade (adds the light and the floor color): soft shadows from shadow maps seen from
   LIGHT_POINTS^2 (ShaderQuality) points on the square light (the floor reads each as its square of the light: one smooth
   penumbra, not LIGHT_POINTS^2 copies), direct light (Lambert), ambient light with occlusion,
   light bounced up from the floor, the lit floor (renderer/floor_light.py, which a caller may keep
   while the object moves) times the object's shadow, and the object's reflection in the floor's glossy coat, if
   given; composited over the background, in sRGB.

A light move reruns only `shade`; a placement or camera edit stages 2 and 3; only another object (or a scale across a
merge threshold) all three. Known gaps (a network's job): the reflection's exact blur and contact, color bleeding
between object parts, exact penumbra shape, and whatever shading stays in photo-colored voxels (renderer/photo.py divides the photo's light out
when it is known, with this shader's own light, so its errors stay in the colors).
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from renderer.floor_texture import floor_texture
from renderer.grid import pool_voxels, shader_pool_factors
from renderer.scene import SHADER_GRID_SIZE, Scene, needs_environment_shading
from renderer.shading.environment_shading import scene_environment, shade_environment
from renderer.shading.geometry import object_geometry, placed
from renderer.shading.lighting import ShadedImage, shade
from renderer.shading.quality import FULL_QUALITY, ShaderQuality
from renderer.shading.surface import floor_reflection, floor_sky_cones, visible_surface

if TYPE_CHECKING:
    from renderer.shading.staged import SceneShaders


def shade_objects(scene: Scene, painted: Sequence[np.ndarray], floor_color, size: int | None = None,
                  grid_size: int = SHADER_GRID_SIZE, reflection: bool = True,
                  quality: ShaderQuality = FULL_QUALITY) -> ShadedImage:
    """shade_scene for a scene of one or several objects, their painted voxels `painted` in the scene's order (several:
    each object's stages and their joins, as the staged shader draws them: renderer/shading/staged.py)."""
    if len(painted) == 1:
        return shade_scene(scene, painted[0], floor_color, size, grid_size, reflection=reflection, quality=quality)
    from renderer.shading.staged import ObjectVoxels, StagedShader

    objects = [ObjectVoxels(o, ("voxels", k), rgba, ("shape", k)) for k, (o, rgba) in enumerate(zip(scene.objects, painted))]
    size = scene.image_size if size is None else size
    return StagedShader(grid_size, quality, reflection=reflection).run_objects(scene, objects, floor_color, size)


OTHERS_SHADOW_SHARE = 0.85  # a point seeing at most this share of the light it sees alone is in the others' shadow
EDGE_COVERAGE = 0.05  # another object covering this much of a pixel makes it an edge, not the object's own


def shadows_of_others(scene: Scene, painted: Sequence[np.ndarray], size: int | None = None,
                      grid_size: int = SHADER_GRID_SIZE, quality: ShaderQuality = FULL_QUALITY,
                      shaders: SceneShaders | None = None, keys: Sequence[Hashable] | None = None) -> np.ndarray:
    """(size, size) bool: the pixels where one object of the scene lies in another's shadow: the object's own
    (covered by no other), seeing at most OTHERS_SHADOW_SHARE of the area light it sees when it stands alone (the
    shader's light visibility, so geometry decides). No pixel in a scene of one object. `shaders`, `keys`: staged
    shaders kept by the caller (their grid and quality in place of `grid_size` and `quality`) and names of the
    voxels' contents (SceneShaders.shade), so that the next view of the same objects reuses their geometry."""
    from renderer.shading.staged import SceneShaders

    size = scene.image_size if size is None else size
    if len(painted) == 1:
        return np.zeros((size, size), dtype=bool)
    shaders = shaders or SceneShaders(grid_size, quality)
    keys = list(range(len(painted))) if keys is None else list(keys)
    together = shaders.shade(scene, painted, keys, size, reflection=False)
    alone = [shaders.shade(scene.alone(k), [rgba], [keys[k]], size, reflection=False, role=("alone", k))
             for k, rgba in enumerate(painted)]
    mask = np.zeros((size, size), dtype=bool)
    for k, own in enumerate(alone):
        others = np.zeros_like(mask)
        for j, other in enumerate(alone):
            if j != k:
                others |= other.coverage > EDGE_COVERAGE
        seen = (own.coverage > 0.5) & ~others
        mask |= seen & (together.visibility < OTHERS_SHADOW_SHARE * own.visibility)
    return mask


def shade_scene(scene: Scene, object_rgba: np.ndarray, floor_color, size: int | None = None,
                grid_size: int = SHADER_GRID_SIZE, cover_behind: bool = True, reflection: bool = True,
                quality: ShaderQuality = FULL_QUALITY) -> ShadedImage:
    """All three stages at once: the shaded image of a scene whose (painted) object voxels are `object_rgba`, at `size`
    (default the scene's), from the object voxels merged as for a `grid_size`^3 grid (renderer.grid.shader_pool_factors;
    `cover_behind`: see visible_surface; `reflection`: False leaves out the floor's reflection of the object, as for a
    network's input; `quality`: ShaderQuality)."""
    resolution = object_rgba.shape[0]
    factors = shader_pool_factors(resolution, scene.object.scale, grid_size)
    merged = pool_voxels(object_rgba, factors)
    geometry = placed(object_geometry(merged, resolution, factors, quality.ambient_occlusion), scene.object,
                      scene.camera.elevation_deg)
    size = scene.image_size if size is None else size
    surface = visible_surface(geometry, size, cover_behind, quality=quality)
    mirrored = floor_reflection(geometry, surface) if reflection else None
    if needs_environment_shading(scene):
        light = scene.light.position if scene.light.enabled else None
        return shade_environment(geometry, surface, light, floor_color, scene_environment(scene),
                                 scene.object.material, mirrored, quality, floor_sky_cones(geometry, surface),
                                 floor_texture(scene), scene.floor.shape)
    return shade(geometry, surface, scene.light.position, floor_color, reflection=mirrored, quality=quality)
