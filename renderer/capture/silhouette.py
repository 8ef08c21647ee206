"""The object's silhouette as a camera sees it: a boolean mask from ray casting the mesh.

open3d's ray casting (Embree) is built once per mesh, in object coordinates; each pose
turns the camera's pixel rays into object coordinates, so a new pose costs only the rays.
"""

from __future__ import annotations

import numpy as np
import trimesh

from renderer.capture.pose import PhotoPose
from renderer.errors import InputError


class SilhouetteRenderer:
    """Masks of one mesh (in object coordinates) for any pose; one ray per pixel centre."""

    def __init__(self, mesh: trimesh.Trimesh):
        import open3d as o3d

        faces = np.asarray(mesh.faces)
        if len(faces) == 0:
            raise InputError("the mesh has no faces to draw a silhouette from")
        self._scene = o3d.t.geometry.RaycastingScene()
        self._scene.add_triangles(o3d.core.Tensor(np.asarray(mesh.vertices, dtype=np.float32)),
                                  o3d.core.Tensor(faces.astype(np.uint32)))
        self._grids: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
        self.rays_cast = 0

    def mask(self, pose: PhotoPose) -> np.ndarray:
        """(H, W) bool: pixels whose centre ray meets the object, for the pose's camera size."""
        import open3d as o3d

        camera = pose.camera
        u, v = self._pixel_centres(camera.width, camera.height)
        origin, directions = camera.pixel_rays(u, v)
        to_object = pose.world_to_object()
        origin_obj = to_object[:3, :3] @ origin + to_object[:3, 3]
        directions_obj = directions @ to_object[:3, :3].T  # unnormalised: a hit is a hit
        rays = np.empty((directions_obj.shape[0], 6), dtype=np.float32)
        rays[:, :3] = origin_obj
        rays[:, 3:] = directions_obj
        hits = self._scene.test_occlusions(o3d.core.Tensor(rays)).numpy()
        self.rays_cast += len(rays)
        return hits.reshape(camera.height, camera.width)

    def _pixel_centres(self, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
        key = (width, height)
        if key not in self._grids:
            v, u = np.mgrid[0:height, 0:width] + 0.5
            self._grids[key] = (u.ravel(), v.ravel())
        return self._grids[key]
