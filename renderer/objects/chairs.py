"""Chairs, the paper's main category: legs or bases, a seat, and optionally a back, arms and a cushion.

Lengths are metres before normalisation. The seat is centred on the origin with its top at
`seat_height`; the back stands on the rear edge of the seat and tilts backwards (towards -z)
by `recline_deg`; the front faces +z.
"""

from __future__ import annotations

import math
from typing import Any

import manifold3d as mf
import numpy as np

from renderer.objects import supports
from renderer.objects.category import Category, Parts
from renderer.objects.params import Choice, Integer, Uniform
from renderer.objects.primitives import ball, bar, box, cushion, plate, tilt_back, upright_plate

# Part -> material role in the default appearance; the order fixes the label numbers.
PARTS = {"seat": "surface", "cushion": "soft", "back": "surface", "arm": "frame", "leg": "frame", "stretcher": "frame"}

PARAMETERS = {
    "leg_style": Choice(("straight", "tapered", "splayed", "pedestal", "sled", "cantilever"), (5, 4, 3, 3, 2, 2)),
    "leg_section": Choice(("round", "square")),
    "leg_thickness": Uniform(0.012, 0.028),  # radius, or half side of a square leg
    "leg_taper": Uniform(0.45, 0.8),  # foot / top thickness of tapered legs
    "leg_splay_deg": Uniform(4.0, 12.0),
    "pedestal_base": Choice(("star", "disc"), (3, 1)),
    "spoke_count": Integer(4, 5),
    "stretchers": Choice((False, True), (3, 2)),
    "seat_shape": Choice(("rect", "rounded", "round"), (9, 7, 4)),
    "seat_width": Uniform(0.38, 0.6),
    "seat_depth": Uniform(0.36, 0.55),
    "seat_height": Uniform(0.38, 0.52),  # floor to top of the seat
    "seat_thickness": Uniform(0.02, 0.07),
    "cushion": Choice((False, True), (2, 1)),
    "cushion_thickness": Uniform(0.035, 0.08),
    "back_style": Choice(("panel", "slats", "rails", "frame", "none"), (6, 4, 4, 3, 3)),
    "back_height": Uniform(0.25, 0.6),  # above the seat
    "back_thickness": Uniform(0.02, 0.05),
    "recline_deg": Uniform(0.0, 18.0),
    "slat_count": Integer(2, 6),
    "arm_style": Choice(("none", "panel", "open"), (11, 4, 5)),
    "arm_height": Uniform(0.16, 0.28),  # above the seat
}


def _seat_plan(p: dict[str, Any]) -> tuple[float, float, float]:
    """Seat width, depth and corner radius; round seats are discs as wide as the seat."""
    width = p["seat_width"]
    depth = width if p["seat_shape"] == "round" else p["seat_depth"]
    corner = 0.25 * min(width, depth) if p["seat_shape"] == "rounded" else 0.0
    return width, depth, corner


def _back_placement(p: dict[str, Any], width: float, depth: float) -> tuple[float, float]:
    """Width of the back and the z of its centre line, so it sits inside the rear edge of the seat."""
    thickness = p["back_thickness"]
    if p["seat_shape"] == "round":
        back_width = 0.75 * width
        chord_z = math.sqrt((width / 2) ** 2 - (back_width / 2 + 0.02) ** 2)  # 2 cm inside the rim
        return back_width, -chord_z + thickness / 2
    back_width = width - 0.3 * min(width, depth) if p["seat_shape"] == "rounded" else width
    return back_width, -depth / 2 + thickness / 2


