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

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numba
import numpy as np
from numba import njit, prange

from renderer.camera import Camera
from renderer.color import linear_to_srgb
from renderer.errors import InputError
from renderer.scene import AMBIENT_RADIANCE, FLOOR_HALF_SIZE, OBJECT_SIZE, Scene
from renderer.surface import Shell, check_object_voxels, grid_from_world, occupancy, sees, voxel_centers_at
from renderer.transform import apply_transform, object_to_world

NEAR_DEPTH = 1e-3  # voxels closer to the image plane than this (or behind it) are dropped


def background_color() -> np.ndarray:
    """sRGB color of the uniform ambient environment seen directly (the path tracer's background)."""
    return np.full(3, linear_to_srgb(AMBIENT_RADIANCE), dtype=np.float32)


@dataclass(frozen=True)
class SplatLayout:
    """Everything a splat shows that colors do not change, so a paint stroke or a new floor color reuses it."""

    voxel: np.ndarray  # (H, W) int64: flat index of the object voxel seen at the pixel, -1 where none is
    floor: np.ndarray  # (H, W) bool: the pixel's ray meets the floor square (floor_mask)
    depth: np.ndarray  # (H, W) float32: that voxel's distance along the view axis (inf where none): objects compose
    box: tuple[slice, slice]  # the rows and columns that hold every pixel showing a voxel: where objects compose


def splat(object_rgba: np.ndarray, object_to_world_matrix: np.ndarray, floor_color, camera: Camera) -> np.ndarray:
    """The splatted image S, (H, W, 3) float32 sRGB in [0, 1], of the object voxels placed in the world."""
    rgba = check_object_voxels(object_rgba)
    return color_splat(splat_layout(Shell(occupancy(rgba)), object_to_world_matrix, camera), rgba, floor_color)


def splat_scene(scene: Scene, object_rgba: np.ndarray, floor_color, size: int | None = None) -> np.ndarray:
    """`splat` with the scene's render camera (at `size`, default the scene's image size) and object placement."""
    return splat(object_rgba, object_to_world(scene.object), floor_color, Camera.from_scene(scene, size))


def splat_objects(scene: Scene, painted: Sequence[np.ndarray], floor_color, size: int | None = None) -> np.ndarray:
    """The splatted image of every object of the scene (their painted voxels in order), each pixel showing the
    nearest object's voxel; for one object, splat_scene's image."""
    camera = Camera.from_scene(scene, size)
    painted = [check_object_voxels(rgba) for rgba in painted]
    layouts = [splat_layout(Shell(occupancy(rgba)), object_to_world(spec), camera)
               for spec, rgba in zip(scene.objects, painted)]
    return compose_splats(layouts, painted, floor_color)


def compose_splats(layouts: Sequence[SplatLayout], painted: Sequence[np.ndarray], floor_color) -> np.ndarray:
    """The splatted image of several objects' layouts (the same camera) with their voxels' colors: each pixel shows
    the nearest object's voxel."""
    image = ground_and_background(layouts[0].floor, floor_color)
    nearest = np.full(layouts[0].voxel.shape, np.inf, dtype=np.float32)
    for layout, rgba in zip(layouts, painted):
        box = layout.box
        voxel, depth, shown, drawn = layout.voxel[box], layout.depth[box], image[box], nearest[box]  # views
        nearer = (voxel >= 0) & (depth < drawn)
        shown[nearer] = np.clip(np.asarray(rgba).reshape(-1, 4)[voxel[nearer], :3], 0.0, 1.0)
        drawn[nearer] = depth[nearer]
    return image


def splat_layout(shell: Shell, object_to_world_matrix: np.ndarray, camera: Camera) -> SplatLayout:
    """Which voxel of an (N, N, N) object grid (its Shell) placed in the world each pixel shows, and where the floor is."""
    n = shell.shape[0]
    matrix = np.asarray(object_to_world_matrix, dtype=np.float64)
    # Integer voxel indices go straight to camera space: one affine map, no world centres in between.
    index_to_object = np.eye(4)
    index_to_object[:3, :3] *= OBJECT_SIZE / n
    index_to_object[:3, 3] = voxel_centers_at(np.zeros((1, 3)), n)[0]
    to_camera = (camera.world_to_camera() @ matrix @ index_to_object)[:3]
    edges = camera.world_to_camera()[:3, :3] @ (matrix[:3, :3] * (OBJECT_SIZE / n))  # a voxel's edges, camera space
    # Each thread splats a contiguous run of the shell into a buffer of its own; the runs' buffers are then merged in
    # shell order, so the image is the one a single pass over the shell draws.
    runs = max(1, min(numba.get_num_threads(), len(shell.voxels)))
    depth = np.full((runs, camera.height, camera.width), np.inf, dtype=np.float32)
    nearest = np.full((runs, camera.height, camera.width), -1, dtype=np.int64)
    (cx, cy), f = camera.principal_point, camera.focal_px
    _splat_shell(shell.coords, shell.faces, apply_transform(grid_from_world(matrix, n), camera.position),
                 np.ascontiguousarray(to_camera), np.ascontiguousarray(edges), f, cx, cy, depth, nearest)
    voxel = np.full((camera.height, camera.width), -1, dtype=np.int64)
    nearest_depth = np.full((camera.height, camera.width), np.inf, dtype=np.float32)
    _merge_runs(depth, nearest, shell.voxels, voxel, nearest_depth)
    rows, cols = np.flatnonzero((voxel >= 0).any(axis=1)), np.flatnonzero((voxel >= 0).any(axis=0))
    box = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1)) if len(rows) else (slice(0, 0), slice(0, 0))
    return SplatLayout(voxel, cached_floor_mask(camera), nearest_depth, box)


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


