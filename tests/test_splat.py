"""Splatting against a hand-written pinhole camera: voxel positions, depth order, hole-free
silhouettes, the floor / background split, and degenerate placements."""

import math

import numpy as np
from scipy.spatial import ConvexHull

from renderer.camera import Camera
from renderer.scene import ObjectSpec, Scene
from renderer.splat import background_color, splat, splat_scene
from renderer.transform import object_to_world

FLOOR = (0.2, 0.7, 0.3)
RED = (0.9, 0.1, 0.1)
BLUE = (0.1, 0.2, 0.9)
DISTANCE, LOOK_AT_Y, FOCAL_OVER_SENSOR = 2.8, 0.5, 40.0 / 36.0


def hand_camera(elevation_deg: float):
    """Camera centre and (right, up, forward) axes of the render camera, from the geometry alone."""
    e = math.radians(elevation_deg)
    eye = np.array([0.0, LOOK_AT_Y + DISTANCE * math.sin(e), DISTANCE * math.cos(e)])
    forward = np.array([0.0, -math.sin(e), -math.cos(e)])
    right = np.array([1.0, 0.0, 0.0])
    up = np.array([0.0, math.cos(e), -math.sin(e)])
    return eye, right, up, forward


def hand_project(points, elevation_deg: float, size: int):
    """Pixel coordinates (u, v) of world points: u = cx + f x / depth, v = cy - f y / depth."""
    eye, right, up, forward = hand_camera(elevation_deg)
    rel = np.atleast_2d(points) - eye
    f = FOCAL_OVER_SENSOR * size
    depth = rel @ forward
    return size / 2 + f * (rel @ right) / depth, size / 2 - f * (rel @ up) / depth


def hand_floor_mask(elevation_deg: float, size: int) -> np.ndarray:
    """Pixels whose ray meets y = 0 inside |x|, |z| <= 10."""
    eye, right, up, forward = hand_camera(elevation_deg)
    f = FOCAL_OVER_SENSOR * size
    rows, cols = np.mgrid[0:size, 0:size]
    x = (cols + 0.5 - size / 2) / f
    y = -(rows + 0.5 - size / 2) / f
    d = x[..., None] * right + y[..., None] * up + forward
    down = d[..., 1] < 0
    t = np.where(down, -eye[1] / np.where(down, d[..., 1], -1.0), 0.0)
    hx, hz = eye[0] + t * d[..., 0], eye[2] + t * d[..., 2]
    return down & (np.abs(hx) <= 10.0) & (np.abs(hz) <= 10.0)


def voxels(n: int, cells: dict) -> np.ndarray:
    rgba = np.zeros((n, n, n, 4), np.float32)
    for (i, j, k), color in cells.items():
        rgba[i, j, k] = (*color, 1.0)
    return rgba


def centre(i, j, k, n):
    """Object-space centre of voxel (i, j, k): box x, z in [-0.5, 0.5], y in [0, 1]."""
    return np.array([-0.5 + (i + 0.5) / n, (j + 0.5) / n, -0.5 + (k + 0.5) / n])


def is_color(image, color):
    return np.all(np.abs(image - np.float32(color)) < 1e-6, axis=-1)


def test_one_voxel_lands_on_the_pinhole_pixel():
    n, size, elevation = 8, 128, 30.0
    image = splat(voxels(n, {(5, 2, 6): RED}), np.eye(4), FLOOR, Camera(elevation, size, size))
    u, v = hand_project(centre(5, 2, 6, n), elevation, size)
    assert is_color(image[int(v[0]), int(u[0])], RED)
    assert is_color(image[int(v[0]) + 20, int(u[0])], FLOOR)


def test_placement_follows_the_scene_object():
    # Rotation by 90 degrees maps object (x, y, z) to world (z, y, -x), then the x/z translation applies.
    n, size = 8, 128
    scene = Scene.single(object=ObjectSpec(voxels="v.npz", rotation_deg=90.0, translation=(0.2, -0.1)),
                  image_size=size)
    x, y, z = centre(1, 3, 6, n)
    u, v = hand_project(np.array([z + 0.2, y, -x - 0.1]), scene.camera.elevation_deg, size)
    image = splat_scene(scene, voxels(n, {(1, 3, 6): BLUE}), FLOOR)
    assert is_color(image[int(v[0]), int(u[0])], BLUE)


def test_front_voxel_hides_the_one_behind_it():
    # At elevation 0 the camera looks along -z: the voxel with the larger k is in front.
    n, size = 8, 128
    for front, back in ((RED, BLUE), (BLUE, RED)):
        image = splat(voxels(n, {(4, 4, 6): front, (4, 4, 2): back}), np.eye(4), FLOOR, Camera(0.0, size, size))
        u, v = hand_project(centre(4, 4, 6, n), 0.0, size)
        assert is_color(image[int(v[0]), int(u[0])], front)
        assert not is_color(image, back).any()


def test_solid_box_silhouette_has_no_holes():
    n, size, elevation = 16, 96, 30.0
    rgba = np.zeros((n, n, n, 4), np.float32)
    rgba[2:14, 0:10, 3:13] = (*RED, 1.0)
    spec = ObjectSpec(voxels="v.npz", rotation_deg=35.0, scale=(1.2, 0.8, 1.0), translation=(0.1, 0.0))
    matrix = object_to_world(spec)
    lo, hi = np.array([-0.5 + 2 / n, 0.0, -0.5 + 3 / n]), np.array([-0.5 + 14 / n, 10 / n, -0.5 + 13 / n])
    corners = np.array([[a, b, c] for a in (lo[0], hi[0]) for b in (lo[1], hi[1]) for c in (lo[2], hi[2])])
    u, v = hand_project(corners @ matrix[:3, :3].T + matrix[:3, 3], elevation, size)
    hull = ConvexHull(np.stack([u, v], axis=1))
    rows, cols = np.mgrid[0:size, 0:size]
    pixels = np.stack([cols.ravel() + 0.5, rows.ravel() + 0.5, np.ones(size * size)], axis=1)
    signed = (pixels @ hull.equations.T).max(axis=1).reshape(size, size)  # > 0 outside, distance in pixels
    image = splat(rgba, matrix, FLOOR, Camera(elevation, size, size))
    red = is_color(image, RED)
    assert red[signed < -0.25].all()  # every pixel inside the silhouette (a quarter pixel of slack)
    assert not red[signed > 1.0].any()  # and nothing beyond the voxels' projected extent
    assert (signed < -0.25).sum() > 900  # the test looks at a real area


