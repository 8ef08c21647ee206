"""The object as the path tracer renders it: the scene the user made, edits included.

The path tracer renders a mesh, while paint strokes and photo capture change the object's voxels. So
the reference object takes its colors from the painted voxels whenever the voxels say more than the
mesh does: a mesh is subdivided to the voxel size and each vertex takes the color of the nearest
occupied voxel (so a painted region keeps its edge to within a voxel); an object with voxels and no
mesh (captured, imported) is rendered as its voxels' exposed faces, each in its voxel's color.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import trimesh
from scipy import ndimage

from renderer.limits import MAX_MESH_FACES
from renderer.pipeline import object_mesh, object_voxels, painted_voxels
from renderer.scene import OBJECT_SIZE, Scene, replaced
from renderer.surface import occupancy
from renderer.transform import OBJECT_BOX_MIN
from renderer.voxel_faces import exposed_faces, voxel_surface_mesh

SUBDIVISION_ROUNDS = 8  # halvings of the longest edges at most: a face of the whole object reaches 1/256 of it


def voxel_colored(scene: Scene) -> bool:
    """Whether the object's colors live in its voxels rather than in its mesh (a voxel file, or paint on the object)."""
    return scene.mesh_path() is None or scene.object.voxels is not None or any(
        op.target in ("region", "object") for op in scene.paint)


def reference_scene(scene: Scene) -> tuple[Scene, trimesh.Trimesh]:
    """The scene and object mesh (object coordinates) to path trace: the object colored from its painted voxels when
    voxel_colored, else the scene's own mesh."""
    if not voxel_colored(scene):
        return scene, object_mesh(scene)
    rgba, _ = painted_voxels(scene, object_voxels(scene))
    # The voxels hold the object color and the paint: the path tracer takes the colors from the mesh alone.
    scene = scene.with_changes(object=replace(scene.object, color=None, paint=()))
    if scene.mesh_path() is None:
        return scene, colored_voxel_faces(rgba)
    return scene, mesh_colored_from_voxels(object_mesh(scene), rgba)


def reference_objects(scene: Scene) -> tuple[Scene, list[trimesh.Trimesh]]:
    """reference_scene of each of the scene's objects: the scene with the objects' colors as their meshes hold them,
    and one mesh per object, in order."""
    objects, meshes = [], []
    for index in range(len(scene.objects)):
        one, mesh = reference_scene(scene.alone(index))
        objects.append(one.object)
        meshes.append(mesh)
    return replaced(scene, objects=tuple(objects)), meshes


def mesh_colored_from_voxels(mesh: trimesh.Trimesh, rgba: np.ndarray) -> trimesh.Trimesh:
    """`mesh` (object coordinates) subdivided to the voxel size, each vertex the sRGB color of the nearest occupied voxel."""
    n = rgba.shape[0]
    voxel = OBJECT_SIZE / n
    vertices, faces = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces)
    for _ in range(SUBDIVISION_ROUNDS):
        edges = np.linalg.norm(vertices[faces] - vertices[faces[:, [1, 2, 0]]], axis=2).max(axis=1)
        if edges.max() <= voxel or 4 * len(faces) > MAX_MESH_FACES:
            break
        long = edges > voxel
        sub_vertices, sub_faces = trimesh.remesh.subdivide(vertices, faces, face_index=np.flatnonzero(long))
        vertices, faces = sub_vertices, sub_faces
    occupied = occupancy(rgba)
    if not occupied.any():
        colors = np.full((len(vertices), 3), 0.5)
    else:
        _, nearest = ndimage.distance_transform_edt(~occupied, return_indices=True)
        cell = np.clip(np.floor((vertices - OBJECT_BOX_MIN) / voxel).astype(np.int64), 0, n - 1)
        i, j, k = (nearest[axis][cell[:, 0], cell[:, 1], cell[:, 2]] for axis in range(3))
        colors = rgba[i, j, k, :3]
    colors_u8 = np.round(np.clip(colors, 0.0, 1.0) * 255.0).astype(np.uint8)
    return trimesh.Trimesh(vertices, faces, vertex_colors=colors_u8, process=False)


def colored_voxel_faces(rgba: np.ndarray) -> trimesh.Trimesh:
    """The voxels' exposed faces as a mesh whose faces have their voxels' sRGB colors."""
    mesh = voxel_surface_mesh(rgba)
    _, colors = exposed_faces(rgba)
    per_triangle = np.repeat(np.round(colors * 255.0).astype(np.uint8), 2, axis=0)  # two triangles per quad
    mesh.visual = trimesh.visual.ColorVisuals(mesh, face_colors=per_triangle)
    return mesh
