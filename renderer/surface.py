"""The shell of an object voxel array, and the object grid's own coordinates.

Splatting and photo coloring only look at the shell (occupied voxels with an empty
6-neighbour), so their work grows with the surface area of the object, not its volume.
Arrays follow renderer/transform.py: rgba[i, j, k, c] over an N^3 grid of the object box.

Grid coordinates: voxel (i, j, k) is the unit cube [i, i+1) x [j, j+1) x [k, k+1), so the
voxel holding a point is its floor. The object's placement is affine, so a world ray is a
straight grid ray too, and "which side of a voxel face a point lies on" can be read there.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from renderer.errors import InputError
from renderer.transform import OBJECT_BOX_MIN, OBJECT_SIZE


def check_object_voxels(rgba: np.ndarray) -> np.ndarray:
    """The array as float32 (N, N, N, 4) object voxels, or InputError naming the wrong shape."""
    arr = np.asarray(rgba)
    if arr.ndim != 4 or arr.shape[3] != 4 or not arr.shape[0] == arr.shape[1] == arr.shape[2] or arr.shape[0] < 1:
        raise InputError(f"object voxels must have shape (N, N, N, 4), got {arr.shape}")
    return arr.astype(np.float32, copy=False)


def occupancy(rgba: np.ndarray) -> np.ndarray:
    """Boolean (N, N, N) occupancy of RGBA object voxels (alpha is 0 or 1; above one half counts)."""
    return np.asarray(rgba)[..., 3] > 0.5


def exposed(occupied: np.ndarray, axis: int, side: int) -> np.ndarray:
    """Occupied voxels whose neighbour one step along `axis` in direction `side` (+1 or -1) is empty or outside."""
    o = np.asarray(occupied, dtype=bool)
    n = o.shape[axis]
    result = o.copy()
    inner = [slice(None)] * 3
    beyond = [slice(None)] * 3
    inner[axis] = slice(0, n - 1) if side > 0 else slice(1, n)
    beyond[axis] = slice(1, n) if side > 0 else slice(0, n - 1)
    result[tuple(inner)] &= ~o[tuple(beyond)]
    return result


def surface_mask(occupied: np.ndarray) -> np.ndarray:
    """Occupied voxels with at least one empty 6-neighbour; the outside of the grid counts as empty."""
    o = np.asarray(occupied, dtype=bool)
    interior = np.zeros_like(o)
    interior[1:-1, 1:-1, 1:-1] = (
        o[1:-1, 1:-1, 1:-1] & o[:-2, 1:-1, 1:-1] & o[2:, 1:-1, 1:-1]
        & o[1:-1, :-2, 1:-1] & o[1:-1, 2:, 1:-1]
        & o[1:-1, 1:-1, :-2] & o[1:-1, 1:-1, 2:]
    )
    return o & ~interior


def facing_exposed(occupied: np.ndarray, viewpoint_grid: np.ndarray, axis: int, side: int) -> np.ndarray:
    """Voxels `exposed` on (axis, side) whose face there has `viewpoint_grid` (grid coordinates) on its outer side."""
    n = np.shape(occupied)[axis]
    face = np.arange(n) + (side > 0)  # coordinate of each cell's face on this side
    sees = (viewpoint_grid[axis] - face) * side > 0
    shape = [1, 1, 1]
    shape[axis] = n
    return exposed(occupied, axis, side) & sees.reshape(shape)


def facing_surface_mask(occupied: np.ndarray, viewpoint_grid: np.ndarray) -> np.ndarray:
    """Occupied voxels with an exposed face whose outer side sees `viewpoint_grid`.

    Any ray from the viewpoint that meets the object enters its first voxel through such a face,
    so the other voxels are never the first one hit: renderers may skip them.
    """
    shell = Shell(occupied)
    mask = np.zeros(shell.shape, dtype=bool)
    mask.reshape(-1)[shell.facing(viewpoint_grid)] = True
    return mask


class Shell:
    """The voxels of an occupancy grid with an exposed face (flat indices, ascending) and which of their six faces
    are exposed: found once per grid, they let a splat from any viewpoint look at these voxels only."""

    SIDES = tuple((axis, side) for axis in range(3) for side in (-1, 1))

    def __init__(self, occupied: np.ndarray):
        occupied = np.asarray(occupied, dtype=bool)
        self.shape = occupied.shape
        faces = [exposed(occupied, axis, side) for axis, side in self.SIDES]
        self.voxels = np.flatnonzero(np.logical_or.reduce(faces))
        self.coords = np.stack(np.unravel_index(self.voxels, self.shape), axis=1)  # (K, 3) integer indices
        self.faces = np.stack([f.reshape(-1)[self.voxels] for f in faces], axis=1)  # (K, 6): exposed on SIDES[i]

    def facing(self, viewpoint_grid: np.ndarray) -> np.ndarray:
        """Flat indices (ascending) of the voxels with an exposed face whose outer side sees `viewpoint_grid`."""
        return self.voxels[self.facing_mask(viewpoint_grid)]

    def facing_mask(self, viewpoint_grid: np.ndarray) -> np.ndarray:
        """(K,) bool over the shell's voxels: those `facing` returns."""
        seen = np.empty(len(self.voxels), dtype=bool)
        _facing(self.coords, self.faces, np.asarray(viewpoint_grid, dtype=np.float64), seen)
        return seen


@njit(cache=True)
def _facing(coords, faces, viewpoint, seen):
    """seen[m] = sees(coords, faces, viewpoint, m) for every shell voxel m: one pass over the shell instead of six numpy passes."""
    for m in range(coords.shape[0]):
        seen[m] = sees(coords, faces, viewpoint, m)


@njit(cache=True, inline="always")
def sees(coords, faces, viewpoint, m):
    """Whether an exposed face of shell voxel m (faces[m, i] on Shell.SIDES[i]) has `viewpoint` on its outer side."""
    any_side = False
    for axis in range(3):
        for s, side in enumerate((-1, 1)):
            face = coords[m, axis] + (side > 0)  # the face's coordinate, as facing_exposed computes it
            any_side |= faces[m, 2 * axis + s] and (viewpoint[axis] - face) * side > 0
    return any_side


def voxel_centers_at(indices: np.ndarray, resolution: int) -> np.ndarray:
    """Object-space centres of the voxels at integer `indices` (n, 3) of an N^3 grid (transform.py convention)."""
    return OBJECT_BOX_MIN + (np.asarray(indices, dtype=np.float64) + 0.5) * (OBJECT_SIZE / resolution)


def grid_from_world(object_to_world_matrix: np.ndarray, resolution: int) -> np.ndarray:
    """4x4 affine map from world points to grid coordinates of the placed object's N^3 grid."""
    to_grid = np.eye(4)
    to_grid[:3, :3] *= resolution / OBJECT_SIZE
    to_grid[:3, 3] = -OBJECT_BOX_MIN * (resolution / OBJECT_SIZE)
    return to_grid @ np.linalg.inv(np.asarray(object_to_world_matrix, dtype=np.float64))
