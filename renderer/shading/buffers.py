"""What a network reads of the voxel shader: its image and buffers side by side."""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from renderer.scene import (
    CAMERA_DISTANCE,
    GRID_EXTENT,
)
from renderer.shading.lighting import ShadedImage

BUFFER_CHANNELS = ("image r", "image g", "image b", "albedo r", "albedo g", "albedo b", "normal x", "normal y",
                   "normal z", "depth", "visibility", "occlusion", "coverage")


def network_buffers(shaded: ShadedImage) -> np.ndarray:
    """(H, W, len(BUFFER_CHANNELS)) float32, each channel in about [-1, 1]: the shaded image (sRGB), the object's
    albedo (sRGB), its world normal, its depth (0 at the look-at distance, +-1 at the grid's faces), the
    share of the light and of the sky each point sees, and the object's coverage; 0 where there is no object."""
    out = np.empty(shaded.coverage.shape + (len(BUFFER_CHANNELS),), dtype=np.float32)
    pack_buffers(shaded.image, shaded.albedo_srgb, shaded.normal, shaded.depth, shaded.visibility,
                         shaded.occlusion, shaded.coverage, CAMERA_DISTANCE, 1.0 / (0.5 * GRID_EXTENT), out)
    return out


# --- compiled loops (numba, cached on disk) ---------------------------------------------------------

@njit(cache=True, parallel=True)
def pack_buffers(image, albedo, normal, depth, visibility, occlusion, coverage, depth_offset, depth_scale, out):
    """out[r, c] = image, albedo, normal (3 each), (depth - depth_offset) * depth_scale (0 where nothing is covered),
    visibility, occlusion, coverage: a network's buffers side by side in one pass, instead of numpy's concatenation."""
    for r in prange(out.shape[0]):
        for c in range(out.shape[1]):
            for k in range(3):
                out[r, c, k] = image[r, c, k]
                out[r, c, 3 + k] = albedo[r, c, k]
                out[r, c, 6 + k] = normal[r, c, k]
            out[r, c, 9] = (depth[r, c] - depth_offset) * depth_scale if coverage[r, c] > 0.0 else 0.0
            out[r, c, 10] = visibility[r, c]
            out[r, c, 11] = occlusion[r, c]
            out[r, c, 12] = coverage[r, c]
