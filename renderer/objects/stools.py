"""Stools: a seat without a back on three or four legs or a pedestal, from footstool to bar stool.

Lengths are metres before normalisation; the seat is centred on the origin with its top at
`seat_height`. With three legs, one leg points to the front (+z).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from renderer.objects import supports
from renderer.objects.category import Category, Parts
from renderer.objects.params import Choice, Integer, Uniform
from renderer.objects.primitives import bar, cushion, plate, ring

# Part -> material role in the default appearance; the order fixes the label numbers.
PARTS = {"seat": "surface", "cushion": "soft", "leg": "frame", "footrest": "frame"}

PARAMETERS = {
    "seat_shape": Choice(("round", "rect", "rounded"), (3, 1, 1)),
    "seat_size": Uniform(0.28, 0.45),  # diameter or side
    "seat_height": Uniform(0.4, 0.8),
    "seat_thickness": Uniform(0.02, 0.07),
    "leg_count": Integer(3, 4),
    "leg_style": Choice(("straight", "splayed", "pedestal"), (2, 3, 2)),
    "leg_section": Choice(("round", "square")),
    "leg_thickness": Uniform(0.012, 0.026),
    "leg_splay_deg": Uniform(5.0, 14.0),
    "pedestal_base": Choice(("disc", "star")),
    "footrest": Choice(("none", "ring", "bars"), (2, 2, 1)),
    "footrest_height": Uniform(0.25, 0.45),  # fraction of the seat height
    "cushion": Choice((False, True), (3, 1)),
    "cushion_thickness": Uniform(0.03, 0.07),
}


def _leg_tops(p: dict[str, Any]) -> np.ndarray:
    """(x, z) of the leg tops, inside the seat outline: corners of square seats, a circle otherwise."""
    r, half = p["leg_thickness"], p["seat_size"] / 2
    if p["seat_shape"] != "round" and p["leg_count"] == 4:
        inset = r + 0.015 + (0.06 * half if p["seat_shape"] == "rounded" else 0.0)
        return supports.corner_points(2 * half, 2 * half, inset)
    return supports.circle_points(p["leg_count"], 0.72 * half, 90.0 if p["leg_count"] == 3 else 45.0)


def _legs(p: dict[str, Any], top_y: float) -> Parts:
    """Three or four legs, straight or splayed, with a foot ring or bars between them."""
    r = p["leg_thickness"]
    splay = p["leg_splay_deg"] if p["leg_style"] == "splayed" else 0.0
    axes = supports.leg_axes(_leg_tops(p), top_y, splay)
    parts: Parts = [("leg", leg) for leg in supports.legs(axes, r, r, p["leg_section"])]
    y = p["footrest_height"] * top_y
    if p["footrest"] == "ring":
        reach = float(np.hypot(*supports.point_at_height(axes[0], y)[[0, 2]]))
        parts.append(("footrest", ring(reach, 0.75 * r, y)))
    elif p["footrest"] == "bars":
        parts += [("footrest", s) for s in supports.stretchers(axes, y, 0.7 * r, p["leg_section"])]
    return parts


def _pedestal(p: dict[str, Any], seat_bottom: float) -> Parts:
    """Central column on a disc or a star, with a foot ring held by three spokes if asked for."""
    column = max(1.8 * p["leg_thickness"], 0.025)
    reach = 0.45 * p["seat_size"]
    parts: Parts = [("leg", plate("round", 0.6 * p["seat_size"], 0.6 * p["seat_size"], 0.02, seat_bottom - 0.015))]
    parts += [
        ("leg", piece)
        for piece in supports.pedestal(seat_bottom - 0.01, column, p["pedestal_base"], reach, p["leg_count"] + 1)
    ]
    if p["footrest"] != "none":
        y = p["footrest_height"] * seat_bottom
        radius = 0.4 * p["seat_size"]
        tube = 0.6 * column
        parts.append(("footrest", ring(radius, tube, y)))
        for x, z in supports.circle_points(3, radius, 90.0):
            parts.append(("footrest", bar((0.0, y, 0.0), (x, y, z), 0.6 * tube)))
    return parts


def build(p: dict[str, Any]) -> Parts:
    """Closed parts of one stool from its parameters."""
    size, top = p["seat_size"], p["seat_height"]
    bottom = top - p["seat_thickness"]
    corner = 0.25 * size if p["seat_shape"] == "rounded" else 0.0
    parts: Parts = [("seat", plate(p["seat_shape"], size, size, p["seat_thickness"], bottom, corner))]
    if p["leg_style"] == "pedestal":
        parts += _pedestal(p, bottom)
    else:
        parts += _legs(p, bottom + 0.01)
    if p["cushion"]:
        t = p["cushion_thickness"]
        parts.append(("cushion", cushion(p["seat_shape"], 0.94 * size, 0.94 * size, t, top - 0.005, 0.45 * t)))
    return parts


CATEGORY = Category(name="stool", parts=PARTS, parameters=PARAMETERS, build=build)
