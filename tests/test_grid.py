"""Transforms and the camera-aligned scene grid (renderer/camera.py, transform.py, grid.py)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy import ndimage

from renderer.camera import Camera, camera_to_grid_index, grid_centers_camera
from renderer.grid import (
    GridPlacement,
    colors_and_changes,
    gather,
    grid_index_to_world,
    ground_grid,
    ground_mask,
    object_cells,
    occupied_spans,
    pool_factors,
    pool_voxels,
    repool_voxels,
    sample_indices,
    scene_grid,
)
from renderer.mesh import normalise_mesh
from renderer.scene import GRID_SIZE, ObjectSpec
from renderer.transform import apply_transform, object_to_world, object_voxel_centers, world_to_object
from renderer.voxels import voxelize

FLOOR = (0.25, 0.5, 0.75)


def single_voxel(n: int, index: tuple[int, int, int], color=(0.9, 0.1, 0.2)) -> np.ndarray:
    rgba = np.zeros((n, n, n, 4), dtype=np.float32)
    rgba[index] = [*color, 1.0]
    return rgba


def object_part(grid: np.ndarray) -> np.ndarray:
    """Occupied grid voxels that are not floor colored."""
    return (grid[..., 3] > 0) & ~np.all(grid[..., :3] == np.float32(FLOOR), axis=-1)


# --- transforms --------------------------------------------------------------------------------


@pytest.mark.parametrize("elevation", [0.0, 30.0, 89.0])
def test_world_camera_world_round_trip(elevation):
    cam = Camera(elevation)
    points = np.random.default_rng(1).uniform(-3, 3, size=(100, 3))
    back = apply_transform(cam.camera_to_world(), apply_transform(cam.world_to_camera(), points))
    assert np.abs(back - points).max() < 1e-5
    # The camera sits on the +z side at the given elevation, looking at the scene centre.
    assert np.allclose(apply_transform(cam.world_to_camera(), np.array([0.0, 0.5, 0.0])), [0, 0, -cam.distance])


def test_object_placement_round_trip_and_full_turn():
    spec = ObjectSpec(mesh="m", translation=(0.3, -0.4), rotation_deg=37.0, scale=(0.8, 1.2, 1.1))
    points = np.random.default_rng(2).uniform(-1, 1, size=(50, 3))
    back = apply_transform(world_to_object(spec), apply_transform(object_to_world(spec), points))
    assert np.abs(back - points).max() < 1e-5
    turned = ObjectSpec(mesh="m", translation=(0.3, -0.4), rotation_deg=37.0 + 360.0, scale=(0.8, 1.2, 1.1))
    assert np.abs(object_to_world(turned) - object_to_world(spec)).max() < 1e-12


def test_grid_index_to_world_matches_the_camera_grid_centres():
    corners = np.array([[0, 0, 0], [127, 0, 0], [0, 127, 0], [0, 0, 127], [5, 77, 100]])
    centres_world = apply_transform(Camera(30.0).camera_to_world(), grid_centers_camera()[tuple(corners.T)])
    np.testing.assert_allclose(apply_transform(grid_index_to_world(30.0), corners + 0.5), centres_world, atol=1e-12)


# --- object resampling ------------------------------------------------------------------------


def test_single_object_voxel_lands_where_the_camera_predicts():
    # A coarse 10^3 object (voxel 0.1 = 5 grid voxels) needs no merging: plain nearest sampling.
    n, index = 10, (3, 2, 6)
    spec = ObjectSpec(mesh="m", translation=(0.1, -0.2), rotation_deg=25.0)
    assert pool_factors(n, spec.scale) == (1, 1, 1)
    grid = scene_grid(single_voxel(n, index), spec, FLOOR, 30.0)

    cam = Camera(30.0)
    centre_world = apply_transform(object_to_world(spec), object_voxel_centers(n)[index])
    d, r, c = np.floor(camera_to_grid_index(apply_transform(cam.world_to_camera(), centre_world))).astype(int)
    np.testing.assert_allclose(grid[d, r, c], [0.9, 0.1, 0.2, 1.0], atol=1e-7)

    # Independently: a grid voxel is occupied iff its centre falls in the object voxel's box.
    centres_object = apply_transform(world_to_object(spec) @ cam.camera_to_world(), grid_centers_camera())
    lo = np.array([-0.5, 0.0, -0.5]) + np.array(index) / n
    inside = np.all((centres_object >= lo) & (centres_object < lo + 1.0 / n), axis=-1)
    assert np.array_equal(object_part(grid), inside)
    assert 100 < inside.sum() < 150  # about (0.1 / 0.02)^3 = 125 grid voxels


def test_every_grid_voxel_takes_the_object_voxel_its_centre_falls_in():
    """A random 12^3 object, turned, moved and stretched: each grid voxel (outside the ground) holds the object
    voxel whose box contains its centre, found here by mapping every centre into object space one by one."""
    rng = np.random.default_rng(7)
    n = 12
    rgba = np.zeros((n, n, n, 4), dtype=np.float32)
    filled = rng.random((n, n, n)) < 0.3
    rgba[filled] = np.concatenate([rng.random((int(filled.sum()), 3)), np.ones((int(filled.sum()), 1))], axis=1)
    spec = ObjectSpec(mesh="m", translation=(-0.15, 0.2), rotation_deg=-52.0, scale=(1.1, 0.8, 1.3))
    assert pool_factors(n, spec.scale) == (1, 1, 1)
    grid = scene_grid(rgba, spec, FLOOR, 35.0)
    centres = apply_transform(world_to_object(spec) @ Camera(35.0).camera_to_world(), grid_centers_camera())
    index = np.floor((centres - np.array([-0.5, 0.0, -0.5])) * n).astype(int)
    inside = np.all((index >= 0) & (index < n), axis=-1)
    expected = np.zeros(grid.shape, dtype=np.float32)
    expected[inside] = rgba[tuple(index[inside].T)]
    not_ground = ~ground_mask(35.0)
    np.testing.assert_array_equal(grid[not_ground], expected[not_ground])
    assert expected[..., 3].sum() > 1000


def test_pool_voxels_by_hand():
    rgba = np.zeros((4, 4, 4, 4), dtype=np.float32)
    rgba[0, 0, 0] = [1.0, 0.0, 0.0, 1.0]
    rgba[1, 1, 0] = [0.0, 0.0, 1.0, 1.0]
    rgba[3, 3, 3] = [0.2, 0.4, 0.6, 1.0]
    pooled = pool_voxels(rgba, (2, 2, 2))
    assert pooled.shape == (2, 2, 2, 4)
    np.testing.assert_allclose(pooled[0, 0, 0], [0.5, 0.0, 0.5, 1.0])  # mean of its two occupied voxels
    np.testing.assert_allclose(pooled[1, 1, 1], [0.2, 0.4, 0.6, 1.0])  # empty members do not darken it
    assert pooled[..., 3].sum() == 2
    uneven = pool_voxels(rgba, (3, 1, 4))  # blocks of 3 along x: [0, 3) and the partial [3, 4)
    assert uneven.shape == (2, 4, 1, 4)
    np.testing.assert_allclose(uneven[1, 3, 0], [0.2, 0.4, 0.6, 1.0])
    np.testing.assert_allclose(uneven[0, 0, 0], [1.0, 0.0, 0.0, 1.0])


@pytest.mark.parametrize("factors", [(2, 2, 2), (3, 1, 4), (1, 2, 1), (5, 5, 5)])
def test_pool_voxels_equals_block_means(factors):
    # The reference pads each axis to whole blocks and averages each block's occupied members in float64: the
    # merge must agree to float32 rounding, count its partial last blocks, and be occupied where any member is.
    rng = np.random.default_rng(7)
    rgba = np.zeros((13, 11, 9, 4), dtype=np.float32)
    occupied = rng.random(rgba.shape[:3]) < 0.3
    rgba[occupied] = np.concatenate([rng.random((occupied.sum(), 3)), np.ones((occupied.sum(), 1))], axis=1)
    rgba[~occupied, :3] = rng.random(((~occupied).sum(), 3))  # colors of empty voxels must not count
    blocks = [-(-n // f) for n, f in zip(rgba.shape[:3], factors)]
    padded_colors = np.zeros((*(b * f for b, f in zip(blocks, factors)), 3))
    padded_occupied = np.zeros(padded_colors.shape[:3])
    padded_colors[:13, :11, :9] = rgba[..., :3] * occupied[..., None]
    padded_occupied[:13, :11, :9] = occupied
    shape = (blocks[0], factors[0], blocks[1], factors[1], blocks[2], factors[2])
    count = padded_occupied.reshape(shape).sum(axis=(1, 3, 5))
    total = padded_colors.reshape(*shape, 3).sum(axis=(1, 3, 5))
    pooled = pool_voxels(rgba, factors)
    assert pooled.shape == (*blocks, 4) and pooled.dtype == np.float32
    np.testing.assert_array_equal(pooled[..., 3], (count > 0).astype(np.float32))
    np.testing.assert_allclose(pooled[..., :3], total / np.maximum(count, 1)[..., None], rtol=1e-6, atol=1e-7)



@pytest.mark.parametrize("factors", [(2, 2, 2), (3, 1, 4), (5, 5, 5)])
def test_pooling_only_the_occupied_box_equals_pooling_every_block(factors):
    # A box of occupied voxels off the grid's middle, empty voxels with colors in it and around it: the blocks outside
    # the box are empty either way, so the merge within it alone is the same array.
    rng = np.random.default_rng(11)
    rgba = np.zeros((17, 14, 19, 4), dtype=np.float32)
    rgba[..., :3] = rng.random((17, 14, 19, 3))
    inside = np.zeros(rgba.shape[:3], dtype=bool)
    inside[5:13, 3:9, 7:18] = rng.random((8, 6, 11)) < 0.4
    rgba[inside, 3] = 1.0
    box = occupied_spans(inside)
    assert box != ((0, 17), (0, 14), (0, 19))
    np.testing.assert_array_equal(pool_voxels(rgba, factors, box), pool_voxels(rgba, factors))
    assert pool_voxels(rgba, factors)[..., 3].any()

@pytest.mark.parametrize("scale", [0.75, 1.0, 1.25])
def test_resampled_thin_shell_stays_closed(scale):
    # At resolution 64 an object voxel is thinner than a grid voxel; plain nearest sampling
    # of the one-voxel shell would leave holes. Filling the grid shell must fill its centre.
    sphere = normalise_mesh(trimesh.creation.icosphere(subdivisions=3))
    spec = ObjectSpec(mesh="m", rotation_deg=17.0, scale=(scale,) * 3)
    grid = scene_grid(voxelize(sphere, 64), spec, FLOOR, 30.0)
    centre = apply_transform(Camera(30.0).world_to_camera(), np.array([0.0, 0.5 * scale, 0.0]))
    d, r, c = np.floor(camera_to_grid_index(centre)).astype(int)
    shell = object_part(grid)
    assert not shell[d, r, c] and ndimage.binary_fill_holes(shell)[d, r, c]


# --- floor, caching and hard cases ----------------------------------------------------------------


def test_floor_is_three_voxels_below_y0_at_elevation_0():
    # At elevation 0 the grid is level: row r has world y = 0.5 + 1.28 - (r + 0.5) * 0.02,
    # which lies in [-0.06, 0) for rows 89, 90 and 91 only.
    grid = scene_grid(single_voxel(10, (5, 9, 5)), ObjectSpec(mesh="m"), FLOOR, 0.0)
    floor_rows = np.flatnonzero(np.all(grid[..., 3] == 1, axis=(0, 2)) & np.all(grid[:, :, :, 2] == np.float32(0.75), axis=(0, 2)))
    assert floor_rows.tolist() == [89, 90, 91]
    np.testing.assert_array_equal(grid[:, 89:92, :, :3], np.broadcast_to(np.float32(FLOOR), (128, 3, 128, 3)))


def test_floor_color_change_needs_only_the_gather():
    rgba = single_voxel(10, (5, 0, 5))
    spec = ObjectSpec(mesh="m", rotation_deg=10.0)
    factors = pool_factors(10, spec.scale)
    pooled = pool_voxels(rgba, factors)
    indices = sample_indices(GridPlacement(10, factors, spec, 20.0))
    for floor in [(0.0, 0.0, 0.0), (1.0, 0.5, 0.25)]:
        np.testing.assert_array_equal(gather(pooled, floor, indices), scene_grid(rgba, spec, floor, 20.0))


def sphere_voxels() -> np.ndarray:
    return voxelize(normalise_mesh(trimesh.creation.icosphere(subdivisions=2)), 32)


@pytest.mark.parametrize("elevation", [0.0, 89.0])
def test_extreme_elevations_keep_object_and_floor(elevation):
    grid = scene_grid(sphere_voxels(), ObjectSpec(mesh="m"), FLOOR, elevation)
    assert grid.shape == (GRID_SIZE,) * 3 + (4,) and grid.dtype == np.float32
    assert np.isfinite(grid).all()
    floor = np.all(grid[..., :3] == np.float32(FLOOR), axis=-1) & (grid[..., 3] == 1)
    assert floor.sum() > 128 * 128 and object_part(grid).sum() > 500


def test_object_partly_outside_the_grid_is_clipped():
    rgba = sphere_voxels()
    centred = object_part(scene_grid(rgba, ObjectSpec(mesh="m"), FLOOR, 30.0)).sum()
    moved = scene_grid(rgba, ObjectSpec(mesh="m", translation=(1.2, 0.0)), FLOOR, 30.0)  # grid half-width 1.28
    assert np.isfinite(moved).all()
    assert 0 < object_part(moved).sum() < 0.8 * centred
    far = scene_grid(rgba, ObjectSpec(mesh="m", translation=(90.0, -90.0)), FLOOR, 30.0)
    assert object_part(far).sum() == 0 and far[..., 3].sum() > 0


def test_tiny_scale_gives_at_most_a_few_voxels():
    grid = scene_grid(sphere_voxels(), ObjectSpec(mesh="m", scale=(1e-3,) * 3), FLOOR, 30.0)
    assert np.isfinite(grid).all()
    assert object_part(grid).sum() <= 8


@pytest.mark.parametrize("elevation, rotation, translation, scale", [
    (30.0, 25.0, (0.2, -0.3), (1.0, 1.0, 1.0)),
    (0.0, -140.0, (-0.9, 0.6), (0.5, 1.7, 1.2)),
    (10.0, 0.0, (3.0, 0.0), (1.0, 1.0, 1.0)),  # outside the grid: an empty window
])
def test_every_object_voxel_of_the_grid_lies_in_the_object_window(elevation, rotation, translation, scale):
    """The window the engine samples and crops to holds every grid voxel that takes an object row."""
    rgba = sphere_voxels()
    spec = ObjectSpec(translation=translation, rotation_deg=rotation, scale=scale)
    factors = pool_factors(rgba.shape[0], scale)
    empty_row = pool_voxels(rgba, factors)[..., 0].size
    placement = GridPlacement(rgba.shape[0], factors, spec, elevation)
    full = sample_indices(placement)
    box = tuple(slice(a, b) for a, b in placement.window)
    outside = full.copy()
    outside[box] = empty_row
    assert np.all(outside >= empty_row)
    assert (full[box] < empty_row).any() == (translation[0] < 2.0)  # the object is in the grid unless moved out


@pytest.mark.parametrize("elevation, rotation, translation, scale", [
    (30.0, 25.0, (0.2, -0.3), (1.0, 1.0, 1.0)),
    (0.0, -140.0, (-0.9, 0.6), (0.5, 1.7, 1.2)),
    (89.0, 60.0, (1.3, -1.2), (2.0, 2.0, 2.0)),  # partly outside the grid
    (10.0, 0.0, (3.0, 0.0), (1.0, 1.0, 1.0)),  # outside the grid: no cell
])
def test_the_ground_with_the_objects_cells_over_it_is_the_scene_grid(elevation, rotation, translation, scale):
    """What scenes of several objects join (renderer.pipeline.scene_grid_for) is, for one object, scene_grid's grid."""
    rgba = sphere_voxels()
    rgba[..., :3] = np.where(rgba[..., 3:] > 0.5, np.random.default_rng(0).random(rgba.shape[:3] + (3,)), 0.0)
    spec = ObjectSpec(translation=translation, rotation_deg=rotation, scale=scale)
    grid = ground_grid(FLOOR, elevation, 64)
    cells, rows = object_cells(rgba, spec, FLOOR, elevation, 64)
    grid.reshape(-1, 4)[cells] = rows
    np.testing.assert_array_equal(grid, scene_grid(rgba, spec, FLOOR, elevation, grid_size=64))
    assert (len(cells) > 0) == (translation[0] < 2.0)


