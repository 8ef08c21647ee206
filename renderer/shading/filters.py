"""Compiled 3-D filters for the shader's geometry stage, giving what scipy.ndimage gives (tested against it), and
numpy's argwhere of a volume.

Written here because scipy's filters run on one thread and copy every line into a buffer, where
these passes run over both cores with the innermost loop along contiguous memory (docs/results.md, "Measurements behind the code"). Each blur pass rounds to
float32 and adds in scipy's order, so the results are scipy's to the last bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


def gaussian_weights(sigma: float, truncate: float) -> np.ndarray:
    """The normalised 1-D gaussian of scipy.ndimage.gaussian_filter: radius int(truncate * sigma + 0.5)."""
    radius = int(truncate * float(sigma) + 0.5)
    x = np.arange(-radius, radius + 1)
    weights = np.exp(-0.5 / (float(sigma) * float(sigma)) * x**2)
    return weights / weights.sum()


def gaussian_blur(volume: np.ndarray, sigma: float, truncate: float) -> np.ndarray:
    """scipy.ndimage.gaussian_filter(volume, sigma, truncate=truncate) of a float32 (D, H, W) volume ('reflect' border)."""
    full = gaussian_weights(sigma, truncate)
    weights = full[len(full) // 2:]  # the centre, then outwards
    current = np.ascontiguousarray(volume, dtype=np.float32)
    for axis in range(3):
        out = np.empty_like(current)
        _blur_pass(current, weights, axis, out)
        current = out
    return current


def minimum_filter(volume: np.ndarray, size: int) -> np.ndarray:
    """scipy.ndimage.minimum_filter(volume, size) of a float32 (D, H, W) volume (odd `size`, 'reflect' border:
    the reflected voxels lie inside the window already, so the window is clipped to the volume)."""
    if size % 2 != 1:
        raise ValueError(f"the minimum filter's size must be odd, got {size}")
    current = np.ascontiguousarray(volume, dtype=np.float32)
    for axis in range(3):
        out = np.empty_like(current)
        _minimum_pass(current, size // 2, axis, out)
        current = out
    return current


@njit(cache=True, inline="always")
def _reflect(i, n):
    """Index i folded into [0, n) as scipy's 'reflect' border extends a line (d c b a | a b c d | d c b a)."""
    period = 2 * n
    m = i % period
    return m if m < n else period - 1 - m


@njit(cache=True, parallel=True)
def _blur_pass(volume, weights, axis, out):
    """One axis of the blur: out = volume correlated with the symmetric kernel whose centre and right half are
    `weights`, in float64 as scipy sums (centre first, then the outermost pair inwards), rounded to float32."""
    n0, n1, n2 = volume.shape
    radius = weights.shape[0] - 1
    if axis == 2:
        for i in prange(n0):
            padded = np.empty(n2 + 2 * radius)  # one line with its reflected border, in float64
            total = np.empty(n2)
            for j in range(n1):
                for k in range(n2):
                    padded[k + radius] = volume[i, j, k]
                for q in range(radius):  # the borders (an index modulo per voxel would cost more than the sums)
                    padded[q] = volume[i, j, _reflect(q - radius, n2)]
                    padded[n2 + radius + q] = volume[i, j, _reflect(n2 + q, n2)]
                for k in range(n2):  # each sum over the whole line at once: the loops over k vectorise
                    total[k] = padded[k + radius] * weights[0]
                for t in range(radius, 0, -1):
                    for k in range(n2):
                        total[k] += (padded[k + radius - t] + padded[k + radius + t]) * weights[t]
                for k in range(n2):
                    out[i, j, k] = total[k]
        return
    outer, length = (n1, n0) if axis == 0 else (n0, n1)
    for o in prange(outer):
        total = np.empty(n2)
        for p in range(length):
            for k in range(n2):
                total[k] = np.float64(_along(volume, axis, o, p, k)) * weights[0]
            for t in range(radius, 0, -1):
                before, after = _reflect(p - t, length), _reflect(p + t, length)
                for k in range(n2):
                    total[k] += (np.float64(_along(volume, axis, o, before, k))
                                 + np.float64(_along(volume, axis, o, after, k))) * weights[t]
            for k in range(n2):
                _store(out, axis, o, p, k, total[k])


