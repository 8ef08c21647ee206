"""The Photo tab's model: a photo, the pose being aligned to it, and the mesh's silhouette drawn over it.

The user aligns by hand (drag on the photo to turn, Shift+drag to move, the wheel to scale, or
the numeric fields), lets the search refine that pose or find one from nothing, then colors
the object from the photo; optionally the scene takes the photo's view (placement and elevation).
The commands that do this in the editor are in app/editor/photo_tool.py, the tab in photo_panel.py.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import trimesh
from PIL import Image

from renderer.camera import Camera
from renderer.capture.capture import ASPECT_TOLERANCE, Capture, capture_appearance, mask_at_size, trusted_pixels
from renderer.capture.light_fit import FittedLight
from renderer.capture.pose import MAX_ELEVATION_DEG, PhotoPose, load_pose, photo_camera
from renderer.capture.silhouette import SilhouetteRenderer
from renderer.errors import InputError
from renderer.io import load_image, photo_focal_35mm
from renderer.pipeline import object_mesh
from renderer.scene import Scene
from renderer.voxel_faces import voxel_surface_mesh
from renderer.voxels import ProgressCallback

if TYPE_CHECKING:
    from renderer.voxel_cache import VoxelCache

OVERLAY_SIDE = 320  # default long side of the overlay (the Photo tab asks for the size it shows)
OUTLINE_COLOR = np.array([1.0, 0.2, 0.6])
STROKE_OBJECT, STROKE_BACKGROUND = np.array([0.2, 0.9, 0.3]), np.array([0.95, 0.3, 0.2])
UNTRUSTED_COLOR = np.array([1.0, 0.7, 0.1])  # the mask's rim, whose pixels do not color the object
DISK_COLOR = np.array([0.2, 0.8, 1.0])  # the outline of a saucer or plate the search found under the object
TURN_DEG_PER_PIXEL = 0.5  # per pixel the mouse moves over the overlay as shown
SHIFT_PER_PIXEL = 0.004  # object units per pixel the mouse moves over the overlay
SCALE_PER_WHEEL_STEP = 1.05
SHOWN_SIZES_KEPT = 4  # resized photos kept (a drag uses two sizes: small while dragging, full after)


class PhotoAlignment:
    """A loaded photo and its current pose; `overlay()` shows how well the pose fits."""

    def __init__(self, path: str | Path, scene: Scene, camera_path: str | Path | None = None):
        self.path = Path(path)
        self.rgb, self.alpha = load_image(path)
        self.focal_35mm = photo_focal_35mm(path)  # the lens the photo's EXIF states, if it does
        h, w = self.rgb.shape[:2]
        if camera_path is not None:
            filed = load_pose(camera_path, scene.object)
            _check_aspect(filed.camera, w, h, self.path)
            self.pose = filed.at_size(w, h)
        else:  # start from the scene's own view, which is what a user sets up to match the photo, through its lens
            self.pose = PhotoPose(photo_camera(w, h, self.focal_35mm, scene.camera.elevation_deg),
                                  scene.object.rotation_deg, scene.object.translation, scene.object.scale)
        self.mesh: trimesh.Trimesh | None = None  # the object's shape, which the search aligns
        self._silhouettes: SilhouetteRenderer | None = None
        self._mesh_key: object = None
        self._shown_photos: dict[tuple[int, int], np.ndarray] = {}  # the photo resized for the overlay, by size
        self.revision = 0  # grows with every pose change, so the window knows when to redraw the overlay
        self.box: tuple[int, int, int, int] | None = None  # the user's box around the object (photo pixels), or None
        self.strokes = np.zeros((h, w), np.int8)  # the user's strokes: 1 object, -1 background, 0 none
        self.mask: np.ndarray | None = None  # the object's mask as segmented from the photo with these hints, to show
        self.trusted: np.ndarray | None = None  # the mask's pixels that color the object (capture.trusted_pixels)
        self.divide_light = True  # coloring fits the photo's light and divides it out (else colors keep the shading)
        self.light_note = ""  # what the last coloring did with the photo's light
        self.fitted_light: FittedLight | None = None  # the light the last coloring fitted, if it did
        self.floor_disk = 0.0  # radius (object units) of the saucer or plate the last search found under the object

    def set_mesh(self, mesh: trimesh.Trimesh, key: object, silhouettes: SilhouetteRenderer | None = None) -> None:
        """Use this mesh (object coordinates) for the silhouette; `key` names it so reloading is skipped.

        `silhouettes` is the mesh's renderer when it was already built (building one takes up to a
        second, so the editor does it in a background job).
        """
        if key != self._mesh_key:
            self._silhouettes = silhouettes or SilhouetteRenderer(mesh)
            self.mesh = mesh
            self._mesh_key = key
            self.floor_disk = 0.0  # found under another shape
            self.revision += 1

    @property
    def mesh_key(self) -> object:
        """The key of the mesh in use (None before `set_mesh`)."""
        return self._mesh_key

    @property
    def silhouettes(self) -> SilhouetteRenderer | None:
        return self._silhouettes

    def set_box(self, box: tuple[float, float, float, float] | None) -> None:
        """The object's box (x0, y0, x1, y1 in photo pixels, any corner order), clipped to the photo; None clears it."""
        if box is None:
            self.box = None
        else:
            h, w = self.rgb.shape[:2]
            x0, x1 = sorted((int(np.clip(box[0], 0, w)), int(np.clip(box[2], 0, w))))
            y0, y1 = sorted((int(np.clip(box[1], 0, h)), int(np.clip(box[3], 0, h))))
            self.box = (x0, y0, x1, y1) if x1 - x0 >= 2 and y1 - y0 >= 2 else None

    def stroke(self, x: float, y: float, radius: float, object_: bool) -> None:
        """Paint a disc of `radius` photo pixels at (x, y) as surely object (or surely background)."""
        h, w = self.strokes.shape
        x0, x1 = max(0, int(x - radius)), min(w, int(x + radius) + 1)  # only the disc's square: a drag paints
        y0, y1 = max(0, int(y - radius)), min(h, int(y + radius) + 1)  # every frame, on photos of millions of pixels
        if x0 >= x1 or y0 >= y1:
            return
        yy, xx = np.ogrid[y0:y1, x0:x1]
        self.strokes[y0:y1, x0:x1][(xx - x) ** 2 + (yy - y) ** 2 <= radius**2] = 1 if object_ else -1
        self.mask = None  # segmented without these strokes
        self.revision += 1

    def clear_hints(self) -> None:
        self.box, self.mask = None, None
        self.strokes[:] = 0
        self.revision += 1

    def hints(self) -> dict:
        """The user's hints as find_pose takes them (photo pixels)."""
        return {"box": self.box, "object_strokes": self.strokes > 0 if (self.strokes > 0).any() else None,
                "background_strokes": self.strokes < 0 if (self.strokes < 0).any() else None}

    def set_mask(self, mask: np.ndarray | None) -> None:
        self.mask = mask
        self.trusted = trusted_pixels(mask)
        self.revision += 1

    def set_pose(self, pose: PhotoPose) -> None:
        h, w = self.rgb.shape[:2]
        elevation = float(np.clip(pose.camera.elevation_deg, 0.0, MAX_ELEVATION_DEG))
        # The light is the photo's (its camera file's), whatever pose a search or a drag proposes.
        self.pose = replace(pose, camera=replace(pose.camera, elevation_deg=elevation),
                            light=self.pose.light).at_size(w, h)
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
        shown = self._shown_photo(size)
        if self.mask is not None or self.strokes.any():  # the segmentation and strokes, over the photo
            shown = shown.copy()
            if self.mask is not None:
                segmented = mask_at_size(self.mask, size)
                shown[~segmented] *= 0.45  # the background darkened: what stays bright is the object
                rim = segmented & ~mask_at_size(self.trusted, size)  # on the object, but too near its edge to trust
                shown[rim] = 0.5 * shown[rim] + 0.5 * UNTRUSTED_COLOR
            strokes = np.asarray(Image.fromarray(self.strokes.astype(np.uint8) + 1).resize(size, Image.Resampling.NEAREST))
            shown[strokes == 2] = STROKE_OBJECT
            shown[strokes == 0] = STROKE_BACKGROUND
        if self._silhouettes is None:
            return shown
        pose = self.pose.at_size(*size)
        mask = self._silhouettes.mask(pose)
        outline = mask & ~_eroded(mask)
        shown = shown.copy()
        if self.floor_disk > 0.0:  # the saucer's rim where the object does not hide it
            disk = self._silhouettes.floor_radii(pose, self.floor_disk) <= self.floor_disk
            shown[disk & ~_eroded(disk) & ~mask] = DISK_COLOR
        shown[mask] = 0.75 * shown[mask] + 0.25 * OUTLINE_COLOR
        shown[outline] = OUTLINE_COLOR
        return shown

    def _shown_photo(self, size: tuple[int, int]) -> np.ndarray:
        """The photo resized to `size` (width, height), kept: a drag redraws the overlay every frame."""
        if size not in self._shown_photos:
            if len(self._shown_photos) >= SHOWN_SIZES_KEPT:
                self._shown_photos.clear()
            small = Image.fromarray((self.rgb * 255).astype(np.uint8)).resize(size, Image.Resampling.BOX)
            self._shown_photos[size] = np.asarray(small, dtype=np.float32) / 255.0
        return self._shown_photos[size]

    def colors(self, object_rgba: np.ndarray, pose: PhotoPose | None = None,
               progress: ProgressCallback | None = None) -> Capture:
        """`object_rgba` recolored from the photo seen at `pose` (default: the current one), occupancy unchanged;
        the photo's light fitted and divided out when `divide_light` is set."""
        pose = self.pose if pose is None else pose
        return capture_appearance(object_rgba, self.mesh, self.rgb, self.alpha, pose, search=False, path=self.path,
                                  fit_photo_light=self.divide_light, progress=progress, **self.hints())

    def set_light(self, capture: Capture) -> None:
        """Keep what a coloring did with the photo's light, to show it."""
        self.light_note, self.fitted_light = capture.light_note, capture.fitted_light


