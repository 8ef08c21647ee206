"""Random assemblies of simple solids, for training on shapes beyond furniture.

Users load anything, and a network trained on chairs, tables, sofas and stools alone learns
furniture. This category adds what furniture rarely has, drawn at random rather than designed:
blocks, cylinders, balls and cones stacked against each other, drilled through by bars, hollowed
from the top, and spanned by thin rods, or a tree of rods alone. It shares ingredients (holes,
thin parts, concave insides) with the generalisation shapes of `novel.py`, but none of their
builders, and it is for training only. Lengths are metres before normalisation, y up.
"""

from __future__ import annotations

from typing import Any

import manifold3d as mf
import numpy as np

from renderer.objects.category import Category, Parts
from renderer.objects.params import Choice, Integer, Uniform
from renderer.objects.primitives import ROUND_SEGMENTS, bar, box

PIECES = ("block", "cylinder", "ball", "cone")

# Part -> material role in the default appearance; the order fixes the label numbers.
PARTS = {"body": "surface", "detail": "frame"}

PARAMETERS = {
    "layout_seed": Integer(0, 2**31 - 1),  # draws the pieces, cuts and rods below
    "size": Uniform(0.3, 0.6),
    "pieces": Choice((0, 1, 2, 3, 4, 5), weights=(1, 2, 2, 2, 2, 1)),  # 0: a tree of rods alone
    "cuts": Choice((0, 1, 2, 3), weights=(3, 2, 2, 1)),  # bars drilled through the pieces
    "hollow": Choice((False, True), weights=(2, 1)),  # an open cavity cut from the top
    "rods": Choice((0, 2, 4, 8), weights=(3, 2, 2, 1)),  # thin rods between points on the surface
    "rod_radius": Uniform(0.004, 0.025),
}


def _piece(kind: str, extent: np.ndarray, center: np.ndarray, rng: np.random.Generator) -> mf.Manifold:
    """One solid of `kind` filling roughly the box `extent` around `center`."""
    if kind == "block":
        return box(extent, center)
    if kind == "ball":
        return mf.Manifold.sphere(1.0, ROUND_SEGMENTS * 2).scale(tuple(extent / 2)).translate(tuple(center))
    axis = int(rng.integers(3))  # cylinders and cones lie along x, stand along y, or lie along z
    half = np.zeros(3)
    half[axis] = extent[axis] / 2
    radius = float(np.delete(extent, axis).mean()) / 2
    end_radius = radius if kind == "cylinder" else radius * float(rng.uniform(0.0, 0.5))
    return bar(center - half, center + half, radius, max(end_radius, 1e-3), section="round")


def _pieces(p: dict[str, Any], rng: np.random.Generator) -> mf.Manifold:
    """Pieces placed one against another: each is centred inside the box of one placed before."""
    size = p["size"]
    solid = mf.Manifold()
    boxes: list[tuple[np.ndarray, np.ndarray]] = []
    for _ in range(p["pieces"]):
        extent = size * rng.uniform(0.15, 0.7, 3)
        if rng.random() < 0.3:  # a plate or a slab: one side thin
            extent[rng.integers(3)] *= 0.2
        if boxes:
            low, high = boxes[int(rng.integers(len(boxes)))]
            center = rng.uniform(low, high)
        else:
            center = np.array([0.0, extent[1] / 2, 0.0])
        solid += _piece(PIECES[int(rng.integers(len(PIECES)))], extent, center, rng)
        boxes.append((center - extent / 2, center + extent / 2))
    return solid


def _rod_tree(p: dict[str, Any], rng: np.random.Generator) -> Parts:
    """Thin rods joining random points in a box, each new point to one before it: connected, like a frame."""
    size = p["size"]
    points = [np.array([0.0, 0.0, 0.0])]
    parts: Parts = []
    for _ in range(int(rng.integers(4, 12))):
        point = rng.uniform((-size / 2, 0.0, -size / 2), (size / 2, size, size / 2))
        start = points[int(rng.integers(len(points)))]
        if np.linalg.norm(point - start) > 1e-3:
            parts.append(("body", bar(start, point, 2 * p["rod_radius"])))
            points.append(point)
    return parts


def build(p: dict[str, Any]) -> Parts:
    """Closed parts of one assembly from its parameters."""
    rng = np.random.default_rng(p["layout_seed"])
    if p["pieces"] == 0:
        return _rod_tree(p, rng)
    solid = _pieces(p, rng)
    bounds = np.array(solid.bounding_box())
    low, high = bounds[:3], bounds[3:]
    extent = high - low
    for _ in range(p["cuts"]):
        through = rng.uniform(low + 0.2 * extent, high - 0.2 * extent)
        axis = np.zeros(3)
        axis[int(rng.integers(3))] = 1.0
        reach = float(extent.max())
        radius = float(extent.min()) * rng.uniform(0.08, 0.25)
        section = "round" if rng.random() < 0.6 else "square"
        solid -= bar(through - reach * axis, through + reach * axis, radius, section=section)
    if p["hollow"]:
        wall = float(rng.uniform(0.1, 0.25))
        cavity = extent * np.array([1 - 2 * wall, rng.uniform(0.3, 0.8), 1 - 2 * wall])
        center = np.array([(low[0] + high[0]) / 2, high[1] - cavity[1] / 2 + 1e-3, (low[2] + high[2]) / 2])
        solid -= box(cavity, center)
    if solid.is_empty():  # cut away entirely: keep the bounding block, so every seed gives an object
        solid = box(extent, (low + high) / 2)
    solid = max(solid.decompose(), key=lambda piece: piece.volume())  # cuts can split it: keep one object
    parts: Parts = [("body", solid)]
    if p["rods"]:
        mesh = solid.to_mesh()
        vertices = np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3]
        for _ in range(p["rods"]):
            start, end = vertices[rng.integers(len(vertices), size=2)]
            if np.linalg.norm(end - start) < 0.05 * extent.max():
                continue
            rod = bar(start, end, p["rod_radius"])
            joined = solid + rod
            if len(joined.decompose()) == 1:  # a rod grazing the surface can leave a sliver apart: skip it
                parts.append(("detail", rod))
                solid = joined
    return parts


CATEGORY = Category(name="solids", parts=PARTS, parameters=PARAMETERS, build=build)