def _back_pieces(p: dict[str, Any], back_width: float) -> list[mf.Manifold]:
    """The back in its own frame: x across, y up from 0 to back_height, z thickness centred on 0."""
    style, height, thickness = p["back_style"], p["back_height"], p["back_thickness"]
    if style == "panel":
        shape = "rect" if p["seat_shape"] == "rect" else "rounded"
        return [upright_plate(shape, back_width, height, thickness, corner_radius=0.3 * min(back_width, height))]
    post = max(p["leg_thickness"], 0.5 * thickness)
    rail = min(0.06, 0.2 * height)
    inner_x = back_width / 2 - post
    pieces = [box((2 * post, height, thickness), (sx * inner_x, height / 2, 0.0)) for sx in (-1, 1)]
    pieces.append(box((back_width, rail, thickness), (0.0, height - rail / 2, 0.0)))
    if style == "slats":
        gap_width = 2 * inner_x / p["slat_count"]
        for i in range(p["slat_count"]):
            x = -inner_x + (i + 0.5) * gap_width
            pieces.append(
                box((0.45 * gap_width, height - rail / 2, 0.8 * thickness), (x, (height - rail / 2) / 2, 0.0))
            )
    elif style == "rails":
        for y in np.linspace(0.25 * height, height - 1.5 * rail, max(p["slat_count"] - 1, 1)):
            pieces.append(box((2 * inner_x, 0.7 * rail, 0.8 * thickness), (0.0, float(y), 0.0)))
    elif style == "frame":
        pieces.append(box((2 * inner_x, rail, thickness), (0.0, rail / 2 + 0.01, 0.0)))
    return pieces


def _leg_corner(p: dict[str, Any], width: float, depth: float, radius: float) -> tuple[float, float]:
    """Half spacing (x, z) of the legs so they stay under the seat: inside the corners, or the disc."""
    if p["seat_shape"] == "round":
        return 0.31 * width, 0.31 * depth
    inset = radius + 0.012 + (0.08 * min(width, depth) if p["seat_shape"] == "rounded" else 0.0)
    return width / 2 - inset, depth / 2 - inset


def _four_leg_supports(p: dict[str, Any], width: float, depth: float, top_y: float) -> Parts:
    """Four legs (straight, tapered or splayed) under the seat, with optional stretchers."""
    r = p["leg_thickness"]
    hx, hz = _leg_corner(p, width, depth, r)
    tops = supports.corner_points(2 * hx, 2 * hz, 0.0)
    splay = p["leg_splay_deg"] if p["leg_style"] == "splayed" else 0.0
    foot = r * p["leg_taper"] if p["leg_style"] == "tapered" else r
    section = "round" if p["leg_style"] == "splayed" else p["leg_section"]
    axes = supports.leg_axes(tops, top_y, splay)
    parts: Parts = [("leg", leg) for leg in supports.legs(axes, r, foot, section)]
    if p["stretchers"]:
        y = 0.3 * top_y
        parts += [("stretcher", s) for s in supports.stretchers(axes, y, 0.6 * min(r, foot), section)]
    return parts


def _tube_frame_supports(p: dict[str, Any], width: float, depth: float, top_y: float) -> Parts:
    """Bent metal tubes: a sled (closed side loops) or a cantilever (floor runners, posts at the front only)."""
    r = 0.8 * p["leg_thickness"]
    x, z_front = _leg_corner(p, width, depth, r)
    z_back = -z_front
    parts: Parts = []
    for sx in (-x, x):
        floor_front, floor_back = (sx, r, z_front + 0.02), (sx, r, z_back - 0.02)
        parts.append(("leg", bar(floor_front, floor_back, r)))
        parts.append(("leg", ball(floor_front, r)))
        parts.append(("leg", ball(floor_back, r)))
        parts.append(("leg", bar(floor_front, (sx, top_y, z_front - 0.03), r)))
        if p["leg_style"] == "sled":
            parts.append(("leg", bar(floor_back, (sx, top_y, z_back + 0.03), r)))
        else:
            under = top_y - r
            parts.append(("leg", bar((sx, under, z_front - 0.03), (sx, under, z_back + 0.03), r)))
    if p["leg_style"] == "cantilever":
        parts.append(("stretcher", bar((-x, r, z_back - 0.02), (x, r, z_back - 0.02), r)))
    return parts


def _supports(p: dict[str, Any], width: float, depth: float, seat_bottom: float) -> Parts:
    """Whatever holds the seat up, reaching 1 cm into the seat so the union joins them."""
    top_y = seat_bottom + 0.01
    style = p["leg_style"]
    if style in ("straight", "tapered", "splayed"):
        return _four_leg_supports(p, width, depth, top_y)
    if style in ("sled", "cantilever"):
        return _tube_frame_supports(p, width, depth, top_y)
    column = 1.6 * p["leg_thickness"]
    reach = 0.5 * max(width, depth)
    plate_under = box((0.5 * width, 0.03, 0.5 * depth), (0.0, seat_bottom - 0.01, 0.0))
    return [("leg", plate_under)] + [
        ("leg", piece)
        for piece in supports.pedestal(seat_bottom - 0.02, column, p["pedestal_base"], reach, p["spoke_count"])
    ]


