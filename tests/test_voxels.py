"""Surface voxelisation and voxel files (renderer/voxels.py).

Expected counts come from geometry, not from the code: a voxel is occupied when its closed
box meets the surface.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import trimesh
from scipy import ndimage

from renderer import voxels as voxels_module
from renderer.errors import InputError
from renderer.mesh import clean_mesh, normalise_mesh
from renderer.transform import OBJECT_BOX_MIN
from renderer.voxels import VOXEL_EPS, load_voxels, save_voxels, surface_hits, voxelize


def occupied(rgba: np.ndarray) -> np.ndarray:
    return rgba[..., 3] > 0.5


def to_object(points_in_voxels: np.ndarray, n: int) -> np.ndarray:
    """Voxel-unit coordinates of an n^3 grid to object coordinates."""
    return OBJECT_BOX_MIN + np.asarray(points_in_voxels, dtype=float) / n


def random_rotation(seed: int) -> np.ndarray:
    q, r = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


# --- counts geometry predicts ------------------------------------------------------------------


def test_axis_aligned_box_gives_a_one_voxel_shell():
    # Box corners at voxel coordinates (3.3, 2.7, 5.2) and (15.6, 17.1, 12.9) of a 20^3 grid:
    # it meets voxels 3..15, 2..17, 5..12 (13 x 16 x 8) and only the outer layer of that block,
    # so the shell has 13*16*8 - 11*14*6 = 740 voxels, exactly.
    lo, hi = np.array([3.3, 2.7, 5.2]), np.array([15.6, 17.1, 12.9])
    mesh = trimesh.creation.box(bounds=to_object([lo, hi], 20))
    occ = occupied(voxelize(mesh, 20))
    assert occ.sum() == 740
    expected = np.zeros((20, 20, 20), dtype=bool)
    expected[3:16, 2:18, 5:13] = True
    expected[4:15, 3:17, 6:12] = False
    assert np.array_equal(occ, expected)


def test_normalised_cube_fills_the_outer_layer_of_the_grid():
    # The normalised unit cube lies exactly on the grid's outer faces: N^3 - (N-2)^3 voxels.
    occ = occupied(voxelize(normalise_mesh(trimesh.creation.box()), 20))
    assert occ.sum() == 20**3 - 18**3


def box_distances(n: int, centre: np.ndarray, grow: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Nearest and farthest distance from `centre` (voxel units) to every voxel box of an n^3 grid."""
    lo = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), axis=-1) - grow
    hi = lo + 1.0 + 2.0 * grow
    nearest = np.linalg.norm(np.maximum(np.maximum(lo - centre, centre - hi), 0.0), axis=-1)
    farthest = np.linalg.norm(np.maximum(np.abs(centre - lo), np.abs(centre - hi)), axis=-1)
    return nearest, farthest


def test_sphere_shell_count_lies_within_the_geometric_bounds():
    # An icosphere's surface lies between its inradius r (nearest face plane) and its
    # circumradius R (vertices). A voxel meeting the surface meets the shell r <= |p| <= R
    # (upper bound); a voxel reaching inside r and outside R must be crossed by the closed
    # surface (lower bound). For a true sphere the count is about 4 pi R^2 * E|n|_1 = 6 pi R^2
    # voxels (E|n|_1 = 3/2 on the sphere), about 3,100 here.
    n, centre = 32, np.array([0.013, 0.507, -0.021])
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=0.4)
    sphere.apply_translation(centre)
    offsets = sphere.triangles[:, 0] - centre
    r = np.abs(np.einsum("ij,ij->i", offsets, sphere.face_normals)).min() * n
    big_r = np.linalg.norm(sphere.vertices - centre, axis=1).max() * n
    c = (centre - OBJECT_BOX_MIN) * n

    count = occupied(voxelize(sphere, n)).sum()

    nearest, farthest = box_distances(n, c, grow=VOXEL_EPS)
    upper = np.sum((nearest <= big_r) & (farthest >= r))
    nearest, farthest = box_distances(n, c)
    lower = np.sum((nearest < r) & (farthest > big_r))
    assert lower <= count <= upper
    assert upper - lower < 0.02 * count  # the bounds are tight, so the check has teeth
    assert abs(count - 6 * np.pi * (0.4 * n) ** 2) < 0.1 * count


