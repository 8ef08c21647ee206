"""Closed building blocks for furniture: boxes, plates, bars between two points, balls, rings, cushions.

Every function returns a manifold3d.Manifold, a closed (watertight) solid. Units are metres,
y points up and the front of a piece of furniture faces +z; the category builders place the
blocks and `assembly.assemble` unions them into one mesh.
"""

from __future__ import annotations

from collections.abc import Sequence

import manifold3d as mf
import numpy as np

ROUND_SEGMENTS = 16  # segments around a leg, a bar or a round seat: smooth enough at 100^3 voxels
BALL_SEGMENTS = 12
PLAN_SHAPES = ("rect", "rounded", "round")

# Turns a shape drawn in the xy plane and extruded along +z into one lying flat on the floor:
# (x, y, z) -> (x, z, -y), a proper rotation, so the solid stays outward-facing.
_PLAN_TO_FLOOR = ((1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0), (0.0, -1.0, 0.0, 0.0))


def box(size: Sequence[float], center: Sequence[float]) -> mf.Manifold:
    """Axis-aligned box of `size` (x, y, z) centred at `center`."""
    return mf.Manifold.cube(tuple(float(s) for s in size), center=True).translate(tuple(float(c) for c in center))


def plan_outline(shape: str, width: float, depth: float, corner_radius: float = 0.0) -> mf.CrossSection:
    """A 2D outline centred at the origin: rectangle, rectangle with round corners, or ellipse."""
    if shape == "rect":
        return mf.CrossSection.square((width, depth), center=True)
    if shape == "rounded":
        r = min(corner_radius, 0.49 * min(width, depth))
        inner = mf.CrossSection.square((width - 2 * r, depth - 2 * r), center=True)
        return inner.offset(r, mf.JoinType.Round, circular_segments=ROUND_SEGMENTS * 2)
    if shape == "round":
        return mf.CrossSection.circle(0.5, ROUND_SEGMENTS * 2).scale((width, depth))
    raise ValueError(f"unknown plan shape {shape!r}; expected one of {PLAN_SHAPES}")


def plate(
    shape: str,
    width: float,
    depth: float,
    thickness: float,
    y_bottom: float,
    corner_radius: float = 0.0,
    center_xz: Sequence[float] = (0.0, 0.0),
) -> mf.Manifold:
    """Horizontal plate (seat, table top, base disc): `width` along x, `depth` along z, from y_bottom up."""
    solid = mf.Manifold.extrude(plan_outline(shape, width, depth, corner_radius), thickness)
    return solid.transform(_PLAN_TO_FLOOR).translate((float(center_xz[0]), y_bottom, float(center_xz[1])))


def upright_plate(shape: str, width: float, height: float, thickness: float, corner_radius: float = 0.0) -> mf.Manifold:
    """Vertical plate facing +z (a chair back): `width` along x, y from 0 to `height`, z centred on 0."""
    lying = plate(shape, width, height, thickness, -thickness / 2, corner_radius)
    # Stand it up: (x, y, z) -> (x, -z, y), then lift its lower edge to y = 0.
    stand_up = ((1.0, 0.0, 0.0, 0.0), (0.0, 0.0, -1.0, height / 2), (0.0, 1.0, 0.0, 0.0))
    return lying.transform(stand_up)


