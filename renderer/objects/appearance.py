"""The three appearance settings of the paper (section 4.1), baked into per-vertex colors.

`single`: one random color for the whole object. `default`: per-part materials (the stand-in
for ShapeNet's own). `textured`: a procedural texture projected triplanar, its family drawn
from the train or the test families. Every setting also draws a random floor color.

Colors are sRGB RGBA uint8 in `mesh.visual.vertex_colors`, the one representation both the
voxeliser and the path tracer read. Patterned settings first split the mesh's edges down to
about one voxel at 100^3 (manifold3d refinement, which keeps the mesh watertight and each
face's part label), so a pattern is sampled finely enough to survive voxelisation.
"""

from __future__ import annotations

import math
from typing import Any

import manifold3d as mf
import numpy as np
import trimesh

from renderer.color import to_uint8
from renderer.errors import InputError
from renderer.objects.assembly import LabeledMesh
from renderer.objects.generate import category_of, check_seed, check_split
from renderer.objects.materials import choose_materials
from renderer.objects.palette import uniform_color
from renderer.objects.textures import draw_texture, triplanar

SETTINGS = ("single", "default", "textured")
EDGE_LENGTH = {"single": None, "default": 0.015, "textured": 0.01}  # object units; None: keep the mesh as built
MAX_FACES = 150_000
_TRIANGLE_AREA_PER_EDGE2 = 0.35  # measured mean triangle area / edge_length^2 after refinement, used to pick the edge
_FLOOR_STREAM, _OBJECT_STREAM = 2, 3  # generator streams, independent of the geometry's


def refine(obj: LabeledMesh, edge_length: float, max_faces: int = MAX_FACES) -> LabeledMesh:
    """Split edges to about `edge_length` (longer if needed to stay within `max_faces`), keeping labels and watertightness."""
    source = mf.Mesh64(
        vert_properties=np.array(obj.mesh.vertices, dtype=np.float64),
        tri_verts=np.array(obj.mesh.faces, dtype=np.uint64),
        face_id=np.array(obj.face_labels, dtype=np.uint32),
    )
    solid = mf.Manifold(source)
    if solid.status() != mf.Error.NoError:
        raise InputError(f"the {obj.category} mesh is not a closed manifold ({solid.status()}); cannot refine it")
    edge = max(edge_length, math.sqrt(obj.mesh.area / (_TRIANGLE_AREA_PER_EDGE2 * max_faces)))
    refined = solid.refine_to_length(edge)
    while refined.num_tri() > max_faces:
        edge *= 1.15
        refined = solid.refine_to_length(edge)
    out = refined.to_mesh64()
    mesh = trimesh.Trimesh(np.array(out.vert_properties)[:, :3], np.array(out.tri_verts, dtype=np.int64), process=False)
    labels = np.array(out.face_id, dtype=np.int64)
    return LabeledMesh(
        mesh=mesh, face_labels=labels, part_names=obj.part_names, category=obj.category, params=obj.params
    )


def vertex_labels(obj: LabeledMesh) -> np.ndarray:
    """A part label per vertex: the lowest label among its faces (seam vertices go to the earlier-listed part)."""
    labels = np.full(len(obj.mesh.vertices), np.iinfo(np.int64).max)
    np.minimum.at(labels, obj.mesh.faces.ravel(), np.repeat(obj.face_labels, 3))
    return labels


def part_axis(points: np.ndarray) -> np.ndarray:
    """Unit axis (x, y or z) along which a part's points extend furthest: the grain direction."""
    axis = np.zeros(3)
    axis[int(np.argmax(np.ptp(points, axis=0)))] = 1.0
    return axis


def _default_colors(obj: LabeledMesh, rng: np.random.Generator) -> tuple[np.ndarray, dict[str, Any]]:
    """Per-part material colors; returns vertex colors and the material chosen for each part present."""
    roles = category_of(obj.category).parts
    materials = choose_materials(rng)
    labels = vertex_labels(obj)
    vertices = obj.mesh.vertices
    colors = np.zeros((len(vertices), 3))
    used = {}
    for label in np.unique(labels):
        name = obj.part_names[label]
        material_name, look = materials[roles[name]]
        mask = labels == label
        colors[mask] = look(vertices[mask], part_axis(vertices[mask]))
        used[name] = material_name
    return colors, {"materials": used}


def _textured_colors(obj: LabeledMesh, rng: np.random.Generator, split: str) -> tuple[np.ndarray, dict[str, Any]]:
    """Triplanar texture from a family of the split; returns vertex colors and the family name."""
    family, texture = draw_texture(rng, split)
    colors = triplanar(texture, obj.mesh.vertices, obj.mesh.vertex_normals)
    return colors, {"family": family}


def apply_appearance(
    obj: LabeledMesh, setting: str, seed: int, split: str
) -> tuple[trimesh.Trimesh, tuple[float, float, float], dict[str, Any]]:
    """Color an object in one of the SETTINGS; returns the colored mesh, a floor color and what was drawn.

    The floor color depends on the seed only; `split` picks the texture families of `textured`.
    Colors are sRGB in [0, 1] in the returned info, uint8 RGBA on the mesh.
    """
    if setting not in SETTINGS:
        raise InputError(f"unknown appearance setting {setting!r}; expected one of {', '.join(SETTINGS)}")
    seed, split = check_seed(seed), check_split(split)
    floor = to_uint8(uniform_color(np.random.default_rng([seed, _FLOOR_STREAM]))) / 255.0
    rng = np.random.default_rng([seed, _OBJECT_STREAM, SETTINGS.index(setting)])
    edge = EDGE_LENGTH[setting]
    shaped = obj if edge is None else refine(obj, edge)
    if setting == "single":
        color = to_uint8(uniform_color(rng)) / 255.0
        colors, info = np.tile(color, (len(shaped.mesh.vertices), 1)), {"color": color.tolist()}
    elif setting == "default":
        colors, info = _default_colors(shaped, rng)
    else:
        colors, info = _textured_colors(shaped, rng, split)
    rgba = np.concatenate([to_uint8(colors), np.full((len(colors), 1), 255, dtype=np.uint8)], axis=1)
    mesh = trimesh.Trimesh(shaped.mesh.vertices.copy(), shaped.mesh.faces.copy(), vertex_colors=rgba, process=False)
    info = {"setting": setting, "seed": seed, "split": split, "faces": len(mesh.faces), **info}
    return mesh, (float(floor[0]), float(floor[1]), float(floor[2])), info