@pytest.mark.parametrize("box, kinds", [
    ([(30, 90), (40, 110), (20, 100)], {"object", "empty", "ground"}),
    ([(0, 128), (100, 128), (0, 128)], {"empty", "ground"}),
    ([(5, 9), (5, 9), (5, 9)], {"empty"}),
])
def test_sample_indices_over_a_box_are_the_whole_grids_there(box, kinds):
    rgba = sphere_voxels()
    spec = ObjectSpec(translation=(0.1, -0.2), rotation_deg=35.0, scale=(1.0, 1.2, 0.9))
    factors = pool_factors(rgba.shape[0], spec.scale)
    empty_row = pool_voxels(rgba, factors)[..., 0].size
    placement = GridPlacement(rgba.shape[0], factors, spec, 25.0)
    full = sample_indices(placement)
    part = sample_indices(placement, box=box)
    np.testing.assert_array_equal(part, full[tuple(slice(*span) for span in box)])
    background = sample_indices(placement, box=box, with_object=False)  # the ground and empty rows alone
    np.testing.assert_array_equal(background, np.where(part > empty_row, part, empty_row))
    found = {"object": (part < empty_row).any(), "empty": (part == empty_row).any(), "ground": (part > empty_row).any()}
    assert {kind for kind, present in found.items() if present} == kinds


