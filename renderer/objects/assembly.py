"""From named closed parts to one watertight, labelled mesh standing in the object box.

The parts are unioned with manifold3d, which remembers for every output triangle the part it
came from, so each face keeps its part label (seat, leg, ...) through the boolean union.
The result is scaled uniformly so its longest side is OBJECT_SIZE, centred on x and z, and
set on the floor (min y = 0): the object box of renderer/transform.py.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import manifold3d as mf
import numpy as np
import trimesh

from renderer.transform import OBJECT_BOX_MAX, OBJECT_BOX_MIN


@dataclass
class LabeledMesh:
    """A generated object: its mesh, a part label per face (an index into part_names), and how it was made."""

    mesh: trimesh.Trimesh
    face_labels: np.ndarray
    part_names: tuple[str, ...]
    category: str
    params: dict[str, Any] = field(default_factory=dict)


def fit_object_box(vertices: np.ndarray) -> np.ndarray:
    """Scale uniformly to longest side OBJECT_SIZE, centre on x and z, and put the lowest point at y = 0."""
    low, high = vertices.min(axis=0), vertices.max(axis=0)
    scale = float((OBJECT_BOX_MAX - OBJECT_BOX_MIN).max()) / float((high - low).max())
    anchor = np.array([(low[0] + high[0]) / 2, low[1], (low[2] + high[2]) / 2])
    box_anchor = np.array(
        [(OBJECT_BOX_MIN[0] + OBJECT_BOX_MAX[0]) / 2, OBJECT_BOX_MIN[1], (OBJECT_BOX_MIN[2] + OBJECT_BOX_MAX[2]) / 2]
    )
    return (vertices - anchor) * scale + box_anchor


def manifold_to_labeled_arrays(
    solid: mf.Manifold, label_of_id: dict[int, int]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices (float64), faces and per-face labels of a manifold, labels looked up by original mesh id."""
    out = solid.to_mesh64()
    vertices = np.array(out.vert_properties, dtype=np.float64)[:, :3]
    faces = np.array(out.tri_verts, dtype=np.int64).reshape(-1, 3)
    run_starts = np.array(out.run_index, dtype=np.int64) // 3
    run_labels = [label_of_id[int(i)] for i in np.array(out.run_original_id)]
    labels = np.repeat(np.array(run_labels, dtype=np.int64), np.diff(run_starts))
    return vertices, faces, labels


def assemble(
    parts: list[tuple[str, mf.Manifold]], part_names: tuple[str, ...], category: str, params: dict[str, Any]
) -> LabeledMesh:
    """Union the named parts into one watertight mesh in the object box, each face labelled with its part."""
    originals = [solid.as_original() for _, solid in parts]
    label_of_id = {solid.original_id(): part_names.index(name) for (name, _), solid in zip(parts, originals)}
    union = mf.Manifold.batch_boolean(originals, mf.OpType.Add)
    vertices, faces, labels = manifold_to_labeled_arrays(union, label_of_id)
    mesh = trimesh.Trimesh(fit_object_box(vertices), faces, process=False)
    return LabeledMesh(mesh=mesh, face_labels=labels, part_names=part_names, category=category, params=params)
