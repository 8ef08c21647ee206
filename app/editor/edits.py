"""Every edit the editor makes, as a pure function from a scene to a new scene.

A value outside what the editor allows (a scale <= 0, the light under the floor or off the floor's
square, a camera at 90 degrees) is refused with an InputError that names the bounds, so a typed value
is never changed without a word; drags in the viewport stop at the bounds themselves (`clamp`).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from renderer.environment import environment_light
from renderer.errors import InputError
from renderer.floor_texture import floor_texture
from renderer.limits import MAX_OBJECTS
from renderer.scene import (
    FLOOR_HALF_SIZE,
    FLOOR_SHAPES,
    MAX_TEXTURE_SCALE,
    CameraSpec,
    EnvironmentSpec,
    MaterialSpec,
    ObjectSpec,
    PaintOp,
    Scene,
    SkySpec,
)
from renderer.transform import footprint_radius

MIN_LIGHT_HEIGHT = 0.05
MAX_LIGHT_HEIGHT = 10.0
MAX_ELEVATION = 89.0
MIN_SCALE = 0.05
MAX_SCALE = 20.0
MAX_POSITION = FLOOR_HALF_SIZE  # the object and the light stay over the floor's square
MAX_STRENGTH = 20.0  # an environment's strength the editor offers
MIN_TEXTURE_SCALE = 0.05  # world units a floor texture's repeat spans at the least (finer ones shimmer)


def clamp(value: float, lo: float, hi: float) -> float:
    return min(max(float(value), lo), hi)


def _check(name: str, values, lo: float, hi: float) -> tuple[float, ...]:
    values = tuple(float(v) for v in values)
    if not all(math.isfinite(v) and lo <= v <= hi for v in values):
        shown = ", ".join(f"{v:g}" for v in values)
        raise InputError(f"{name} must be from {lo:g} to {hi:g}, got {shown}")
    return values


def move_light(scene: Scene, position: tuple[float, float, float]) -> Scene:
    """The light centred at `position`: over the floor's square, between MIN_ and MAX_LIGHT_HEIGHT above it."""
    x, z = _check("light x and z", (position[0], position[2]), -MAX_POSITION, MAX_POSITION)
    (y,) = _check("light height", (position[1],), MIN_LIGHT_HEIGHT, MAX_LIGHT_HEIGHT)
    return scene.with_changes(light=replace(scene.light, position=(x, y, z)))


def switch_area_light(scene: Scene, enabled: bool) -> Scene:
    """The area light on or off (off only while an environment lights the scene)."""
    if not enabled and scene.environment is None:
        raise InputError("the area light can be off only when a sky or an environment image lights the scene")
    return scene.with_changes(light=replace(scene.light, enabled=bool(enabled)))


def set_environment(scene: Scene, environment: EnvironmentSpec | None) -> Scene:
    """Another environment (None: the uniform ambient light, with the area light back on)."""
    light = scene.light if environment is not None else replace(scene.light, enabled=True)
    return scene.with_changes(environment=environment, light=light)


def use_sky(scene: Scene) -> Scene:
    """A sky (the default sun) in place of the ambient light or an image, keeping the turn and strength."""
    env = scene.environment or EnvironmentSpec()
    return set_environment(scene, replace(env, image=None, sky=env.sky or SkySpec()))


def use_environment_image(scene: Scene, path: Path) -> Scene:
    """An environment image (absolute path) in place of the ambient light or the sky; read now, so that a file that
    is not a map is refused here, in one line, and the render finds it read."""
    env = scene.environment or EnvironmentSpec()
    edited = set_environment(scene, replace(env, image=str(Path(path).resolve()), sky=None))
    environment_light(edited)
    return edited


def use_floor_texture(scene: Scene, path: Path) -> Scene:
    """The floor textured by an image (absolute path), read now so that a file that is not an image is refused here
    in one line; the floor color becomes the texture's mean (what the viewport shows)."""
    textured = scene.with_changes(floor=replace(scene.floor, texture=str(Path(path).resolve())))
    texture = floor_texture(textured)
    return textured.with_changes(floor=replace(textured.floor, color=texture.mean_srgb))


def set_floor_texture_scale(scene: Scene, scale: float) -> Scene:
    """World units one repeat of the floor's texture spans."""
    (scale,) = _check("texture scale", (scale,), MIN_TEXTURE_SCALE, MAX_TEXTURE_SCALE)
    return scene.with_changes(floor=replace(scene.floor, texture_scale=scale))


def set_floor_shape(scene: Scene, shape: str) -> Scene:
    """The floor as a square (to the horizon) or a disk (the paper's ground, its edge in view)."""
    if shape not in FLOOR_SHAPES:
        raise InputError(f'floor shape must be one of {", ".join(FLOOR_SHAPES)}, got {shape!r}')
    return scene.with_changes(floor=replace(scene.floor, shape=shape))


