"""The one camera model of the project: a pinhole looking at the scene centre from an elevation.

Conventions used everywhere (splatting, path tracing, photo coloring, the editor):
- World: y up, floor at y = 0; the camera is on the +z side at azimuth 0, so at elevation 0
  it looks along -z.
- Camera coordinates (OpenGL style): x right, y up, the camera looks along -z.
- Pixels: column u grows to the right, row v grows downwards; pixel (row i, column j) has its
  centre at (u, v) = (j + 0.5, i + 0.5).
- Camera-aligned scene grid (what the network reads): an array indexed [depth, row, column],
  a cube of side GRID_EXTENT centred on the look-at point. Depth index 0 is nearest to the
  camera; row 0 is the top of the image (camera +y); column 0 is the left (camera -x).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from renderer.scene import CAMERA_DISTANCE, FOCAL_MM, GRID_EXTENT, GRID_SIZE, LOOK_AT, SENSOR_MM, Scene


@dataclass(frozen=True)
class Camera:
    """Pinhole camera orbiting LOOK_AT at `distance`, `elevation_deg` above the floor plane.

    `azimuth_deg` turns the camera about the vertical axis (0 for the render camera; the
    photo camera of a captured appearance may differ). `principal_offset` shifts the image
    centre, in pixels, for photos whose object is off centre.
    """

    elevation_deg: float
    width: int = 256
    height: int = 256
    distance: float = CAMERA_DISTANCE
    azimuth_deg: float = 0.0
    focal_mm: float = FOCAL_MM
    sensor_mm: float = SENSOR_MM
    target: tuple[float, float, float] = LOOK_AT
    principal_offset: tuple[float, float] = (0.0, 0.0)

    @classmethod
    def from_scene(cls, scene: Scene, size: int | None = None) -> Camera:
        """The render camera of a scene, at the scene's image size or `size`."""
        s = scene.image_size if size is None else size
        return cls(elevation_deg=scene.camera.elevation_deg, width=s, height=s)

    # --- extrinsics ---------------------------------------------------------------------

    @property
    def position(self) -> np.ndarray:
        """Camera centre in world coordinates."""
        el, az = math.radians(self.elevation_deg), math.radians(self.azimuth_deg)
        offset = np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)])
        return np.asarray(self.target, dtype=np.float64) + self.distance * offset

    def camera_to_world(self) -> np.ndarray:
        """4x4 matrix taking camera coordinates to world coordinates."""
        return _camera_to_world(self).copy()

    def world_to_camera(self) -> np.ndarray:
        """4x4 matrix taking world coordinates to camera coordinates (inverse of a rigid map)."""
        return _world_to_camera(self).copy()

    # --- intrinsics ---------------------------------------------------------------------

    @property
    def focal_px(self) -> float:
        """Focal length in pixels; the sensor width maps to the image width."""
        return self.focal_mm / self.sensor_mm * self.width

    @property
    def fov_x_deg(self) -> float:
        return math.degrees(2.0 * math.atan(0.5 * self.sensor_mm / self.focal_mm))

    @property
    def principal_point(self) -> tuple[float, float]:
        return (0.5 * self.width + self.principal_offset[0], 0.5 * self.height + self.principal_offset[1])

    def intrinsics(self) -> np.ndarray:
        """3x3 matrix K mapping camera rays (x, -y, -z) to pixels (u, v, 1)."""
        cx, cy = self.principal_point
        f = self.focal_px
        return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])

    # --- projection ---------------------------------------------------------------------

    def project(self, points_world: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Project world points (..., 3) to pixel coordinates u, v and depth (distance along the view axis).

        Points behind the camera get depth <= 0; callers must discard them.
        """
        p = np.asarray(points_world, dtype=np.float64)
        w2c = self.world_to_camera()
        pc = p @ w2c[:3, :3].T + w2c[:3, 3]
        depth = -pc[..., 2]
        safe = np.where(depth > 1e-9, depth, 1e-9)
        cx, cy = self.principal_point
        u = cx + self.focal_px * pc[..., 0] / safe
        v = cy - self.focal_px * pc[..., 1] / safe
        return u, v, depth

    def pixel_rays(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World-space ray origin (3,) and unit directions (..., 3) through pixel coordinates (u, v).

        The camera-space direction is (x, y, -1); each world component is a weighted sum of x and y, written
        per component (faster than stacking and multiplying by the rotation)."""
        cx, cy = self.principal_point
        x, y = np.broadcast_arrays((np.asarray(u, dtype=np.float64) - cx) / self.focal_px,
                                   (cy - np.asarray(v, dtype=np.float64)) / self.focal_px)
        c2w = self.camera_to_world()
        d_world = np.empty(x.shape + (3,))
        for k in range(3):
            d_world[..., k] = c2w[k, 0] * x + c2w[k, 1] * y - c2w[k, 2]
        d_world /= np.sqrt(np.einsum("...i,...i->...", d_world, d_world))[..., None]
        return c2w[:3, 3].copy(), d_world


# --- extrinsic matrices, kept per camera (a frame asks for them dozens of times, and building them is slow)


@lru_cache(maxsize=64)
def _camera_to_world(camera: Camera) -> np.ndarray:
    eye = camera.position
    forward = np.asarray(camera.target, dtype=np.float64) - eye
    forward /= np.linalg.norm(forward)
    # Elevation is below 90 degrees, so forward is never parallel to world up.
    right = np.cross(forward, np.array([0.0, 1.0, 0.0]))
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, up, -forward, eye
    m.flags.writeable = False
    return m


@lru_cache(maxsize=64)
def _world_to_camera(camera: Camera) -> np.ndarray:
    c2w = _camera_to_world(camera)
    rot, eye = c2w[:3, :3], c2w[:3, 3]
    m = np.eye(4)
    m[:3, :3] = rot.T
    m[:3, 3] = -rot.T @ eye
    m.flags.writeable = False
    return m


# --- the camera-aligned scene grid -----------------------------------------------------------


def grid_voxel_size(grid_size: int = GRID_SIZE, extent: float = GRID_EXTENT) -> float:
    return extent / grid_size


def grid_centers_camera(grid_size: int = GRID_SIZE, extent: float = GRID_EXTENT, distance: float = CAMERA_DISTANCE) -> np.ndarray:
    """Camera-space centres of every grid voxel, shape (D, H, W, 3), indexed [depth, row, column]."""
    s = extent / grid_size
    idx = (np.arange(grid_size) + 0.5) * s - 0.5 * extent  # -extent/2 .. +extent/2
    z = -(distance + idx)  # depth index 0 nearest the camera
    y = -idx  # row 0 at the top
    x = idx  # column 0 at the left
    zz, yy, xx = np.meshgrid(z, y, x, indexing="ij")
    return np.stack([xx, yy, zz], axis=-1)


def camera_to_grid_index(points_camera: np.ndarray, grid_size: int = GRID_SIZE, extent: float = GRID_EXTENT,
                         distance: float = CAMERA_DISTANCE) -> np.ndarray:
    """Continuous grid coordinates (depth, row, column) of camera-space points; voxel k spans [k, k+1)."""
    p = np.asarray(points_camera, dtype=np.float64)
    s = extent / grid_size
    half = 0.5 * extent
    depth = (-p[..., 2] - distance + half) / s
    row = (-p[..., 1] + half) / s
    col = (p[..., 0] + half) / s
    return np.stack([depth, row, col], axis=-1)
