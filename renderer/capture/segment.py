"""Which pixels of a photo show the object: its alpha channel, or GrabCut's segmentation.

Without alpha, a first guess comes from the photo's border when it is a plain backdrop: a smooth
color field (a quadratic in the pixel coordinates, per channel) fitted to a band of border pixels,
refitted without the pixels it explains badly, so an object touching the border or a soft vignette
does not spoil it; pixels far from that field are probably the object. GrabCut
(renderer/capture/grabcut.py) then separates object and background from that guess, or, when the
border is not plain (a floor and a sky), from the frame's middle, the user's box and strokes or the
object's silhouette at a pose already found. A cluttered photo (a room, a street: edges all along its
border) without any of those is refused with a request for a box: GrabCut from the frame's middle
cuts out whatever stands there, and the pose fitted to that is wrong.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy import ndimage

from renderer.capture.grabcut import Hints, grabcut_mask, shadow_pixels, without_specks
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
SHADOW_SHARE = 0.05  # of the pixels that differ from a plain backdrop: more shadow-like ones than this mean a lit floor
BUSY_BAND_FRACTION = 0.15  # clutter is measured in a band this share of the shorter side wide along the border
BUSY_EDGE = 0.02  # sRGB change per pixel (after a BUSY_BLUR-pixel blur, which takes out sensor noise) that is an edge
BUSY_BLUR = 1.5
BUSY_MASK_MARGIN = 0.01  # the object's cut, grown by this share of the shorter side, is left out of the band
MAX_BUSY_SHARE = 0.15  # a band with edges on more of it than this is clutter. Measured (the capture bench's photos at
# 256^2, the test and novel data sets' 290 path-traced images): floor-and-sky photos 0-0.075, data-set images 0-0.134,
# photographs behind the object (scikit-image's samples, blurred, noisy, JPEG) 0.164-0.61
PLAIN_SIGMA = 0.01  # a border whose smooth color field leaves more residual than this (robust sRGB std) is not plain:
# a studio backdrop leaves about 0.0013, a floor under a sky 0.017-0.1 (the horizon, the light's spot)


def object_mask(rgb: np.ndarray, alpha: np.ndarray | None = None, path: str | Path | None = None,
                hints: Hints | None = None) -> np.ndarray:
    """(H, W) bool mask of the object in a photo ((H, W, 3) sRGB in [0, 1], alpha (H, W) or None).

    The alpha channel when it has one; else GrabCut (renderer/capture/grabcut.py), started from the user's
    `hints` (a box, strokes, a silhouette at a found pose) and from what differs from the border when the
    border is a plain backdrop. Raises InputError naming `path` when the object cannot be separated.
    """
    if alpha is not None and np.any(alpha < OPAQUE):
        mask = np.asarray(alpha) >= OPAQUE
        if not mask.any():
            raise InputError("the photo's alpha channel is fully transparent: there is no object in it", path)
        return mask
    hints = hints or Hints()
    told = any(h is not None for h in (hints.box, hints.prior, hints.object_strokes, hints.background_strokes))
    rgb = np.asarray(rgb, dtype=np.float64)
    try:
        rough = _differs_from_background(rgb, path)
    except InputError:
        rough = None  # a floor under a sky: GrabCut starts from the frame's middle (or the hints)
    if rough is not None and not told:
        if rough.mean() < MIN_OBJECT_FRACTION:
            raise InputError("found no object: the photo looks like plain background", path)
        if rough.mean() > MAX_OBJECT_FRACTION:
            raise InputError("the object fills the photo; give it an alpha channel (transparent background)", path)
        if not _has_shadow_side(rgb, rough):
            return rough  # a plain backdrop: what differs from it is the object, to the pixel
    mask = grabcut_mask(rgb, replace(hints, rough=None if told else rough), path)
    if rough is None and not told:
        busy = busy_border_share(rgb, mask)
        if busy > MAX_BUSY_SHARE:
            raise InputError(f"the photo's background is cluttered (edges on {100 * busy:.0f} % of its border): draw a "
                             "box around the object first (Photo tab; nvr capture --box)", path)
    if mask.mean() > MAX_OBJECT_FRACTION:
        raise InputError("the object fills the photo; draw a box around it or give it an alpha channel", path)
    return mask


def busy_border_share(rgb: np.ndarray, cut: np.ndarray | None = None) -> float:
    """Share of a band along the photo's border (BUSY_BAND_FRACTION of its shorter side) on an edge, outside the
    object's `cut` (grown by BUSY_MASK_MARGIN): a floor under a sky has the horizon there and little else, a room or a
    street has edges everywhere. A simple measure (no learned clutter classifier ships in the registries'
    packages); leaving the cut out keeps a textured object that touches the border from counting as clutter."""
    h, w = rgb.shape[:2]
    blurred = ndimage.gaussian_filter(np.asarray(rgb, dtype=np.float64), sigma=(BUSY_BLUR, BUSY_BLUR, 0.0))
    gy, gx = np.gradient(blurred, axis=(0, 1))
    edge = np.sqrt((gx**2 + gy**2).sum(axis=2)) > BUSY_EDGE
    band = max(1, round(BUSY_BAND_FRACTION * min(h, w)))
    border = np.zeros((h, w), dtype=bool)
    border[:band], border[-band:], border[:, :band], border[:, -band:] = True, True, True, True
    if cut is not None:
        border &= ~ndimage.binary_dilation(cut, iterations=max(1, round(BUSY_MASK_MARGIN * min(h, w))))
    return float(edge[border].mean()) if border.any() else 0.0


def _has_shadow_side(rgb: np.ndarray, rough: np.ndarray) -> bool:
    """Whether a good part (SHADOW_SHARE) of what differs from the backdrop looks like the backdrop in shadow:
    then the backdrop is a lit floor, and GrabCut must separate object from shadow; else the difference is the object."""
    import cv2

    labels = np.where(rough, cv2.GC_PR_FGD, cv2.GC_PR_BGD).astype(np.uint8)
    return shadow_pixels(rgb, labels).sum() > SHADOW_SHARE * rough.sum()


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
            raise InputError("the photo's border is not a plain background", path)
        coefficients, *_ = np.linalg.lstsq(design[keep.ravel()], rgb[keep], rcond=None)
        residual = np.linalg.norm(rgb - (design @ coefficients).reshape(h, w, 3), axis=2)
        sigma = 1.4826 * np.median(residual[keep]) + 1e-4
        threshold = max(MIN_CONTRAST, NOISE_SIGMAS * sigma)
        keep = border & (residual < threshold)
    if sigma > PLAIN_SIGMA:
        raise InputError("the photo's border is not a plain background", path)
    return without_specks(residual >= threshold, SPECK_FRACTION)


def _quadratic_design(h: int, w: int) -> np.ndarray:
    """(H*W, 6) rows [1, x, y, x^2, xy, y^2] for pixel coordinates scaled to [-1, 1]."""
    y, x = np.mgrid[0:h, 0:w]
    x = (2.0 * x + 1.0) / w - 1.0
    y = (2.0 * y + 1.0) / h - 1.0
    return np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=-1).reshape(h * w, 6)