def clear_floor_texture(scene: Scene) -> Scene:
    """The plain floor color again (the texture's mean, which the floor took when it was loaded)."""
    return scene.with_changes(floor=replace(scene.floor, texture=None, texture_scale=1.0))


def set_sky(scene: Scene, elevation_deg: float, azimuth_deg: float, turbidity: float) -> Scene:
    (elevation,) = _check("sun elevation", (elevation_deg,), 0.0, 90.0)
    (turbidity,) = _check("turbidity", (turbidity,), 1.0, 10.0)
    (azimuth,) = _check("sun azimuth", (azimuth_deg,), -1e6, 1e6)
    sky = SkySpec(elevation, (azimuth + 180.0) % 360.0 - 180.0, turbidity)
    return set_environment(scene, replace(scene.environment or EnvironmentSpec(), sky=sky, image=None))


def turn_environment(scene: Scene, rotation_deg: float | None = None, strength: float | None = None) -> Scene:
    """The environment turned about the vertical axis and/or made stronger or weaker."""
    env = scene.environment
    if env is None:
        raise InputError("there is no environment to turn: choose a sky or an image first")
    if rotation_deg is not None:
        (rotation,) = _check("environment rotation", (rotation_deg,), -1e6, 1e6)
        env = replace(env, rotation_deg=(rotation + 180.0) % 360.0 - 180.0)
    if strength is not None:
        (strength,) = _check("environment strength", (strength,), 0.0, MAX_STRENGTH)
        env = replace(env, strength=strength)
    return set_environment(scene, env)


def set_material(scene: Scene, material: MaterialSpec) -> Scene:
    values = _check("material roughness, specular and metallic",
                    (material.roughness, material.specular, material.metallic), 0.0, 1.0)
    return scene.with_changes(object=replace(scene.object, material=MaterialSpec(*values)))


# What a user picks before tuning the sliders: (roughness, specular, metallic).
MATERIAL_PRESETS = {
    "matte": MaterialSpec(),
    "plastic": MaterialSpec(0.35, 0.5, 0.0),
    "ceramic": MaterialSpec(0.12, 0.6, 0.0),
    "rubber": MaterialSpec(0.8, 0.25, 0.0),
    "metal": MaterialSpec(0.25, 0.5, 1.0),
}


def set_elevation(scene: Scene, elevation_deg: float) -> Scene:
    (elevation,) = _check("camera elevation", (elevation_deg,), 0.0, MAX_ELEVATION)
    return scene.with_changes(camera=CameraSpec(elevation))


def set_floor_color(scene: Scene, color: tuple[float, float, float]) -> Scene:
    return scene.with_changes(floor=replace(scene.floor, color=_check("floor color", color, 0.0, 1.0)))


def place_object(scene: Scene, translation: tuple[float, float] | None = None, rotation_deg: float | None = None,
                 scale: tuple[float, float, float] | None = None) -> Scene:
    """The object moved on the floor, turned about the vertical axis and/or scaled per axis."""
    o = scene.object
    if translation is not None:
        o = replace(o, translation=_check("position", translation, -MAX_POSITION, MAX_POSITION))
    if rotation_deg is not None:
        (rotation,) = _check("rotation", (rotation_deg,), -1e6, 1e6)
        o = replace(o, rotation_deg=(rotation + 180.0) % 360.0 - 180.0)
    if scale is not None:
        o = replace(o, scale=_check("scale", scale, MIN_SCALE, MAX_SCALE))
    return scene.with_changes(object=o)


def paint(scene: Scene, op: PaintOp) -> Scene:
    """One more paint stroke (bucket fill of a region or the whole object), or a floor fill: the floor's new color."""
    if op.target == "floor":
        return set_floor_color(scene, op.color)
    return scene.with_changes(paint=(*scene.paint, op))


def replace_object_source(scene: Scene, mesh: Path | None = None, voxels: Path | None = None, up: str = "y",
                          resolution: int | None = None) -> Scene:
    """The object made from another mesh or voxel file (absolute path); placement and material kept, paint reset.
    The scene's color stays when the mesh is the one it had (voxelised again, another up axis); another object
    shows its own colors."""
    same = mesh is not None and scene.mesh_path() is not None and Path(mesh).resolve() == scene.mesh_path().resolve()
    o = replace(scene.object, mesh=None if mesh is None else str(Path(mesh).resolve()),
                voxels=None if voxels is None else str(Path(voxels).resolve()), up=up,
                color=scene.object.color if same else None,
                resolution=scene.object.resolution if resolution is None else resolution, paint=())
    return scene.with_changes(object=o)


