"""The Photo tab's model: a photo, the pose being aligned to it, and the mesh's silhouette drawn over it.

The user aligns by hand (drag on the photo to turn, Shift+drag to move, the wheel to scale, or
the numeric fields), lets the search refine that pose or find one from nothing, then colors
the object from the photo; optionally the scene takes the photo's view (placement and elevation).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import trimesh

from renderer.camera import Camera
from renderer.capture.capture import capture_appearance
from renderer.capture.pose import MAX_ELEVATION_DEG, PhotoPose, load_pose
from renderer.capture.silhouette import SilhouetteRenderer
from renderer.io import load_image
from renderer.scene import ObjectSpec, Scene

OVERLAY_SIDE = 320  # long side of the photo shown in the Photo tab
OUTLINE_COLOR = np.array([1.0, 0.2, 0.6])
TURN_DEG_PER_PIXEL = 0.5
SHIFT_PER_PIXEL = 0.004  # object units per pixel of the overlay
SCALE_PER_WHEEL_STEP = 1.05


class PhotoAlignment:
    """A loaded photo and its current pose; `overlay()` shows how well the pose fits."""

    def __init__(self, path: str | Path, scene: Scene, camera_path: str | Path | None = None):
        self.path = Path(path)
        self.rgb, self.alpha = load_image(path)
        h, w = self.rgb.shape[:2]
        if camera_path is not None:
            self.pose = load_pose(camera_path, scene.object).at_size(w, h)
        else:  # start from the scene's own view, which is what a user sets up to match the photo
            self.pose = PhotoPose(Camera(scene.camera.elevation_deg, w, h), scene.object.rotation_deg,
                                  scene.object.translation, scene.object.scale)
        self._silhouettes: SilhouetteRenderer | None = None
        self._mesh_key: object = None
        self.revision = 0  # grows with every pose change, so the window knows when to redraw the overlay

    def set_mesh(self, mesh: trimesh.Trimesh, key: object) -> None:
        """Use this mesh (object coordinates) for the silhouette; `key` names it so reloading is skipped."""
        if key != self._mesh_key:
            self._silhouettes = SilhouetteRenderer(mesh)
            self._mesh_key = key
            self.revision += 1

    @property
    def silhouettes(self) -> SilhouetteRenderer | None:
        return self._silhouettes

    def set_pose(self, pose: PhotoPose) -> None:
        h, w = self.rgb.shape[:2]
        elevation = float(np.clip(pose.camera.elevation_deg, 0.0, MAX_ELEVATION_DEG))
        self.pose = replace(pose, camera=replace(pose.camera, elevation_deg=elevation)).at_size(w, h)
        self.revision += 1

    def turn(self, dx_pixels: float, dy_pixels: float) -> None:
        """Mouse drag on the overlay: right turns the object, down raises the camera."""
        p = self.pose
        self.set_pose(replace(p, rotation_deg=_wrap(p.rotation_deg + TURN_DEG_PER_PIXEL * dx_pixels),
                              camera=replace(p.camera, elevation_deg=p.camera.elevation_deg + TURN_DEG_PER_PIXEL * dy_pixels)))

    def shift(self, dx_pixels: float, dy_pixels: float) -> None:
        """Shift+drag: move the object on the floor, across the view (x) and towards the camera (z)."""
        x, z = self.pose.translation
        self.set_pose(replace(self.pose, translation=(x + SHIFT_PER_PIXEL * dx_pixels, z + SHIFT_PER_PIXEL * dy_pixels)))

    def zoom(self, wheel_steps: float) -> None:
        factor = SCALE_PER_WHEEL_STEP**wheel_steps
        self.set_pose(replace(self.pose, scale=tuple(s * factor for s in self.pose.scale)))

    def overlay(self, long_side: int = OVERLAY_SIDE) -> np.ndarray:
        """The photo at display size with the silhouette's outline drawn over it ((H, W, 3) sRGB)."""
        h, w = self.rgb.shape[:2]
        factor = min(1.0, long_side / max(h, w))
        size = (max(1, round(w * factor)), max(1, round(h * factor)))
        from PIL import Image

        shown = np.asarray(Image.fromarray((self.rgb * 255).astype(np.uint8)).resize(size, Image.Resampling.BOX),
                           dtype=np.float32) / 255.0
        if self._silhouettes is None:
            return shown
        mask = self._silhouettes.mask(self.pose.at_size(*size))
        outline = mask & ~_eroded(mask)
        shown = shown.copy()
        shown[mask] = 0.75 * shown[mask] + 0.25 * OUTLINE_COLOR
        shown[outline] = OUTLINE_COLOR
        return shown


def scene_with_photo_view(scene: Scene, pose: PhotoPose) -> Scene:
    """The scene placed and seen as in the photo: the pose's rotation, translation, scale and elevation."""
    return scene.with_changes(object=pose.placed(scene.object),
                              camera=replace(scene.camera, elevation_deg=pose.camera.elevation_deg))


def color_from_photo(object_rgba: np.ndarray, spec: ObjectSpec, photo_path: str | Path,
                     camera_path: str | Path) -> np.ndarray:
    """The object voxels recolored from a photo with a known camera (occupancy unchanged)."""
    photo, alpha = load_image(photo_path)
    pose = load_pose(camera_path, spec)
    return capture_appearance(object_rgba, None, photo, alpha, pose, search=False, path=photo_path).rgba


def _eroded(mask: np.ndarray) -> np.ndarray:
    """Pixels whose 4 neighbours are all in the mask."""
    inner = mask.copy()
    inner[1:] &= mask[:-1]
    inner[:-1] &= mask[1:]
    inner[:, 1:] &= mask[:, :-1]
    inner[:, :-1] &= mask[:, 1:]
    return inner


def _wrap(angle_deg: float) -> float:
    return math.remainder(angle_deg, 360.0)
