"""The object in a photo without an alpha channel, by GrabCut (OpenCV): color models of object and
background fitted by graph cuts, started from what is known.

What is known, strongest first: the user's strokes (sure object, sure background); the object's
silhouette at a pose already found (eroded: sure object; itself: probable object; elsewhere
probable background); the user's box (outside: sure background, and the background is modelled
from what surrounds the box); the photo's border (background where nothing says object).
GrabCut's background model is a mixture of several colors, so a floor and a sky behind the object
are two background regions, not one. Light on the floor is background too: a shadow is the floor
darker, and the light's bright spot fades out softly where an object is outlined.
The field's standard tool is used rather than a hand-made color model: it is what the photo's
clutter needs, and it is maintained (opencv-python-headless).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage

from renderer.color import srgb_to_linear
from renderer.errors import InputError

ITERATIONS = 5
BORDER_FRACTION = 0.02  # the border band taken as background, as a share of the shorter side
PRIOR_MARGIN_FRACTION = 0.02  # a silhouette prior is eroded/dilated by this share of the shorter side
BOX_CONTEXT = 1.0  # with a box, GrabCut sees the box grown by this share of its size on each side
CENTER_MARGIN = 0.1  # without box or prior, the object is looked for inside this margin of the frame
MIN_OBJECT_FRACTION = 0.002  # of the image: less than this is nothing
SPECK_FRACTION = 0.001  # object components smaller than this share of the image are dropped
SHADOW_CHROMA = 0.03  # largest chromaticity difference from the row's background that can still be shadow
SHADOW_MIN_COLOR = 0.03  # the background's chromaticity must be at least this far from grey for the test
SHADOW_DARKEST, SHADOW_LIGHTEST = 0.15, 0.9  # brightness of a shadow relative to the lit background beside it
SHADOW_PLAIN_ROW = 0.02  # the row's background varies in chromaticity (median deviation) by less than this: a floor,
# not clutter, whose median color says nothing about a shadow (the test took a box's object pixels for shadow)
SOFT_CHROMA = 0.15  # largest linear chromaticity difference from the row's floor that a pixel darker than the floor
# can have and still be light on it (a penumbra): a white light's strength keeps a floor's linear chromaticity; a dark
# leg on a green floor differs by more (docs/results.md, "Measurements behind the code")
SOFT_EDGE = 0.03  # sRGB change per pixel (after a 1-pixel blur) below which an edge is soft: light on the floor
# (a highlight's or a penumbra's edge changes by about 0.01 a pixel), not an object's outline (0.09-0.35)


@dataclass(frozen=True)
class Hints:
    """What the user or an earlier step says about where the object is; all optional. Masks are (H, W) bool."""

    box: tuple[int, int, int, int] | None = None  # x0, y0, x1, y1 in pixels, the object inside
    object_strokes: np.ndarray | None = None
    background_strokes: np.ndarray | None = None
    prior: np.ndarray | None = None  # the object's silhouette at a found pose
    rough: np.ndarray | None = None  # a rough guess (e.g. what differs from a plain border): probable object


def grabcut_mask(rgb: np.ndarray, hints: Hints = Hints(), path: str | Path | None = None) -> np.ndarray:
    """(H, W) bool mask of the object in `rgb` ((H, W, 3) sRGB in [0, 1]); InputError when nothing separates."""
    import cv2

    h, w = rgb.shape[:2]
    labels = _initial_labels(h, w, hints, path)
    if not np.isin(labels, (cv2.GC_FGD, cv2.GC_PR_FGD)).any() or not np.isin(labels, (cv2.GC_BGD, cv2.GC_PR_BGD)).any():
        raise InputError("the hints leave no room for object or for background", path)
    window = context_window(hints.box, h, w)  # with a box, the background is modelled from what is around it
    rgb, labels = rgb[window], labels[window]
    image = np.ascontiguousarray(np.round(np.clip(rgb, 0.0, 1.0) * 255.0).astype(np.uint8)[..., ::-1])  # OpenCV: BGR
    background_model, object_model = np.zeros((1, 65), np.float64), np.zeros((1, 65), np.float64)
    cv2.setRNGSeed(0)  # GrabCut's color models start from OpenCV's global random state: fix it, same photo same mask
    try:
        cv2.grabCut(image, labels, None, background_model, object_model, ITERATIONS, cv2.GC_INIT_WITH_MASK)
    except cv2.error:
        raise InputError("cannot tell the object from the background (one of them has no colors to model)", path) from None
    first_cut = (labels == cv2.GC_FGD) | (labels == cv2.GC_PR_FGD)
    # The floor in shadow and light on the floor (the light's bright spot) are background: cut again with them as
    # such, within what the first cut took as object (the new color models must not take in more of the floor).
    floor = row_floor(rgb, labels)
    lighting = shadow_pixels(rgb, labels, floor) | soft_lighting_pixels(rgb, labels, floor)
    if lighting.any():
        labels[labels == cv2.GC_PR_BGD] = cv2.GC_BGD
        labels[lighting] = cv2.GC_BGD
        try:
            cv2.grabCut(image, labels, None, background_model, object_model, ITERATIONS, cv2.GC_INIT_WITH_MASK)
        except cv2.error:
            pass  # the first cut stands, without the lighting
        labels[lighting] = cv2.GC_BGD
    mask = _placed((labels == cv2.GC_FGD) | (labels == cv2.GC_PR_FGD), window, h, w)
    if mask.mean() < MIN_OBJECT_FRACTION:
        # All of it looked like light on the floor: a dark object before a plain sky can. The first cut stands.
        mask = _placed(first_cut, window, h, w)
    if mask.mean() < MIN_OBJECT_FRACTION:
        raise InputError("found no object: nothing in the photo separates from the background", path)
    return mask


def _placed(cut: np.ndarray, window: tuple[slice, slice], h: int, w: int) -> np.ndarray:
    """A cut of the window as a mask of the whole photo, without specks."""
    mask = np.zeros((h, w), dtype=bool)
    mask[window] = cut
    return without_specks(mask, SPECK_FRACTION)


def context_window(box: tuple[int, int, int, int] | None, h: int, w: int) -> tuple[slice, slice]:
    """The part of the photo GrabCut looks at: all of it, or the box grown by BOX_CONTEXT of its size on each side
    (a background far from the object, a room's other end, says little about what surrounds it)."""
    if box is None:
        return slice(0, h), slice(0, w)
    x0, y0, x1, y1 = (int(v) for v in box)
    x0, x1, y0, y1 = min(x0, x1), max(x0, x1), min(y0, y1), max(y0, y1)
    gx, gy = round(BOX_CONTEXT * (x1 - x0)), round(BOX_CONTEXT * (y1 - y0))
    return slice(max(0, y0 - gy), min(h, y1 + gy)), slice(max(0, x0 - gx), min(w, x1 + gx))


def _initial_labels(h: int, w: int, hints: Hints, path) -> np.ndarray:
    import cv2

    labels = np.full((h, w), cv2.GC_PR_BGD, np.uint8)
    side = min(h, w)
    if hints.prior is not None:
        prior = np.asarray(hints.prior, dtype=bool)
        if prior.shape != (h, w):
            raise InputError(f"the silhouette is {prior.shape[1]}x{prior.shape[0]}, the photo {w}x{h}", path)
        margin = max(1, round(PRIOR_MARGIN_FRACTION * side))
        labels[prior] = cv2.GC_PR_FGD  # around it probable background: the floor between a chair's legs stays floor
        labels[ndimage.binary_erosion(prior, iterations=margin)] = cv2.GC_FGD
    elif hints.rough is not None:
        margin = max(1, round(PRIOR_MARGIN_FRACTION * side))
        labels[ndimage.binary_dilation(np.asarray(hints.rough, dtype=bool), iterations=margin)] = cv2.GC_PR_FGD
    elif hints.box is None:
        m = round(CENTER_MARGIN * side)
        labels[m:h - m, m:w - m] = cv2.GC_PR_FGD
    if hints.box is not None:
        x0, y0, x1, y1 = (int(v) for v in hints.box)
        x0, x1, y0, y1 = max(0, min(x0, x1)), min(w, max(x0, x1)), max(0, min(y0, y1)), min(h, max(y0, y1))
        if x1 - x0 < 2 or y1 - y0 < 2:
            raise InputError(f"the box {list(hints.box)} holds no pixels of the {w}x{h} photo", path)
        inside = np.zeros((h, w), dtype=bool)
        inside[y0:y1, x0:x1] = True
        labels[~inside] = cv2.GC_BGD
        if hints.prior is None:
            labels[inside] = cv2.GC_PR_FGD
    band = max(1, round(BORDER_FRACTION * side))
    border = np.zeros((h, w), dtype=bool)
    border[:band], border[-band:], border[:, :band], border[:, -band:] = True, True, True, True
    labels[border & (labels == cv2.GC_PR_BGD)] = cv2.GC_BGD  # where nothing says object, the border is background
    for strokes, label in ((hints.object_strokes, cv2.GC_FGD), (hints.background_strokes, cv2.GC_BGD)):
        if strokes is not None:
            labels[np.asarray(strokes, dtype=bool)] = label
    return labels


@dataclass(frozen=True)
class RowFloor:
    """Per row of the photo, the background beside the probable object, for telling light on a floor from objects."""

    uniform: np.ndarray  # (H,) bool: that background is one color (a floor, not clutter)
    colored: np.ndarray  # (H,) bool: ... and that color is not grey
    chroma: np.ndarray  # (H, 3) its median chromaticity (of sRGB values)
    linear_chroma: np.ndarray  # (H, 3) the same of linear values, which a white light's strength does not change
    brightness: np.ndarray  # (H,) its median brightness (sum of the channels)


def row_floor(rgb: np.ndarray, labels: np.ndarray) -> RowFloor:
    """The background of each row (+-2 rows) that holds probable object, from GrabCut's labels."""
    import cv2

    h = labels.shape[0]
    background = (labels == cv2.GC_BGD) | (labels == cv2.GC_PR_BGD)
    brightness = rgb.sum(axis=2) + 1e-6
    linear_chroma = _chromaticity(srgb_to_linear(np.clip(rgb, 0.0, 1.0)))
    floor = RowFloor(np.zeros(h, dtype=bool), np.zeros(h, dtype=bool), np.zeros((h, 3)), np.zeros((h, 3)), np.ones(h))
    for row in np.flatnonzero((labels == cv2.GC_PR_FGD).any(axis=1)):
        rows = slice(max(0, row - 2), row + 3)
        band = background[rows]
        if band.sum() < 4:
            continue
        band_chroma = rgb[rows][band] / brightness[rows][band][:, None]
        floor.chroma[row] = np.median(band_chroma, axis=0)
        floor.linear_chroma[row] = np.median(linear_chroma[rows][band], axis=0)
        floor.brightness[row] = np.median(brightness[rows][band])
        floor.uniform[row] = np.median(np.abs(band_chroma - floor.chroma[row]).max(axis=1)) <= SHADOW_PLAIN_ROW
        floor.colored[row] = np.abs(floor.chroma[row] - 1.0 / 3.0).max() >= SHADOW_MIN_COLOR
    return floor


def _chromaticity(rgb: np.ndarray) -> np.ndarray:
    """Each pixel's color over the sum of its channels."""
    return rgb / (rgb.sum(axis=-1, keepdims=True) + 1e-6)


def shadow_pixels(rgb: np.ndarray, labels: np.ndarray, floor: RowFloor | None = None) -> np.ndarray:
    """Pixels taken as probable object that look like the floor of their rows in shadow: the same chromaticity,
    darker by SHADOW_DARKEST to SHADOW_LIGHTEST. Rows whose background is grey (a darker grey object cannot be
    told from its shadow by color) or not of one color (clutter, or a floor whitened by the light's spot) are
    left alone. What the user or a pose said is object (sure labels) stays. `floor`: row_floor's, if known."""
    import cv2

    probable = labels == cv2.GC_PR_FGD
    if not probable.any():
        return np.zeros(labels.shape, dtype=bool)
    floor = row_floor(rgb, labels) if floor is None else floor
    brightness = rgb.sum(axis=2) + 1e-6
    ratio = brightness / floor.brightness[:, None]
    similar = np.abs(rgb / brightness[..., None] - floor.chroma[:, None, :]).max(axis=2) < SHADOW_CHROMA
    plain = (floor.uniform & floor.colored)[:, None]
    return probable & plain & similar & (ratio >= SHADOW_DARKEST) & (ratio <= SHADOW_LIGHTEST)


def soft_lighting_pixels(rgb: np.ndarray, labels: np.ndarray, floor: RowFloor | None = None) -> np.ndarray:
    """Probable-object pixels in rows with a floor of one color (grey too), brighter than that floor or of its
    linear chromaticity (SOFT_CHROMA), reached from the cut's soft edges without crossing an edge: the light's bright
    spot and a shadow's penumbra fade into the floor, an object is outlined (a smoothly shaded object in clutter is
    not on a plain floor, so it is left alone; a dark leg in the shadow of its object, whose outline is soft there,
    differs from the floor in color). Sure labels are never changed."""
    import cv2

    probable = labels == cv2.GC_PR_FGD
    if not probable.any():
        return np.zeros(labels.shape, dtype=bool)
    floor = row_floor(rgb, labels) if floor is None else floor
    like_floor = np.abs(_chromaticity(srgb_to_linear(np.clip(rgb, 0.0, 1.0))) - floor.linear_chroma[:, None, :])
    brighter = rgb.sum(axis=2) > floor.brightness[:, None]  # the light's spot, whose clipped channels move its color
    lit = probable & floor.uniform[:, None] & ((like_floor.max(axis=2) < SOFT_CHROMA) | brighter)
    blurred = ndimage.gaussian_filter(np.asarray(rgb, dtype=np.float64), sigma=(1.0, 1.0, 0.0))
    gy, gx = np.gradient(blurred, axis=(0, 1))
    smooth = ndimage.maximum_filter(np.sqrt((gx**2 + gy**2).sum(axis=2)), size=3) < SOFT_EDGE
    cut = probable | (labels == cv2.GC_FGD)
    soft_edge = cut & ~ndimage.binary_erosion(cut) & smooth
    return ndimage.binary_propagation(soft_edge & lit, mask=lit & smooth)


def without_specks(mask: np.ndarray, fraction: float) -> np.ndarray:
    """`mask` without its components smaller than `fraction` of the image (the largest stays if all are)."""
    labels, count = ndimage.label(mask)
    if count == 0:
        return mask
    sizes = ndimage.sum_labels(mask, labels, index=np.arange(1, count + 1))
    keep = np.flatnonzero(sizes >= fraction * mask.size) + 1
    if len(keep) == 0:
        keep = np.array([int(np.argmax(sizes)) + 1])
    return np.isin(labels, keep)
