"""The staged path from a Scene to the network's input grid; each stage is a pure function the live engine can cache.

object_voxels (mesh or voxel file, base color) -> painted_voxels (paint strokes) -> scene_grid_for (placement,
camera elevation; every object's: painted_objects). object_mesh is the mesh the voxels come from.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import trimesh

from renderer.errors import InputError
from renderer.grid import ground_grid, object_cells
from renderer.mesh import load_mesh, normalise_mesh
from renderer.paint import Color, apply_paint, fill_object
from renderer.scene import GRID_SIZE, Scene
from renderer.voxels import ProgressCallback, load_voxels, voxelize


def object_mesh(scene: Scene) -> trimesh.Trimesh:
    """The object's mesh in object coordinates (read, turned y-up, normalised), e.g. for the path tracer."""
    path = scene.mesh_path()
    if path is None:
        raise InputError("the scene's object has no mesh, only voxels")
    return normalise_mesh(load_mesh(path, up=scene.object.up))


def object_voxels(scene: Scene, progress: ProgressCallback | None = None) -> np.ndarray:
    """The object's voxels: its voxel file if given, else its mesh voxelised at its resolution; then its base color.

    Meshes without colors come out gray (renderer.mesh.UNCOLORED_GRAY).
    """
    voxels_path = scene.voxels_path()
    if voxels_path is not None:
        rgba = load_voxels(voxels_path)
    else:
        rgba = voxelize(object_mesh(scene), scene.object.resolution, progress=progress)
    return rgba if scene.object.color is None else fill_object(rgba, scene.object.color)


def painted_voxels(scene: Scene, rgba: np.ndarray) -> tuple[np.ndarray, Color]:
    """The object voxels and floor color after replaying the scene's paint strokes."""
    return apply_paint(rgba, scene.floor.color, scene.paint)


def painted_objects(scene: Scene) -> list[np.ndarray]:
    """Every object's painted voxels, in the scene's order."""
    return [painted_voxels(one, object_voxels(one))[0] for one in map(scene.alone, range(len(scene.objects)))]


def scene_grid_for(scene: Scene, painted: Sequence[np.ndarray], floor_color: Color,
                   grid_size: int = GRID_SIZE) -> np.ndarray:
    """The network's camera-aligned input grid (grid_size^3 x 4) for the scene's objects (their painted voxels, one
    array per object in order) and camera: the ground, and each object's cells over it (renderer.grid.object_cells).
    Where objects meet, the later object's voxels win."""
    elevation = scene.camera.elevation_deg
    grid = ground_grid(floor_color, elevation, grid_size)
    for rgba, o in zip(painted, scene.objects):
        cells, rows = object_cells(rgba, o, floor_color, elevation, grid_size)
        grid.reshape(-1, 4)[cells] = rows
    return grid
