"""Several objects' shader stages joined into one scene: what the camera sees first, every object's shadows.

Each object keeps its own stages (geometry, placement, surface, colors, reflection: renderer/shading/staged.py), so
an edit of one object reruns that object's stages alone; these joins are cheap passes over their results, and the
lighting stage reads the joins as it reads one object's stages:

- join_surfaces: per pixel the nearest object's point (least view depth); coverage and the floor's open sky combine
  as independent occluders (one minus the product of what each leaves).
- join_reflections: per pixel of the floor's reflection the nearest mirrored point.
- join_occluders: every object's shadow occluders in one geometry, each object's kept apart, so each object shadows
  the others and the floor from shadow maps of its own (as fine as when it stands alone).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from renderer.camera import Camera
from renderer.shading.geometry import ObjectGeometry
from renderer.shading.surface import FloorReflection, VisibleSurface, surface_images


def join_surfaces(surfaces: Sequence[VisibleSurface]) -> tuple[VisibleSurface, np.ndarray]:
    """One surface of the objects' surfaces (the same camera and size), and the index of the object each of its
    points belongs to (N,) int. A pixel shows the nearest object's point; a silhouette pixel partly covered by two
    objects is covered by 1 - (1 - a)(1 - b) and shows the nearer one's point."""
    if len(surfaces) == 1:
        return surfaces[0], np.zeros(len(surfaces[0].points), dtype=np.int64)
    first = surfaces[0]
    rows, cols, owner, index = _nearest([s.pixels for s in surfaces], [s.depth for s in surfaces], first.size)

    def pick(name: str) -> np.ndarray:
        return _pick([getattr(s, name) for s in surfaces], owner, index)

    srgb = _pick([s.images.albedo_srgb[s.pixels[:, 0], s.pixels[:, 1]] for s in surfaces], owner, index)
    uncovered = np.prod([1.0 - s.coverage.astype(np.float64) for s in surfaces], axis=0)
    floor_occlusion = np.prod([s.floor_occlusion for s in surfaces], axis=0).astype(np.float32)
    pixels = np.stack([rows, cols], axis=1)
    joined = replace(first, coverage=(1.0 - uncovered).astype(np.float32), pixels=pixels, points=pick("points"),
                     normals=pick("normals"), color_voxels=pick("color_voxels"), color_points=pick("color_points"),
                     color_spread=pick("color_spread"), albedo=pick("albedo"), occlusion=pick("occlusion"),
                     depth=pick("depth"), floor_occlusion=floor_occlusion)
    images = surface_images(first.size, pixels, srgb, joined.albedo, joined.normals, joined.depth, joined.occlusion,
                            first.floor, floor_occlusion)
    return replace(joined, images=images), owner


def join_reflections(reflections: Sequence[FloorReflection], elevation_deg: float) -> tuple[FloorReflection, np.ndarray]:
    """One floor reflection of the objects' reflections, and each point's object (N,) int: per pixel the mirrored
    point nearest the camera."""
    if len(reflections) == 1:
        return reflections[0], np.zeros(len(reflections[0].points), dtype=np.int64)
    side = reflections[0].side
    eye = Camera(elevation_deg, width=side, height=side).position
    distances = [np.linalg.norm(r.points * np.array([1.0, -1.0, 1.0]) - eye, axis=1) for r in reflections]
    rows, cols, owner, index = _nearest([r.pixels for r in reflections], distances, side)
    joined = FloorReflection(side=side, pixels=np.stack([rows, cols], axis=1),
                             **{name: _pick([getattr(r, name) for r in reflections], owner, index)
                                for name in ("points", "normals", "albedo", "occlusion", "weight")})
    return joined, owner


def _nearest(pixels: Sequence[np.ndarray], distances: Sequence[np.ndarray],
             side: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per pixel of a `side`^2 image, the nearest of the objects' points (object k's at pixels[k], (N_k, 2), at
    distances[k]): the pixels that have one (rows, columns, row-major) and, for each, its object and its row there."""
    best = np.full((side, side), np.inf)
    owner_image = np.full((side, side), -1, dtype=np.int64)
    row_image = np.zeros((side, side), dtype=np.int64)
    for k, (where, distance) in enumerate(zip(pixels, distances)):
        r, c = where[:, 0], where[:, 1]
        nearer = distance < best[r, c]
        best[r[nearer], c[nearer]] = distance[nearer]
        owner_image[r[nearer], c[nearer]] = k
        row_image[r[nearer], c[nearer]] = np.flatnonzero(nearer)
    rows, cols = np.nonzero(owner_image >= 0)
    return rows, cols, owner_image[rows, cols], row_image[rows, cols]


def _pick(values: Sequence[np.ndarray], owner: np.ndarray, index: np.ndarray) -> np.ndarray:
    """For each chosen point, row index[i] of object owner[i]'s array in `values` (one array per object)."""
    out = np.empty((len(owner), *values[0].shape[1:]), dtype=values[0].dtype)
    for k, v in enumerate(values):
        mine = owner == k
        out[mine] = v[index[mine]]
    return out


def join_occluders(geometries: Sequence[ObjectGeometry]) -> ObjectGeometry:
    """The placed geometry the lighting reads, with every object's shadow occluders, where each object's end (its
    shadow maps are its own: renderer.shading.lighting.ShadowMaps), and their joint box. Its voxel size and
    occluder block (the shadows' biases) are those of the object with the widest block."""
    if len(geometries) == 1:
        return geometries[0]
    widest = max(geometries, key=lambda g: g.occluder_width)
    occluders = np.concatenate([g.occluders for g in geometries])
    boxes = [g.occluder_box for g in geometries if not g.empty]
    box = (np.stack([np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)])
           if boxes else widest.occluder_box)
    ends = np.cumsum([len(g.occluders) for g in geometries])
    parts = tuple((int(end), g.occluder_width, g.occluder_box) for end, g in zip(ends, geometries))
    return replace(widest, occluders=occluders, occluder_box=box, occluder_parts=parts)
