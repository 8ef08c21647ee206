"""What the mouse points at: a voxel of a placed object, the nearest object, a point on a horizontal plane, the light.

Voxel picking walks the ray through the object's grid voxel by voxel (Amanatides & Woo's
traversal) in the grid coordinates of renderer/surface.py, where voxel (i, j, k) is the unit
cube at (i, j, k); the placement is affine, so the world ray stays straight there.
"""

from __future__ import annotations

import math

import numpy as np

from renderer.scene import LIGHT_SIZE, OBJECT_SIZE, ObjectSpec
from renderer.surface import grid_from_world
from renderer.transform import OBJECT_BOX_MIN, apply_transform, object_to_world


def pick_voxel(occupied: np.ndarray, spec: ObjectSpec, origin: np.ndarray, direction: np.ndarray) -> tuple[int, int, int] | None:
    """Index (i, j, k) of the first occupied object voxel the world ray meets, or None."""
    n = occupied.shape[0]
    to_grid = grid_from_world(object_to_world(spec), n)
    o = to_grid[:3, :3] @ np.asarray(origin, dtype=np.float64) + to_grid[:3, 3]
    d = to_grid[:3, :3] @ np.asarray(direction, dtype=np.float64)
    entry = _box_entry(o, d, n)
    if entry is None:
        return None
    return _first_occupied(occupied, o + d * entry, d)


def _box_entry(o: np.ndarray, d: np.ndarray, n: int) -> float | None:
    """Ray parameter (>= 0) where the ray enters the grid box [0, n]^3, or None if it misses it."""
    t_near, t_far = 0.0, math.inf
    for axis in range(3):
        if abs(d[axis]) < 1e-12:
            if not 0.0 <= o[axis] <= n:
                return None
            continue
        t0, t1 = sorted(((0.0 - o[axis]) / d[axis], (n - o[axis]) / d[axis]))
        t_near, t_far = max(t_near, t0), min(t_far, t1)
    return t_near if t_near <= t_far else None


def _first_occupied(occupied: np.ndarray, start: np.ndarray, d: np.ndarray) -> tuple[int, int, int] | None:
    """Step from `start` (on or inside the box) through the voxels along d; the first occupied one."""
    n = occupied.shape[0]
    cell = [min(max(int(math.floor(start[a])), 0), n - 1) for a in range(3)]
    step = [1 if d[a] > 0 else -1 for a in range(3)]
    t_max, t_delta = [], []
    for a in range(3):
        if abs(d[a]) < 1e-12:
            t_max.append(math.inf)
            t_delta.append(math.inf)
        else:
            boundary = cell[a] + (1 if d[a] > 0 else 0)
            t_max.append((boundary - start[a]) / d[a])
            t_delta.append(abs(1.0 / d[a]))
    while all(0 <= c < n for c in cell):
        if occupied[cell[0], cell[1], cell[2]]:
            return cell[0], cell[1], cell[2]
        a = int(np.argmin(t_max))
        cell[a] += step[a]
        t_max[a] += t_delta[a]
    return None


def nearest_object(objects: list[tuple[ObjectSpec, np.ndarray]], origin: np.ndarray, direction: np.ndarray,
                   labels: list[int] | None = None) -> int | None:
    """Of `objects` ((placement, occupancy) pairs), the one whose occupied voxel the ray meets nearest the origin:
    its label (default: its position in the list), or None when the ray meets none."""
    best, chosen = math.inf, None
    for k, (spec, occupied) in enumerate(objects):
        voxel = pick_voxel(occupied, spec, origin, direction)
        if voxel is None:
            continue
        centre = OBJECT_BOX_MIN + (np.asarray(voxel) + 0.5) * (OBJECT_SIZE / occupied.shape[0])
        distance = float(np.linalg.norm(apply_transform(object_to_world(spec), centre) - origin))
        if distance < best:
            best, chosen = distance, (k if labels is None else labels[k])
    return chosen


def ray_at_height(origin: np.ndarray, direction: np.ndarray, height: float) -> np.ndarray | None:
    """Where the ray meets the horizontal plane y = height (in front of its origin), or None."""
    dy = float(direction[1])
    if abs(dy) < 1e-9:
        return None
    t = (height - float(origin[1])) / dy
    return None if t <= 0 else np.asarray(origin, dtype=np.float64) + t * np.asarray(direction, dtype=np.float64)


def hits_light(origin: np.ndarray, direction: np.ndarray, light_position: tuple[float, float, float],
               margin: float = 0.1) -> bool:
    """Whether the ray passes through the light's square (side LIGHT_SIZE, horizontal), grown by `margin`."""
    point = ray_at_height(origin, direction, light_position[1])
    if point is None:
        return False
    half = 0.5 * LIGHT_SIZE + margin
    return abs(point[0] - light_position[0]) <= half and abs(point[2] - light_position[2]) <= half