@njit(cache=True, parallel=True)
def _splat_shell(coords, faces, viewpoint, to_camera, edges, f, cx, cy, depth, nearest):
    """The shell voxels that face `viewpoint` (surface.sees), each drawn over the pixels it covers: thread t splats
    the t-th of depth.shape[0] contiguous runs of the shell into depth[t] (float32) and nearest[t] (the shell row of
    the pixel's nearest voxel; of voxels at the same float32 depth, the first).

    A voxel covers the pixels whose centres lie within the bounding box of its projected cube, always including the
    pixel holding its centre (so a voxel smaller than a pixel still shows). The box is first-order perspective: a
    camera-space offset (dx, dy, dz) at a point with x/depth = a, y/depth = b moves the pixel by
    f/depth * (dx + a dz, -(dy + b dz)), and a parallelepiped with camera-space edges e_k spans half of sum_k |.| of
    its edges' offsets each side. Voxels nearer the image plane than NEAR_DEPTH are dropped. A loop: with numpy's
    scatter-minimum over every (voxel, pixel) pair (np.minimum.at) the whole layout took 2.6-2.8 times as long on a
    test chair at 100^3 and 200^3."""
    runs, count = depth.shape[0], coords.shape[0]
    height, width = depth.shape[1], depth.shape[2]
    for run in prange(runs):
        for m in range(run * count // runs, (run + 1) * count // runs):
            if not sees(coords, faces, viewpoint, m):
                continue
            x, y, z = float(coords[m, 0]), float(coords[m, 1]), float(coords[m, 2])
            px = to_camera[0, 0] * x + to_camera[0, 1] * y + to_camera[0, 2] * z + to_camera[0, 3]
            py = to_camera[1, 0] * x + to_camera[1, 1] * y + to_camera[1, 2] * z + to_camera[1, 3]
            distance = -(to_camera[2, 0] * x + to_camera[2, 1] * y + to_camera[2, 2] * z + to_camera[2, 3])
            if distance <= NEAR_DEPTH:
                continue
            u = cx + f * px / distance
            v = cy - f * py / distance
            a = (u - cx) / f
            b = (cy - v) / f
            half_u = 0.0
            half_v = 0.0
            for k in range(3):
                half_u += abs(edges[0, k] + a * edges[2, k])
                half_v += abs(edges[1, k] + b * edges[2, k])
            scale = 0.5 * f / distance
            col0, col1 = _covered_range(u, scale * half_u, width)
            row0, row1 = _covered_range(v, scale * half_v, height)
            d = np.float32(distance)
            for r in range(row0, row1 + 1):
                for c in range(col0, col1 + 1):
                    if d < depth[run, r, c]:  # a run's voxels come in shell order: a tie keeps the first
                        depth[run, r, c] = d
                        nearest[run, r, c] = m


@njit(cache=True, parallel=True)
def _merge_runs(depth, nearest, shell_voxels, voxel, nearest_depth):
    """voxel[r, c] = the flat grid index of the nearest of the runs' voxels at the pixel (an earlier run's on a tie,
    as one pass in shell order keeps the first), nearest_depth[r, c] its depth; left as they are where no run drew
    one."""
    for r in prange(voxel.shape[0]):
        for c in range(voxel.shape[1]):
            best, row = np.float32(np.inf), -1
            for run in range(depth.shape[0]):
                if depth[run, r, c] < best:
                    best, row = depth[run, r, c], nearest[run, r, c]
            if row >= 0:
                voxel[r, c] = shell_voxels[row]
                nearest_depth[r, c] = best


@njit(cache=True, inline="always")
def _covered_range(centre, half, size):
    """First and last pixel (clipped to the image; first > last: none) whose centre lies within `half` of `centre`,
    always including the pixel holding `centre`."""
    c = min(max(centre, -1.0), size + 1.0)
    h = min(half, size + 2.0)
    own = math.floor(c)
    first = min(math.ceil(c - h - 0.5), own)
    last = max(math.floor(c + h - 0.5), own)
    return int(max(first, 0)), int(min(last, size - 1))
