"""Structural parameters of a category: how each one is drawn at random, and overrides by name.

A category declares its parameters once as a dict name -> Choice | Uniform | Integer; the
same declaration draws them from a seeded generator (always in declaration order, so a seed
gives the same object forever) and checks values a caller sets by hand.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from renderer.errors import InputError


@dataclass(frozen=True)
class Choice:
    """One of a few named options, with optional relative weights."""

    options: tuple[Any, ...]
    weights: tuple[float, ...] | None = None

    def draw(self, rng: np.random.Generator) -> Any:
        p = None if self.weights is None else np.asarray(self.weights) / sum(self.weights)
        return self.options[int(rng.choice(len(self.options), p=p))]

    def accepts(self, value: Any) -> bool:
        return value in self.options


@dataclass(frozen=True)
class Uniform:
    """A real number drawn uniformly from [low, high]."""

    low: float
    high: float

    def draw(self, rng: np.random.Generator) -> float:
        return float(rng.uniform(self.low, self.high))

    def accepts(self, value: Any) -> bool:
        return isinstance(value, int | float) and not isinstance(value, bool) and self.low <= value <= self.high


@dataclass(frozen=True)
class Integer:
    """A whole number drawn uniformly from low..high inclusive."""

    low: int
    high: int

    def draw(self, rng: np.random.Generator) -> int:
        return int(rng.integers(self.low, self.high + 1))

    def accepts(self, value: Any) -> bool:
        return isinstance(value, int) and not isinstance(value, bool) and self.low <= value <= self.high


Parameter = Choice | Uniform | Integer


def draw_params(
    spec: Mapping[str, Parameter], rng: np.random.Generator, overrides: Mapping[str, Any] | None = None
) -> dict[str, Any]:
    """Draw every parameter in declaration order, then replace the overridden ones (checked against `spec`).

    All draws happen even for overridden names, so an override changes nothing else about the object.
    """
    params = {name: parameter.draw(rng) for name, parameter in spec.items()}
    for name, value in (overrides or {}).items():
        if name not in spec:
            raise InputError(f"unknown parameter {name!r}; known: {', '.join(spec)}")
        if not spec[name].accepts(value):
            raise InputError(f"parameter {name!r} = {value!r} is outside {spec[name]}")
        params[name] = value
    return params
