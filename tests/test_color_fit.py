"""The color objective of the pose search (renderer/capture/color_fit.py) and the refinement built on it."""

import math
from dataclasses import replace

import numpy as np
import pytest

from renderer.camera import Camera
from renderer.capture.align import (
    OUTSIDE_BOX_WEIGHT,
    WINDOW_ROTATION_DEG,
    in_box_score,
    refine_by_colors,
    refine_placement,
    rotation_error_deg,
    search_in_box,
    silhouette_iou,
)
from renderer.capture.capture import find_pose
from renderer.capture.color_fit import LEVELS, color_separation, quantised_colors
from renderer.capture.grabcut import context_window
from renderer.capture.pose import PhotoPose
from renderer.capture.silhouette import SilhouetteRenderer
from renderer.objects import generate_object


def test_colors_fall_into_their_bins():
    rgb = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], [[0.0, 0.0, 1.0], [0.5, 0.5, 0.5]]])
    bins = quantised_colors(rgb, (2, 2))
    top = LEVELS - 1
    assert bins.tolist() == [[0, top * LEVELS * LEVELS], [top, (4 * LEVELS + 4) * LEVELS + 4]]
    assert quantised_colors(np.zeros((8, 6, 3)), (4, 3)).shape == (4, 3)


def test_separation_of_known_splits():
    bins = np.zeros((4, 4), dtype=np.int64)
    bins[:, 2:] = 5  # two colors, left and right
    left = np.zeros((4, 4), dtype=bool)
    left[:, :2] = True
    assert color_separation(left, bins) == pytest.approx(1.0)  # the mask is the color
    top = np.zeros((4, 4), dtype=bool)
    top[:2] = True
    assert color_separation(top, bins) == pytest.approx(0.0, abs=1e-12)  # says nothing about it
    assert color_separation(np.zeros((4, 4), bool), bins) == 0.0
    assert color_separation(np.ones((4, 4), bool), bins) == 0.0
    # Within the region of the left column and the right one, `left` still tells the colors apart.
    region = np.zeros((4, 4), dtype=bool)
    region[:, [0, 3]] = True
    assert color_separation(left, bins, region) == pytest.approx(1.0)
    # A quarter of the pixels inside, all of one color that also fills a quarter outside: by hand, the mutual
    # information is H(inside) - H(inside | color) = H(1/4) - (1/2) ln 2, over H(1/4).
    quarter = np.zeros((4, 4), dtype=bool)
    quarter[:, 2] = True  # one column of the right color's two
    h = -(0.25 * math.log(0.25) + 0.75 * math.log(0.75))
    assert color_separation(quarter, bins) == pytest.approx((h - 0.5 * math.log(2)) / h)


