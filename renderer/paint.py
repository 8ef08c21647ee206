"""Bucket-fill painting of object voxels (paper section 3.2) and replay of a scene's paint strokes.

Colors are sRGB in [0, 1]. Every function returns a new array; the input is never changed.
Fills compare colors on the occupied voxels only (`occupied_voxels`), so their cost follows the
object's surface rather than the grid. Paint changes colors, never occupancy: a caller that
paints one object many times (the live engine) computes the occupied voxels once and passes them in.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from scipy import ndimage

from renderer.errors import InputError
from renderer.scene import PaintOp

Color = tuple[float, float, float]
COLOR_SLACK = 1e-6  # so a tolerance of exactly the difference counts despite float rounding
FACE_NEIGHBOURS = ndimage.generate_binary_structure(3, 1)  # 6-connectivity


def occupied_voxels(rgba: np.ndarray) -> np.ndarray:
    """Flat indices (ascending) of the occupied voxels of an RGBA object grid: alpha at least one half."""
    return np.flatnonzero(np.asarray(rgba)[..., 3] >= 0.5)


def fill_region(rgba: np.ndarray, seed: tuple[int, int, int], color: Color, tolerance: float,
                occupied: np.ndarray | None = None) -> np.ndarray:
    """Paint the 6-connected occupied voxels around `seed` whose color is within `tolerance` of the seed's.

    Color distance is the largest absolute channel difference. The seed must be an occupied
    voxel of the grid. `occupied`: the grid's `occupied_voxels`, if the caller keeps them.
    """
    return _paint(rgba, fill_region_voxels(rgba, seed, tolerance, occupied), color)


def fill_region_voxels(rgba: np.ndarray, seed, tolerance: float, occupied: np.ndarray | None = None) -> np.ndarray:
    """The flat indices of the voxels `fill_region` would paint (the editor previews them under the cursor)."""
    shape = np.shape(rgba)[:3]
    seed = tuple(int(s) for s in seed)
    if len(seed) != 3 or not all(0 <= s < n for s, n in zip(seed, shape)):
        raise InputError(f"paint seed {list(seed)} is outside the {'x'.join(map(str, shape))} object grid")
    if not rgba[seed][3] >= 0.5:
        raise InputError(f"paint seed {list(seed)} is on an empty voxel; pick a voxel of the object")
    occupied = occupied_voxels(rgba) if occupied is None else occupied
    seed_flat = int(np.ravel_multi_index(seed, shape))
    similar = occupied[_color_distance(rgba, occupied, seed_flat) <= tolerance + COLOR_SLACK]
    mask = np.zeros(shape, dtype=bool)
    mask.reshape(-1)[similar] = True
    labels = ndimage.label(mask, structure=FACE_NEIGHBOURS)[0].reshape(-1)
    return similar[labels[similar] == labels[seed_flat]]


def fill_object(rgba: np.ndarray, color: Color, occupied: np.ndarray | None = None) -> np.ndarray:
    """Paint every occupied voxel (`occupied`: the grid's `occupied_voxels`, if the caller keeps them)."""
    return _paint(rgba, occupied_voxels(rgba) if occupied is None else occupied, color)


def apply_paint(rgba: np.ndarray, floor_color: Color, ops: Iterable[PaintOp],
                occupied: np.ndarray | None = None) -> tuple[np.ndarray, Color]:
    """Replay paint strokes in order: region and object fills on the voxels, floor fills on the floor color.

    `occupied`: the voxels' `occupied_voxels`, if the caller keeps them (else found at the first fill).
    """
    for op in ops:
        if op.target == "floor":
            floor_color = tuple(op.color)
            continue
        if op.target not in ("object", "region"):
            raise InputError(f'paint target must be "region", "object" or "floor", got {op.target!r}')
        if op.target == "region" and op.seed is None:
            raise InputError("a region fill needs a seed voxel")
        occupied = occupied_voxels(rgba) if occupied is None else occupied
        if op.target == "object":
            rgba = fill_object(rgba, op.color, occupied)
        else:
            rgba = fill_region(rgba, op.seed, op.color, op.tolerance, occupied)
    return rgba, floor_color


def _color_distance(rgba: np.ndarray, voxels: np.ndarray, seed_flat: int) -> np.ndarray:
    """Largest absolute channel difference between the voxels at flat indices `voxels` and the one at `seed_flat`.

    One channel at a time: numpy reduces a trailing axis of length 3 several times slower.
    """
    rows = np.asarray(rgba).reshape(-1, 4)
    seed = rows[seed_flat]
    distance = np.abs(rows[voxels, 0] - seed[0])
    for channel in (1, 2):
        np.maximum(distance, np.abs(rows[voxels, channel] - seed[channel]), out=distance)
    return distance


def _paint(rgba: np.ndarray, voxels: np.ndarray, color: Color) -> np.ndarray:
    """A copy of `rgba` with the voxels at flat indices `voxels` set to `color`."""
    out = np.array(rgba, dtype=np.float32, copy=True)
    out.reshape(-1, 4)[voxels, :3] = np.clip(np.asarray(color, dtype=np.float32), 0.0, 1.0)
    return out
