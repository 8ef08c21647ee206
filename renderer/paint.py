"""Bucket-fill painting of object voxels (paper section 3.2) and replay of a scene's paint strokes.

Colors are sRGB in [0, 1]. Every function returns a new array; the input is never changed.
Fills compare colors on the occupied voxels only (`occupied_voxels`), so their cost follows the
object's surface rather than the grid. Paint changes colors, never occupancy: a caller that
paints one object many times (the live engine) computes the occupied voxels once and passes them in.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
from numba import njit, prange

from renderer.errors import InputError
from renderer.scene import SIMILARITIES, PaintOp

Color = tuple[float, float, float]
COLOR_SLACK = 1e-6  # so a tolerance of exactly the difference counts despite float rounding
# The "perceptual" similarity: CIELAB distance / 100 of each voxel's color averaged with its occupied neighbours of
# a like color (within NEIGHBOUR_RANGE in every channel: photo colors are noisy voxel to voxel, and a part's edge
# must not blend with the next part), lightness counting LIGHTNESS_WEIGHT (shading in photo colors is mostly
# lightness; a change of hue is another part). Fewer blotches than "rgb" on captured colors: docs/results.md.
LIGHTNESS_WEIGHT = 0.5
NEIGHBOUR_RANGE = 0.15


def occupied_voxels(rgba: np.ndarray) -> np.ndarray:
    """Flat indices (ascending) of the occupied voxels of an RGBA object grid: alpha at least one half."""
    return np.flatnonzero(np.asarray(rgba)[..., 3] >= 0.5)


def fill_region(rgba: np.ndarray, seed: tuple[int, int, int], color: Color, tolerance: float,
                occupied: np.ndarray | None = None, out: np.ndarray | None = None,
                similarity: str = "rgb") -> np.ndarray:
    """Paint the 6-connected occupied voxels around `seed` whose color is within `tolerance` of the seed's.

    `similarity` "rgb": the largest absolute channel difference; "perceptual": see LIGHTNESS_WEIGHT. The seed must be
    an occupied voxel of the grid. `occupied`: the grid's `occupied_voxels`, if the caller keeps them. `out`: see
    `paint_voxels`.
    """
    return paint_voxels(rgba, fill_region_voxels(rgba, seed, tolerance, occupied, similarity), color, out)


def fill_region_voxels(rgba: np.ndarray, seed, tolerance: float, occupied: np.ndarray | None = None,
                       similarity: str = "rgb") -> np.ndarray:
    """The flat indices of the voxels `fill_region` would paint (the editor previews them under the cursor)."""
    if similarity not in SIMILARITIES:
        raise InputError(f"paint similarity must be one of {', '.join(SIMILARITIES)}, got {similarity!r}")
    shape = np.shape(rgba)[:3]
    seed = tuple(int(s) for s in seed)
    if len(seed) != 3 or not all(0 <= s < n for s, n in zip(seed, shape)):
        raise InputError(f"paint seed {list(seed)} is outside the {'x'.join(map(str, shape))} object grid")
    if not rgba[seed][3] >= 0.5:
        raise InputError(f"paint seed {list(seed)} is on an empty voxel; pick a voxel of the object")
    occupied = occupied_voxels(rgba) if occupied is None else occupied
    seed_flat = int(np.ravel_multi_index(seed, shape))
    distance = (_color_distance(rgba, occupied, seed_flat) if similarity == "rgb"
                else _perceptual_distance(rgba, occupied, seed_flat))
    similar = occupied[distance <= tolerance + COLOR_SLACK]
    mask = np.zeros(shape, dtype=bool)
    mask.reshape(-1)[similar] = True
    return np.sort(_flood(mask, seed_flat, len(similar)))


@njit(cache=True)
def _flood(mask, seed_flat, most):
    """Flat indices of the 6-connected voxels of `mask` reached from `seed_flat` (at most `most` of them), in the
    order found. A breadth-first search visits the region alone: labelling every component of the grid
    (scipy.ndimage.label) costs the whole grid, whatever the region's size."""
    n0, n1, n2 = mask.shape
    flat = mask.reshape(-1)
    found = np.empty(most, dtype=np.int64)
    found[0] = seed_flat
    flat[seed_flat] = False  # visited voxels leave the mask
    head, tail = 0, 1
    while head < tail:
        v = found[head]
        head += 1
        i, rest = divmod(v, n1 * n2)
        j, k = divmod(rest, n2)
        for di, dj, dk in ((-1, 0, 0), (1, 0, 0), (0, -1, 0), (0, 1, 0), (0, 0, -1), (0, 0, 1)):
            a, b, c = i + di, j + dj, k + dk
            if 0 <= a < n0 and 0 <= b < n1 and 0 <= c < n2:
                w = (a * n1 + b) * n2 + c
                if flat[w]:
                    flat[w] = False
                    found[tail] = w
                    tail += 1
    return found[:tail]


def fill_object(rgba: np.ndarray, color: Color, occupied: np.ndarray | None = None,
                out: np.ndarray | None = None) -> np.ndarray:
    """Paint every occupied voxel (`occupied`: the grid's `occupied_voxels`, if the caller keeps them; `out`: see
    `paint_voxels`)."""
    return paint_voxels(rgba, occupied_voxels(rgba) if occupied is None else occupied, color, out)


