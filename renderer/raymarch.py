"""Ray marching through an object's occupancy, in the object's grid coordinates (renderer/surface.py).

There voxels are unit cubes, so a step of half a unit never jumps over a voxel. World points
become grid points with `surface.grid_from_world`.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from renderer.surface import facing_exposed

MARCH_STEP = 0.5  # distance between samples along a ray, in voxels


class OccupancyMarcher:
    """Marches many rays at once through one (N, N, N) boolean occupancy, vectorised over the rays."""

    def __init__(self, occupied: np.ndarray):
        self.occupied = np.asarray(occupied, dtype=bool)
        self.size = self.occupied.shape[0]
        self._skip = _skip_lengths(self.occupied).reshape(-1)

    def first_occupied(self, origin: np.ndarray, direction: np.ndarray, t_first: np.ndarray,
                       t_last: np.ndarray) -> np.ndarray:
        """Flat index of the first occupied voxel sampled at t_first, t_first + MARCH_STEP, ... <= t_last; -1 if none.

        Samples that are certainly empty are skipped (see `_skip_lengths`); the result equals
        plain marching in steps of MARCH_STEP. Samples outside the grid count as empty.
        """
        n = self.size
        occ_flat = self.occupied.reshape(-1)
        result = np.full(len(origin), -1, dtype=np.int64)
        t = np.array(t_first, dtype=np.float64)
        limit = np.asarray(t_last, dtype=np.float64) + 1e-9  # keeps a sample landing exactly on t_last
        active = np.flatnonzero(t <= limit)
        while active.size:
            ijk = np.floor(origin[active] + direction[active] * t[active, None]).astype(np.int64)
            inside = np.all((ijk >= 0) & (ijk < n), axis=1)
            flat = np.where(inside, (ijk[:, 0] * n + ijk[:, 1]) * n + ijk[:, 2], 0)
            hit = inside & occ_flat[flat]
            result[active[hit]] = flat[hit]
            t[active] += np.where(inside, self._skip[flat], MARCH_STEP)
            active = active[~hit & (t[active] <= limit[active])]
        return result

    def visible_from(self, camera_grid: np.ndarray) -> np.ndarray:
        """(N, N, N) bool: voxels with an exposed face turned to the camera whose face centre the camera sees.

        Aiming at an exposed face rather than the voxel centre keeps a flat surface seen at a
        grazing angle visible: the ray to a centre would cross the neighbouring voxels of the
        same surface layer. The first sample lies a quarter voxel off the face, in the empty
        neighbour, so a voxel never hides itself.
        """
        cam = np.asarray(camera_grid, dtype=np.float64)
        owner, origin = self._facing_exposed_faces(cam)
        to_camera = cam - origin
        distance = np.maximum(np.linalg.norm(to_camera, axis=1), 1e-12)
        direction = to_camera / distance[:, None]
        stop = np.minimum(distance, _box_exit(origin, direction, self.size))
        blocker = self.first_occupied(origin, direction, np.full(len(owner), 0.5 * MARCH_STEP), stop)
        visible = np.zeros(self.occupied.size, dtype=bool)
        visible[owner[blocker < 0]] = True
        return visible.reshape(self.occupied.shape)

    def first_occupied_towards(self, camera_grid: np.ndarray, flat_indices: np.ndarray) -> np.ndarray:
        """Flat index of the first occupied voxel on the ray from the camera to each given voxel's centre.

        The samples are laid backwards from the centre, so the last one is the centre itself and
        an occupied target is found at the latest at itself.
        """
        cam = np.asarray(camera_grid, dtype=np.float64)
        centre = np.stack(np.unravel_index(flat_indices, self.occupied.shape), axis=1) + 0.5
        origin = np.broadcast_to(cam, centre.shape)
        to_centre = centre - cam
        distance = np.linalg.norm(to_centre, axis=1)
        direction = to_centre / np.maximum(distance, 1e-12)[:, None]
        enter = np.clip(_box_entry(origin, direction, self.size), 0.0, distance)
        first = distance - np.floor((distance - enter) / MARCH_STEP) * MARCH_STEP
        return self.first_occupied(origin, direction, first, distance)

    def _facing_exposed_faces(self, cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Flat voxel index and centre point of every exposed surface face whose outer side sees the camera."""
        owners, centres = [], []
        for axis in range(3):
            for side in (-1, 1):
                flat = np.flatnonzero(facing_exposed(self.occupied, cam, axis, side))
                face = np.stack(np.unravel_index(flat, self.occupied.shape), axis=1) + 0.5
                face[:, axis] += 0.5 * side
                owners.append(flat)
                centres.append(face)
        return np.concatenate(owners), np.concatenate(centres)


def _skip_lengths(occ: np.ndarray) -> np.ndarray:
    """Per voxel, how far along any ray the next sample may go without missing an occupied voxel.

    From a point in a voxel whose nearest occupied voxel is D voxels away (chessboard distance),
    every point within D - 1 lies in an empty voxel; so the samples closer than that are skipped.
    """
    if not occ.any():
        return np.full(occ.shape, float(occ.shape[0]))
    distance = ndimage.distance_transform_cdt(~occ, metric="chessboard")
    return (np.floor(np.maximum(distance - 1, 0) / MARCH_STEP) + 1) * MARCH_STEP


def _slabs(origin: np.ndarray, direction: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Ray parameters where each ray crosses the planes 0 and n of each axis, ordered near/far per axis."""
    d = np.where(np.abs(direction) < 1e-12, 1e-12, direction)
    t0 = (0.0 - origin) / d
    t1 = (n - origin) / d
    return np.minimum(t0, t1), np.maximum(t0, t1)


def _box_entry(origin: np.ndarray, direction: np.ndarray, n: int) -> np.ndarray:
    """Ray parameter where each ray enters the grid box [0, n]^3 (negative when it starts inside)."""
    near, _ = _slabs(origin, direction, n)
    return near.max(axis=1)


def _box_exit(origin: np.ndarray, direction: np.ndarray, n: int) -> np.ndarray:
    """Ray parameter where each ray leaves the grid box [0, n]^3."""
    _, far = _slabs(origin, direction, n)
    return far.min(axis=1)
