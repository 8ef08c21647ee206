"""The viewport and the neural render side by side in one image, for figures and bug reports.

The render keeps its exact pixels, each repeated `scale` times in both directions so that a
256^2 render is not a thumbnail beside the viewport; the viewport is drawn at the same height
with the view the user has set.
"""

from __future__ import annotations

import math

import numpy as np

MIN_HEIGHT = 512  # smaller renders are enlarged by a whole factor to at least this height


def scale_for(render_size: int) -> int:
    """The whole factor that enlarges a render of `render_size` pixels to at least MIN_HEIGHT."""
    return max(1, math.ceil(MIN_HEIGHT / render_size))


def compose(viewport: np.ndarray, render: np.ndarray) -> np.ndarray:
    """(H, W + H, 3) uint8: the viewport (H, W, 3) uint8 on the left, the (S, S, 3) uint8 render enlarged to H on the right."""
    size = render.shape[0]
    scale = viewport.shape[0] // size
    if viewport.shape[0] != size * scale or render.shape[1] != size:
        raise ValueError(f"the viewport's height {viewport.shape[0]} is not a multiple of the square render's {size}")
    enlarged = np.repeat(np.repeat(render, scale, axis=0), scale, axis=1)
    return np.concatenate([viewport, enlarged], axis=1)