def _frame_along(start: np.ndarray, end: np.ndarray) -> tuple[tuple[float, ...], ...]:
    """3x4 transform taking the +z axis from the origin onto the segment start -> end (length kept).

    The local x axis stays horizontal where possible, so square legs line up with the furniture.
    """
    direction = (end - start) / np.linalg.norm(end - start)
    reference = np.array([1.0, 0.0, 0.0]) if abs(direction[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    v = np.cross(direction, reference)
    v /= np.linalg.norm(v)
    u = np.cross(v, direction)
    matrix = np.column_stack([u, v, direction, start])
    return tuple(tuple(float(x) for x in row) for row in matrix)


def bar(
    start: Sequence[float],
    end: Sequence[float],
    radius: float,
    end_radius: float | None = None,
    section: str = "round",
) -> mf.Manifold:
    """Straight leg, rail or tube from `start` to `end`; round or square section, tapered if end_radius differs.

    For a square section `radius` is half the side.
    """
    p0, p1 = np.asarray(start, dtype=float), np.asarray(end, dtype=float)
    length = float(np.linalg.norm(p1 - p0))
    r1 = radius if end_radius is None else end_radius
    if section == "round":
        solid = mf.Manifold.cylinder(length, radius, r1, ROUND_SEGMENTS)
    elif section == "square":
        square = mf.CrossSection.square((2 * radius, 2 * radius), center=True)
        solid = mf.Manifold.extrude(square, length, scale_top=(r1 / radius, r1 / radius))
    else:
        raise ValueError(f"unknown bar section {section!r}; expected 'round' or 'square'")
    return solid.transform(_frame_along(p0, p1))


def ball(center: Sequence[float], radius: float) -> mf.Manifold:
    """Sphere: rounds the joints of bent tubes and makes small feet."""
    return mf.Manifold.sphere(radius, BALL_SEGMENTS).translate(tuple(float(c) for c in center))


def ring(radius: float, tube_radius: float, height: float) -> mf.Manifold:
    """Horizontal torus around the vertical axis at `height` (a stool's foot ring)."""
    profile = mf.CrossSection.circle(tube_radius, BALL_SEGMENTS).translate((radius, 0.0))
    return mf.Manifold.revolve(profile, ROUND_SEGMENTS * 2).transform(_PLAN_TO_FLOOR).translate((0.0, height, 0.0))


def cushion(
    shape: str,
    width: float,
    depth: float,
    thickness: float,
    y_bottom: float,
    roundness: float,
    center_xz: Sequence[float] = (0.0, 0.0),
) -> mf.Manifold:
    """Padded block with rounded edges: the convex hull of thin plates following a quarter-circle profile."""
    r = min(roundness, 0.49 * thickness, 0.24 * min(width, depth))
    sheet = 1e-3 * thickness
    angles = np.linspace(0.0, np.pi / 2, 4)
    layers = []
    for a in angles:
        inset = r * (1.0 - np.sin(a))
        rise = r * (1.0 - np.cos(a))
        for y in (y_bottom + rise, y_bottom + thickness - rise - sheet):
            layers.append(
                plate(shape, width - 2 * inset, depth - 2 * inset, sheet, y, corner_radius=2.0 * r, center_xz=center_xz)
            )
    return mf.Manifold.batch_hull(layers)


def rounded_box(size: Sequence[float], center: Sequence[float], roundness: float) -> mf.Manifold:
    """Box of `size` (x, y, z) centred at `center` with all edges rounded (sofa bodies, arms, backs)."""
    sx, sy, sz = (float(s) for s in size)
    cx, cy, cz = (float(c) for c in center)
    return cushion("rounded", sx, sz, sy, cy - sy / 2, roundness, center_xz=(cx, cz))


def tilt_back(solid: mf.Manifold, angle_deg: float, pivot_y: float, pivot_z: float) -> mf.Manifold:
    """Rotate about the horizontal x-parallel line through (pivot_y, pivot_z) so parts above it lean towards -z."""
    a = np.radians(angle_deg)
    c, s = float(np.cos(a)), float(np.sin(a))
    # y' = c (y - py) + s (z - pz) + py ;  z' = -s (y - py) + c (z - pz) + pz
    matrix = (
        (1.0, 0.0, 0.0, 0.0),
        (0.0, c, s, pivot_y - c * pivot_y - s * pivot_z),
        (0.0, -s, c, pivot_z + s * pivot_y - c * pivot_z),
    )
    return solid.transform(matrix)
