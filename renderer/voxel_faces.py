"""The visible faces of object voxels: one quad per exposed voxel face (the viewport draws them; the path
tracer renders them for an object that has voxels but no mesh).

Only faces whose neighbour is empty (renderer/surface.py `exposed`) can ever be seen, so a
100^3 object becomes a few tens of thousands of quads instead of a million cubes. Face ids:
0 +x, 1 -x, 2 +y, 3 -y, 4 +z, 5 -z (axis = id // 2, side = + for even ids).
"""

from __future__ import annotations

import numpy as np
import trimesh

from renderer.scene import OBJECT_SIZE
from renderer.surface import exposed, occupancy
from renderer.transform import OBJECT_BOX_MIN

QUAD_CORNERS = np.array([[0, 0], [1, 0], [0, 1], [1, 1]])
QUAD_TRIANGLES = np.array([[0, 1, 2], [2, 1, 3]])


def exposed_faces(rgba: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Faces (F, 4) float32 as (i, j, k, face id) and their colors (F, 3) float32 sRGB."""
    occupied = occupancy(rgba)
    cells, colors = [], []
    for face in range(6):
        axis, side = face // 2, (1 if face % 2 == 0 else -1)
        ijk = np.argwhere(exposed(occupied, axis, side))
        cells.append(np.column_stack([ijk, np.full(len(ijk), face)]).astype(np.float32))
        colors.append(rgba[ijk[:, 0], ijk[:, 1], ijk[:, 2], :3].astype(np.float32))
    return np.concatenate(cells), np.clip(np.concatenate(colors), 0.0, 1.0)


def face_corners(face: int) -> np.ndarray:
    """(4, 3) offsets of a face's corners from its voxel's lowest corner, in the viewport shader's order."""
    axis, side = face // 2, 1 if face % 2 == 0 else 0
    corners = np.empty((4, 3), dtype=np.int64)
    corners[:, axis] = side
    corners[:, (axis + 1) % 3], corners[:, (axis + 2) % 3] = QUAD_CORNERS[:, 0], QUAD_CORNERS[:, 1]
    return corners


def voxel_surface_mesh(rgba: np.ndarray) -> trimesh.Trimesh:
    """The exposed faces of the object voxels as triangles in object coordinates: the object's shape
    when it has no mesh (a photo's alignment needs one for its silhouette)."""
    cells, _ = exposed_faces(rgba)
    ijk, faces = cells[:, :3].astype(np.int64), cells[:, 3].astype(np.int64)
    offsets = np.stack([face_corners(face) for face in range(6)])[faces]  # (F, 4, 3)
    corners = (ijk[:, None, :] + offsets).reshape(-1, 3)
    vertices = OBJECT_BOX_MIN + corners * (OBJECT_SIZE / rgba.shape[0])
    triangles = (4 * np.arange(len(cells))[:, None, None] + QUAD_TRIANGLES).reshape(-1, 3)
    return trimesh.Trimesh(vertices, triangles, process=False)
