"""The one stage cache: each stage's last result with the key it was computed for, and what the last pass ran.

RenderReport is that record for one render, the same for every renderer (models/renderers.py).

A staged renderer asks for each stage by name with the key of exactly what that stage reads; the cache returns the
kept result when the key is the same, else computes, times and keeps the new one. One result per stage: a live
editor asks for the latest scene, so older keys are never asked for again.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Hashable
from dataclasses import dataclass
from typing import Any


class StageCache:
    """Stage results by name, each with its key; `stage_ms`: the stages computed since `begin`, in order, in ms."""

    def __init__(self, settle: Callable[[], None] | None = None) -> None:
        """`settle`: called after each computation before it is timed (a GPU's asynchronous work waited for)."""
        self._memo: dict[str, tuple[Hashable, Any]] = {}
        self._settle = settle
        self.stage_ms: dict[str, float] = {}

    def begin(self) -> None:
        """Start a new pass: `stage_ms` lists only the stages computed from now on."""
        self.stage_ms = {}

    def __call__(self, name: str, key: Hashable, compute: Callable[[], Any], keep: bool = True) -> Any:
        """The stage's kept result if it was computed for `key`, else compute and time it; `keep`: False computes
        without keeping (a one-off image of another size leaves the live size's result in place)."""
        if self.cached(name, key):
            return self._memo[name][1]
        start = time.perf_counter()
        value = compute()
        if self._settle is not None:
            self._settle()
        self.stage_ms[name] = (time.perf_counter() - start) * 1000.0
        if keep:
            self._memo[name] = (key, value)
        return value

    def cached(self, name: str, key: Hashable) -> bool:
        return name in self._memo and self._memo[name][0] == key

    def last(self, name: str) -> Any | None:
        """The stage's last kept result whatever its key (a stage that updates its last result), or None."""
        entry = self._memo.get(name)
        return None if entry is None else entry[1]

    def forget(self, name: str) -> None:
        """Drop one stage's result (before it is changed in place, so no stale key stays with it)."""
        self._memo.pop(name, None)

    def clear(self) -> None:
        """Forget every stage: the next pass computes all of them."""
        self._memo.clear()


@dataclass(frozen=True)
class RenderReport:
    """What one render did, for status bars, benchmarks and tests: the stages that ran (in order) and their times."""

    stages_run: tuple[str, ...]
    stage_ms: dict[str, float]
    total_ms: float
    preview: bool
    grid_fraction: float | None = None  # share of the grid the voxel branch read, if it ran
    note: str = ""  # what the image is when it is not what the renderer usually draws
