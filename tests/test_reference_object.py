"""The path tracer renders the scene the user made: painted and captured voxel colors, painted floors, voxel-only objects."""

import colorsys

import numpy as np
import trimesh

from renderer.color import srgb_to_linear
from renderer.pathtrace.path_tracer import render_pathtraced
from renderer.reference_object import colored_voxel_faces, mesh_colored_from_voxels, reference_scene, voxel_colored
from renderer.scene import CameraSpec, FloorSpec, LightSpec, ObjectSpec, PaintOp, Scene
from renderer.surface import exposed, occupancy
from renderer.voxels import save_voxels

RED, BLUE = (0.85, 0.1, 0.1), (0.1, 0.2, 0.85)


def half_and_half(n: int = 16) -> np.ndarray:
    """A full block of voxels, red where x < 0 (the lower half of i), blue elsewhere."""
    rgba = np.ones((n, n, n, 4), np.float32)
    rgba[: n // 2, ..., :3], rgba[n // 2:, ..., :3] = RED, BLUE
    return rgba


def test_a_mesh_takes_the_color_of_the_nearest_voxel_at_each_vertex_after_subdivision_to_the_voxel_size():
    box = trimesh.creation.box([1.0, 1.0, 1.0])
    box.apply_translation([0.0, 0.5, 0.0])  # object coordinates: the unit box standing on the floor
    colored = mesh_colored_from_voxels(box, half_and_half(16))
    vertices, colors = colored.vertices, colored.visual.vertex_colors[:, :3] / 255.0
    edges = np.linalg.norm(vertices[colored.faces] - vertices[colored.faces[:, [1, 2, 0]]], axis=2)
    assert edges.max() <= 1.0 / 16 + 1e-9  # no face spans more than a voxel
    left, right = vertices[:, 0] < -1.0 / 16, vertices[:, 0] > 1.0 / 16
    assert np.allclose(colors[left], RED, atol=1 / 255) and np.allclose(colors[right], BLUE, atol=1 / 255)


def test_voxel_faces_carry_their_voxel_colors():
    rgba = half_and_half(4)
    mesh = colored_voxel_faces(rgba)
    occupied = occupancy(rgba)
    count = sum(int(exposed(occupied, axis, side).sum()) for axis in range(3) for side in (1, -1))
    assert len(mesh.faces) == 2 * count  # two triangles per exposed face
    centres_x = mesh.triangles_center[:, 0]
    colors = mesh.visual.face_colors[:, :3] / 255.0
    assert np.allclose(colors[centres_x < -0.01], RED, atol=1 / 255) and np.allclose(colors[centres_x > 0.01], BLUE, atol=1 / 255)


def _scene(tmp_path, **changes) -> Scene:
    box = trimesh.creation.box([0.6, 0.6, 0.6])
    box.apply_translation([0.0, 0.3, 0.0])
    box.export(tmp_path / "box.obj")
    base = dict(object=ObjectSpec(mesh="box.obj", resolution=16, rotation_deg=30.0), floor=FloorSpec((0.6, 0.6, 0.6)),
                light=LightSpec((0.0, 2.75, 0.5)), camera=CameraSpec(30.0), image_size=48, base_dir=tmp_path)
    return Scene.single(**{**base, **changes})


def _object_hue(scene: Scene, mesh: trimesh.Trimesh) -> float:
    image = render_pathtraced(scene, mesh, size=48, spp=8).image
    middle = image[18:34, 18:30]  # the box fills the image's middle
    return colorsys.rgb_to_hsv(*srgb_to_linear(middle).mean(axis=(0, 1)))[0]


def test_painting_the_object_and_the_floor_changes_the_path_traced_image(tmp_path):
    plain = _scene(tmp_path)
    assert not voxel_colored(plain)
    painted = _scene(tmp_path, paint=(PaintOp("object", RED),), floor=FloorSpec((0.9, 0.9, 0.2)))
    assert voxel_colored(painted)
    scene, mesh = reference_scene(painted)
    assert scene.floor.color == (0.9, 0.9, 0.2)
    assert mesh.visual.kind == "vertex" and np.allclose(mesh.visual.vertex_colors[:, :3] / 255.0, RED, atol=1 / 255)
    hue = _object_hue(scene, mesh)
    assert min(hue, 1.0 - hue) < 0.03  # red (the plain box is grey: no hue to speak of)
    plain_scene, plain_mesh = reference_scene(plain)
    assert plain_mesh.visual.kind != "vertex" and plain_scene.floor.color == (0.6, 0.6, 0.6)


def test_an_object_of_voxels_alone_is_path_traced_as_its_voxels(tmp_path):
    save_voxels(tmp_path / "block.npz", half_and_half(8))
    scene, mesh = reference_scene(_scene(tmp_path, object=ObjectSpec(voxels="block.npz", scale=(0.6, 0.6, 0.6))))
    assert mesh.visual.kind == "face"
    image = render_pathtraced(scene, mesh, size=32, spp=4).image
    assert np.isfinite(image).all() and image.std() > 0.02
