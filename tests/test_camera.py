"""The camera model against hand-computed pinhole projections, and the grid convention."""

import math

import numpy as np

from renderer.camera import Camera, camera_to_grid_index, grid_centers_camera
from renderer.scene import CAMERA_DISTANCE, GRID_EXTENT, LOOK_AT


def test_look_at_point_projects_to_the_image_centre():
    for elevation in (0.0, 30.0, 89.0):
        u, v, depth = Camera(elevation, 200, 200).project(np.array(LOOK_AT))
        assert abs(u - 100.0) < 1e-9 and abs(v - 100.0) < 1e-9
        assert abs(depth - CAMERA_DISTANCE) < 1e-9


def test_projection_matches_the_pinhole_formula_at_elevation_zero():
    # At elevation 0 the camera sits at LOOK_AT + (0, 0, d) looking along -z: a point offset by
    # (dx, dy) at the look-at depth lands at centre + f * (dx, -dy) / d, f = 40 / 36 * width.
    cam = Camera(0.0, 256, 256)
    point = np.array([LOOK_AT[0] + 0.3, LOOK_AT[1] + 0.2, LOOK_AT[2]])
    u, v, _ = cam.project(point)
    f = 40.0 / 36.0 * 256
    assert abs(u - (128 + f * 0.3 / CAMERA_DISTANCE)) < 1e-9
    assert abs(v - (128 - f * 0.2 / CAMERA_DISTANCE)) < 1e-9


def test_camera_height_follows_the_elevation():
    cam = Camera(30.0)
    expected = LOOK_AT[1] + CAMERA_DISTANCE * math.sin(math.radians(30.0))
    assert abs(cam.position[1] - expected) < 1e-12


def test_world_to_camera_round_trip():
    rng = np.random.default_rng(0)
    points = rng.uniform(-2, 2, size=(100, 3))
    for elevation in (0.0, 5.0, 45.0, 89.0):
        cam = Camera(elevation, azimuth_deg=17.0)
        back = (points @ cam.world_to_camera()[:3, :3].T + cam.world_to_camera()[:3, 3]) @ cam.camera_to_world()[:3, :3].T
        back += cam.camera_to_world()[:3, 3]
        assert np.abs(back - points).max() < 1e-5


def test_pixel_rays_pass_through_projected_points():
    cam = Camera(35.0, 64, 48, principal_offset=(3.0, -2.0))
    point = np.array([0.3, 0.7, -0.2])
    u, v, depth = cam.project(point)
    origin, direction = cam.pixel_rays(u, v)
    along = np.dot(point - origin, direction)
    assert np.linalg.norm(origin + along * direction - point) < 1e-9


def test_grid_indexing_convention():
    centers = grid_centers_camera(8, GRID_EXTENT)
    # depth 0 is nearest the camera, row 0 at the top, column 0 at the left
    assert centers[0, 0, 0, 2] > centers[1, 0, 0, 2]
    assert centers[0, 0, 0, 1] > centers[0, 1, 0, 1]
    assert centers[0, 0, 0, 0] < centers[0, 0, 1, 0]
    index = camera_to_grid_index(centers[3, 5, 6], 8, GRID_EXTENT)
    assert np.allclose(index, [3.5, 5.5, 6.5])
    # the grid is centred on the look-at point
    assert np.allclose(centers.reshape(-1, 3).mean(0), [0, 0, -CAMERA_DISTANCE])
