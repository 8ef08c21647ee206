"""Every edit the editor makes, as a pure function from a scene to a new scene.

A value outside what the editor allows (a scale <= 0, the light under the floor or off the floor's
square, a camera at 90 degrees) is refused with an InputError that names the bounds, so a typed value
is never changed without a word; drags in the viewport stop at the bounds themselves (`clamp`).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

from renderer.environment import environment_light
from renderer.errors import InputError
from renderer.floor_texture import floor_texture
from renderer.scene import (
    FLOOR_HALF_SIZE,
    FLOOR_SHAPES,
    MAX_TEXTURE_SCALE,
    CameraSpec,
    EnvironmentSpec,
    MaterialSpec,
    PaintOp,
    Scene,
    SkySpec,
)

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
