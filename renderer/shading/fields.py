"""Compiled sampling of the shader's voxel fields (numba, cached on disk), shared by its stages.

Coordinates are a crop's voxel coordinates: voxel (i, j, k) spans [i, i+1) x [j, j+1) x [k, k+1), its centre at
(i + 0.5, j + 0.5, k + 0.5). numpy would need every ray's steps as arrays of (rays x steps); these loops stop each
ray where it hits and skip empty space by the distance field, so their work follows the object, not the grid.
"""

from __future__ import annotations

import numpy as np
from numba import njit

FAR = np.float32(3.0e38)
HIT_GAP = 0.02  # a ray stops where its gap (how far outside the surface) falls below this


@njit(cache=True, inline="always")
def cell_corners(n0, n1, n2, x, y, z):
    """The voxel centres around crop coordinates (x, y, z), clamped to the crop's edge voxels: the lower and upper
    indices per axis and the weights of the upper ones."""
    x = min(max(x - 0.5, 0.0), n0 - 1.000001)
    y = min(max(y - 0.5, 0.0), n1 - 1.000001)
    z = min(max(z - 0.5, 0.0), n2 - 1.000001)
    i, j, k = int(x), int(y), int(z)
    return i, j, k, min(i + 1, n0 - 1), min(j + 1, n1 - 1), min(k + 1, n2 - 1), x - i, y - j, z - k


@njit(cache=True, inline="always")
def sample(field, x, y, z):
    """Trilinear sample of `field` at crop coordinates (x, y, z); clamped to the crop's edge voxels."""
    i, j, k, i1, j1, k1, fx, fy, fz = cell_corners(field.shape[0], field.shape[1], field.shape[2], x, y, z)
    c00 = field[i, j, k] * (1 - fz) + field[i, j, k1] * fz
    c01 = field[i, j1, k] * (1 - fz) + field[i, j1, k1] * fz
    c10 = field[i1, j, k] * (1 - fz) + field[i1, j, k1] * fz
    c11 = field[i1, j1, k] * (1 - fz) + field[i1, j1, k1] * fz
    return (c00 * (1 - fy) + c01 * fy) * (1 - fx) + (c10 * (1 - fy) + c11 * fy) * fx


@njit(cache=True, inline="always")
def sample_pair(fields, x, y, z):
    """`sample` of both fields of (n0, n1, n2, 2) `fields` at once (the same weights, neighbouring memory)."""
    i, j, k, i1, j1, k1, fx, fy, fz = cell_corners(fields.shape[0], fields.shape[1], fields.shape[2], x, y, z)
    return (blend_fields(fields, 0, i, j, k, i1, j1, k1, fx, fy, fz), blend_fields(fields, 1, i, j, k, i1, j1, k1, fx, fy, fz))


@njit(cache=True, inline="always")
def blend_fields(fields, f, i, j, k, i1, j1, k1, fx, fy, fz):
    """Field `f` of `fields` interpolated between the eight voxel centres of a `cell_corners`."""
    c00 = fields[i, j, k, f] * (1 - fz) + fields[i, j, k1, f] * fz
    c01 = fields[i, j1, k, f] * (1 - fz) + fields[i, j1, k1, f] * fz
    c10 = fields[i1, j, k, f] * (1 - fz) + fields[i1, j, k1, f] * fz
    c11 = fields[i1, j1, k, f] * (1 - fz) + fields[i1, j1, k1, f] * fz
    return (c00 * (1 - fy) + c01 * fy) * (1 - fx) + (c10 * (1 - fy) + c11 * fy) * fx


@njit(cache=True, inline="always")
def surface_gap(fields, level, thin, x, y, z):
    """How far (in voxels of distance) a point lies outside the surface; negative inside. `fields`: distance, core."""
    distance, core = sample_pair(fields, x, y, z)
    return distance - max(level, core + thin)