@pytest.mark.parametrize("seed", [0, 1])
def test_thin_closed_surfaces_give_closed_shells(seed):
    # No 6-connected path may leak from inside to outside: filling the holes must fill the centre.
    n = 40
    rot = random_rotation(seed)
    cube = trimesh.creation.box(extents=[0.5, 0.5, 0.5])
    cube.vertices = cube.vertices @ rot.T + [0.0, 0.5, 0.0]
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.3)
    sphere.vertices = sphere.vertices @ rot.T + [0.01, 0.5, 0.02]
    for mesh in (cube, sphere):
        occ = occupied(voxelize(mesh, n))
        centre = tuple(((np.array([0.0, 0.5, 0.0]) - OBJECT_BOX_MIN) * n).astype(int))
        assert not occ[centre] and ndimage.binary_fill_holes(occ)[centre]


# --- exactness against an independent triangle-box test ------------------------------------------


def clip_polygon(polygon: list[np.ndarray], axis: int, bound: float, keep_above: bool) -> list[np.ndarray]:
    """Sutherland-Hodgman: the part of a convex polygon on one side of an axis-aligned plane."""
    out = []
    for i, p in enumerate(polygon):
        q = polygon[(i + 1) % len(polygon)]
        p_in = p[axis] >= bound if keep_above else p[axis] <= bound
        q_in = q[axis] >= bound if keep_above else q[axis] <= bound
        if p_in:
            out.append(p)
        if p_in != q_in:
            t = (bound - p[axis]) / (q[axis] - p[axis])
            out.append(p + t * (q - p))
    return out