@njit(cache=True, parallel=True)
def _minimum_pass(volume, radius, axis, out):
    """One axis of the minimum filter: the least value within `radius` voxels along `axis`."""
    n0, n1, n2 = volume.shape
    if axis == 2:
        for i in prange(n0):
            for j in range(n1):
                for k in range(n2):
                    out[i, j, k] = volume[i, j, k]
                for shift in range(1, radius + 1):  # each neighbour offset over the whole line at once
                    for k in range(n2 - shift):
                        out[i, j, k] = min(out[i, j, k], volume[i, j, k + shift])
                    for k in range(shift, n2):
                        out[i, j, k] = min(out[i, j, k], volume[i, j, k - shift])
        return
    outer, length = (n1, n0) if axis == 0 else (n0, n1)
    for o in prange(outer):
        least = np.empty(n2, dtype=volume.dtype)
        for p in range(length):
            for k in range(n2):
                least[k] = _along(volume, axis, o, p, k)
            for q in range(max(p - radius, 0), min(p + radius + 1, length)):
                for k in range(n2):
                    least[k] = min(least[k], _along(volume, axis, o, q, k))
            for k in range(n2):
                _store(out, axis, o, p, k, least[k])


@njit(cache=True, inline="always")
def _along(volume, axis, o, p, k):
    """volume at position p along `axis` (0 or 1), o along the other of the first two axes, k along the last."""
    return volume[p, o, k] if axis == 0 else volume[o, p, k]


@njit(cache=True, inline="always")
def _store(volume, axis, o, p, k, value):
    if axis == 0:
        volume[p, o, k] = value
    else:
        volume[o, p, k] = value


@njit(cache=True, parallel=True)
def block_mean2(occupied):
    """The mean of every 2 x 2 x 2 block of a bool or float volume (float32, half size rounded up; missing voxels past an
    odd side count as empty, as if the volume were padded with zeros)."""
    n0, n1, n2 = occupied.shape
    h0, h1, h2 = (n0 + 1) // 2, (n1 + 1) // 2, (n2 + 1) // 2
    out = np.empty((h0, h1, h2), dtype=np.float32)
    for a in prange(h0):
        for b in range(h1):
            for c in range(h2):
                count = 0
                for i in range(2 * a, min(2 * a + 2, n0)):
                    for j in range(2 * b, min(2 * b + 2, n1)):
                        for k in range(2 * c, min(2 * c + 2, n2)):
                            count += occupied[i, j, k]
                out[a, b, c] = count / 8.0
    return out


@njit(cache=True, parallel=True)
def mask_coverage2(mask):
    """block_coverage2 of a bool volume whose set voxels cover their faces along every axis: per 2^3 block and axis,
    the share of its four columns along the axis that hold a set voxel (cells past an odd side count as empty)."""
    n0, n1, n2 = mask.shape
    h0, h1, h2 = (n0 + 1) // 2, (n1 + 1) // 2, (n2 + 1) // 2
    out = np.zeros((h0, h1, h2, 3), dtype=np.float32)
    for a in prange(h0):
        for b in range(h1):
            for c in range(h2):
                for i in range(2 * a, min(2 * a + 2, n0)):
                    for j in range(2 * b, min(2 * b + 2, n1)):
                        for k in range(2 * c, min(2 * c + 2, n2)):
                            if mask[i, j, k]:
                                # This voxel's column along each axis holds a set voxel: count each column once.
                                first_i = i == 2 * a or not mask[2 * a, j, k]
                                first_j = j == 2 * b or not mask[i, 2 * b, k]
                                first_k = k == 2 * c or not mask[i, j, 2 * c]
                                out[a, b, c, 0] += 0.25 * first_i
                                out[a, b, c, 1] += 0.25 * first_j
                                out[a, b, c, 2] += 0.25 * first_k
    return out


