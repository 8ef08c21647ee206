"""Splatting (paper section 3.4): the image S of the colored voxels seen by the target camera.

Every surface voxel that faces the camera (it has an exposed face whose outer side sees the
camera; no other voxel can be the first one a camera ray meets) is projected at its centre
and drawn as an axis-aligned rectangle covering the voxel's projected cube, so neighbouring
voxels always overlap and a solid surface has no holes. A z-buffer keeps the nearest voxel of
each pixel. Pixels that no voxel
covers show the flat floor color where the camera ray meets the floor square, else the
background: the ambient environment seen directly, as the path tracer shows it.

The floor never hides a voxel: the camera (elevation >= 0 above a look-at point at y > 0) and
the object (standing on y = 0) both lie above the floor plane, so every segment between them
does too. Object pixels are therefore simply drawn over the ground.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from renderer.camera import Camera
from renderer.color import linear_to_srgb
from renderer.errors import InputError
from renderer.scene import AMBIENT_RADIANCE, FLOOR_HALF_SIZE, OBJECT_SIZE, Scene
from renderer.surface import Shell, check_object_voxels, grid_from_world, occupancy, voxel_centers_at
from renderer.transform import apply_transform, object_to_world

NEAR_DEPTH = 1e-3  # voxels closer to the image plane than this (or behind it) are dropped
CANDIDATE_BUDGET = 4_000_000  # pixel candidates handled at once: bounds memory for huge footprints
_EMPTY = np.iinfo(np.int64).max  # z-buffer value of a pixel no voxel covers


def background_color() -> np.ndarray:
    """sRGB color of the uniform ambient environment seen directly (the path tracer's background)."""
    return np.full(3, linear_to_srgb(AMBIENT_RADIANCE), dtype=np.float32)


@dataclass(frozen=True)
class SplatLayout:
    """Everything a splat shows that colors do not change, so a paint stroke or a new floor color reuses it."""

    voxel: np.ndarray  # (H, W) int64: flat index of the object voxel seen at the pixel, -1 where none is
    floor: np.ndarray  # (H, W) bool: the pixel's ray meets the floor square (floor_mask)


def splat(object_rgba: np.ndarray, object_to_world_matrix: np.ndarray, floor_color, camera: Camera) -> np.ndarray:
    """The splatted image S, (H, W, 3) float32 sRGB in [0, 1], of the object voxels placed in the world."""
    rgba = check_object_voxels(object_rgba)
    return color_splat(splat_layout(Shell(occupancy(rgba)), object_to_world_matrix, camera), rgba, floor_color)


def splat_scene(scene: Scene, object_rgba: np.ndarray, floor_color, size: int | None = None) -> np.ndarray:
    """`splat` with the scene's render camera (at `size`, default the scene's image size) and object placement."""
    return splat(object_rgba, object_to_world(scene.object), floor_color, Camera.from_scene(scene, size))


def splat_layout(shell: Shell, object_to_world_matrix: np.ndarray, camera: Camera) -> SplatLayout:
    """Which voxel of an (N, N, N) object grid (its Shell) placed in the world each pixel shows, and where the floor is."""
    n = shell.shape[0]
    matrix = np.asarray(object_to_world_matrix, dtype=np.float64)
    flat = shell.facing(apply_transform(grid_from_world(matrix, n), camera.position))
    voxel = np.full((camera.height, camera.width), -1, dtype=np.int64)
    if flat.size:
        centres = apply_transform(matrix, voxel_centers_at(np.stack(np.unravel_index(flat, (n, n, n)), axis=1), n))
        edges = matrix[:3, :3] * (OBJECT_SIZE / n)  # columns: the voxel's edge vectors in the world
        nearest = nearest_point_per_pixel(centres, edges, camera)
        covered = nearest >= 0
        voxel[covered] = flat[nearest[covered]]
    return SplatLayout(voxel, cached_floor_mask(camera))


def color_splat(layout: SplatLayout, object_rgba: np.ndarray, floor_color) -> np.ndarray:
    """The splatted image of `layout` with the voxels' colors: floor color on the floor, background elsewhere."""
    image = ground_and_background(layout.floor, floor_color)
    covered = layout.voxel >= 0
    image[covered] = np.clip(np.asarray(object_rgba).reshape(-1, 4)[layout.voxel[covered], :3], 0.0, 1.0)
    return image


def ground_and_background(floor: np.ndarray, floor_color) -> np.ndarray:
    """(H, W, 3) float32 image of the empty scene: floor color where `floor` (floor_mask), background elsewhere."""
    color = np.asarray(floor_color, dtype=np.float64)
    if color.shape != (3,) or not np.all(np.isfinite(color)):
        raise InputError(f"floor color must be 3 finite sRGB values, got {floor_color!r}")
    rows = np.stack([background_color(), np.clip(color, 0.0, 1.0).astype(np.float32)])
    return np.take(rows, np.asarray(floor, dtype=bool).view(np.uint8), axis=0)  # row 1 on the floor (np.where: 6x slower)


@lru_cache(maxsize=8)
def cached_floor_mask(camera: Camera) -> np.ndarray:
    """Cached, read-only `floor_mask`: the editor renders many frames with one camera, and the splat, the shader
    and the lit floor each need it."""
    mask = floor_mask(camera)
    mask.flags.writeable = False
    return mask


def floor_mask(camera: Camera) -> np.ndarray:
    """(H, W) bool: the ray through the pixel centre meets the plane y = 0 inside the floor square."""
    rows, cols = np.mgrid[0 : camera.height, 0 : camera.width]
    origin, dirs = camera.pixel_rays(cols + 0.5, rows + 0.5)
    down = dirs[..., 1] < 0.0
    t = np.where(down, -origin[1] / np.where(down, dirs[..., 1], -1.0), 0.0)
    hit_x = origin[0] + t * dirs[..., 0]
    hit_z = origin[2] + t * dirs[..., 2]
    return down & (np.abs(hit_x) <= FLOOR_HALF_SIZE) & (np.abs(hit_z) <= FLOOR_HALF_SIZE)


def nearest_point_per_pixel(centres_world: np.ndarray, edges_world: np.ndarray, camera: Camera) -> np.ndarray:
    """(H, W) index of the nearest splatted voxel per pixel, -1 where none.

    `centres_world` (n, 3) are voxel centres; the columns of `edges_world` (3, 3) are the world
    edge vectors shared by all voxels (the placed voxel is a parallelepiped).
    """
    u, v, depth = camera.project(centres_world)
    keep = np.flatnonzero(depth > NEAR_DEPTH)
    u, v, depth = u[keep], v[keep], depth[keep]
    half_u, half_v = footprint_half_sizes(u, v, depth, edges_world, camera)
    col0, col1 = _covered_range(u, half_u, camera.width)
    row0, row1 = _covered_range(v, half_v, camera.height)
    inside = np.flatnonzero((col0 <= col1) & (row0 <= row1))
    keys = _depth_keys(depth[inside], keep[inside])
    zbuffer = np.full(camera.height * camera.width, _EMPTY, dtype=np.int64)
    for chunk in _chunks(((col1 - col0 + 1) * (row1 - row0 + 1))[inside]):
        sel = inside[chunk]
        pixels, owner = _rectangle_pixels(col0[sel], col1[sel], row0[sel], row1[sel], camera.width)
        np.minimum.at(zbuffer, pixels, keys[chunk][owner])
    nearest = np.where(zbuffer == _EMPTY, -1, zbuffer & 0xFFFFFFFF)
    return nearest.reshape(camera.height, camera.width)


def footprint_half_sizes(u: np.ndarray, v: np.ndarray, depth: np.ndarray, edges_world: np.ndarray,
                         camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Half width and half height, in pixels, of the bounding box of each voxel's projected cube.

    First-order perspective: a camera-space offset (dx, dy, dz) at a point with x/depth = a,
    y/depth = b moves the pixel by f/depth * (dx + a dz, -(dy + b dz)); the box of a
    parallelepiped with edges e_k spans half of sum_k |.| of its edges' offsets.
    """
    edges_cam = camera.world_to_camera()[:3, :3] @ edges_world  # columns e_k in camera space
    f = camera.focal_px
    cx, cy = camera.principal_point
    a = (u - cx) / f
    b = (cy - v) / f
    ex, ey, ez = edges_cam
    half_u = sum(np.abs(ex[k] + a * ez[k]) for k in range(3))
    half_v = sum(np.abs(ey[k] + b * ez[k]) for k in range(3))
    scale = 0.5 * f / depth
    return scale * half_u, scale * half_v


def _covered_range(centre: np.ndarray, half: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """First and last pixel whose centre lies within `half` of `centre`, always including the pixel
    holding `centre` (so a voxel smaller than a pixel still shows), clipped to the image."""
    c = np.clip(centre, -1.0, size + 1.0)
    h = np.minimum(half, size + 2.0)
    own = np.floor(c)
    first = np.minimum(np.ceil(c - h - 0.5), own)
    last = np.maximum(np.floor(c + h - 0.5), own)
    return np.maximum(first, 0).astype(np.int64), np.minimum(last, size - 1).astype(np.int64)


def _depth_keys(depth: np.ndarray, point_index: np.ndarray) -> np.ndarray:
    """int64 keys ordered by depth then point index: positive float32 bits sort like the floats."""
    bits = depth.astype(np.float32).view(np.int32).astype(np.int64)
    return (bits << 32) | point_index.astype(np.int64)


def _chunks(counts: np.ndarray):
    """Consecutive slices of points whose pixel counts sum to about CANDIDATE_BUDGET (at least one point each)."""
    ends = np.cumsum(counts)
    start = 0
    while start < len(counts):
        base = ends[start - 1] if start > 0 else 0
        stop = max(int(np.searchsorted(ends, base + CANDIDATE_BUDGET, side="right")), start + 1)
        yield slice(start, stop)
        start = stop


def _rectangle_pixels(col0, col1, row0, row1, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Flat pixel indices of every inclusive rectangle, and which rectangle each belongs to."""
    ncols = col1 - col0 + 1
    counts = ncols * (row1 - row0 + 1)
    owner = np.repeat(np.arange(len(counts)), counts)
    starts = np.cumsum(counts) - counts
    local = np.arange(owner.size) - starts[owner]
    rows = row0[owner] + local // ncols[owner]
    cols = col0[owner] + local % ncols[owner]
    return rows * width + cols, owner
