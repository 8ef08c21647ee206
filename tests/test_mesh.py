"""Mesh loading, cleaning, normalisation and material colors (renderer/mesh.py)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from PIL import Image

from renderer.errors import InputError
from renderer.mesh import clean_mesh, load_mesh, mesh_colors_at, normalise_mesh


def box(extents=(1.0, 1.0, 1.0), offset=(0.0, 0.0, 0.0)) -> trimesh.Trimesh:
    mesh = trimesh.creation.box(extents=extents)
    mesh.apply_translation(offset)
    return mesh


@pytest.mark.parametrize("ext", [".obj", ".ply", ".stl", ".off", ".glb"])
def test_every_format_loads_the_same_box(tmp_path, ext):
    path = tmp_path / f"box{ext}"
    box((2.0, 4.0, 1.0), (10.0, 20.0, 30.0)).export(path)
    mesh = load_mesh(path)
    assert len(mesh.faces) == 12
    np.testing.assert_allclose(mesh.bounds, [[9.0, 18.0, 29.5], [11.0, 22.0, 30.5]], atol=1e-6)


def test_normalise_fits_the_object_box():
    # Longest side 4 -> scale 1/4; x, z centred; bottom at y = 0.
    mesh = normalise_mesh(box((2.0, 4.0, 1.0), (10.0, 20.0, 30.0)))
    np.testing.assert_allclose(mesh.bounds, [[-0.25, 0.0, -0.125], [0.25, 1.0, 0.125]], atol=1e-12)


@pytest.mark.parametrize("scale", [1e6, 1e-6])
def test_normalise_is_scale_invariant(scale):
    unit = trimesh.creation.icosphere(subdivisions=1)
    unit.vertices = unit.vertices * [1.0, 0.6, 0.3] + [0.2, -0.1, 0.05]
    scaled = unit.copy()
    scaled.vertices = scaled.vertices * scale + 3.0 * scale
    a = normalise_mesh(clean_mesh(unit))
    b = normalise_mesh(clean_mesh(scaled))
    assert len(b.faces) == len(unit.faces) == 80
    np.testing.assert_allclose(b.vertices, a.vertices, atol=1e-9)


def test_z_up_becomes_y_up(tmp_path):
    path = tmp_path / "tall_in_z.ply"
    box((1.0, 2.0, 3.0)).export(path)
    mesh = load_mesh(path, up="z")
    # (x, y, z) -> (x, z, -y): the 3-long z side stands up, the 2-long y side points along z.
    np.testing.assert_allclose(mesh.extents, [1.0, 3.0, 2.0], atol=1e-9)
    assert mesh.is_winding_consistent and mesh.volume > 0  # a rotation, not a mirror: normals still point out


def test_clean_drops_degenerate_duplicate_and_nan_faces():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [np.nan, 0, 0], [1, 0, 0]], dtype=float)
    faces = np.array([
        [0, 1, 2],  # good
        [2, 1, 0],  # duplicate of the first, other order
        [0, 5, 2],  # duplicate again, through a repeated vertex position
        [0, 1, 3],  # degenerate: collinear
        [0, 0, 2],  # degenerate: repeated index
        [0, 1, 4],  # touches a NaN vertex
    ])
    mesh = clean_mesh(trimesh.Trimesh(vertices, faces, process=False))
    assert len(mesh.faces) == 1
    assert np.isfinite(mesh.vertices).all() and len(mesh.vertices) == 3


def test_load_errors_are_one_line_input_errors(tmp_path):
    with pytest.raises(InputError, match="file not found"):
        load_mesh(tmp_path / "missing.obj")
    (tmp_path / "points.xyz").write_text("0 0 0\n")
    with pytest.raises(InputError, match="unsupported mesh format"):
        load_mesh(tmp_path / "points.xyz")
    (tmp_path / "broken.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\nend_header\n\x00")
    with pytest.raises(InputError, match="cannot read mesh|file is cut|not a GLB file"):
        load_mesh(tmp_path / "broken.ply")
    (tmp_path / "garbage.glb").write_bytes(b"\x00\x01not a glb at all")
    with pytest.raises(InputError, match="cannot read mesh|file is cut|not a GLB file"):
        load_mesh(tmp_path / "garbage.glb")
    (tmp_path / "no_faces.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(InputError, match="no faces"):
        load_mesh(tmp_path / "no_faces.obj")
    (tmp_path / "flat.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
    with pytest.raises(InputError, match="no usable faces") as info:
        load_mesh(tmp_path / "flat.obj")
    assert "\n" not in str(info.value) and "flat.obj" in str(info.value)
    with pytest.raises(InputError, match="up axis"):
        load_mesh(tmp_path / "flat.obj", up="x")


def test_normalise_rejects_an_empty_mesh():
    with pytest.raises(InputError):
        normalise_mesh(trimesh.Trimesh())


# --- colors ----------------------------------------------------------------------------------


def triangle() -> trimesh.Trimesh:
    return trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], process=False)


def test_vertex_colors_interpolate_barycentrically():
    mesh = triangle()
    mesh.visual.vertex_colors = [[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255]]
    points = np.array([[0, 0, 0], [1, 0, 0], [1 / 3, 1 / 3, 0], [0.5, 0.0, 0.0]])
    colors = mesh_colors_at(mesh, points, np.zeros(4, dtype=int))
    np.testing.assert_allclose(colors, [[1, 0, 0], [0, 1, 0], [1 / 3, 1 / 3, 1 / 3], [0.5, 0.5, 0]], atol=1e-12)


def test_uniform_vertex_colors_are_exact_even_off_the_face():
    mesh = triangle()
    mesh.visual.vertex_colors = np.tile([51, 102, 204, 255], (3, 1))
    points = np.array([[0.2, 0.2, 0.0], [2.0, 2.0, 0.3], [-1.0, 0.5, 0.0]])  # last two snap into the face
    colors = mesh_colors_at(mesh, points, np.zeros(3, dtype=int))
    np.testing.assert_allclose(colors, np.tile([0.2, 0.4, 0.8], (3, 1)), atol=1e-12)


def test_face_colors_and_default_gray():
    mesh = box()
    assert np.allclose(mesh_colors_at(mesh, mesh.triangles_center, np.arange(12)), 0.5)
    mesh.visual.face_colors = [[255, 0, 0, 255]] * 6 + [[0, 0, 255, 255]] * 6
    colors = mesh_colors_at(mesh, mesh.triangles_center, np.arange(12))
    np.testing.assert_allclose(colors[:6], np.tile([1, 0, 0], (6, 1)))
    np.testing.assert_allclose(colors[6:], np.tile([0, 0, 1], (6, 1)))


def textured_quad(material) -> trimesh.Trimesh:
    quad = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], [[0, 1, 2], [0, 2, 3]], process=False)
    quad.visual = trimesh.visual.TextureVisuals(uv=[[0, 0], [1, 0], [1, 1], [0, 1]], material=material)
    return quad


def test_texture_lookup_puts_v_zero_at_the_bottom_row():
    # 2x2 image: top row red, green; bottom row blue, white.
    pixels = np.array([[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]], dtype=np.uint8)
    quad = textured_quad(trimesh.visual.material.SimpleMaterial(image=Image.fromarray(pixels)))
    points = np.array([[0.25, 0.75, 0], [0.75, 0.75, 0], [0.25, 0.25, 0], [0.75, 0.25, 0]])
    colors = mesh_colors_at(quad, points, np.array([1, 0, 1, 0]))
    np.testing.assert_allclose(colors, [[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]])


def test_gltf_base_color_factor_is_linear():
    # glTF factors are linear: 0.5 linear is sRGB 1.055 * 0.5^(1/2.4) - 0.055 = 0.7354.
    material = trimesh.visual.material.PBRMaterial(baseColorFactor=[0.5, 0.5, 0.5, 1.0])
    colors = mesh_colors_at(textured_quad(material), [[0.5, 0.5, 0.0]], [0])
    np.testing.assert_allclose(colors, [[0.7354] * 3], atol=3e-3)  # the factor is stored as 8 bits


def test_glb_scene_keeps_each_parts_texture(tmp_path):
    parts = []
    for i, rgb in enumerate([(255, 0, 0), (0, 255, 0)]):
        part = box(offset=(2.0 * i, 0.0, 0.0))
        texture = Image.fromarray(np.full((4, 4, 3), rgb, dtype=np.uint8))
        material = trimesh.visual.material.PBRMaterial(baseColorTexture=texture, baseColorFactor=[1.0, 1.0, 1.0, 1.0])
        part.visual = trimesh.visual.TextureVisuals(uv=np.full((len(part.vertices), 2), 0.5), material=material)
        parts.append(part)
    colored = box(offset=(4.0, 0.0, 0.0))
    colored.visual.vertex_colors = [0, 0, 255, 255]
    for name, scene_parts, expected in [("textured", parts, [[1, 0, 0], [0, 1, 0]]),
                                        ("mixed", [parts[0], colored], [[1, 0, 0], [0, 0, 1]])]:
        path = tmp_path / f"{name}.glb"
        trimesh.Scene(scene_parts).export(path)
        mesh = load_mesh(path)
        colors = mesh_colors_at(mesh, mesh.triangles_center, np.arange(len(mesh.faces)))
        left = mesh.triangles_center[:, 0] < mesh.triangles_center[:, 0].mean()
        np.testing.assert_allclose(colors[left], np.tile(expected[0], (left.sum(), 1)), atol=1e-6)
        np.testing.assert_allclose(colors[~left], np.tile(expected[1], ((~left).sum(), 1)), atol=1e-6)


def test_open3d_reads_what_trimesh_cannot(tmp_path, monkeypatch):
    import trimesh as trimesh_module

    from renderer.mesh import load_mesh as load

    box = trimesh_module.creation.box(extents=(1.0, 2.0, 3.0))
    box.visual.vertex_colors = (255, 0, 0, 255)
    box.export(tmp_path / "box.ply")

    def fail(*args, **kwargs):
        raise ValueError("simulated trimesh failure")

    monkeypatch.setattr(trimesh_module, "load_scene", fail)
    mesh = load(tmp_path / "box.ply")
    assert len(mesh.faces) == 12
    assert np.allclose(np.ptp(mesh.vertices, axis=0), (1.0, 2.0, 3.0))
    assert (mesh.visual.vertex_colors[:, :3] == (255, 0, 0)).all()


@pytest.mark.filterwarnings("error")
def test_colors_on_a_sliver_face_are_finite_blends_of_its_corners():
    # A face of a generated sofa whose barycentric coordinates come out [-inf, inf, inf]: the two
    # infinite weights used to overflow the normalising sum (a warning, and a black voxel).
    sliver = [[0.462048606719899, 0.061920006046366466, -0.2825970340677612],
              [0.4620486067210798, 0.06192000604636646, -0.29690392963797446],
              [0.4620486067210798, 0.06192000604636646, -0.2819860096057233]]
    corners = [[200, 40, 40, 255], [40, 200, 40, 255], [40, 40, 200, 255]]
    mesh = trimesh.Trimesh(np.array(sliver), [[0, 1, 2]], vertex_colors=corners, process=False)
    colors = mesh_colors_at(mesh, np.array([[0.465, 0.061919983848763585, -0.295]]), np.array([0]))
    assert np.isfinite(colors).all()
    assert colors.sum() == pytest.approx(280 / 255)  # a convex blend of corners each summing to 280


def test_a_missing_material_file_is_named_so_callers_can_warn(tmp_path):
    from renderer.mesh import missing_material_files

    obj = tmp_path / "m.obj"
    obj.write_text("mtllib there.mtl\nmtllib gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "there.mtl").write_text("newmtl a\nKd 1 0 0\n")
    assert missing_material_files(obj) == ["gone.mtl"]
    assert missing_material_files(tmp_path / "other.ply") == []
