"""What a furniture category provides: its part names, its structural parameters and its builder."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import manifold3d as mf

from renderer.objects.params import Parameter

Parts = list[tuple[str, mf.Manifold]]


@dataclass(frozen=True)
class Category:
    """A category: `build(params)` returns closed parts, in metres, front facing +z.

    `parts` maps each part name to its material role in the `default` appearance
    (frame, surface, soft, upholstery, cushions); its order fixes the part label numbers.
    """

    name: str
    parts: Mapping[str, str]
    parameters: Mapping[str, Parameter]
    build: Callable[[dict[str, Any]], Parts]

    @property
    def part_names(self) -> tuple[str, ...]:
        return tuple(self.parts)
