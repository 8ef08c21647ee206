"""The viewport's own camera: orbit, pan and zoom around a target, independent of the render camera.

It is a renderer.camera.Camera (the project's one camera model) whose azimuth, elevation,
distance and target the mouse changes; `projection_matrix` turns its pinhole intrinsics into
the OpenGL clip transform for drawing.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from renderer.camera import Camera

ORBIT_DEG_PER_PIXEL = 0.4
ZOOM_PER_STEP = 0.88  # distance factor per mouse wheel step
MIN_DISTANCE, MAX_DISTANCE = 0.3, 60.0
MAX_PITCH = 89.0
NEAR, FAR = 0.05, 200.0

HOME = Camera(elevation_deg=28.0, azimuth_deg=35.0, distance=5.5, focal_mm=28.0, target=(0.0, 0.5, 0.0))


def viewport_camera(view: Camera, width: int, height: int) -> Camera:
    """The view at a viewport's pixel size (focal length scales with the width)."""
    return replace(view, width=max(1, int(width)), height=max(1, int(height)))


def orbit(view: Camera, dx: float, dy: float) -> Camera:
    """Turn around the target: dragging right turns the scene right, dragging down looks from higher up."""
    elevation = min(max(view.elevation_deg + dy * ORBIT_DEG_PER_PIXEL, -MAX_PITCH), MAX_PITCH)
    return replace(view, azimuth_deg=(view.azimuth_deg - dx * ORBIT_DEG_PER_PIXEL) % 360.0, elevation_deg=elevation)


def pan(view: Camera, dx: float, dy: float) -> Camera:
    """Slide the target in the view plane so the point under the mouse follows it (dx, dy in pixels)."""
    c2w = view.camera_to_world()
    world_per_pixel = view.distance / view.focal_px
    shift = (-dx * c2w[:3, 0] + dy * c2w[:3, 1]) * world_per_pixel
    return replace(view, target=tuple((np.asarray(view.target) + shift).tolist()))


def pan_in_viewport(view: Camera, dx: float, dy: float, width: int, height: int) -> Camera:
    """`pan` as the viewport of `width` x `height` pixels shows the view (its focal length in pixels is the
    viewport's: at the view's own size a pixel would move the target several times too far)."""
    return replace(view, target=pan(viewport_camera(view, width, height), dx, dy).target)


# Blender's numpad views: from the front (the render camera's side, +z), the right (+x) and above; Ctrl: opposite.
VIEWS = {"front": (0.0, 0.0), "back": (180.0, 0.0), "right": (90.0, 0.0), "left": (270.0, 0.0),
         "top": (0.0, MAX_PITCH), "bottom": (0.0, -MAX_PITCH)}


def looking_from(view: Camera, side: str) -> Camera:
    """The view turned to look from `side` (a key of VIEWS), its target and distance kept."""
    azimuth, elevation = VIEWS[side]
    return replace(view, azimuth_deg=azimuth, elevation_deg=elevation)


def framed(view: Camera, centre, radius: float) -> Camera:
    """The view aimed at `centre` from as far as shows a sphere of `radius` with a margin (the F key)."""
    half_fov = np.arctan(0.5 * view.sensor_mm / view.focal_mm)
    distance = min(max(1.3 * radius / np.sin(half_fov), MIN_DISTANCE), MAX_DISTANCE)
    return replace(view, target=tuple(float(c) for c in centre), distance=float(distance))


def zoom(view: Camera, steps: float) -> Camera:
    """Move towards the target (positive steps) or away from it."""
    distance = min(max(view.distance * ZOOM_PER_STEP**steps, MIN_DISTANCE), MAX_DISTANCE)
    return replace(view, distance=distance)


def projection_matrix(camera: Camera, near: float = NEAR, far: float = FAR) -> np.ndarray:
    """4x4 OpenGL projection matching the camera's pinhole (focal length, principal point, image size)."""
    f = camera.focal_px
    cx, cy = camera.principal_point
    w, h = camera.width, camera.height
    m = np.zeros((4, 4))
    m[0, 0] = 2.0 * f / w
    m[1, 1] = 2.0 * f / h
    m[0, 2] = 1.0 - 2.0 * cx / w
    m[1, 2] = 2.0 * cy / h - 1.0
    m[2, 2] = -(far + near) / (far - near)
    m[2, 3] = -2.0 * far * near / (far - near)
    m[3, 2] = -1.0
    return m


def view_projection(camera: Camera) -> np.ndarray:
    """World to clip space for drawing with `camera`."""
    return projection_matrix(camera) @ camera.world_to_camera()


def frustum_corners(camera: Camera, depth: float) -> np.ndarray:
    """(4, 3) world points at `depth` along the view axis through the image corners (top-left, clockwise)."""
    u = np.array([0.0, camera.width, camera.width, 0.0])
    v = np.array([0.0, 0.0, camera.height, camera.height])
    origin, directions = camera.pixel_rays(u, v)
    forward = -camera.camera_to_world()[:3, 2]
    along = directions @ forward  # cosine of each corner ray with the view axis
    return origin + directions * (depth / along)[:, None]
