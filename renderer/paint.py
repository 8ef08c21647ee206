"""Bucket-fill painting of object voxels (paper section 3.2) and replay of a scene's paint strokes.

Colors are sRGB in [0, 1]. Every function returns a new array; the input is never changed.
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


def fill_region(rgba: np.ndarray, seed: tuple[int, int, int], color: Color, tolerance: float) -> np.ndarray:
    """Paint the 6-connected occupied voxels around `seed` whose color is within `tolerance` of the seed's.

    Color distance is the largest absolute channel difference. The seed must be an occupied
    voxel of the grid.
    """
    occupied = rgba[..., 3] >= 0.5
    seed = tuple(int(s) for s in seed)
    if len(seed) != 3 or not all(0 <= s < n for s, n in zip(seed, occupied.shape)):
        raise InputError(f"paint seed {list(seed)} is outside the {'x'.join(map(str, occupied.shape))} object grid")
    if not occupied[seed]:
        raise InputError(f"paint seed {list(seed)} is on an empty voxel; pick a voxel of the object")
    difference = np.abs(rgba[..., :3] - rgba[seed][:3]).max(axis=-1)
    similar = occupied & (difference <= tolerance + COLOR_SLACK)
    labels, _ = ndimage.label(similar, structure=FACE_NEIGHBOURS)
    return _paint(rgba, labels == labels[seed], color)


def fill_object(rgba: np.ndarray, color: Color) -> np.ndarray:
    """Paint every occupied voxel."""
    return _paint(rgba, rgba[..., 3] >= 0.5, color)


def apply_paint(rgba: np.ndarray, floor_color: Color, ops: Iterable[PaintOp]) -> tuple[np.ndarray, Color]:
    """Replay paint strokes in order: region and object fills on the voxels, floor fills on the floor color."""
    for op in ops:
        if op.target == "floor":
            floor_color = tuple(op.color)
        elif op.target == "object":
            rgba = fill_object(rgba, op.color)
        elif op.target == "region":
            if op.seed is None:
                raise InputError("a region fill needs a seed voxel")
            rgba = fill_region(rgba, op.seed, op.color, op.tolerance)
        else:
            raise InputError(f'paint target must be "region", "object" or "floor", got {op.target!r}')
    return rgba, floor_color


def _paint(rgba: np.ndarray, mask: np.ndarray, color: Color) -> np.ndarray:
    """A copy of `rgba` with the voxels of `mask` set to `color`."""
    out = np.array(rgba, dtype=np.float32, copy=True)
    out[mask, :3] = np.clip(np.asarray(color, dtype=np.float32), 0.0, 1.0)
    return out
