"""The staged Scene -> network input path (renderer/pipeline.py)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from renderer.errors import InputError
from renderer.pipeline import object_mesh, object_voxels, painted_voxels, scene_grid_for
from renderer.scene import FloorSpec, ObjectSpec, PaintOp, Scene
from renderer.voxels import save_voxels


def test_mesh_scene_to_grid(tmp_path):
    trimesh.creation.box(extents=(2.0, 1.0, 1.0)).export(tmp_path / "box.obj")
    scene = Scene.single(
        object=ObjectSpec(mesh="box.obj", resolution=16),
        paint=(PaintOp("object", (0.0, 1.0, 0.0)),),
        floor=FloorSpec((1.0, 0.0, 1.0)),
        base_dir=tmp_path,
    )
    rgba = object_voxels(scene)
    occupied = rgba[..., 3] == 1
    # A 2 x 1 x 1 box normalised to 1 x 0.5 x 0.5: in voxel units x spans [0, 16], y [0, 8] and
    # z [4, 12]. Faces on a voxel boundary mark both sides (those outside the grid are clipped):
    # x covers voxels 0..15, y 0..8 and z 3..12.
    cells = np.argwhere(occupied)
    assert rgba.shape == (16, 16, 16, 4)
    assert cells.min(axis=0).tolist() == [0, 0, 3] and cells.max(axis=0).tolist() == [15, 8, 12]
    np.testing.assert_allclose(rgba[occupied, :3], 0.5)  # an uncolored mesh is gray
    painted, floor = painted_voxels(scene, rgba)
    assert floor == (1.0, 0.0, 1.0)
    grid = scene_grid_for(scene, [painted], floor)
    colors = {tuple(c) for c in grid[grid[..., 3] == 1][:, :3].tolist()}
    assert colors == {(0.0, 1.0, 0.0), (1.0, 0.0, 1.0)}


def test_voxel_file_and_base_color(tmp_path):
    rgba = np.zeros((8, 8, 8, 4), dtype=np.float32)
    rgba[2:6, 0:4, 2:6] = [0.2, 0.4, 0.6, 1.0]
    save_voxels(tmp_path / "v.npz", rgba)
    scene = Scene.single(object=ObjectSpec(voxels="v.npz", color=(1.0, 0.0, 0.0)), base_dir=tmp_path)
    out = object_voxels(scene)
    np.testing.assert_array_equal(out[..., 3], rgba[..., 3])
    np.testing.assert_array_equal(out[rgba[..., 3] == 1, :3], np.tile([1.0, 0.0, 0.0], (64, 1)))


def test_object_mesh_is_normalised_and_needs_a_mesh(tmp_path):
    # z-up file: its 3-long z side becomes the height, then everything is scaled by 1/3.
    trimesh.creation.box(extents=(1.0, 2.0, 3.0)).export(tmp_path / "box.ply")
    mesh = object_mesh(Scene.single(object=ObjectSpec(mesh="box.ply", up="z"), base_dir=tmp_path))
    np.testing.assert_allclose(mesh.bounds, [[-1 / 6, 0.0, -1 / 3], [1 / 6, 1.0, 1 / 3]], atol=1e-12)
    with pytest.raises(InputError, match="no mesh"):
        object_mesh(Scene.single(object=ObjectSpec(voxels="v.npz"), base_dir=tmp_path))