def _seat_edge_x(p: dict[str, Any], width: float, depth: float, corner: float, z: float) -> float:
    """How far the seat reaches sideways (|x| of its outline) at depth z: less near rounded corners."""
    if p["seat_shape"] == "round":
        return math.sqrt(max((width / 2) ** 2 - z * z, 0.0))
    straight = depth / 2 - corner
    if abs(z) <= straight:
        return width / 2
    return width / 2 - corner + math.sqrt(max(corner**2 - (abs(z) - straight) ** 2, 0.0))


def _arms(
    p: dict[str, Any], width: float, depth: float, corner: float, seat_bottom: float, back_z: float | None
) -> Parts:
    """Side panels, or open armrests: a rest bar on a front and a rear post standing on the seat."""
    seat_top, top = p["seat_height"], p["seat_height"] + p["arm_height"]
    arm_depth = (0.6 if p["seat_shape"] == "round" else 0.85) * depth
    if p["arm_style"] == "panel":
        t = 0.03
        x = (0.42 if p["seat_shape"] == "round" else 0.5) * width
        height = top - seat_bottom
        return [
            ("arm", box((t, height, arm_depth), (sx * (x + t / 2 - 0.005), seat_bottom + height / 2, 0.0)))
            for sx in (-1, 1)
        ]
    r = max(p["leg_thickness"] * 0.8, 0.01)
    z_front = arm_depth / 2
    if back_z is None:
        z_back = -arm_depth / 2
        z_rear_post = z_back + r
    else:
        z_back = back_z - p["arm_height"] * math.tan(math.radians(p["recline_deg"]))
        z_rear_post = back_z + p["back_thickness"] / 2 + r
    z_front_post = z_front - r
    x = min(_seat_edge_x(p, width, depth, corner, z) for z in (z_front_post, z_rear_post)) - r - 0.002
    parts: Parts = []
    for sx in (-x, x):
        for z in (z_front_post, z_rear_post):
            parts.append(("arm", bar((sx, seat_top - 0.01, z), (sx, top, z), r)))
        parts.append(("arm", box((0.05, 0.025, z_front - z_back), (sx, top, (z_front + z_back) / 2))))
    return parts


def build(p: dict[str, Any]) -> Parts:
    """Closed parts of one chair from its parameters."""
    width, depth, corner = _seat_plan(p)
    seat_top = p["seat_height"]
    seat_bottom = seat_top - p["seat_thickness"]
    parts: Parts = [("seat", plate(p["seat_shape"], width, depth, p["seat_thickness"], seat_bottom, corner))]
    parts += _supports(p, width, depth, seat_bottom)
    back_z = None
    cushion_depth, cushion_z = 0.94 * depth, 0.0
    if p["back_style"] != "none":
        back_width, back_z = _back_placement(p, width, depth)
        for piece in _back_pieces(p, back_width):
            parts.append(
                (
                    "back",
                    tilt_back(
                        piece.translate((0.0, seat_top - 0.01, back_z)), p["recline_deg"], seat_top - 0.01, back_z
                    ),
                )
            )
        cushion_depth -= p["back_thickness"]
        cushion_z = p["back_thickness"] / 2
    if p["cushion"]:
        pad = cushion(
            p["seat_shape"],
            0.94 * width,
            cushion_depth,
            p["cushion_thickness"],
            seat_top - 0.005,
            roundness=0.4 * p["cushion_thickness"],
            center_xz=(0.0, cushion_z),
        )
        parts.append(("cushion", pad))
    if p["arm_style"] != "none":
        parts += _arms(p, width, depth, corner, seat_bottom, back_z)
    return parts


CATEGORY = Category(name="chair", parts=PARTS, parameters=PARAMETERS, build=build)