def triangle_meets_box(triangle: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> bool:
    polygon = list(triangle)
    for axis in range(3):
        polygon = clip_polygon(polygon, axis, lo[axis], True)
        polygon = clip_polygon(polygon, axis, hi[axis], False) if polygon else polygon
    return len(polygon) > 0


def test_surface_hits_match_polygon_clipping():
    n = 5
    rng = np.random.default_rng(7)
    triangles = np.concatenate([
        rng.uniform(-1.0, 6.0, size=(25, 3, 3)),  # large, partly outside the grid
        rng.uniform(0.0, 5.0, size=(15, 1, 3)) + rng.normal(scale=0.3, size=(15, 3, 3)),  # small
    ])
    tri_id, voxels, points = surface_hits(triangles, n)
    got = set(zip(tri_id.tolist(), map(tuple, voxels.tolist())))
    expected = {
        (t, cell)
        for t in range(len(triangles))
        for cell in itertools.product(range(n), repeat=3)
        if triangle_meets_box(triangles[t], np.array(cell) - VOXEL_EPS, np.array(cell) + 1 + VOXEL_EPS)
    }
    assert got == expected and len(expected) > 100
    # Color sample points lie on their triangle's plane, within two voxels of the voxel centre.
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    off_plane = np.einsum("ij,ij->i", points - triangles[tri_id, 0], normals[tri_id])
    assert np.abs(off_plane).max() < 1e-9
    assert np.linalg.norm(points - (voxels + 0.5), axis=1).max() <= 2.0


# --- colors ----------------------------------------------------------------------------------


def test_two_colored_box_colors_land_on_the_right_voxels():
    n = 10
    cube = normalise_mesh(trimesh.creation.box())
    top = cube.face_normals[:, 1] > 0.5
    cube.visual.face_colors = np.where(top[:, None], [255, 0, 0, 255], [0, 0, 255, 255])
    rgba = voxelize(cube, n)
    # Top layer away from the edges: only the top faces pass through.
    np.testing.assert_array_equal(rgba[1:-1, -1, 1:-1], np.tile([1, 0, 0, 1], (n - 2, n - 2, 1)))
    # Side walls below the top layer (and above the bottom): only blue faces.
    np.testing.assert_array_equal(rgba[0, 1:-1, 1:-1], np.tile([0, 0, 1, 1], (n - 2, n - 2, 1)))
    # Top edges meet both colors: a mix of the two.
    edge = rgba[0, -1, 1:-1]
    assert np.all(edge[:, 0] > 0) and np.all(edge[:, 2] > 0) and np.allclose(edge[:, 0] + edge[:, 2], 1.0)
    assert not occupied(rgba)[1:-1, 1:-1, 1:-1].any()  # hollow


def test_vertex_colors_are_exact():
    # Two separate vertex-colored parts, as the procedural generator makes them.
    legs = trimesh.creation.box(bounds=[[-0.3, 0.0, -0.3], [0.3, 0.6, 0.3]])
    legs.visual.vertex_colors = [26, 102, 230, 255]
    top = trimesh.creation.box(bounds=[[-0.5, 0.8, -0.5], [0.5, 1.0, 0.5]])
    top.visual.vertex_colors = [204, 51, 0, 255]
    rgba = voxelize(trimesh.util.concatenate([legs, top]), 20)
    occ = occupied(rgba)
    j = np.arange(20)[None, :, None] * np.ones((20, 20, 20))
    np.testing.assert_allclose(rgba[occ & (j < 12)][:, :3], np.tile(np.array([26, 102, 230]) / 255, ((occ & (j < 12)).sum(), 1)), atol=1e-6)
    np.testing.assert_allclose(rgba[occ & (j >= 15)][:, :3], np.tile(np.array([204, 51, 0]) / 255, ((occ & (j >= 15)).sum(), 1)), atol=1e-6)


# --- hard cases --------------------------------------------------------------------------------


def test_degenerate_and_duplicate_faces_are_harmless():
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.4)
    sphere.apply_translation([0.0, 0.5, 0.0])
    extra_vertices = np.array([[0.0, 0.5, 0.0], [0.1, 0.5, 0.0], [0.2, 0.5, 0.0], [np.nan, 0.5, 0.0]])
    v = len(sphere.vertices)
    faces = np.concatenate([
        sphere.faces,
        sphere.faces[:30, ::-1],  # duplicates, flipped
        [[0, 0, 1]],  # repeated index
        [[v, v + 1, v + 2]],  # collinear
        [[0, 1, v + 3]],  # NaN vertex
    ])
    dirty = trimesh.Trimesh(np.concatenate([sphere.vertices, extra_vertices]), faces, process=False)
    reference = voxelize(sphere, 24)
    cleaned = clean_mesh(dirty)
    assert len(cleaned.faces) == len(sphere.faces)
    np.testing.assert_array_equal(voxelize(cleaned, 24), reference)
    np.testing.assert_array_equal(voxelize(dirty, 24), reference)  # voxelize alone copes too


def test_open_mesh_voxelises():
    # Unit cube without its top: the top layer keeps only its rim, 20^3 - 18^3 - 18^2 voxels.
    cube = normalise_mesh(trimesh.creation.box())
    cube.update_faces(cube.face_normals[:, 1] < 0.5)
    assert not cube.is_watertight
    occ = occupied(voxelize(cube, 20))
    assert occ.sum() == 20**3 - 18**3 - 18**2
    assert not occ[1:-1, -1, 1:-1].any()


@pytest.mark.parametrize("scale", [1e6, 1e-6])
def test_huge_and_tiny_coordinates_give_the_same_voxels(scale):
    unit = trimesh.creation.icosphere(subdivisions=2)
    unit.vertices = unit.vertices @ random_rotation(3).T * [1.0, 0.7, 0.4]
    scaled = unit.copy()
    scaled.vertices = (scaled.vertices + 5.0) * scale
    expected = voxelize(normalise_mesh(clean_mesh(unit)), 24)
    got = voxelize(normalise_mesh(clean_mesh(scaled)), 24)
    np.testing.assert_array_equal(occupied(got), occupied(expected))
    assert np.isfinite(got).all()


