"""Object placement: object coordinates to world coordinates, and the object's own voxel grid.

Object coordinates: a normalised mesh fits the box x in [-0.5, 0.5], y in [0, 1],
z in [-0.5, 0.5] (longest side 1, centred on x and z, standing on y = 0); its front faces +z,
towards the camera at rotation 0.

Object voxels: an array rgba[i, j, k, c] of shape (N, N, N, 4), float32; i runs along x,
j along y (up), k along z over that box; c is R, G, B (sRGB in [0, 1]) and occupancy (0 or 1).
Voxel (i, j, k) has its centre at (-0.5 + (i + 0.5) / N, (j + 0.5) / N, -0.5 + (k + 0.5) / N).

Placement: p_world = translate(tx, 0, tz) @ rotate_y(rotation) @ scale(sx, sy, sz) @ p_object.
Scaling about the floor point keeps the object standing on the floor; a positive rotation
turns the object counter-clockwise seen from above.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from renderer.scene import OBJECT_SIZE, ObjectSpec

OBJECT_BOX_MIN = np.array([-0.5, 0.0, -0.5]) * OBJECT_SIZE
OBJECT_BOX_MAX = np.array([0.5, 1.0, 0.5]) * OBJECT_SIZE


def rotation_y(angle_deg: float) -> np.ndarray:
    """3x3 rotation about the world's vertical axis."""
    a = math.radians(angle_deg)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def object_to_world(spec: ObjectSpec) -> np.ndarray:
    """4x4 matrix placing the object in the world: scale, then rotate about y, then translate on x, z."""
    m = np.eye(4)
    m[:3, :3] = rotation_y(spec.rotation_deg) @ np.diag(spec.scale)
    m[0, 3], m[2, 3] = spec.translation
    return m


def footprint_radius(obj: ObjectSpec) -> float:
    """Radius of a circle on the floor that holds the object's footprint, whatever its turn (its box is at most one
    unit a side, scaled)."""
    return 0.5 * OBJECT_SIZE * math.hypot(obj.scale[0], obj.scale[2])


def turned_on_platter(objects: Sequence[ObjectSpec], degrees: float) -> tuple[ObjectSpec, ...]:
    """`objects` turned `degrees` about the vertical axis through the world's origin, as on a turntable's platter:
    each about its own axis, and their places about the origin (one object alone turns in place)."""
    turn = rotation_y(degrees)
    turned = []
    for o in objects:
        x, _, z = turn @ np.array([o.translation[0], 0.0, o.translation[1]])
        place = o.translation if len(objects) == 1 else (float(x), float(z))
        turned.append(replace(o, rotation_deg=(o.rotation_deg + degrees + 180.0) % 360.0 - 180.0, translation=place))
    return tuple(turned)


def world_to_object(spec: ObjectSpec) -> np.ndarray:
    """Inverse of `object_to_world`, computed in closed form (no matrix inversion)."""
    inv_scale = np.diag([1.0 / s for s in spec.scale])
    rot_t = rotation_y(spec.rotation_deg).T
    m = np.eye(4)
    m[:3, :3] = inv_scale @ rot_t
    m[:3, 3] = -(inv_scale @ rot_t @ np.array([spec.translation[0], 0.0, spec.translation[1]]))
    return m


def merged_voxel_to_object(resolution: int, factors: tuple[int, int, int]) -> np.ndarray:
    """4x4 matrix from continuous indices of an N^3 object's voxels merged by `factors` to object coordinates
    (merged voxel m spans object voxels m * f to (m + 1) * f along each axis)."""
    matrix = np.eye(4)
    matrix[:3, :3] = np.diag(OBJECT_SIZE / resolution * np.asarray(factors, dtype=np.float64))
    matrix[:3, 3] = OBJECT_BOX_MIN
    return matrix


def object_voxel_centers(resolution: int) -> np.ndarray:
    """Object-space centres of all voxels of an N^3 object grid, shape (N, N, N, 3), indexed [i, j, k]."""
    n = resolution
    t = (np.arange(n) + 0.5) / n
    xs = OBJECT_BOX_MIN[0] + t * OBJECT_SIZE
    ys = OBJECT_BOX_MIN[1] + t * OBJECT_SIZE
    zs = OBJECT_BOX_MIN[2] + t * OBJECT_SIZE
    xx, yy, zz = np.meshgrid(xs, ys, zs, indexing="ij")
    return np.stack([xx, yy, zz], axis=-1)


def apply_transform(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a 4x4 affine matrix to points of shape (..., 3)."""
    p = np.asarray(points, dtype=np.float64)
    return p @ matrix[:3, :3].T + matrix[:3, 3]