@njit(cache=True, parallel=True)
def block_coverage2(coverage):
    """Per 2 x 2 x 2 block of a volume of coverages (n0, n1, n2, 3: the share of a cell's face, across each axis, that
    a line through the cell along that axis finds blocked; a voxel's own occupancy for a voxel), the same of the
    block: along each axis the two cells one behind the other block as 1 - (1 - front) (1 - back), and the block's
    face averages its four columns (half size rounded up; cells past an odd side count as empty). A wall blocks a
    line across it at every size; a bar blocks only its share of the face. The two cells are taken as independent,
    which counts a part lying along the axis through both more than once (more blocked than it is)."""
    n0, n1, n2 = coverage.shape[0], coverage.shape[1], coverage.shape[2]
    h0, h1, h2 = (n0 + 1) // 2, (n1 + 1) // 2, (n2 + 1) // 2
    out = np.empty((h0, h1, h2, 3), dtype=np.float32)
    for a in prange(h0):
        for b in range(h1):
            for c in range(h2):
                for axis in range(3):
                    total = 0.0
                    for p in range(2):
                        for q in range(2):
                            through = 1.0
                            for r in range(2):
                                if axis == 0:
                                    i, j, k = 2 * a + r, 2 * b + p, 2 * c + q
                                elif axis == 1:
                                    i, j, k = 2 * a + p, 2 * b + r, 2 * c + q
                                else:
                                    i, j, k = 2 * a + p, 2 * b + q, 2 * c + r
                                if i < n0 and j < n1 and k < n2:
                                    through *= 1.0 - coverage[i, j, k, axis]
                            total += 1.0 - through
                    out[a, b, c, axis] = 0.25 * total
    return out


def connected_to_border(blocked: np.ndarray) -> np.ndarray:
    """The voxels not `blocked` that a 6-connected path of such voxels joins to the volume's border: the outside of
    the blocked voxels, whose complement is them with their insides. A flood fill from the border's free voxels by
    sweeps along each axis, in both directions, until a round of sweeps reaches nothing new (two or three rounds on
    furniture; a breadth-first fill visits the same voxels one at a time, twice as slow as scipy's labelling)."""
    free = ~np.ascontiguousarray(blocked, dtype=np.bool_)
    reached = np.zeros_like(free)
    for side in (np.s_[0], np.s_[-1]):
        for axis in range(3):
            index = [slice(None)] * 3
            index[axis] = side
            reached[tuple(index)] = free[tuple(index)]
    while sum(_sweep(free, reached, axis) for axis in range(3)) > 0:
        pass
    return reached


@njit(cache=True, parallel=True)
def _sweep(free, reached, axis):
    """Spread `reached` along `axis` through free voxels, forwards then backwards; how many voxels it newly reached."""
    n0, n1, n2 = free.shape
    count = 0
    if axis == 2:
        for line in prange(n0 * n1):
            i, j = line // n1, line % n1
            for k in range(1, n2):
                if reached[i, j, k - 1] and free[i, j, k] and not reached[i, j, k]:
                    reached[i, j, k] = True
                    count += 1
            for k in range(n2 - 2, -1, -1):
                if reached[i, j, k + 1] and free[i, j, k] and not reached[i, j, k]:
                    reached[i, j, k] = True
                    count += 1
        return count
    outer, length = (n1, n0) if axis == 0 else (n0, n1)
    for o in prange(outer):
        for p in range(1, length):
            for k in range(n2):
                if _along(reached, axis, o, p - 1, k) and _along(free, axis, o, p, k) and not _along(reached, axis, o, p, k):
                    _store(reached, axis, o, p, k, True)
                    count += 1
        for p in range(length - 2, -1, -1):
            for k in range(n2):
                if _along(reached, axis, o, p + 1, k) and _along(free, axis, o, p, k) and not _along(reached, axis, o, p, k):
                    _store(reached, axis, o, p, k, True)
                    count += 1
    return count


def occupied_indices(mask: np.ndarray) -> np.ndarray:
    """np.argwhere(mask) of a 3-D bool array ((N, 3) int64 in C order): counted and written one depth slice per
    thread (numpy's runs on one)."""
    mask = np.ascontiguousarray(mask, dtype=np.bool_)
    counts = _slice_counts(mask)
    first = np.concatenate([np.zeros(1, dtype=np.int64), np.cumsum(counts)])
    out = np.empty((int(first[-1]), 3), dtype=np.int64)
    _fill_indices(mask, first, out)
    return out


@njit(cache=True, parallel=True)
def _slice_counts(mask):
    counts = np.zeros(mask.shape[0], dtype=np.int64)
    for i in prange(mask.shape[0]):
        total = 0
        for j in range(mask.shape[1]):
            for k in range(mask.shape[2]):
                total += mask[i, j, k]
        counts[i] = total
    return counts


@njit(cache=True, parallel=True)
def _fill_indices(mask, first, out):
    for i in prange(mask.shape[0]):
        row = first[i]
        for j in range(mask.shape[1]):
            for k in range(mask.shape[2]):
                if mask[i, j, k]:
                    out[row, 0], out[row, 1], out[row, 2] = i, j, k
                    row += 1
