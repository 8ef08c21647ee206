"""Random colors for appearances: uniform picks, palettes of distinct colors, and ramps between colors.

All colors are sRGB triples in [0, 1], the convention of scene files and object voxels.
"""

from __future__ import annotations

import colorsys

import numpy as np


def uniform_color(rng: np.random.Generator) -> np.ndarray:
    """Any sRGB color, each channel uniform in [0, 1] (the paper's 'random RGB values')."""
    return rng.random(3)


def hsv_color(
    rng: np.random.Generator, hue: tuple[float, float], sat: tuple[float, float], val: tuple[float, float]
) -> np.ndarray:
    """A color with hue, saturation and value each drawn uniformly from the given ranges (hue wraps around 1)."""
    h = rng.uniform(*hue) % 1.0
    return np.array(colorsys.hsv_to_rgb(h, rng.uniform(*sat), rng.uniform(*val)))


def palette(rng: np.random.Generator, count: int) -> np.ndarray:
    """`count` colors that are told apart easily: spread hues, alternating dark and light values; shape (count, 3)."""
    start = rng.random()
    colors = []
    for i in range(count):
        hue = start + i / count + rng.uniform(-0.08, 0.08)
        value = (0.25, 0.55) if i % 2 else (0.6, 0.95)
        colors.append(hsv_color(rng, (hue, hue), (0.25, 0.9), value))
    return np.array(colors)


def ramp(t: np.ndarray, colors: np.ndarray) -> np.ndarray:
    """Map values t in [0, 1] to colors by linear interpolation between evenly spaced `colors`; shape (n, 3)."""
    position = np.clip(t, 0.0, 1.0) * (len(colors) - 1)
    low = np.minimum(np.floor(position).astype(np.int64), len(colors) - 2)
    f = (position - low)[:, None]
    return colors[low] * (1.0 - f) + colors[low + 1] * f
