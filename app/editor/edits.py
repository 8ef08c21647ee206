"""Every edit the editor makes, as a pure function from a scene to a new scene.

A value outside what the editor allows (a scale <= 0, the light under the floor or off the floor's
square, a camera at 90 degrees) is refused with an InputError that names the bounds, so a typed value
is never changed without a word; drags in the viewport stop at the bounds themselves (`clamp`).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

from renderer.errors import InputError
from renderer.scene import FLOOR_HALF_SIZE, CameraSpec, FloorSpec, LightSpec, PaintOp, Scene

MIN_LIGHT_HEIGHT = 0.05
MAX_LIGHT_HEIGHT = 10.0
MAX_ELEVATION = 89.0
MIN_SCALE = 0.05
MAX_SCALE = 20.0
MAX_POSITION = FLOOR_HALF_SIZE  # the object and the light stay over the floor's square


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
    return scene.with_changes(light=LightSpec((x, y, z)))


def set_elevation(scene: Scene, elevation_deg: float) -> Scene:
    (elevation,) = _check("camera elevation", (elevation_deg,), 0.0, MAX_ELEVATION)
    return scene.with_changes(camera=CameraSpec(elevation))


def set_floor_color(scene: Scene, color: tuple[float, float, float]) -> Scene:
    return scene.with_changes(floor=FloorSpec(_check("floor color", color, 0.0, 1.0)))


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
    """One more paint stroke (bucket fill of a region, the whole object or the floor)."""
    return scene.with_changes(paint=(*scene.paint, op))


def replace_object_source(scene: Scene, mesh: Path | None = None, voxels: Path | None = None, up: str = "y",
                          resolution: int | None = None) -> Scene:
    """The object made from another mesh or voxel file (absolute path); placement kept, color and paint reset."""
    o = replace(scene.object, mesh=None if mesh is None else str(Path(mesh).resolve()),
                voxels=None if voxels is None else str(Path(voxels).resolve()), up=up, color=None,
                resolution=scene.object.resolution if resolution is None else resolution)
    floor_strokes = tuple(op for op in scene.paint if op.target == "floor")
    return scene.with_changes(object=o, paint=floor_strokes)
