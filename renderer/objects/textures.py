"""Procedural texture families for the `textured` setting, and their triplanar projection onto an object.

The paper draws textures from the Describable Textures Dataset with separate train and test
textures; here whole families are held out: the test families never appear in training, and
each has a training cousin of similar character (value noise / Perlin noise, stripes / zigzag,
checks / plaid, flat cells / crackle, marble and dots and bricks / rings).

A texture is a function from 2D coordinates (n, 2), in object units, to sRGB colors (n, 3).
Feature sizes stay between about 0.02 and 0.3 object units, i.e. 2 to 30 voxels at 100^3,
and at least twice the edge length the mesh is refined to, so vertex colors can carry them.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from renderer.objects.noise import cells, fractal, gradient_noise, make_lattice, value_noise
from renderer.objects.palette import hsv_color, palette, ramp

Texture = Callable[[np.ndarray], np.ndarray]


def _rotated(uv: np.ndarray, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return uv @ np.array([[c, -s], [s, c]])


def _smooth_step(edge0: float, edge1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - edge0) / (edge1 - edge0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _band_index(t: np.ndarray, count: int) -> np.ndarray:
    return np.floor(t).astype(np.int64) % count


def value_clouds(rng: np.random.Generator) -> Texture:
    """Fractal value noise through a ramp of 2-3 colors."""
    lattice, scale, octaves = make_lattice(rng, 2), rng.uniform(0.05, 0.25), int(rng.integers(3, 6))
    colors = palette(rng, int(rng.integers(2, 4)))
    return lambda uv: ramp(_smooth_step(0.25, 0.75, fractal(value_noise, lattice, uv / scale, octaves)), colors)


def stripes(rng: np.random.Generator) -> Texture:
    """Straight parallel stripes of 2-4 cycling colors at a random angle."""
    angle, width = rng.uniform(0, np.pi), rng.uniform(0.025, 0.08)
    colors = palette(rng, int(rng.integers(2, 5)))
    return lambda uv: colors[_band_index(_rotated(uv, angle)[:, 0] / width, len(colors))]


def checks(rng: np.random.Generator) -> Texture:
    """Checkerboard of two colors, rotated."""
    angle, size = rng.uniform(0, np.pi / 2), rng.uniform(0.04, 0.12)
    colors = palette(rng, 2)

    def texture(uv: np.ndarray) -> np.ndarray:
        cell = np.floor(_rotated(uv, angle) / size).astype(np.int64)
        return colors[(cell[:, 0] + cell[:, 1]) % 2]

    return texture


def flat_cells(rng: np.random.Generator) -> Texture:
    """Voronoi cells, each filled with one of 3-6 colors."""
    lattice, size = make_lattice(rng, 2), rng.uniform(0.04, 0.15)
    colors = palette(rng, int(rng.integers(3, 7)))
    return lambda uv: colors[cells(lattice, uv / size)[2] % len(colors)]


def marble(rng: np.random.Generator) -> Texture:
    """Light stone with dark veins: a sine wave across the slab bent by turbulence."""
    lattice, angle = make_lattice(rng, 2), rng.uniform(0, np.pi)
    period, turbulence, sharpness = rng.uniform(0.08, 0.3), rng.uniform(1.0, 4.0), rng.uniform(2.0, 8.0)
    stone = hsv_color(rng, (0.0, 1.0), (0.0, 0.3), (0.75, 0.98))
    vein = hsv_color(rng, (0.0, 1.0), (0.1, 0.6), (0.1, 0.5))
    colors = np.array([stone, vein])

    def texture(uv: np.ndarray) -> np.ndarray:
        bend = turbulence * fractal(gradient_noise, lattice, uv / (2 * period), 4)
        wave = 0.5 + 0.5 * np.sin(2 * np.pi * (_rotated(uv, angle)[:, 0] / period + bend))
        return ramp(wave**sharpness, colors)

    return texture


def dots(rng: np.random.Generator) -> Texture:
    """Polka dots on a square grid, every other row shifted half a cell if staggered."""
    size, radius, staggered = rng.uniform(0.05, 0.14), rng.uniform(0.2, 0.42), bool(rng.integers(2))
    colors = palette(rng, 2)

    def texture(uv: np.ndarray) -> np.ndarray:
        grid = uv / size
        if staggered:
            grid = grid + np.column_stack([0.5 * (np.floor(grid[:, 1]) % 2), np.zeros(len(grid))])
        distance = np.linalg.norm(grid - np.floor(grid) - 0.5, axis=1)
        return ramp(_smooth_step(radius + 0.03, radius - 0.03, distance), colors)

    return texture


def bricks(rng: np.random.Generator) -> Texture:
    """Running-bond bricks of varying shade separated by mortar lines."""
    lattice = make_lattice(rng, 2)
    width = rng.uniform(0.06, 0.2)
    height = width * rng.uniform(0.3, 0.55)
    mortar = rng.uniform(0.08, 0.18) * height
    brick = hsv_color(rng, (0.0, 1.0), (0.3, 0.8), (0.35, 0.8))
    joint = hsv_color(rng, (0.0, 1.0), (0.0, 0.2), (0.55, 0.9))

    def texture(uv: np.ndarray) -> np.ndarray:
        row = np.floor(uv[:, 1] / height)
        along = uv[:, 0] / width + 0.5 * (row % 2)
        column = np.floor(along)
        in_joint = ((along - column) * width < mortar) | ((uv[:, 1] / height - row) * height < mortar)
        shade = 0.75 + 0.5 * lattice.values[lattice.hash(np.column_stack([column, row]).astype(np.int64))]
        return np.where(in_joint[:, None], joint, np.clip(brick * shade[:, None], 0.0, 1.0))

    return texture


def perlin_clouds(rng: np.random.Generator) -> Texture:
    """Fractal gradient noise, plain or turbulent (folded at its midpoint), through a ramp of 2-3 colors."""
    lattice, scale, octaves = make_lattice(rng, 2), rng.uniform(0.05, 0.25), int(rng.integers(3, 6))
    turbulent = bool(rng.integers(2))
    colors = palette(rng, int(rng.integers(2, 4)))

    def texture(uv: np.ndarray) -> np.ndarray:
        n = fractal(gradient_noise, lattice, uv / scale, octaves)
        t = np.abs(2.0 * n - 1.0) * 2.0 if turbulent else _smooth_step(0.3, 0.7, n)
        return ramp(t, colors)

    return texture


def zigzag(rng: np.random.Generator) -> Texture:
    """Chevron bands: stripes displaced by a triangle wave."""
    angle, width = rng.uniform(0, np.pi), rng.uniform(0.025, 0.07)
    period = rng.uniform(0.05, 0.2)
    amplitude = period * rng.uniform(0.2, 0.8)
    colors = palette(rng, int(rng.integers(2, 5)))

    def texture(uv: np.ndarray) -> np.ndarray:
        r = _rotated(uv, angle)
        x = r[:, 0] / period
        triangle = 2.0 * np.abs(x - np.floor(x + 0.5))
        return colors[_band_index((r[:, 1] + amplitude * triangle) / width, len(colors))]

    return texture


def plaid(rng: np.random.Generator) -> Texture:
    """Tartan: a repeating sequence of colored bands along u, the same across v, the two averaged."""
    widths = rng.uniform(0.02, 0.06, size=int(rng.integers(3, 7)))
    edges = np.cumsum(widths)
    colors = palette(rng, int(rng.integers(2, 5)))
    band_colors = colors[rng.integers(len(colors), size=len(widths))]

    def bands(t: np.ndarray) -> np.ndarray:
        return band_colors[np.searchsorted(edges, t % edges[-1], side="right").clip(max=len(widths) - 1)]

    return lambda uv: 0.5 * (bands(uv[:, 0]) + bands(uv[:, 1]))


def crackle(rng: np.random.Generator) -> Texture:
    """Cracked surface: dark lines along Voronoi cell borders over a mottled base."""
    lattice, size = make_lattice(rng, 2), rng.uniform(0.05, 0.15)
    line_width = rng.uniform(0.04, 0.12)
    base = palette(rng, 2)
    line = hsv_color(rng, (0.0, 1.0), (0.0, 0.5), (0.02, 0.25))

    def texture(uv: np.ndarray) -> np.ndarray:
        f1, f2, _ = cells(lattice, uv / size)
        mottled = ramp(value_noise(lattice, uv / (0.7 * size)), base)
        border = _smooth_step(line_width, 0.5 * line_width, f2 - f1)[:, None]
        return mottled * (1.0 - border) + line * border

    return texture


def rings(rng: np.random.Generator) -> Texture:
    """Concentric rings around a random centre, wobbled by noise (like end grain or agate)."""
    lattice = make_lattice(rng, 2)
    centre = rng.uniform(-1.0, 1.0, size=2)
    period = rng.uniform(0.04, 0.1)
    wobble = period * rng.uniform(0.5, 3.0)
    colors = palette(rng, int(rng.integers(2, 4)))

    def texture(uv: np.ndarray) -> np.ndarray:
        radius = np.linalg.norm(uv - centre, axis=1) + wobble * fractal(value_noise, lattice, uv / 0.15, 3)
        return ramp((radius / period) % 1.0, colors)

    return texture


TRAIN_FAMILIES: dict[str, Callable[[np.random.Generator], Texture]] = {
    "value_noise": value_clouds,
    "stripes": stripes,
    "checks": checks,
    "cells": flat_cells,
    "marble": marble,
    "dots": dots,
    "bricks": bricks,
}
TEST_FAMILIES: dict[str, Callable[[np.random.Generator], Texture]] = {
    "perlin_noise": perlin_clouds,
    "zigzag": zigzag,
    "plaid": plaid,
    "crackle": crackle,
    "rings": rings,
}
FAMILIES = {"train": TRAIN_FAMILIES, "test": TEST_FAMILIES}


def draw_texture(rng: np.random.Generator, split: str) -> tuple[str, Texture]:
    """A random texture of a random family of the split ('train' or 'test'), with its family name."""
    families = FAMILIES[split]
    family = sorted(families)[int(rng.integers(len(families)))]
    return family, families[family](rng)


def triplanar(texture: Texture, points: np.ndarray, normals: np.ndarray, sharpness: float = 4.0) -> np.ndarray:
    """Color surface points by projecting the texture along x, y and z, blended by how much the normal faces each axis."""
    weights = np.abs(normals) ** sharpness + 1e-6
    weights /= weights.sum(axis=1, keepdims=True)
    along_x = texture(points[:, [2, 1]])
    along_y = texture(points[:, [0, 2]])
    along_z = texture(points[:, [0, 1]])
    return weights[:, :1] * along_x + weights[:, 1:2] * along_y + weights[:, 2:] * along_z
