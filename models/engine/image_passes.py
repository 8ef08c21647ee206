"""The network's image inputs and output on the CPU, in a few compiled passes (numba, cached on disk).

NVR+ joins its splat branch's inputs along the channels and area-averages them, and at the end upsamples its
correction and applies it to the shaded image. In torch that is a concatenation, a pool, an upsampling, an exp, a
multiply-add, a clamp and a copy into the image layout, each a pass over 256^2 images; these passes do
the same in a fraction of the time (docs/results.md, "Measurements behind the code"). Same arithmetic, in float32 (numpy's exp for the gain).
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


def join_and_pool(images: list[np.ndarray], factor: int) -> np.ndarray:
    """(H / factor, W / factor, sum of C) float32: the (H, W, C) images side by side along the channels, each
    factor x factor block averaged (torch's avg_pool2d of their concatenation)."""
    rows, cols = images[0].shape[0] // factor, images[0].shape[1] // factor
    out = np.empty((rows, cols, sum(image.shape[2] for image in images)), dtype=np.float32)
    first = 0
    for image in images:
        _pool_into(image, factor, out, first)
        first += image.shape[2]
    return out


@njit(cache=True, parallel=True)
def _pool_into(image, factor, out, first):
    """out[r, c, first + k] = the mean of channel k of image's factor x factor block at (r, c), summed in torch's
    order; the source is read row by row."""
    cols, channels = out.shape[1], image.shape[2]
    scale = np.float32(1.0 / (factor * factor))
    for r in prange(out.shape[0]):
        total = np.zeros((cols, channels), dtype=np.float32)
        for i in range(r * factor, (r + 1) * factor):
            row = image[i]
            for c in range(cols):
                for j in range(c * factor, (c + 1) * factor):
                    for k in range(channels):
                        total[c, k] += row[j, k]
        for c in range(cols):
            for k in range(channels):
                out[r, c, first + k] = total[c, k] * scale


def apply_correction(correction: np.ndarray, shaded: np.ndarray) -> np.ndarray:
    """The (S, S, 3) float32 image in [0, 1]: shaded (S, S, 3) * exp(gain) + offset, gain and offset the channels 0-2
    and 3-5 of `correction` (N, N, 6) upsampled bilinearly to S as torch's interpolate does (align_corners=False);
    what NVRPlus.apply_correction computes, then clamped for display (NaN as 0)."""
    size, scale = shaded.shape[0], correction.shape[0] / shaded.shape[0]
    gain, offset = (np.empty((size, shaded.shape[1], 3), dtype=np.float32) for _ in range(2))
    _upsample(correction, 0, scale, gain)
    _upsample(correction, 3, scale, offset)
    with np.errstate(over="ignore"):  # a gain too large for float32 is inf: its pixel saturates, clamped below
        np.exp(gain, out=gain)  # numpy's exp is vectorised; a compiled loop calls a scalar exp per value, 10x slower
    _correct(shaded, gain, offset, gain)
    return gain


@njit(cache=True)
def _sources(size, scale, count):
    """Per output index: the two source indices and the second's weight (torch's align_corners=False)."""
    low, high = np.empty(size, dtype=np.int64), np.empty(size, dtype=np.int64)
    weight = np.empty(size, dtype=np.float32)
    for index in range(size):
        position = max((index + 0.5) * scale - 0.5, 0.0)
        low[index] = min(int(position), count - 1)
        high[index] = min(low[index] + 1, count - 1)
        weight[index] = position - low[index]
    return low, high, weight


@njit(cache=True, inline="always")
def _lerp(a, b, weight):
    """(1 - weight) * a + weight * b in float32, as torch weighs two source values."""
    return (np.float32(1.0) - weight) * a + weight * b


@njit(cache=True, parallel=True)
def _upsample(image, first, scale, out):
    """out[..., k] (S, S, C) = channel first + k of `image` (N, N, more) upsampled bilinearly, scale = N / S."""
    r0s, r1s, wrs = _sources(out.shape[0], scale, image.shape[0])
    c0s, c1s, wcs = _sources(out.shape[1], scale, image.shape[1])
    for r in prange(out.shape[0]):
        top, bottom, wr = image[r0s[r]], image[r1s[r]], wrs[r]
        for c in range(out.shape[1]):
            c0, c1, wc = c0s[c], c1s[c], wcs[c]
            for k in range(out.shape[2]):
                i = first + k
                out[r, c, k] = _lerp(_lerp(top[c0, i], top[c1, i], wc), _lerp(bottom[c0, i], bottom[c1, i], wc), wr)


@njit(cache=True, parallel=True)
def _correct(shaded, gain, offset, out):
    """out = shaded * gain + offset (gain already exp'd), clamped to [0, 1] (NaN as 0); out may be gain."""
    for r in prange(out.shape[0]):
        for c in range(out.shape[1]):
            for k in range(3):
                value = shaded[r, c, k] * gain[r, c, k] + offset[r, c, k]
                out[r, c, k] = min(value, np.float32(1.0)) if value > 0.0 else np.float32(0.0)
