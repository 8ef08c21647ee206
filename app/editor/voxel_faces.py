"""The visible faces of object voxels for the viewport: one quad per exposed voxel face.

Only faces whose neighbour is empty (renderer/surface.py `exposed`) can ever be seen, so a
100^3 object becomes a few tens of thousands of quads instead of a million cubes. Face ids:
0 +x, 1 -x, 2 +y, 3 -y, 4 +z, 5 -z (axis = id // 2, side = + for even ids).
"""

from __future__ import annotations

import numpy as np

from renderer.surface import exposed, occupancy


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