def test_bad_resolution_and_mesh_outside_the_box_raise():
    cube = normalise_mesh(trimesh.creation.box())
    with pytest.raises(InputError, match="resolution"):
        voxelize(cube, 2)
    far = cube.copy()
    far.apply_translation([5.0, 0.0, 0.0])
    with pytest.raises(InputError, match="inside the object box"):
        voxelize(far, 8)


def test_progress_reaches_one(monkeypatch):
    monkeypatch.setattr(voxels_module, "FACES_PER_CHUNK", 50)
    seen = []
    voxelize(normalise_mesh(trimesh.creation.icosphere(subdivisions=2)), 8, progress=seen.append)  # 320 faces
    assert len(seen) == 7 and seen == sorted(seen) and seen[-1] == 1.0


# --- files -----------------------------------------------------------------------------------


def test_voxel_file_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    rgba = np.zeros((6, 6, 6, 4), dtype=np.float32)
    occ = rng.random((6, 6, 6)) < 0.3
    rgba[occ, :3] = rng.random((occ.sum(), 3))
    rgba[occ, 3] = 1.0
    save_voxels(tmp_path / "v.npz", rgba)
    with np.load(tmp_path / "v.npz") as npz:
        assert npz["rgba"].dtype == np.uint8
    back = load_voxels(tmp_path / "v.npz")
    assert back.dtype == np.float32 and back.shape == rgba.shape
    np.testing.assert_array_equal(back[..., 3], rgba[..., 3])
    assert np.abs(back - rgba).max() <= 0.5 / 255 + 1e-7


def test_voxel_file_errors(tmp_path):
    with pytest.raises(InputError, match="file not found"):
        load_voxels(tmp_path / "missing.npz")
    np.savez(tmp_path / "wrong_key.npz", colors=np.zeros((4, 4, 4, 4)))
    with pytest.raises(InputError, match="no 'rgba'"):
        load_voxels(tmp_path / "wrong_key.npz")
    np.savez(tmp_path / "wrong_shape.npz", rgba=np.zeros((4, 5, 4, 4)))
    with pytest.raises(InputError, match="shape"):
        load_voxels(tmp_path / "wrong_shape.npz")
    (tmp_path / "corrupt.npz").write_bytes(b"PK\x03\x04 this is not a zip")
    with pytest.raises(InputError, match="not a readable"):
        load_voxels(tmp_path / "corrupt.npz")
    nan = np.full((4, 4, 4, 4), np.nan, dtype=np.float32)
    np.savez(tmp_path / "nan.npz", rgba=nan)
    assert np.isfinite(load_voxels(tmp_path / "nan.npz")).all()
    with pytest.raises(InputError, match="output folder"):
        save_voxels(tmp_path / "no_such_dir" / "v.npz", np.zeros((4, 4, 4, 4)))


def test_downsampling_keeps_occupancy_and_averages_colors():
    from renderer.voxels import downsample_voxels

    fine = np.zeros((4, 4, 4, 4), np.float32)
    fine[0, 0, 0] = (1.0, 0.0, 0.0, 1.0)
    fine[1, 1, 1] = (0.0, 0.0, 1.0, 1.0)  # same coarse cell as [0, 0, 0]
    fine[3, 3, 3] = (0.0, 1.0, 0.0, 1.0)
    coarse = downsample_voxels(fine, 2)
    assert coarse.shape == (2, 2, 2, 4)
    assert np.allclose(coarse[0, 0, 0], (0.5, 0.0, 0.5, 1.0))
    assert np.allclose(coarse[1, 1, 1], (0.0, 1.0, 0.0, 1.0))
    assert coarse[..., 3].sum() == 2 and np.isfinite(coarse).all()
    # 100 -> 75 does not divide evenly: every fine voxel still lands in exactly one coarse voxel
    rng = np.random.default_rng(0)
    big = np.zeros((100, 100, 100, 4), np.float32)
    big[rng.integers(0, 100, 500), rng.integers(0, 100, 500), rng.integers(0, 100, 500)] = (0.2, 0.4, 0.6, 1.0)
    assert np.allclose(downsample_voxels(big, 75)[..., :3][downsample_voxels(big, 75)[..., 3] > 0], (0.2, 0.4, 0.6))
