"""The pose of a photo: the camera that took it and where the object stood, and its camera file.

A pose uses the project's one camera model (renderer/camera.py) at the photo's size, and the
object placement of the scene file (rotation about the vertical axis, floor translation, scale).
With the default camera (distance, focal length and look-at of every scene) a pose's rotation,
translation and elevation are exactly the scene values that reproduce the photo's view.

Camera file (JSON; the data generator writes one beside each appearance image):
    elevation_deg, width, height              required
    rotation_deg, translation [x, z], scale   the object's placement (default: the scene's)
    distance, focal_mm, sensor_mm             the camera (default: the scene camera's)
    azimuth_deg, principal_offset [du, dv]    optional, for photos taken off the usual orbit
    light [x, y, z]                           optional: the square light's centre when the photo was taken
                                              (world units); capture then divides the light out of the colors
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from renderer.camera import Camera
from renderer.errors import InputError
from renderer.io import load_json, save_json
from renderer.scene import CameraSpec, FloorSpec, LightSpec, ObjectSpec, Scene
from renderer.transform import object_to_world, world_to_object

DEFAULT_PLACEMENT = ObjectSpec()  # placement keys a camera file lacks come from here unless a scene's are given
REQUIRED_KEYS = ("elevation_deg", "width", "height")
MAX_ELEVATION_DEG = 89.0  # the camera model needs the view direction off the vertical


@dataclass(frozen=True)
class PhotoPose:
    """The photo's camera and the object's placement when the photo was taken."""

    camera: Camera
    rotation_deg: float = 0.0
    translation: tuple[float, float] = (0.0, 0.0)
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    light: tuple[float, float, float] | None = None  # the light's centre in the photo, when known

    def placed(self, spec: ObjectSpec) -> ObjectSpec:
        """`spec` moved to where the object stood in the photo."""
        return replace(spec, rotation_deg=self.rotation_deg, translation=self.translation, scale=self.scale)

    def object_to_world(self) -> np.ndarray:
        return object_to_world(self.placed(DEFAULT_PLACEMENT))

    def world_to_object(self) -> np.ndarray:
        return world_to_object(self.placed(DEFAULT_PLACEMENT))

    def at_size(self, width: int, height: int) -> PhotoPose:
        """The same pose for the photo resized to width x height (focal length and offset scale with it)."""
        factor = width / self.camera.width
        offset = (self.camera.principal_offset[0] * factor, self.camera.principal_offset[1] * factor)
        return replace(self, camera=replace(self.camera, width=width, height=height, principal_offset=offset))

    def to_dict(self) -> dict[str, Any]:
        c = self.camera
        data: dict[str, Any] = {
            "elevation_deg": c.elevation_deg, "rotation_deg": self.rotation_deg,
            "translation": list(self.translation), "scale": list(self.scale),
            "width": c.width, "height": c.height, "distance": c.distance,
            "focal_mm": c.focal_mm, "sensor_mm": c.sensor_mm,
        }
        if c.azimuth_deg != 0.0:
            data["azimuth_deg"] = c.azimuth_deg
        if c.principal_offset != (0.0, 0.0):
            data["principal_offset"] = list(c.principal_offset)
        if self.light is not None:
            data["light"] = list(self.light)
        return data


def pose_from_dict(data: Any, spec: ObjectSpec = DEFAULT_PLACEMENT, path: str | Path | None = None) -> PhotoPose:
    """A pose from a camera-file dictionary; placement keys it lacks come from `spec`. InputError names `path`."""
    if not isinstance(data, dict):
        raise InputError("a photo camera file must hold a JSON object", path)
    missing = [key for key in REQUIRED_KEYS if key not in data]
    if missing:
        raise InputError(f"missing {', '.join(missing)}", path)
    width, height = _number(data, "width", path), _number(data, "height", path)
    if width != int(width) or height != int(height) or width < 1 or height < 1:
        raise InputError("width and height must be positive whole numbers of pixels", path)
    camera = Camera(
        elevation_deg=_number(data, "elevation_deg", path), width=int(width), height=int(height),
        distance=_number(data, "distance", path, Camera.distance),
        azimuth_deg=_number(data, "azimuth_deg", path, 0.0),
        focal_mm=_number(data, "focal_mm", path, Camera.focal_mm),
        sensor_mm=_number(data, "sensor_mm", path, Camera.sensor_mm),
        principal_offset=tuple(_numbers(data, "principal_offset", 2, path, (0.0, 0.0))),
    )
    if camera.distance <= 0 or camera.focal_mm <= 0 or camera.sensor_mm <= 0:
        raise InputError("distance, focal_mm and sensor_mm must be positive", path)
    if not 0.0 <= camera.elevation_deg <= MAX_ELEVATION_DEG:
        raise InputError(f"elevation_deg must be in [0, {MAX_ELEVATION_DEG:g}], got {camera.elevation_deg:g}", path)
    scale = tuple(_numbers(data, "scale", 3, path, spec.scale))
    if min(scale) <= 0:
        raise InputError("scale must be positive", path)
    light = tuple(_numbers(data, "light", 3, path, ())) if "light" in data else None
    return PhotoPose(camera, rotation_deg=_number(data, "rotation_deg", path, spec.rotation_deg),
                     translation=tuple(_numbers(data, "translation", 2, path, spec.translation)), scale=scale,
                     light=light)


FILM_DIAGONAL_MM = math.hypot(36.0, 24.0)  # a "35 mm equivalent" focal length is relative to this frame's diagonal


def photo_camera(width: int, height: int, focal_35mm: float | None = None, elevation_deg: float = 0.0) -> Camera:
    """The camera of a photo of width x height pixels: the scene's, or with a lens of `focal_35mm` (35 mm
    equivalent, as EXIF states it), moved with the lens (a dolly zoom) so the object keeps about its size."""
    camera = Camera(elevation_deg, width=width, height=height)
    if focal_35mm is None:
        return camera
    focal_px = focal_35mm * math.hypot(width, height) / FILM_DIAGONAL_MM
    focal_mm = focal_px * camera.sensor_mm / width
    return replace(camera, focal_mm=focal_mm, distance=camera.distance * focal_mm / camera.focal_mm)


def lit_photo_scene(pose: PhotoPose, floor_color: tuple[float, float, float] = FloorSpec().color) -> Scene:
    """The scene the photo shows, lit as it was, as the voxel shader can draw it (to divide the photo's light out);
    InputError saying why when it cannot: the pose knows no light, or its camera is not the scene camera."""
    if pose.light is None:
        raise InputError("the photo's light is unknown")
    c = pose.camera
    if c != Camera(c.elevation_deg, width=c.width, height=c.width):
        raise InputError("the photo's camera is not the scene camera (a square photo from its orbit, 40 mm lens)")
    return Scene.single(object=pose.placed(ObjectSpec()), floor=FloorSpec(tuple(float(v) for v in floor_color)),
                 light=LightSpec(tuple(float(v) for v in pose.light)), camera=CameraSpec(c.elevation_deg),
                 image_size=c.width)


def load_pose(path: str | Path, spec: ObjectSpec = DEFAULT_PLACEMENT) -> PhotoPose:
    """Read a camera file (InputError with the file's name on any problem)."""
    return pose_from_dict(load_json(path), spec, path)


def save_pose(path: str | Path, pose: PhotoPose) -> None:
    save_json(path, pose.to_dict())


def _number(data: dict[str, Any], key: str, path: str | Path | None, default: float | None = None) -> float:
    value = data.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise InputError(f"{key} must be a finite number", path)
    return float(value)


def _numbers(data: dict[str, Any], key: str, length: int, path: str | Path | None, default: tuple) -> list[float]:
    value = data.get(key, list(default))
    if not isinstance(value, (list, tuple)) or len(value) != length:
        raise InputError(f"{key} must be a list of {length} numbers", path)
    return [_number({key: v}, key, path) for v in value]