def test_floor_below_the_horizon_and_background_above_at_elevation_zero():
    # At elevation 0 the eye is 0.5 above the floor, 2.8 in front of the look-at point; a ray
    # dropping by (v - cy) / f per unit of depth meets the floor 0.5 f / (v - cy) ahead, which
    # lies on the floor square (z >= -10) while that distance is at most 12.8.
    size = 256
    image = splat(np.zeros((4, 4, 4, 4), np.float32), np.eye(4), FLOOR, Camera(0.0, size, size))
    f = FOCAL_OVER_SENSOR * size
    first_floor_row = math.ceil(size / 2 + 0.5 * f / 12.8 - 0.5)
    column = image[:, size // 2]
    assert is_color(column[first_floor_row:], FLOOR).all()
    assert is_color(column[:first_floor_row], background_color()).all()


def test_floor_region_matches_hand_rays():
    size = 64
    for elevation in (0.0, 10.0, 30.0, 89.0):
        image = splat(np.zeros((4, 4, 4, 4), np.float32), np.eye(4), FLOOR, Camera(elevation, size, size))
        expected = hand_floor_mask(elevation, size)
        assert np.array_equal(is_color(image, FLOOR), expected)
        assert np.array_equal(is_color(image, background_color()), ~expected)
    assert hand_floor_mask(89.0, size).all()  # looking down, the floor fills the view


def test_object_covers_the_floor_seen_from_above():
    n, size = 8, 64
    rgba = np.zeros((n, n, n, 4), np.float32)
    rgba[:, 0:2] = (*RED, 1.0)  # a flat slab on the floor, the full object footprint
    image = splat(rgba, np.eye(4), FLOOR, Camera(89.0, size, size))
    u, v = hand_project(np.array([[0.0, 0.25, 0.0], [0.6, 0.0, 0.6]]), 89.0, size)
    assert is_color(image[int(v[0]), int(u[0])], RED)
    assert is_color(image[int(v[1]), int(u[1])], FLOOR)


def test_empty_object_shows_floor_and_background_only():
    image = splat(np.zeros((8, 8, 8, 4), np.float32), np.eye(4), FLOOR, Camera(30.0, 32, 32))
    assert image.shape == (32, 32, 3) and image.dtype == np.float32
    assert (is_color(image, FLOOR) | is_color(image, background_color())).all()


def test_degenerate_placements_give_finite_images():
    rgba = np.zeros((8, 8, 8, 4), np.float32)
    rgba[1:7, 1:7, 1:7] = (*RED, 1.0)
    camera = Camera(0.0, 48, 48)
    cases = {
        "half outside the view": ObjectSpec(voxels="v", translation=(1.3, 0.0)),
        "behind the camera": ObjectSpec(voxels="v", translation=(0.0, 4.0)),
        "around the camera": ObjectSpec(voxels="v", translation=(0.0, 2.8), scale=(3.0, 3.0, 3.0)),
        "huge": ObjectSpec(voxels="v", scale=(40.0, 40.0, 40.0)),
        "tiny": ObjectSpec(voxels="v", scale=(1e-6, 1e-6, 1e-6)),
    }
    red = {}
    for name, spec in cases.items():
        image = splat(rgba, object_to_world(spec), FLOOR, camera)
        assert np.isfinite(image).all() and image.min() >= 0 and image.max() <= 1, name
        red[name] = is_color(image, RED)
    assert red["half outside the view"][:, -1].any() and not red["half outside the view"][:, :20].any()
    assert not red["behind the camera"].any()
    assert 1 <= red["tiny"].sum() <= 4


def test_the_layout_does_not_depend_on_how_many_threads_split_the_shell(monkeypatch):
    # Each thread splats a run of the shell into its own buffer and the runs are merged in shell order: the image must
    # be the single pass's, ties included (at elevation 0 a slab's voxels share one depth and overlap).
    from renderer import splat as splat_module
    from renderer.surface import Shell

    rng = np.random.default_rng(3)
    n = 24
    occupied = np.zeros((n, n, n), bool)
    occupied[4:20, 0:14, 9:13] = True  # a slab facing the elevation-0 camera
    occupied |= rng.random((n, n, n)) < 0.08  # and scattered voxels in front of and behind it
    shell = Shell(occupied)
    matrix = object_to_world(ObjectSpec(voxels="v.npz", rotation_deg=20.0, scale=(1.2, 0.9, 1.0)))
    for elevation in (0.0, 35.0):
        camera = Camera(elevation, 72, 72)
        layouts = {}
        for runs in (1, 2, 3, 7):
            monkeypatch.setattr(splat_module.numba, "get_num_threads", lambda runs=runs: runs)
            layouts[runs] = splat_module.splat_layout(shell, matrix, camera).voxel
        assert (layouts[1] >= 0).sum() > 500
        for runs in (2, 3, 7):
            np.testing.assert_array_equal(layouts[runs], layouts[1])
