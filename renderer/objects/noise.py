"""Seeded lattice noise in any dimension: value noise, gradient (Perlin-style) noise, fractal sums, cells.

A `Lattice` holds the random tables of one noise instance; every function takes points of
shape (n, d) and returns one value per point. Used by the texture families and the material
looks of the appearance settings.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

TABLE_SIZE = 256  # lattice hashes repeat every 256 cells, far beyond any object (1 unit, cells >= 0.01)


@dataclass(frozen=True)
class Lattice:
    """Random tables of one noise instance: a permutation for hashing cells, and per-cell values, gradients, offsets."""

    perm: np.ndarray
    values: np.ndarray
    gradients: np.ndarray
    offsets: np.ndarray

    def hash(self, cells: np.ndarray) -> np.ndarray:
        """Table index of each integer cell (n, d), by chained permutation lookups."""
        h = np.zeros(cells.shape[0], dtype=np.int64)
        for axis in range(cells.shape[1]):
            h = self.perm[(h + cells[:, axis]) % TABLE_SIZE]
        return h


def make_lattice(rng: np.random.Generator, dim: int) -> Lattice:
    """Fresh random tables for `dim`-dimensional noise."""
    gradients = rng.normal(size=(TABLE_SIZE, dim))
    gradients /= np.linalg.norm(gradients, axis=1, keepdims=True)
    return Lattice(
        perm=rng.permutation(TABLE_SIZE),
        values=rng.random(TABLE_SIZE),
        gradients=gradients,
        offsets=rng.random((TABLE_SIZE, dim)),
    )


def _fade(t: np.ndarray) -> np.ndarray:
    """Quintic smoothstep 6t^5 - 15t^4 + 10t^3: blends lattice corners without visible creases."""
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


def _corners(dim: int) -> np.ndarray:
    return np.array(list(itertools.product((0, 1), repeat=dim)), dtype=np.int64)


def _blend_corners(points: np.ndarray, corner_value) -> np.ndarray:
    """Sum over the lattice cell's corners of smooth weights times corner_value(corner, cell, frac)."""
    cell = np.floor(points).astype(np.int64)
    frac = points - cell
    w = _fade(frac)
    total = np.zeros(points.shape[0])
    for corner in _corners(points.shape[1]):
        weight = np.prod(np.where(corner == 1, w, 1.0 - w), axis=1)
        total += weight * corner_value(corner, cell, frac)
    return total


def value_noise(lattice: Lattice, points: np.ndarray) -> np.ndarray:
    """Smoothly interpolated random values at the lattice cells, in [0, 1]."""
    return _blend_corners(points, lambda corner, cell, frac: lattice.values[lattice.hash(cell + corner)])


def gradient_noise(lattice: Lattice, points: np.ndarray) -> np.ndarray:
    """Perlin-style noise: random gradients at lattice cells, blended; mapped to [0, 1] around 0.5."""

    def corner_value(corner, cell, frac):
        return np.sum(lattice.gradients[lattice.hash(cell + corner)] * (frac - corner), axis=1)

    return np.clip(0.5 + _blend_corners(points, corner_value), 0.0, 1.0)


def fractal(
    noise: Callable[[Lattice, np.ndarray], np.ndarray],
    lattice: Lattice,
    points: np.ndarray,
    octaves: int,
    gain: float = 0.5,
) -> np.ndarray:
    """Sum of `octaves` copies of a [0, 1] noise at doubling frequency and `gain`-scaled weight, still in [0, 1]."""
    total, amplitude, weights = np.zeros(points.shape[0]), 1.0, 0.0
    for octave in range(octaves):
        shift = 17.31 * (octave + 1)  # decorrelates the octaves, which share the same tables
        total += amplitude * noise(lattice, points * 2.0**octave + shift)
        weights += amplitude
        amplitude *= gain
    return total / weights


def cells(lattice: Lattice, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Voronoi cells of one random feature point per lattice cell: nearest distance F1, second F2, nearest cell id."""
    cell = np.floor(points).astype(np.int64)
    n = points.shape[0]
    f1, f2 = np.full(n, np.inf), np.full(n, np.inf)
    nearest = np.zeros(n, dtype=np.int64)
    for step in itertools.product((-1, 0, 1), repeat=points.shape[1]):
        neighbour = cell + np.array(step)
        h = lattice.hash(neighbour)
        d = np.linalg.norm(neighbour + lattice.offsets[h] - points, axis=1)
        closer = d < f1
        f2 = np.where(closer, f1, np.minimum(f2, d))
        nearest = np.where(closer, h, nearest)
        f1 = np.where(closer, d, f1)
    return f1, f2, nearest
