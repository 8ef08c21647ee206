"""The object's silhouette as a camera sees it: a boolean mask from ray casting the mesh.

open3d's ray casting (Embree) is built once per mesh, in object coordinates; each pose
turns the camera's pixel rays into object coordinates, so a new pose costs only the rays,
and only those within the projection of the mesh's bounding box are cast.
"""

from __future__ import annotations

import math

import numpy as np
import trimesh

from renderer.capture.pose import PhotoPose
from renderer.errors import InputError

MAX_RAY_GRIDS = 16  # lenses and sizes whose camera-space rays are kept (a search uses three sizes, one lens)


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
        vertices = np.asarray(mesh.vertices, dtype=np.float64)
        self.footprint_radius = 0.5 * float(max(np.ptp(vertices[:, 0]), np.ptp(vertices[:, 2])))
        low, high = vertices.min(axis=0), vertices.max(axis=0)
        self._corners = np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1])
                                  for z in (low[2], high[2])])  # the bounding box's, object coordinates
        self._grids: dict[tuple, np.ndarray] = {}  # camera-space ray directions by lens and size
        self.rays_cast = 0

    def mask(self, pose: PhotoPose) -> np.ndarray:
        """(H, W) bool: pixels whose centre ray meets the object, for the pose's camera size."""
        out = np.zeros((pose.camera.height, pose.camera.width), dtype=bool)
        window = self._window(pose)
        if window is not None:
            origin, directions = self._camera_rays(pose, window)
            out[window] = self.occluded(np.broadcast_to(origin, directions.shape), directions).reshape(
                out[window].shape)
        return out

    def floor_radii(self, pose: PhotoPose, reach: float = math.inf) -> np.ndarray:
        """(H, W): how far from the object's vertical axis (object units) each pixel centre's ray meets the floor
        it stands on (object y = 0); inf where the ray does not go down to it, or meets it farther than `reach`
        (only the rays within the projection of that square of the floor are cast)."""
        h, w = pose.camera.height, pose.camera.width
        radii = np.full((h, w), np.inf)
        window = None
        if math.isfinite(reach):
            window = self._window(pose, np.array([[x, 0.0, z] for x in (-reach, reach) for z in (-reach, reach)]))
            if window is None:
                return radii
        origin, directions = self._camera_rays(pose, window)
        down = directions[:, 1] < 0.0
        t = -origin[1] / np.where(down, directions[:, 1], -1.0)  # finite everywhere: no inf times a zero component
        found = np.hypot(origin[0] + t * directions[:, 0], origin[2] + t * directions[:, 2])
        found[~down | (t <= 0.0) | (found > reach)] = np.inf
        if window is None:
            return found.reshape(h, w)
        radii[window] = found.reshape(radii[window].shape)
        return radii

    def surface(self, pose: PhotoPose) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What each pixel centre's ray meets first, in object coordinates: (H, W) bool hit, and for the hits
        (N, 3) points and (N, 3) unit normals facing the camera."""
        import open3d as o3d

        hits = np.zeros((pose.camera.height, pose.camera.width), dtype=bool)
        window = self._window(pose)
        if window is None:
            return hits, np.zeros((0, 3)), np.zeros((0, 3))
        origin, directions = self._camera_rays(pose, window)
        cast = self._scene.cast_rays(o3d.core.Tensor(_rays(np.broadcast_to(origin, directions.shape), directions)))
        self.rays_cast += len(directions)
        t = cast["t_hit"].numpy()
        hit = np.isfinite(t)
        points = origin + t[hit, None] * directions[hit]
        normals = cast["primitive_normals"].numpy()[hit].astype(np.float64)
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
        normals *= np.where(np.einsum("ij,ij->i", normals, directions[hit]) > 0.0, -1.0, 1.0)[:, None]
        hits[window] = hit.reshape(hits[window].shape)  # row-major within the window: the hits keep their order
        return hits, points, normals

    def occluded(self, origins: np.ndarray, directions: np.ndarray, far: float = np.inf) -> np.ndarray:
        """(N,) bool: whether each ray (object coordinates; directions need not be unit) meets the object at a
        parameter below `far`."""
        import open3d as o3d

        self.rays_cast += len(directions)
        return self._scene.test_occlusions(o3d.core.Tensor(_rays(origins, directions)), tfar=float(far)).numpy()

    def _window(self, pose: PhotoPose, corners: np.ndarray | None = None) -> tuple[slice, slice] | None:
        """The rows and columns whose pixel centres the projection of the convex hull of `corners` (object
        coordinates; the bounding box's when None) may cover (a pixel's margin for rounding); all of them when a
        corner is behind the camera; None when none is."""
        camera = pose.camera
        to_world = pose.object_to_world()
        corners = self._corners if corners is None else corners
        u, v, depth = camera.project(corners @ to_world[:3, :3].T + to_world[:3, 3])
        if np.any(depth <= 1e-6):
            return slice(0, camera.height), slice(0, camera.width)
        c0, c1 = max(0, math.floor(u.min() - 1.5)), min(camera.width, math.ceil(u.max() + 0.5))
        r0, r1 = max(0, math.floor(v.min() - 1.5)), min(camera.height, math.ceil(v.max() + 0.5))
        return None if c0 >= c1 or r0 >= r1 else (slice(r0, r1), slice(c0, c1))

    def _camera_rays(self, pose: PhotoPose, window: tuple[slice, slice] | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The camera's origin (3,) and (H*W, 3) pixel-centre ray directions (row-major; those of `window` only when
        given), in object coordinates (not unit: a pose costs one 3x3 product of the camera-space directions, which
        depend on the lens and size only)."""
        camera = pose.camera
        to_camera_space = camera.camera_to_world()
        to_object = pose.world_to_object()
        turn = to_object[:3, :3] @ to_camera_space[:3, :3]
        origin = to_object[:3, :3] @ to_camera_space[:3, 3] + to_object[:3, 3]
        grid = self._camera_space_rays(camera)
        if window is not None:
            grid = grid.reshape(camera.height, camera.width, 3)[window].reshape(-1, 3)
        return origin, grid @ turn.T

    def _camera_space_rays(self, camera) -> np.ndarray:
        """(H*W, 3) unit directions through the pixel centres in camera space, as Camera.pixel_rays makes them (the
        same float rounding keeps a search on the same path)."""
        cx, cy = camera.principal_point
        key = (camera.width, camera.height, camera.focal_px, cx, cy)
        if key not in self._grids:
            if len(self._grids) >= MAX_RAY_GRIDS:
                self._grids.clear()
            v, u = np.mgrid[0:camera.height, 0:camera.width] + 0.5
            rays = np.stack([(u.ravel() - cx) / camera.focal_px, (cy - v.ravel()) / camera.focal_px,
                             np.full(u.size, -1.0)], axis=1)
            self._grids[key] = rays / np.linalg.norm(rays, axis=1, keepdims=True)  # unit, as pixel_rays gives them
        return self._grids[key]


def _rays(origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """(N, 6) float32 rays as open3d takes them."""
    rays = np.empty((directions.shape[0], 6), dtype=np.float32)
    rays[:, :3] = origins
    rays[:, 3:] = directions
    return rays
