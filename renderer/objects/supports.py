"""What holds furniture up, shared by chairs, tables and stools: legs, stretchers, pedestals, bases.

A leg is described by its axis, a (top, bottom) pair of 3D points; legs splay outwards from
the centre by tilting the bottom point away from the vertical axis.
"""

from __future__ import annotations

import math

import manifold3d as mf
import numpy as np

from renderer.objects.primitives import ball, bar, plate

LegAxis = tuple[np.ndarray, np.ndarray]


def corner_points(width: float, depth: float, inset: float) -> np.ndarray:
    """(x, z) of four legs under a width x depth top, `inset` in from each edge, in order around the rim."""
    hx, hz = width / 2 - inset, depth / 2 - inset
    return np.array([[-hx, hz], [hx, hz], [hx, -hz], [-hx, -hz]])


def circle_points(count: int, radius: float, start_deg: float) -> np.ndarray:
    """(x, z) of `count` legs evenly around a circle, the first at `start_deg` from +x towards +z."""
    angles = np.radians(start_deg) + 2 * np.pi * np.arange(count) / count
    return radius * np.column_stack([np.cos(angles), np.sin(angles)])


def leg_axes(tops_xz: np.ndarray, top_y: float, splay_deg: float) -> list[LegAxis]:
    """Axes from (x, top_y, z) down to the floor, the foot moved outwards by top_y * tan(splay)."""
    axes = []
    for x, z in tops_xz:
        outward = np.array([x, z]) / max(math.hypot(x, z), 1e-9)
        foot = np.array([x, z]) + outward * top_y * math.tan(math.radians(splay_deg))
        axes.append((np.array([x, top_y, z]), np.array([foot[0], 0.0, foot[1]])))
    return axes


def point_at_height(axis: LegAxis, y: float) -> np.ndarray:
    """The point of a leg axis at height y."""
    top, bottom = axis
    return bottom + (top - bottom) * (y - bottom[1]) / (top[1] - bottom[1])


def legs(axes: list[LegAxis], radius: float, foot_radius: float, section: str) -> list[mf.Manifold]:
    """One straight (possibly tapered) leg per axis."""
    return [bar(top, bottom, radius, foot_radius, section) for top, bottom in axes]


def stretchers(axes: list[LegAxis], y: float, radius: float, section: str) -> list[mf.Manifold]:
    """Bars at height y joining each leg to the next one around the rim."""
    points = [point_at_height(axis, y) for axis in axes]
    return [bar(points[i], points[(i + 1) % len(points)], radius, section=section) for i in range(len(points))]


def star_base(spokes: int, reach: float, spoke_radius: float, hub_y: float, start_deg: float) -> list[mf.Manifold]:
    """Office-chair base: spokes sloping down from a hub at hub_y to ball feet resting on the floor."""
    foot_r = 1.4 * spoke_radius
    parts = [bar((0.0, hub_y - 1.5 * spoke_radius, 0.0), (0.0, hub_y + 1.5 * spoke_radius, 0.0), 2.2 * spoke_radius)]
    for x, z in circle_points(spokes, reach, start_deg):
        parts.append(bar((0.0, hub_y, 0.0), (x, foot_r * 1.6, z), spoke_radius))
        parts.append(ball((x, foot_r, z), foot_r))
    return parts


def disc_base(radius: float, thickness: float) -> mf.Manifold:
    """Round flat foot of a pedestal."""
    return plate("round", 2 * radius, 2 * radius, thickness, 0.0)


def pedestal(top_y: float, column_radius: float, base: str, reach: float, spokes: int) -> list[mf.Manifold]:
    """Central column from its base up to top_y, on a star of spokes ("star") or a round plate ("disc")."""
    if base == "star":
        hub_y = 0.09
        return [
            bar((0.0, hub_y, 0.0), (0.0, top_y, 0.0), column_radius),
            *star_base(spokes, reach, 0.6 * column_radius, hub_y, 90.0),
        ]
    if base == "disc":
        thickness = 0.025
        return [bar((0.0, thickness / 2, 0.0), (0.0, top_y, 0.0), column_radius), disc_base(reach, thickness)]
    raise ValueError(f"unknown pedestal base {base!r}; expected 'star' or 'disc'")
