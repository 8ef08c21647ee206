"""Sofas: an upholstered base, seat and back cushions, arms of several styles, short legs or a plinth.

Lengths are metres before normalisation; the sofa is centred on the origin, seats side by side
along x, the back at -z and the front facing +z. An optional chaise extends one end forward.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from renderer.objects.category import Category, Parts
from renderer.objects.params import Choice, Integer, Uniform
from renderer.objects.primitives import bar, rounded_box, tilt_back

# Part -> material role in the default appearance; the order fixes the label numbers.
PARTS = {
    "base": "upholstery",
    "seat_cushion": "cushions",
    "back": "upholstery",
    "back_cushion": "cushions",
    "arm": "upholstery",
    "leg": "frame",
}  # part -> material role

PARAMETERS = {
    "seats": Integer(1, 4),
    "seat_unit_width": Uniform(0.5, 0.7),
    "seat_depth": Uniform(0.5, 0.7),
    "seat_height": Uniform(0.38, 0.48),  # floor to top of the seat cushions
    "seat_cushion_thickness": Uniform(0.08, 0.16),
    "bench_cushion": Choice((False, True), (3, 1)),  # one long seat cushion instead of one per seat
    "base_style": Choice(("legs", "plinth"), (3, 1)),
    "leg_height": Uniform(0.05, 0.18),
    "leg_section": Choice(("round", "square")),
    "leg_thickness": Uniform(0.015, 0.03),
    "arm_style": Choice(("box", "rolled", "slim", "none"), (4, 3, 2, 1)),
    "arm_width": Uniform(0.1, 0.22),
    "arm_height": Uniform(0.12, 0.28),  # above the seat
    "back_height": Uniform(0.3, 0.55),  # above the seat
    "back_thickness": Uniform(0.12, 0.25),
    "recline_deg": Uniform(0.0, 15.0),
    "back_cushions": Choice((False, True)),
    "roundness": Uniform(0.01, 0.05),
    "chaise": Choice(("none", "left", "right"), (4, 1, 1)),
    "chaise_length": Uniform(0.5, 0.8),
}


def _arm_width(p: dict[str, Any]) -> float:
    """How wide each arm is for its style (0 without arms)."""
    return {"none": 0.0, "slim": max(0.4 * p["arm_width"], 0.05)}.get(p["arm_style"], p["arm_width"])


def _arm(p: dict[str, Any], x: float, arm_w: float, floor_y: float, z_back: float, z_front: float) -> Parts:
    """One arm centred on x, from floor_y to arm height, spanning z_back..z_front."""
    top = p["seat_height"] + p["arm_height"]
    depth, z = z_front - z_back, (z_front + z_back) / 2
    r = p["roundness"]
    if p["arm_style"] != "rolled":
        return [("arm", rounded_box((arm_w, top - floor_y, depth), (x, (top + floor_y) / 2, z), r))]
    roll = 0.6 * arm_w
    body_top = top - roll
    outward = np.sign(x) * 0.15 * arm_w
    return [
        ("arm", rounded_box((arm_w, body_top - floor_y, depth), (x, (body_top + floor_y) / 2, z), r)),
        ("arm", bar((x + outward, body_top, z_front - 0.01), (x + outward, body_top, z_back + 0.01), roll)),
    ]


def _legs(p: dict[str, Any], xs: list[float], zs: list[float]) -> Parts:
    """Short legs under the base at every (x, z) of the given rows and columns."""
    top = p["leg_height"] + 0.02
    r = p["leg_thickness"]
    return [("leg", bar((x, 0.0, z), (x, top, z), r, 0.7 * r, p["leg_section"])) for x in xs for z in zs]


def build(p: dict[str, Any]) -> Parts:
    """Closed parts of one sofa from its parameters."""
    seats, unit = p["seats"], p["seat_unit_width"]
    arm_w = _arm_width(p)
    inner_w = seats * unit
    half_w = inner_w / 2 + arm_w
    back_t, r = p["back_thickness"], p["roundness"]
    z_back, z_front = -(p["seat_depth"] + back_t) / 2, (p["seat_depth"] + back_t) / 2
    floor_y = p["leg_height"] if p["base_style"] == "legs" else 0.0
    base_top = p["seat_height"] - p["seat_cushion_thickness"]
    seat_top = p["seat_height"]

    parts: Parts = [
        (
            "base",
            rounded_box((2 * half_w, base_top - floor_y, z_front - z_back), (0.0, (base_top + floor_y) / 2, 0.0), r),
        )
    ]

    # The chaise: the end seat unit continues forward by chaise_length.
    chaise_x = {"left": -inner_w / 2 + unit / 2, "right": inner_w / 2 - unit / 2}.get(p["chaise"])
    chaise_front = z_front + p["chaise_length"] if chaise_x is not None else z_front
    if chaise_x is not None:
        length = p["chaise_length"] + 0.05
        parts.append(
            (
                "base",
                rounded_box(
                    (unit, base_top - floor_y, length),
                    (chaise_x, (base_top + floor_y) / 2, z_front + length / 2 - 0.05),
                    r,
                ),
            )
        )

    # The back and its cushions lean back together about the back's lower front edge.
    pivot_y, pivot_z = base_top, z_back + back_t
    back_top = seat_top + p["back_height"]
    back = rounded_box(
        (2 * half_w, back_top - floor_y, back_t), (0.0, (back_top + floor_y) / 2, z_back + back_t / 2), r
    )
    parts.append(("back", tilt_back(back, p["recline_deg"], pivot_y, pivot_z)))
    seat_z_back = z_back + back_t - 0.01
    if p["back_cushions"]:
        t = 0.55 * back_t + 0.04
        height = 0.85 * (back_top - seat_top)
        for i in range(seats):
            x = -inner_w / 2 + (i + 0.5) * unit
            pad = rounded_box(
                (unit - 0.01, height, t),
                (x, seat_top - 0.01 + height / 2, z_back + back_t + t / 2 - 0.01),
                2 * r + 0.02,
            )
            parts.append(("back_cushion", tilt_back(pad, p["recline_deg"], pivot_y, pivot_z)))
        seat_z_back += t

    # Seat cushions lie on the base between the arms, in front of the back (and its cushions);
    # the cushion of the chaise end reaches the chaise front.
    if p["bench_cushion"]:
        cushions = [(0.0, inner_w, z_front)] + ([(chaise_x, unit, chaise_front)] if chaise_x is not None else [])
    else:
        cushions = [(-inner_w / 2 + (i + 0.5) * unit, unit, z_front) for i in range(seats)]
        if chaise_x is not None:
            end = 0 if p["chaise"] == "left" else seats - 1
            cushions[end] = (chaise_x, unit, chaise_front)
    thickness = seat_top - base_top + 0.01
    for x, w, front in cushions:
        depth = front - seat_z_back
        size = (w - 0.01, thickness, depth)
        parts.append(
            (
                "seat_cushion",
                rounded_box(size, (x, base_top - 0.01 + thickness / 2, seat_z_back + depth / 2), 2 * r + 0.02),
            )
        )

    if arm_w > 0:
        for sx in (-1, 1):
            on_chaise = chaise_x is not None and np.sign(chaise_x) == sx
            parts += _arm(p, sx * (half_w - arm_w / 2), arm_w, floor_y, z_back, chaise_front if on_chaise else z_front)

    if p["base_style"] == "legs":
        inset = 0.06
        xs = [-half_w + inset, half_w - inset] + ([0.0] if seats >= 3 else [])
        parts += _legs(p, xs, [z_back + inset, z_front - inset])
        if chaise_x is not None:
            parts += _legs(p, [chaise_x - unit / 2 + inset, chaise_x + unit / 2 - inset], [chaise_front - inset])
    return parts


CATEGORY = Category(name="sofa", parts=PARTS, parameters=PARAMETERS, build=build)
