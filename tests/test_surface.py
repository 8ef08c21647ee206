"""The voxel shell: surface voxels, exposed faces and the faces a viewpoint can see."""

import numpy as np

from renderer.surface import Shell, exposed, facing_exposed, facing_surface_mask, surface_mask, voxel_centers_at


def cube(n=6, lo=1, hi=5):
    occupied = np.zeros((n, n, n), bool)
    occupied[lo:hi, lo:hi, lo:hi] = True
    return occupied


def test_surface_of_a_solid_cube_is_its_shell():
    occupied = cube()
    assert surface_mask(occupied).sum() == 4**3 - 2**3
    assert not surface_mask(occupied)[2:4, 2:4, 2:4].any()
    full = np.ones((3, 3, 3), bool)  # the grid's outside counts as empty
    assert surface_mask(full).sum() == 26


def test_exposed_faces_and_facing_voxels():
    occupied = cube()
    plus_x = exposed(occupied, 0, 1)
    assert plus_x.sum() == 16 and plus_x[4].sum() == 16
    # Seen from far out on +x, level with the cube's middle: only the +x face turns towards it.
    assert np.array_equal(facing_surface_mask(occupied, np.array([100.0, 3.0, 3.0])), plus_x)
    # From a corner direction three faces are seen: 3 * 16 voxels minus shared edges (3 * 4) plus the corner.
    assert facing_surface_mask(occupied, np.array([100.0, 100.0, 100.0])).sum() == 3 * 16 - 3 * 4 + 1


def test_voxel_centres_follow_the_object_box():
    centres = voxel_centers_at(np.array([[0, 0, 0], [3, 3, 3]]), 4)
    assert np.allclose(centres, [[-0.375, 0.125, -0.375], [0.375, 0.875, 0.375]])


def test_shell_facing_is_the_union_of_facing_exposed_faces():
    rng = np.random.default_rng(0)
    occupied = rng.random((7, 8, 9)) < 0.4
    shell = Shell(occupied)
    for viewpoint in (np.array([3.5, 20.0, -4.0]), np.array([-30.0, 4.0, 4.5]), np.array([3.0, 4.0, 4.0])):
        union = np.zeros(occupied.shape, dtype=bool)
        for axis in range(3):
            for side in (-1, 1):
                union |= facing_exposed(occupied, viewpoint, axis, side)
        assert union.any()
        np.testing.assert_array_equal(shell.facing(viewpoint), np.flatnonzero(union))
