"""Shapes unlike the furniture, for testing how renderers generalise: never used for training.

A torus (flat or standing), a cup with an opening and a handle, a blobby four-legged animal, a box
pierced by holes, and a thin lattice. Each has what the furniture lacks: a hole through the middle,
a concave inside, smooth organic curvature, or many thin parts. Lengths are metres before
normalisation, y up, front facing +z.
"""

from __future__ import annotations

from typing import Any

import manifold3d as mf
import numpy as np

from renderer.objects.category import Category, Parts
from renderer.objects.params import Choice, Integer, Uniform
from renderer.objects.primitives import BALL_SEGMENTS, ROUND_SEGMENTS, ball, bar, box, ring

SHAPES = ("torus", "cup", "animal", "holed_box", "lattice")

# Part -> material role in the default appearance; the order fixes the label numbers.
PARTS = {"body": "surface", "detail": "frame"}

PARAMETERS = {
    "shape": Choice(SHAPES),
    "size": Uniform(0.3, 0.5),
    "thickness": Uniform(0.15, 0.35),  # of tubes and walls, as a share of what the shape allows
    "upright": Choice((False, True)),  # the torus stands on its rim
    "holes": Integer(1, 3),  # per face direction of the holed box; lattice cells per side
    "stretch": Uniform(0.7, 1.3),  # the animal's body length, the cup's height
}


def _torus(p: dict[str, Any]) -> Parts:
    radius = p["size"] / 2
    tube = radius * (0.2 + 0.5 * p["thickness"])
    solid = ring(radius, tube, tube)
    if p["upright"]:  # stand it on its rim, facing the camera
        stand = ((1.0, 0.0, 0.0, 0.0), (0.0, 0.0, -1.0, 0.0), (0.0, 1.0, 0.0, 0.0))
        solid = solid.translate((0.0, -tube, 0.0)).transform(stand).translate((0.0, radius + tube, 0.0))
    return [("body", solid)]


def _cup(p: dict[str, Any]) -> Parts:
    radius, height = p["size"] / 2, p["size"] * p["stretch"]
    wall = radius * (0.08 + 0.25 * p["thickness"])
    outer = mf.Manifold.cylinder(height, radius, radius, ROUND_SEGMENTS * 2)
    inner = mf.Manifold.cylinder(height, radius - wall, radius - wall, ROUND_SEGMENTS * 2).translate((0.0, 0.0, wall))
    standing = ((1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0), (0.0, -1.0, 0.0, 0.0))  # z up -> y up
    cup = (outer - inner).transform(standing)
    # The handle: half a standing ring on the +x side.
    grip = 0.32 * height
    profile = mf.CrossSection.circle(0.8 * wall, BALL_SEGMENTS).translate((grip, 0.0))
    loop = mf.Manifold.revolve(profile, ROUND_SEGMENTS * 2)  # a ring around z: standing in the xy plane
    half = box((grip + wall, 2 * grip + 2 * wall, 2 * wall), ((grip + wall) / 2, 0.0, 0.0))
    handle = (loop ^ half).translate((radius - 0.5 * wall, height / 2, 0.0))
    return [("body", cup), ("detail", handle)]


def _animal(p: dict[str, Any]) -> Parts:
    length = p["size"] * p["stretch"]
    girth = 0.22 * p["size"] * (0.8 + p["thickness"])
    leg_height = 0.35 * p["size"]
    body_y = leg_height + girth
    body = mf.Manifold.sphere(1.0, BALL_SEGMENTS * 2).scale((girth, girth, length / 2)).translate((0.0, body_y, 0.0))
    head = ball((0.0, body_y + 0.8 * girth, length / 2 + 0.3 * girth), 0.7 * girth)
    leg_radius = 0.28 * girth
    legs = [bar((x, body_y, z), (x, 0.0, z), leg_radius, 0.8 * leg_radius)
            for x in (-0.5 * girth, 0.5 * girth) for z in (-0.3 * length, 0.3 * length)]
    tail = bar((0.0, body_y, -0.45 * length), (0.0, body_y + 0.6 * girth, -0.75 * length), 0.25 * leg_radius)
    ears = [ball((x, body_y + 1.4 * girth, length / 2 + 0.3 * girth), 0.25 * girth) for x in (-0.35 * girth, 0.35 * girth)]
    return [("body", body), ("body", head), *[("detail", part) for part in (*legs, tail, *ears)]]


def _holed_box(p: dict[str, Any]) -> Parts:
    side = p["size"]
    solid = box((side, side, side), (0.0, side / 2, 0.0))
    count = p["holes"]
    radius = side / (2 * count + 1) * (0.3 + 0.5 * p["thickness"])
    offsets = (np.arange(count) + 0.5) / count * side - side / 2
    for a in offsets:
        for b in offsets if count > 1 else (0.0,):
            reach = 0.6 * side
            solid -= bar((a, side / 2 + b, -reach), (a, side / 2 + b, reach), radius)  # front to back
            solid -= bar((-reach, side / 2 + a, b), (reach, side / 2 + a, b), radius)  # side to side
            solid -= bar((a, -0.1 * side, b), (a, 1.1 * side, b), radius)  # top to bottom
    return [("body", solid)]


def _lattice(p: dict[str, Any]) -> Parts:
    side, cells = p["size"], p["holes"] + 1
    radius = side * (0.008 + 0.02 * p["thickness"])
    ticks = np.linspace(-side / 2, side / 2, cells + 1)
    parts: Parts = []
    for a in ticks:
        for b in ticks:
            parts.append(("body", bar((a, 0.0, b), (a, side, b), radius)))  # vertical
            parts.append(("detail", bar((-side / 2, side / 2 + a, b), (side / 2, side / 2 + a, b), radius)))
            parts.append(("detail", bar((a, side / 2 + b, -side / 2), (a, side / 2 + b, side / 2), radius)))
    return parts


BUILDERS = {"torus": _torus, "cup": _cup, "animal": _animal, "holed_box": _holed_box, "lattice": _lattice}


def build(p: dict[str, Any]) -> Parts:
    """Closed parts of one shape from its parameters."""
    return BUILDERS[p["shape"]](p)


CATEGORY = Category(name="novel", parts=PARTS, parameters=PARAMETERS, build=build)