def scene_with_photo_view(scene: Scene, pose: PhotoPose) -> Scene:
    """The scene placed and seen as in the photo: the pose's rotation, translation, scale and elevation."""
    return scene.with_changes(object=pose.placed(scene.object),
                              camera=replace(scene.camera, elevation_deg=pose.camera.elevation_deg))


def shape_key(scene: Scene) -> tuple:
    """What the object's shape depends on: its mesh file and up axis, or (without a mesh) its voxels' source."""
    mesh = scene.mesh_path()
    if mesh is not None:
        return ("mesh", str(mesh.resolve()), scene.object.up)
    return ("voxels", str(scene.voxels_path().resolve()), scene.object.resolution)


def object_shape(scene: Scene, voxels: VoxelCache) -> trimesh.Trimesh:
    """The object's shape in object coordinates, to align with a photo: its mesh, else the surface of its voxels."""
    if scene.mesh_path() is not None:
        return object_mesh(scene)
    return voxel_surface_mesh(voxels.object_rgba(scene))


def _check_aspect(camera: Camera, width: int, height: int, path: Path) -> None:
    """A camera file made for another aspect ratio than the photo's is a mistake (a resized photo is fine)."""
    if abs(camera.width * height - camera.height * width) > ASPECT_TOLERANCE * camera.width * height:
        raise InputError(f"the photo is {width}x{height} pixels but its camera is {camera.width}x{camera.height}", path)


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