def test_occupied_spans_bound_the_true_entries():
    mask = np.zeros((6, 7, 8), dtype=bool)
    assert occupied_spans(mask) is None
    mask[1, 5, 2] = mask[3, 2, 6] = True
    assert occupied_spans(mask) == ((1, 4), (2, 6), (2, 7))


@pytest.mark.parametrize("factors", [(2, 2, 2), (3, 1, 2), (1, 1, 1)])
def test_repooling_after_a_change_equals_pooling_from_scratch(factors):
    """Exactly (bit for bit), with partial blocks at the far sides (11 is not a multiple of 2 or 3)."""
    rng = np.random.default_rng(sum(factors))
    before = np.zeros((11, 11, 11, 4), dtype=np.float32)
    occupied = rng.random((11, 11, 11)) < 0.4
    before[occupied] = np.concatenate([rng.random((occupied.sum(), 3)), np.ones((occupied.sum(), 1))], axis=1)
    after = before.copy()
    after[8:11, 0:3, 9:11, :3] = (0.2, 0.9, 0.4)  # a stroke in a far corner
    after[0, 5, 5] = (0.7, 0.7, 0.7, 1.0)  # a voxel that was empty
    pooled = pool_voxels(before, factors)
    every = np.arange(before[..., 0].size)
    repooled = repool_voxels(pooled, after, factors, colors_and_changes(after, every, before.reshape(-1, 4))[1])
    np.testing.assert_array_equal(repooled, pool_voxels(after, factors))
    np.testing.assert_array_equal(pooled, pool_voxels(before, factors))  # the old result is left alone
    assert len(colors_and_changes(before, every, before.reshape(-1, 4))[1]) == 0
    np.testing.assert_array_equal(repool_voxels(pooled, before, factors, np.zeros(0, dtype=int)), pooled)
    # Paint recolors occupied voxels alone: told which of them changed (the engine compares those rows only), the
    # merge is redone in place.
    painted = before.copy()
    corner = np.zeros_like(occupied)
    corner[8:11, 0:3, 9:11] = True
    painted[corner & occupied, :3] = (0.2, 0.9, 0.4)
    occupied_flat = np.flatnonzero(occupied)
    rows, changed = colors_and_changes(painted, occupied_flat, before.reshape(-1, 4)[occupied_flat])
    np.testing.assert_array_equal(rows, painted.reshape(-1, 4)[occupied_flat])
    np.testing.assert_array_equal(changed, np.flatnonzero((corner & occupied).reshape(-1)))
    in_place = pool_voxels(before, factors)
    out = repool_voxels(in_place, painted, factors, changed, in_place=True)
    assert out is in_place or factors == (1, 1, 1)  # nothing to merge: the voxels themselves
    np.testing.assert_array_equal(out, pool_voxels(painted, factors))


