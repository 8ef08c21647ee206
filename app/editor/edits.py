"""Every edit the editor makes, as a pure function from a scene to a new scene.

Values are clamped to what a scene may hold (light above the floor, elevation below 90
degrees, positive scale), so dragging past a limit stops there instead of failing.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from renderer.scene import CameraSpec, FloorSpec, LightSpec, PaintOp, Scene

MIN_LIGHT_HEIGHT = 0.05
MAX_ELEVATION = 89.0
MIN_SCALE = 0.05
MAX_SCALE = 20.0
MAX_POSITION = 50.0


def _clamp(value: float, lo: float, hi: float) -> float:
    return min(max(float(value), lo), hi)


def move_light(scene: Scene, position: tuple[float, float, float]) -> Scene:
    """The light centred at `position` (height kept above the floor)."""
    x, y, z = position
    p = (_clamp(x, -MAX_POSITION, MAX_POSITION), _clamp(y, MIN_LIGHT_HEIGHT, MAX_POSITION), _clamp(z, -MAX_POSITION, MAX_POSITION))
    return scene.with_changes(light=LightSpec(p))


def set_elevation(scene: Scene, elevation_deg: float) -> Scene:
    return scene.with_changes(camera=CameraSpec(_clamp(elevation_deg, 0.0, MAX_ELEVATION)))


def set_floor_color(scene: Scene, color: tuple[float, float, float]) -> Scene:
    return scene.with_changes(floor=FloorSpec(tuple(_clamp(c, 0.0, 1.0) for c in color)))


def place_object(scene: Scene, translation: tuple[float, float] | None = None, rotation_deg: float | None = None,
                 scale: tuple[float, float, float] | None = None) -> Scene:
    """The object moved on the floor, turned about the vertical axis and/or scaled per axis."""
    o = scene.object
    if translation is not None:
        o = replace(o, translation=tuple(_clamp(t, -MAX_POSITION, MAX_POSITION) for t in translation))
    if rotation_deg is not None:
        o = replace(o, rotation_deg=(float(rotation_deg) + 180.0) % 360.0 - 180.0)
    if scale is not None:
        o = replace(o, scale=tuple(_clamp(s, MIN_SCALE, MAX_SCALE) for s in scale))
    return scene.with_changes(object=o)


def paint(scene: Scene, op: PaintOp) -> Scene:
    """One more paint stroke (bucket fill of a region, the whole object or the floor)."""
    return scene.with_changes(paint=(*scene.paint, op))


def replace_object_source(scene: Scene, mesh: Path | None = None, voxels: Path | None = None, up: str = "y") -> Scene:
    """The object made from another mesh or voxel file (absolute path); placement kept, color and paint reset."""
    o = replace(scene.object, mesh=None if mesh is None else str(Path(mesh).resolve()),
                voxels=None if voxels is None else str(Path(voxels).resolve()), up=up, color=None)
    floor_strokes = tuple(op for op in scene.paint if op.target == "floor")
    return scene.with_changes(object=o, paint=floor_strokes)
