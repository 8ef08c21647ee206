"""Tables: a top on legs, pedestals, trestles or solid end panels, with an optional apron and lower shelf.

Lengths are metres before normalisation; the top is centred on the origin with its upper
face at `height`; width runs along x, depth along z.
"""

from __future__ import annotations

from typing import Any

from renderer.objects import supports
from renderer.objects.category import Category, Parts
from renderer.objects.params import Choice, Uniform
from renderer.objects.primitives import bar, box, plate

# Part -> material role in the default appearance; the order fixes the label numbers.
PARTS = {"top": "surface", "leg": "frame", "apron": "frame", "shelf": "surface"}

PARAMETERS = {
    "top_shape": Choice(("rect", "rounded", "round"), (9, 6, 5)),
    "width": Uniform(0.6, 1.8),
    "depth_ratio": Uniform(0.45, 1.0),  # depth / width (round tops: at least 0.6, an ellipse below 1)
    "height": Uniform(0.4, 0.78),  # floor to top surface: coffee table to dining table
    "top_thickness": Uniform(0.02, 0.06),
    "leg_style": Choice(("straight", "tapered", "splayed", "pedestal", "trestle", "panel"), (5, 4, 3, 3, 2, 2)),
    "leg_section": Choice(("round", "square")),
    "leg_thickness": Uniform(0.015, 0.04),
    "leg_taper": Uniform(0.45, 0.8),
    "leg_splay_deg": Uniform(3.0, 10.0),
    "leg_inset": Uniform(0.02, 0.12),  # from the edge of the top to the legs
    "pedestal_base": Choice(("disc", "star")),
    "apron": Choice((False, True)),
    "shelf": Choice((False, True), (3, 1)),
    "shelf_height": Uniform(0.12, 0.3),  # fraction of the table height
}


def _top_plan(p: dict[str, Any]) -> tuple[float, float, float]:
    """Width, depth and corner radius of the top."""
    width = p["width"]
    ratio = max(p["depth_ratio"], 0.6) if p["top_shape"] == "round" else p["depth_ratio"]
    depth = width * ratio
    corner = 0.2 * depth if p["top_shape"] == "rounded" else 0.0
    return width, depth, corner


def _leg_frame(p: dict[str, Any], width: float, depth: float) -> tuple[float, float]:
    """Half spacing (x, z) of the four legs, kept inside round and rounded tops."""
    inset = p["leg_inset"] + p["leg_thickness"]
    if p["top_shape"] == "round":
        return 0.35 * width - inset / 2, 0.35 * depth - inset / 2
    if p["top_shape"] == "rounded":
        inset += 0.06 * depth
    return width / 2 - inset, depth / 2 - inset


def _four_legs(p: dict[str, Any], width: float, depth: float, under_top: float) -> Parts:
    """Four legs with optional apron boards under the top and an optional shelf between the legs."""
    r = p["leg_thickness"]
    hx, hz = _leg_frame(p, width, depth)
    splay = p["leg_splay_deg"] if p["leg_style"] == "splayed" else 0.0
    foot = r * p["leg_taper"] if p["leg_style"] == "tapered" else r
    section = "round" if p["leg_style"] == "splayed" else p["leg_section"]
    axes = supports.leg_axes(supports.corner_points(2 * hx, 2 * hz, 0.0), under_top + 0.01, splay)
    parts: Parts = [("leg", leg) for leg in supports.legs(axes, r, foot, section)]
    if p["apron"]:
        apron_h, t = min(0.09, 0.15 * under_top), 0.6 * r
        y = under_top - apron_h / 2 + 0.005
        parts += [("apron", box((2 * hx, apron_h, t), (0.0, y, sz * hz))) for sz in (-1, 1)]
        parts += [("apron", box((t, apron_h, 2 * hz), (sx * hx, y, 0.0))) for sx in (-1, 1)]
    if p["shelf"]:
        y = p["shelf_height"] * under_top
        corner = supports.point_at_height(axes[1], y)  # the front-right leg at shelf height
        sx, sz = abs(corner[0]) + 0.4 * r, abs(corner[2]) + 0.4 * r
        parts.append(("shelf", plate("rect", 2 * sx, 2 * sz, 0.02, y - 0.01)))
    return parts


def _pedestals(p: dict[str, Any], width: float, depth: float, under_top: float) -> Parts:
    """One central pedestal, or two along x for long tables, each with a mounting plate under the top."""
    centres = [0.0] if width <= 1.1 else [-width / 4, width / 4]
    column = max(2.0 * p["leg_thickness"], 0.04)
    reach = 0.4 * min(depth, 0.8)
    parts: Parts = []
    for cx in centres:
        parts.append(("leg", box((0.3 * depth, 0.03, 0.3 * depth), (cx, under_top - 0.01, 0.0))))
        for piece in supports.pedestal(under_top - 0.02, column, p["pedestal_base"], reach, 4):
            parts.append(("leg", piece.translate((cx, 0.0, 0.0))))
    return parts


def _end_supports(p: dict[str, Any], width: float, depth: float, under_top: float) -> Parts:
    """Trestles (foot, post, cap and a beam between them) or solid end panels, near both ends of the top."""
    r = p["leg_thickness"]
    hx = _leg_frame(p, width, depth)[0]
    span = 0.8 * depth if p["top_shape"] != "round" else 0.6 * depth
    parts: Parts = []
    for sx in (-hx, hx):
        if p["leg_style"] == "panel":
            parts.append(("leg", box((2 * r, under_top + 0.01, span), (sx, (under_top + 0.01) / 2, 0.0))))
        else:
            parts.append(("leg", box((2.5 * r, 0.05, span), (sx, 0.025, 0.0))))
            parts.append(("leg", box((2.5 * r, 0.05, span), (sx, under_top - 0.02, 0.0))))
            parts.append(("leg", bar((sx, 0.04, 0.0), (sx, under_top - 0.03, 0.0), 1.2 * r, section="square")))
    if p["leg_style"] == "trestle":
        parts.append(("leg", bar((-hx, 0.4 * under_top, 0.0), (hx, 0.4 * under_top, 0.0), 0.8 * r, section="square")))
    elif p["shelf"]:
        y = p["shelf_height"] * under_top
        parts.append(("shelf", box((2 * hx, 0.02, span), (0.0, y, 0.0))))
    return parts


def build(p: dict[str, Any]) -> Parts:
    """Closed parts of one table from its parameters."""
    width, depth, corner = _top_plan(p)
    under_top = p["height"] - p["top_thickness"]
    parts: Parts = [("top", plate(p["top_shape"], width, depth, p["top_thickness"], under_top, corner))]
    style = p["leg_style"]
    if style in ("straight", "tapered", "splayed"):
        parts += _four_legs(p, width, depth, under_top)
    elif style == "pedestal":
        parts += _pedestals(p, width, depth, under_top)
    else:
        parts += _end_supports(p, width, depth, under_top)
    return parts


CATEGORY = Category(name="table", parts=PARTS, parameters=PARAMETERS, build=build)