# --- the object list ---------------------------------------------------------------------------

ROOM_STEP = 0.1  # world units between the places add_object and duplicate_object try
ROOM_MARGIN = 0.05  # the gap they leave between two objects' footprints


def object_label(scene: Scene, index: int) -> str:
    """What the object list shows for object `index`: its name, else its mesh's or voxel file's name."""
    o = scene.objects[index]
    return o.name if o.name is not None else Path(o.mesh or o.voxels or f"object {index + 1}").stem


def add_object(scene: Scene, obj: ObjectSpec) -> Scene:
    """The scene with `obj` added last, named after its file (unique), on the floor nearest the scene's centre
    where its footprint meets no other object's."""
    if len(scene.objects) >= MAX_OBJECTS:
        raise InputError(f"a scene holds at most {MAX_OBJECTS} objects")
    base = obj.name or Path(obj.mesh or obj.voxels or "object").stem
    placed = replace(obj, name=_unique_name(scene, base), translation=_free_place(scene, obj, (0.0, 0.0)))
    return scene.with_changes(objects=(*scene.objects, placed))


def duplicate_object(scene: Scene, index: int) -> Scene:
    """The scene with a copy of object `index` added last (paint and material too), named as Blender names a copy
    ("chair.001"), beside the original where there is room."""
    if len(scene.objects) >= MAX_OBJECTS:
        raise InputError(f"a scene holds at most {MAX_OBJECTS} objects")
    o = scene.objects[index]
    base = object_label(scene, index).rsplit(".", 1)
    stem = base[0] if len(base) == 2 and base[1].isdigit() else object_label(scene, index)
    name = next(f"{stem}.{k:03d}" for k in range(1, MAX_OBJECTS + 2) if f"{stem}.{k:03d}" not in _names(scene))
    copy = replace(o, name=name, translation=_free_place(scene, o, o.translation))
    return scene.with_changes(objects=(*scene.objects, copy))


def delete_object(scene: Scene, index: int) -> Scene:
    """The scene without object `index` (refused for the last one: a scene holds at least one object)."""
    if len(scene.objects) == 1:
        raise InputError("a scene holds at least one object: load another in its place in the Object tab")
    return scene.with_changes(objects=scene.objects[:index] + scene.objects[index + 1:])


def rename_object(scene: Scene, index: int, name: str) -> Scene:
    """Object `index` named `name` (spaces around it dropped; empty: no name); a name another object has is refused."""
    name = name.strip() or None
    if name is not None and name in _names(scene, but=index):
        raise InputError(f"another object is named {name!r}: names are unique")
    o = scene.objects[index]
    return scene.with_changes(objects=scene.objects[:index] + (replace(o, name=name),) + scene.objects[index + 1:])


def _names(scene: Scene, but: int | None = None) -> set[str]:
    """What the object list shows for every object but `but`: names, and the file names of unnamed objects."""
    return {object_label(scene, i) for i in range(len(scene.objects)) if i != but}


def _unique_name(scene: Scene, base: str) -> str:
    """`base`, or base.001, base.002 ... when an object has that name already."""
    taken = _names(scene)
    return base if base not in taken else next(f"{base}.{k:03d}" for k in range(1, MAX_OBJECTS + 2)
                                                 if f"{base}.{k:03d}" not in taken)


def _free_place(scene: Scene, obj: ObjectSpec, near: tuple[float, float]) -> tuple[float, float]:
    """The floor point nearest `near`, on a grid of ROOM_STEP, where `obj`'s footprint meets no object's in `scene`
    (with ROOM_MARGIN between them), within the floor the editor allows. Written here: a grid search over circles is
    a few lines, and the editor needs no packing library's generality."""
    radius = footprint_radius(obj)
    others = [(np.asarray(o.translation), footprint_radius(o) + radius + ROOM_MARGIN) for o in scene.objects]
    steps = np.arange(-MAX_POSITION, MAX_POSITION + 1e-9, ROOM_STEP)
    x, z = np.meshgrid(steps, steps, indexing="ij")
    points = np.stack([x.ravel(), z.ravel()], axis=1)
    free = np.ones(len(points), dtype=bool)
    for centre, reach in others:
        free &= np.linalg.norm(points - centre, axis=1) >= reach
    if not free.any():
        raise InputError("there is no room left on the floor for another object")
    candidates = points[free]
    # Beside rather than in front or behind: the render camera looks along -z, so a place off in z is weighed double.
    best = candidates[np.argmin(np.linalg.norm((candidates - np.asarray(near)) * [1.0, 2.0], axis=1))]
    return round(float(best[0]), 6) + 0.0, round(float(best[1]), 6) + 0.0  # + 0.0: no -0.0 in files
