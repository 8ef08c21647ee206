"""Float images resized with Pillow's filters, per channel in 32-bit float mode ("F"): no 8-bit rounding, pixel
centres aligned, and area averaging (BOX) when made smaller; and bilinear interpolation of a coarse grid inside a
compiled loop (`linear_weights`, `bilinear_at`), for a shader that reads coarse values where it writes pixels
instead of making a full-size image of them first."""

from __future__ import annotations

import numpy as np
from numba import njit, prange
from PIL import Image


def resized(image: np.ndarray, size: tuple[int, int], resample: Image.Resampling = Image.Resampling.BOX) -> np.ndarray:
    """`image` ((H, W) or (H, W, C) float) at `size` (width, height), float32."""
    channels = image[..., None] if image.ndim == 2 else image
    stacked = np.stack([np.asarray(Image.fromarray(np.asarray(channels[..., c], dtype=np.float32)).resize(size, resample))
                        for c in range(channels.shape[2])], axis=-1)
    return stacked[..., 0] if image.ndim == 2 else stacked


def downscaled(image: np.ndarray, long_side: int) -> np.ndarray:
    """`image` with its long side at most `long_side`, by area averaging (unchanged if it is already that small)."""
    h, w = image.shape[:2]
    if max(h, w) <= long_side:
        return image
    factor = long_side / max(h, w)
    return resized(image, (max(1, round(w * factor)), max(1, round(h * factor))))


def downscaled_mask(mask: np.ndarray, long_side: int, min_cover: float = 0.25) -> np.ndarray:
    """A boolean mask with its long side at most `long_side`, set where at least `min_cover` of a pixel's area was:
    a part half a new pixel wide keeps a line of pixels, where sampling the nearest pixel breaks it up."""
    return downscaled(np.asarray(mask, dtype=np.float32), long_side) >= min_cover


def linear_weights(samples: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each of `size` pixel centres: the sample left of it, the one right of it, and the weight of
    the right one, interpolating linearly between values at pixel-centre positions `samples`."""
    centres = np.arange(size) + 0.5
    right = np.clip(np.searchsorted(samples, centres, side="right"), 1, len(samples) - 1)
    left = right - 1
    weight = np.clip((centres - samples[left]) / (samples[right] - samples[left]), 0.0, 1.0)
    return left, right, weight.astype(np.float32)


@njit(cache=True, inline="always")
def bilinear_at(coarse, top, bottom, down, left, right, across, k):
    """Channel k of the (h, w, c) `coarse` values between rows `top`, `bottom` and columns `left`, `right`, the lower
    row weighing `down` and the right column `across` (`linear_weights` of its row and column)."""
    one = np.float32(1.0)  # float32 throughout (the values and weights are)
    upper = coarse[top, left, k] * (one - across) + coarse[top, right, k] * across
    lower = coarse[bottom, left, k] * (one - across) + coarse[bottom, right, k] * across
    return upper * (one - down) + lower * down


def upsampled(coarse: np.ndarray, row_weights: tuple, col_weights: tuple) -> np.ndarray:
    """Bilinear interpolation of (h, w, c) coarse float32 values to the full image, by each pixel row's and column's
    `linear_weights`."""
    top, bottom, down = row_weights
    left, right, across = col_weights
    out = np.empty((len(top), len(left), coarse.shape[2]), dtype=np.float32)
    _bilinear(np.ascontiguousarray(coarse, dtype=np.float32), top, bottom, down, left, right, across, out)
    return out


@njit(cache=True, parallel=True)
def _bilinear(coarse, top, bottom, down, left, right, across, out):
    """out[r, c] = coarse interpolated between rows top[r], bottom[r] and columns left[c], right[c]: compiled, one
    pass over the image (numpy's gathers were slower, and its BLAS fought the network's threads)."""
    for r in prange(out.shape[0]):
        t, b, wd = top[r], bottom[r], down[r]
        for c in range(out.shape[1]):
            for k in range(out.shape[2]):
                out[r, c, k] = bilinear_at(coarse, t, b, wd, left[c], right[c], across[c], k)