def apply_paint(rgba: np.ndarray, floor_color: Color, ops: Iterable[PaintOp],
                occupied: np.ndarray | None = None, out: np.ndarray | None = None) -> tuple[np.ndarray, Color]:
    """Replay paint strokes in order: region and object fills on the voxels, floor fills on the floor color.

    Only what the last state shows is replayed: the last floor fill, and the object's strokes from its last
    whole-object fill on (which paints over every stroke before it). `occupied`: the voxels' `occupied_voxels`, if
    the caller keeps them (else found at the first fill). `out`: an array of the voxels' shape the fills may write
    into instead of a new one (see `paint_voxels`).
    """
    floor = [op for op in ops if op.target == "floor"]
    if floor:
        floor_color = tuple(floor[-1].color)
    for op in needed_strokes([op for op in ops if op.target != "floor"]):
        occupied = occupied_voxels(rgba) if occupied is None else occupied
        rgba = paint_voxels(rgba, stroke_voxels(rgba, op, occupied), op.color, out)
    return rgba, floor_color


def needed_strokes(strokes: Sequence[PaintOp]) -> Sequence[PaintOp]:
    """The object's strokes from its last whole-object fill on: those before it leave no trace."""
    last = max((i for i, op in enumerate(strokes) if op.target == "object"), default=0)
    return strokes[last:]


def stroke_voxels(rgba: np.ndarray, op: PaintOp, occupied: np.ndarray | None = None) -> np.ndarray:
    """The flat indices of the voxels an object or region stroke paints on `rgba` (`occupied`: see apply_paint)."""
    if op.target not in ("object", "region"):
        raise InputError(f'paint target must be "region", "object" or "floor", got {op.target!r}')
    if op.target == "region" and op.seed is None:
        raise InputError("a region fill needs a seed voxel")
    occupied = occupied_voxels(rgba) if occupied is None else occupied
    return occupied if op.target == "object" else fill_region_voxels(rgba, op.seed, op.tolerance, occupied,
                                                                     op.similarity)


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


def paint_voxels(rgba: np.ndarray, voxels: np.ndarray, color: Color, out: np.ndarray | None = None) -> np.ndarray:
    """A copy of `rgba` with the voxels at flat indices `voxels` set to `color`: a new array, or `out` (float32, the
    shape of `rgba`; `rgba` itself is allowed). A new array takes twice as long as a copy into a used one:
    fresh memory is mapped page by page."""
    if out is None:
        out = np.array(rgba, dtype=np.float32, copy=True)
    elif out is not rgba:
        np.copyto(out, rgba)
    out.reshape(-1, 4)[voxels, :3] = np.clip(np.asarray(color, dtype=np.float32), 0.0, 1.0)
    return out


def _perceptual_distance(rgba: np.ndarray, voxels: np.ndarray, seed_flat: int) -> np.ndarray:
    """The "perceptual" distance (LIGHTNESS_WEIGHT) between the voxels at flat indices `voxels` (ascending, holding
    `seed_flat`) and the seed: CIELAB by OpenCV (sRGB in, L in [0, 100]) of the neighbourhood means, over 100."""
    import cv2  # here, as elsewhere in the project: loading OpenCV slows the start of every command that paints

    rgba = np.asarray(rgba, dtype=np.float32)
    means = np.empty((len(voxels), 3), dtype=np.float32)
    _neighbourhood_means(rgba, voxels, NEIGHBOUR_RANGE, means)
    lab = cv2.cvtColor(means.reshape(-1, 1, 3), cv2.COLOR_RGB2Lab).reshape(-1, 3)
    difference = lab - lab[np.searchsorted(voxels, seed_flat)]
    difference[:, 0] *= LIGHTNESS_WEIGHT
    return np.sqrt(np.einsum("ij,ij->i", difference, difference)) / 100.0


@njit(cache=True, parallel=True)
def _neighbourhood_means(rgba, voxels, within, out):
    """out[i] = the mean color of the occupied voxels (alpha >= 0.5) among the 3 x 3 x 3 around flat index voxels[i]
    (itself included) whose channels each lie within `within` of its own: a pass over the surface, not a
    convolution of the grid."""
    n0, n1, n2 = rgba.shape[0], rgba.shape[1], rgba.shape[2]
    for v in prange(voxels.shape[0]):
        i, rest = divmod(voxels[v], n1 * n2)
        j, k = divmod(rest, n2)
        r0, g0, b0 = rgba[i, j, k, 0], rgba[i, j, k, 1], rgba[i, j, k, 2]
        r = g = b = 0.0
        count = 0
        for a in range(max(i - 1, 0), min(i + 2, n0)):
            for c in range(max(j - 1, 0), min(j + 2, n1)):
                for d in range(max(k - 1, 0), min(k + 2, n2)):
                    if (rgba[a, c, d, 3] >= 0.5 and abs(rgba[a, c, d, 0] - r0) <= within
                            and abs(rgba[a, c, d, 1] - g0) <= within and abs(rgba[a, c, d, 2] - b0) <= within):
                        r, g, b, count = r + rgba[a, c, d, 0], g + rgba[a, c, d, 1], b + rgba[a, c, d, 2], count + 1
        out[v, 0], out[v, 1], out[v, 2] = r / count, g / count, b / count  # count >= 1: the voxel itself