def cluttered_photo(silhouette: np.ndarray, block: int, seed: int = 0) -> np.ndarray:
    """A red object with noise over `block`-pixel squares of random colors, some of them near the object's own."""
    rng = np.random.default_rng(seed)
    h, w = silhouette.shape
    blocks = rng.uniform(0.0, 1.0, (h // block + 1, w // block + 1, 3))
    blocks[rng.uniform(size=blocks.shape[:2]) < 0.15] = (0.6, 0.25, 0.2)  # background patches of a similar red
    photo = np.kron(blocks, np.ones((block, block, 1)))[:h, :w]
    photo[silhouette] = (0.8, 0.15, 0.1)
    return np.clip(photo + rng.normal(0.0, 0.03, photo.shape), 0.0, 1.0)


@pytest.fixture(scope="module")
def chair_photo():
    chair = generate_object("chair", 8).mesh
    silhouettes = SilhouetteRenderer(chair)
    truth = PhotoPose(Camera(25.0, 160, 160), rotation_deg=40.0, translation=(0.1, -0.1))
    return chair, silhouettes, truth, silhouettes.mask(truth)


def test_refining_by_colors_finds_the_pose_a_poor_mask_hides(chair_photo):
    _, silhouettes, truth, mask = chair_photo
    photo = cluttered_photo(mask, block=12)
    start = replace(truth, rotation_deg=50.0, camera=replace(truth.camera, elevation_deg=31.0), translation=(0.15, -0.05))
    poor = np.zeros_like(mask)
    rows, cols = np.nonzero(mask)
    poor[rows.min():rows.max() + 1, cols.min():cols.max() + 1] = True  # the object's box, not its shape
    region = np.zeros_like(mask)
    region[context_window((cols.min(), rows.min(), cols.max() + 1, rows.max() + 1), *mask.shape)] = True
    bins = quantised_colors(photo, mask.shape)
    larger = silhouettes.mask(replace(start, scale=(1.5,) * 3))  # takes in many distinct background colors
    assert color_separation(mask, bins, region) > color_separation(larger, bins, region) + 0.2
    found = refine_by_colors(silhouettes, photo, start, poor, region)
    assert rotation_error_deg(found.pose.rotation_deg, truth.rotation_deg) < 2.0
    assert abs(found.pose.camera.elevation_deg - truth.camera.elevation_deg) < 2.0
    assert silhouette_iou(silhouettes.mask(found.pose), mask) > 0.9
    assert found.mask is poor and found.iou == pytest.approx(silhouette_iou(silhouettes.mask(found.pose), poor), abs=0.05)


def test_refining_the_placement_keeps_the_rotation_and_fits_the_rest_to_the_mask(chair_photo):
    _, silhouettes, truth, mask = chair_photo
    plain = np.full(mask.shape + (3,), 0.5)  # colors that tell nothing: every silhouette separates them equally (0)
    start = replace(truth, camera=replace(truth.camera, elevation_deg=28.0), translation=(0.12, -0.08),
                    scale=(1.05,) * 3)
    alone = refine_by_colors(silhouettes, plain, start, mask)
    assert alone.pose == start  # nothing to gain from the colors: the pose stays
    placed = refine_placement(silhouettes, plain, start, mask)
    assert placed.pose.rotation_deg == truth.rotation_deg
    assert abs(placed.pose.camera.elevation_deg - truth.camera.elevation_deg) < 1.0
    assert placed.iou > 0.95 and placed.iou == pytest.approx(silhouette_iou(silhouettes.mask(placed.pose), mask), abs=0.03)
    turned = refine_placement(silhouettes, plain, replace(start, rotation_deg=46.0), mask)
    assert turned.pose.rotation_deg == 46.0  # the rotation is the colors' to settle, not the mask's


def test_a_boxed_capture_in_clutter_finds_the_pose(chair_photo):
    chair, silhouettes, truth, mask = chair_photo
    photo = cluttered_photo(mask, block=32)  # GrabCut's mask of it is poor (IoU 0.73): the mask alone gave a pose
    # 4 degrees off in rotation and 22 in elevation
    rows, cols = np.nonzero(mask)
    box = (cols.min() - 6, rows.min() - 6, cols.max() + 7, rows.max() + 7)
    found = find_pose(chair, photo, box=box)
    assert rotation_error_deg(found.pose.rotation_deg, truth.rotation_deg) < 3.0
    assert abs(found.pose.camera.elevation_deg - truth.camera.elevation_deg) < 3.0
    assert silhouette_iou(silhouettes.mask(found.pose), mask) > 0.9


def _box_and_region(mask: np.ndarray, margin: int) -> tuple[tuple[int, int, int, int], np.ndarray]:
    rows, cols = np.nonzero(mask)
    box = (cols.min() - margin, rows.min() - margin, cols.max() + 1 + margin, rows.max() + 1 + margin)
    region = np.zeros_like(mask)
    region[context_window(box, *mask.shape)] = True
    return box, region


def test_the_search_in_a_box_finds_the_pose_without_a_mask(chair_photo):
    _, silhouettes, truth, mask = chair_photo
    photo = cluttered_photo(mask, block=12, seed=3)
    box, region = _box_and_region(mask, margin=5)
    nothing = np.zeros_like(mask)  # the search reads no mask: one that shows nothing changes nothing
    found = search_in_box(silhouettes, photo, box, region, nothing)
    assert rotation_error_deg(found.pose.rotation_deg, truth.rotation_deg) < 3.0
    assert abs(found.pose.camera.elevation_deg - truth.camera.elevation_deg) < 3.0
    assert silhouette_iou(silhouettes.mask(found.pose), mask) > 0.9
    assert found.mask is nothing and found.iou == 0.0


def test_the_search_in_a_box_from_a_rough_pose_stays_near_it(chair_photo):
    _, silhouettes, truth, mask = chair_photo
    photo = cluttered_photo(mask, block=12, seed=3)
    box, region = _box_and_region(mask, margin=5)
    # A rough pose facing the other way: the search keeps to its window (the box alone would find the truth, as above).
    rough = replace(truth, rotation_deg=truth.rotation_deg + 180.0)
    found = search_in_box(silhouettes, photo, box, region, np.zeros_like(mask), initial=rough)
    assert rotation_error_deg(found.pose.rotation_deg, rough.rotation_deg) <= WINDOW_ROTATION_DEG + 10.0
    near = replace(truth, rotation_deg=truth.rotation_deg + 25.0)
    found = search_in_box(silhouettes, photo, box, region, np.zeros_like(mask), initial=near)
    assert rotation_error_deg(found.pose.rotation_deg, truth.rotation_deg) < 3.0


def test_the_score_in_a_box_keeps_the_silhouette_inside_it(chair_photo):
    _, silhouettes, truth, mask = chair_photo
    photo = cluttered_photo(mask, block=12, seed=3)
    box, region = _box_and_region(mask, margin=5)
    true_score = in_box_score(silhouettes, photo, box, region, truth)
    assert true_score > 0.5
    # The same silhouette moved so that about half of it leaves the box loses about half the weight.
    moved = replace(truth, translation=(truth.translation[0] + 0.35, truth.translation[1]))
    moved_mask = silhouettes.mask(moved)
    rows, cols = np.nonzero(moved_mask)
    outside = np.mean(cols >= box[2])
    assert 0.2 < outside < 0.8
    assert in_box_score(silhouettes, photo, box, region, moved) < true_score - OUTSIDE_BOX_WEIGHT * outside + 0.2
    # A silhouette that is not there at all scores the least.
    gone = replace(truth, translation=(50.0, 50.0))
    assert in_box_score(silhouettes, photo, box, region, gone) == -OUTSIDE_BOX_WEIGHT
