"""Ray marching through occupancy: the skipping marcher against plain half-voxel stepping,
grid coordinates, and visibility of thin walls and grazing faces."""

import numpy as np

from renderer.raymarch import MARCH_STEP, OccupancyMarcher
from renderer.scene import ObjectSpec
from renderer.surface import grid_from_world
from renderer.transform import object_to_world


def plain_march(occupied, origin, direction, t_first, t_last):
    """Reference: test every sample t_first + m * MARCH_STEP <= t_last in turn."""
    n = occupied.shape[0]
    t = t_first
    while t <= t_last + 1e-9:
        ijk = np.floor(origin + direction * t).astype(int)
        if np.all((ijk >= 0) & (ijk < n)) and occupied[tuple(ijk)]:
            return int(np.ravel_multi_index(tuple(ijk), occupied.shape))
        t += MARCH_STEP
    return -1


def test_skipping_gives_the_same_hits_as_plain_marching():
    rng = np.random.default_rng(3)
    n = 16
    occupied = np.zeros((n, n, n), bool)
    occupied[rng.integers(0, n, 60), rng.integers(0, n, 60), rng.integers(0, n, 60)] = True
    occupied[10:14, 2:6, 3:12] = True
    origin = rng.uniform(-8, n + 8, size=(400, 3))
    direction = rng.uniform(0, n, size=(400, 3)) - origin  # towards random points of the grid
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    t_first = rng.uniform(0, 1, 400)
    t_last = t_first + rng.uniform(0, 40, 400)
    got = OccupancyMarcher(occupied).first_occupied(origin, direction, t_first, t_last)
    expected = [plain_march(occupied, *args) for args in zip(origin, direction, t_first, t_last)]
    assert np.array_equal(got, expected)
    assert (got >= 0).sum() > 50 and (got < 0).sum() > 50  # both outcomes are exercised


def test_grid_coordinates_put_voxel_centres_at_half_integers():
    n = 10
    matrix = object_to_world(ObjectSpec(voxels="v", translation=(0.3, -0.2), rotation_deg=25.0, scale=(1.1, 0.9, 1.2)))
    centre_object = np.array([-0.5 + 3.5 / n, 7.5 / n, -0.5 + 1.5 / n])  # voxel (3, 7, 1)
    world = matrix[:3, :3] @ centre_object + matrix[:3, 3]
    to_grid = grid_from_world(matrix, n)
    assert np.allclose(to_grid[:3, :3] @ world + to_grid[:3, 3], [3.5, 7.5, 1.5])


def test_wall_hides_what_is_behind_it_and_grazing_faces_stay_visible():
    n = 12
    occupied = np.zeros((n, n, n), bool)
    occupied[:, 0:2, :] = True  # a slab on the floor
    occupied[2:10, 4:8, 8] = True  # a one-voxel wall ...
    occupied[5, 5, 4] = True  # ... with a voxel behind it, seen from +z
    camera = np.array([6.0, 6.0, 60.0])
    marcher = OccupancyMarcher(occupied)
    visible = marcher.visible_from(camera)
    assert visible[5, 5, 8] and not visible[5, 5, 4]
    # The slab top is seen at about 4 degrees; away from the wall's shadow it stays visible.
    assert visible[:, 1, 9:].all()
    assert not visible[:, 0, :-1].any()  # the lower layer shows only its front face
    hit = marcher.first_occupied_towards(camera, np.array([np.ravel_multi_index((5, 5, 4), occupied.shape)]))
    assert hit[0] == np.ravel_multi_index((5, 5, 8), occupied.shape)
