"""Which pixels of a photo show the object: its alpha channel, or what differs from the background.

Without alpha, the background is estimated from the photo's border: a smooth color field (a
quadratic in the pixel coordinates, per channel) fitted to a band of border pixels, refitted
without the pixels it explains badly, so an object touching the border or a soft vignette does
not spoil it. Pixels far from that field are the object. When the border itself is not a plain
background (a cluttered room, an object filling the frame) the fit cannot explain most of it,
and segmentation stops with a message instead of guessing.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy import ndimage

from renderer.errors import InputError

BORDER_FRACTION = 0.04  # width of the border band, as a fraction of the shorter side
MIN_BORDER_EXPLAINED = 0.75  # share of the border the background field must explain (an object may touch the rest)
START_TOLERANCE = 0.25  # sRGB distance from the border's median color that may still be background (shading)
MIN_CONTRAST = 0.1  # smallest sRGB distance from the background that counts as object
NOISE_SIGMAS = 6.0  # ... or this many robust standard deviations of the border's residual
MIN_OBJECT_FRACTION = 0.002  # of the image: less than this is nothing
MAX_OBJECT_FRACTION = 0.9
SPECK_FRACTION = 0.0005  # components smaller than this share of the image are noise
OPAQUE = 0.5  # alpha at or above this is object


def object_mask(rgb: np.ndarray, alpha: np.ndarray | None = None, path: str | Path | None = None) -> np.ndarray:
    """(H, W) bool mask of the object in a photo ((H, W, 3) sRGB in [0, 1], alpha (H, W) or None).

    Raises InputError naming `path` when the object cannot be separated.
    """
    if alpha is not None and np.any(alpha < OPAQUE):
        mask = np.asarray(alpha) >= OPAQUE
        if not mask.any():
            raise InputError("the photo's alpha channel is fully transparent: there is no object in it", path)
        return mask
    mask = _differs_from_background(np.asarray(rgb, dtype=np.float64), path)
    fraction = mask.mean()
    if fraction < MIN_OBJECT_FRACTION:
        raise InputError("found no object: the photo looks like plain background", path)
    if fraction > MAX_OBJECT_FRACTION:
        raise InputError("the object fills the photo; give it an alpha channel (transparent background)", path)
    return mask


def _differs_from_background(rgb: np.ndarray, path: str | Path | None) -> np.ndarray:
    h, w = rgb.shape[:2]
    band = max(1, round(BORDER_FRACTION * min(h, w)))
    border = np.zeros((h, w), dtype=bool)
    border[:band], border[-band:], border[:, :band], border[:, -band:] = True, True, True, True
    design = _quadratic_design(h, w)
    # Start from the border's median color, which an object covering less than half the border cannot move.
    median_residual = np.linalg.norm(rgb - np.median(rgb[border], axis=0), axis=2)
    keep = border & (median_residual < START_TOLERANCE)
    for _ in range(4):
        if keep.sum() < MIN_BORDER_EXPLAINED * border.sum():
            raise InputError("cannot tell the object from the background: the photo's border is not a plain "
                             "background; give the photo an alpha channel or a camera file", path)
        coefficients, *_ = np.linalg.lstsq(design[keep.ravel()], rgb[keep], rcond=None)
        residual = np.linalg.norm(rgb - (design @ coefficients).reshape(h, w, 3), axis=2)
        sigma = 1.4826 * np.median(residual[keep]) + 1e-4
        threshold = max(MIN_CONTRAST, NOISE_SIGMAS * sigma)
        keep = border & (residual < threshold)
    mask = residual >= threshold
    labels, count = ndimage.label(mask)
    if count == 0:
        return mask
    sizes = ndimage.sum_labels(mask, labels, index=np.arange(1, count + 1))
    large = np.flatnonzero(sizes >= SPECK_FRACTION * h * w) + 1
    return np.isin(labels, large)


def _quadratic_design(h: int, w: int) -> np.ndarray:
    """(H*W, 6) rows [1, x, y, x^2, xy, y^2] for pixel coordinates scaled to [-1, 1]."""
    y, x = np.mgrid[0:h, 0:w]
    x = (2.0 * x + 1.0) / w - 1.0
    y = (2.0 * y + 1.0) / h - 1.0
    return np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=-1).reshape(h * w, 6)
