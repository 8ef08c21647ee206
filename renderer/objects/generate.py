"""Procedural furniture, the stand-in for ShapeNet: one object per (category, integer seed), forever.

Train and test objects come from disjoint seed ranges (`split_seeds`), so no object of the
test set is ever trained on.
"""

from __future__ import annotations

import zlib
from collections.abc import Mapping
from typing import Any

import numpy as np

from renderer.errors import InputError
from renderer.objects import chairs, novel, sofas, solids, stools, tables
from renderer.objects.assembly import LabeledMesh, assemble
from renderer.objects.category import Category
from renderer.objects.params import draw_params

CATEGORIES: dict[str, Category] = {
    c.name: c
    for c in (chairs.CATEGORY, tables.CATEGORY, sofas.CATEGORY, stools.CATEGORY, novel.CATEGORY, solids.CATEGORY)
}

SPLITS = ("train", "test")
SEEDS_PER_SPLIT = 1_000_000
_SPLIT_START = {"train": 0, "test": SEEDS_PER_SPLIT}
_GEOMETRY_STREAM = 1  # keeps geometry draws independent of appearance draws made from the same seed


def check_seed(seed: int) -> int:
    """A seed is a non-negative integer (numpy integers allowed)."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise InputError(f"seed must be a non-negative integer, got {seed!r}")
    return int(seed)


def check_split(split: str) -> str:
    """A split is 'train' or 'test'."""
    if split not in SPLITS:
        raise InputError(f"unknown split {split!r}; expected one of {', '.join(SPLITS)}")
    return split


def split_seeds(split: str, count: int) -> np.ndarray:
    """The first `count` object seeds of a split; train uses [0, 1e6), test [1e6, 2e6)."""
    check_split(split)
    if not 0 <= count <= SEEDS_PER_SPLIT:
        raise InputError(f"count must be between 0 and {SEEDS_PER_SPLIT}, got {count}")
    return _SPLIT_START[split] + np.arange(count, dtype=np.int64)


def split_seed(split: str, k: int) -> int:
    """The split's seed number `k` (0 <= k < SEEDS_PER_SPLIT): split_seeds(split, k + 1)[k]."""
    check_split(split)
    if not 0 <= k < SEEDS_PER_SPLIT:
        raise InputError(f"seed number must be between 0 and {SEEDS_PER_SPLIT - 1}, got {k}")
    return _SPLIT_START[split] + int(k)


def category_of(name: str) -> Category:
    """Look a category up by name."""
    if name not in CATEGORIES:
        raise InputError(f"unknown category {name!r}; expected one of {', '.join(CATEGORIES)}")
    return CATEGORIES[name]


def generate_object(category: str, seed: int, overrides: Mapping[str, Any] | None = None) -> LabeledMesh:
    """Build the object of `category` for `seed`: draw its parameters, build its parts, union, normalise.

    `overrides` sets named parameters by hand (checked against the category's declaration).
    """
    spec = category_of(category)
    stream = zlib.crc32(category.encode())  # per-category stream, stable if categories are added
    rng = np.random.default_rng([check_seed(seed), _GEOMETRY_STREAM, stream])
    params = draw_params(spec.parameters, rng, overrides)
    return assemble(spec.build(params), spec.part_names, category, params)
