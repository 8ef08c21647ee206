"""Appearance from a photo with a known camera: recolor the object's voxels from the pixels they project to.

The camera file is the data generator's photo_camera.json: the camera's `elevation_deg`,
`width`, `height`, `distance`, `focal_mm`, `sensor_mm`, and the object's placement when the
photo was taken (`rotation_deg`, `translation`); the object's scale is the scene's. Optional
keys `azimuth_deg` and `principal_offset` place an off-centre photo.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from renderer.camera import Camera
from renderer.errors import InputError
from renderer.io import load_image, load_json
from renderer.photo import color_voxels_from_photo
from renderer.scene import ObjectSpec
from renderer.transform import object_to_world

REQUIRED_KEYS = ("elevation_deg", "width", "height")


def load_photo_camera(path: str | Path, spec: ObjectSpec) -> tuple[Camera, ObjectSpec]:
    """The photo's camera and the object's placement in the photo (InputError on a bad file)."""
    data = load_json(path)
    if not isinstance(data, dict):
        raise InputError("a photo camera file must hold a JSON object", path)
    missing = [key for key in REQUIRED_KEYS if key not in data]
    if missing:
        raise InputError(f"missing {', '.join(missing)}", path)
    camera = Camera(
        elevation_deg=_number(data, "elevation_deg", path), width=int(_number(data, "width", path)),
        height=int(_number(data, "height", path)), distance=_number(data, "distance", path, Camera.distance),
        azimuth_deg=_number(data, "azimuth_deg", path, 0.0), focal_mm=_number(data, "focal_mm", path, Camera.focal_mm),
        sensor_mm=_number(data, "sensor_mm", path, Camera.sensor_mm),
        principal_offset=tuple(_numbers(data, "principal_offset", 2, path, (0.0, 0.0))),
    )
    placed = replace(spec, rotation_deg=_number(data, "rotation_deg", path, spec.rotation_deg),
                     translation=tuple(_numbers(data, "translation", 2, path, spec.translation)))
    if camera.width < 1 or camera.height < 1 or camera.distance <= 0 or camera.focal_mm <= 0 or camera.sensor_mm <= 0:
        raise InputError("width, height, distance, focal_mm and sensor_mm must be positive", path)
    return camera, placed


def color_from_photo(object_rgba: np.ndarray, spec: ObjectSpec, photo_path: str | Path,
                     camera_path: str | Path) -> np.ndarray:
    """The object voxels recolored from the photo (occupancy unchanged); InputError if photo and camera disagree."""
    camera, placed = load_photo_camera(camera_path, spec)
    photo, _ = load_image(photo_path)
    try:
        return color_voxels_from_photo(object_rgba, object_to_world(placed), photo, camera).rgba
    except InputError as exc:
        raise InputError(exc.problem, photo_path) from None


def _number(data: dict[str, Any], key: str, path: str | Path, default: float | None = None) -> float:
    value = data.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise InputError(f"{key} must be a finite number", path)
    return float(value)


def _numbers(data: dict[str, Any], key: str, length: int, path: str | Path, default: tuple) -> list[float]:
    value = data.get(key, list(default))
    if not isinstance(value, (list, tuple)) or len(value) != length:
        raise InputError(f"{key} must be a list of {length} numbers", path)
    return [_number({key: v}, key, path) for v in value]
