"""Coloring voxels from a photo, checked against photos of boxes rendered by an independent
analytic ray caster: recovered colors, visibility, the hidden voxels' rules (blend, first visible) and the
mirror rule."""

import numpy as np
import pytest

from renderer.camera import Camera
from renderer.dataset_config import HIDDEN_RULES
from renderer.errors import InputError
from renderer.photo import color_voxels_from_photo, is_mirror_symmetric, mirror_symmetry_score
from renderer.scene import ObjectSpec
from renderer.transform import object_to_world

N = 12
BACKGROUND = (0.5, 0.5, 0.5)
TOLERANCE = 0.01  # sampled far from color edges, bilinear interpolation returns the face color itself
# Face colors of a box, keyed by (axis, side): axis 0 = x, 1 = y, 2 = z; side +1 faces +axis.
FACES = {(0, -1): (0.6, 0.1, 0.7), (0, 1): (0.1, 0.8, 0.2), (1, -1): (0.3, 0.3, 0.3),
         (1, 1): (0.1, 0.2, 0.9), (2, -1): (0.9, 0.9, 0.1), (2, 1): (0.9, 0.1, 0.1)}


UNMOVED = ObjectSpec(voxels="v")


class Box:
    """Voxels [lo, hi) of the N^3 object grid; its object-space bounds follow x, z in [-0.5, 0.5], y in [0, 1]."""

    def __init__(self, lo, hi, faces=FACES):
        self.lo_idx, self.hi_idx, self.faces = np.array(lo), np.array(hi), faces
        offset = np.array([-0.5, 0.0, -0.5])
        self.lo, self.hi = offset + self.lo_idx / N, offset + self.hi_idx / N

    def fill(self, rgba):
        (a, b, c), (d, e, f) = self.lo_idx, self.hi_idx
        rgba[a:d, b:e, c:f] = (0.0, 0.0, 0.0, 1.0)


def first_face(origin, direction, boxes):
    """Per ray (object space): color of the first box face hit, hit point, and whether anything was hit."""
    d = np.where(np.abs(direction) < 1e-12, 1e-12, direction)
    best_t = np.full(len(origin), np.inf)
    color = np.tile(np.float64(BACKGROUND), (len(origin), 1))
    for box in boxes:
        t0, t1 = (box.lo - origin) / d, (box.hi - origin) / d
        near, far = np.minimum(t0, t1), np.maximum(t0, t1)
        t_in, t_out = near.max(axis=1), far.min(axis=1)
        axis = near.argmax(axis=1)
        side = -np.sign(d[np.arange(len(d)), axis])  # the entered face looks back along the ray
        hit = (t_in <= t_out) & (t_in > 0) & (t_in < best_t)
        for (ax, sd), c in box.faces.items():
            color[hit & (axis == ax) & (side == sd)] = c
        best_t[hit] = t_in[hit]
    return color, origin + best_t[:, None] * direction, np.isfinite(best_t)


def to_object(matrix, camera, world_dirs):
    inv = np.linalg.inv(matrix)
    return inv[:3, :3] @ camera.position + inv[:3, 3], world_dirs @ inv[:3, :3].T


def photograph(boxes, matrix, camera):
    rows, cols = np.mgrid[0 : camera.height, 0 : camera.width]
    _, dirs = camera.pixel_rays(cols.ravel() + 0.5, rows.ravel() + 0.5)
    origin, d = to_object(matrix, camera, dirs)
    color, _, _ = first_face(np.broadcast_to(origin, d.shape), d, boxes)
    return color.reshape(camera.height, camera.width, 3)


def voxel_rays(indices, matrix, camera):
    """Object-space rays from the camera through the given voxels' centres."""
    centres = np.array([-0.5, 0.0, -0.5]) + (np.asarray(indices) + 0.5) / N
    origin = to_object(matrix, camera, np.zeros((1, 3)))[0]
    d = centres - origin
    return np.broadcast_to(origin, d.shape), d / np.linalg.norm(d, axis=1, keepdims=True)


def scene(boxes, camera, spec=UNMOVED):
    rgba = np.zeros((N, N, N, 4), np.float32)
    for box in boxes:
        box.fill(rgba)
    matrix = object_to_world(spec)
    return rgba, matrix, photograph(boxes, matrix, camera)


def test_visible_voxels_recover_their_face_colors():
    # Seen from the front right and above, the box shows its +x, +y and +z faces.
    box = Box((2, 0, 2), (10, 8, 10))
    camera = Camera(35.0, width=320, height=256, azimuth_deg=40.0, principal_offset=(10.0, -6.0))
    spec = ObjectSpec(voxels="v", translation=(0.1, -0.05), rotation_deg=10.0)
    rgba, matrix, photo = scene([box], camera, spec)
    result = color_voxels_from_photo(rgba, matrix, photo, camera)
    i, j, k = np.indices((N, N, N))
    occupied = rgba[..., 3] > 0
    on_face = {(0, 1): occupied & (i == 9), (1, 1): occupied & (j == 7), (2, 1): occupied & (k == 9)}
    assert np.array_equal(result.visible, on_face[0, 1] | on_face[1, 1] | on_face[2, 1])
    faces_touched = sum(m.astype(int) for m in (i == 2, i == 9, j == 0, j == 7, k == 2, k == 9))
    for (axis, side), mask in on_face.items():
        inner = mask & (faces_touched == 1)  # on this face only, away from the box edges
        assert inner.sum() >= 36
        error = np.abs(result.rgba[inner, :3] - np.float32(FACES[axis, side])).max()
        assert error < TOLERANCE, (axis, side, error)
    assert np.array_equal(result.rgba[..., 3], rgba[..., 3])


@pytest.mark.parametrize("rule", HIDDEN_RULES)
def test_hidden_voxels_behind_a_one_colored_face_take_its_color(rule):
    front = Box((1, 0, 8), (11, 12, 10))
    back = Box((4, 2, 2), (8, 6, 4), faces={key: (0.0, 1.0, 1.0) for key in FACES})
    camera = Camera(20.0, width=160, height=160)
    rgba, matrix, photo = scene([front, back], camera)
    result = color_voxels_from_photo(rgba, matrix, photo, camera, hidden_rule=rule)
    behind = np.zeros((N, N, N), bool)
    behind[4:8, 2:6, 2:4] = True
    assert not result.visible[behind].any()
    assert np.abs(result.rgba[behind, :3] - np.float32(FACES[2, 1])).max() < TOLERANCE


def test_mirror_copies_the_visible_side_and_otherwise_the_first_visible_voxel():
    box = Box((2, 0, 2), (10, 8, 10))  # symmetric about x = 0: i -> 11 - i maps 2..9 to itself
    camera = Camera(20.0, width=256, height=256, azimuth_deg=60.0)
    rgba, matrix, photo = scene([box], camera)
    hidden_side = np.zeros((N, N, N), bool)
    hidden_side[2, 1:7, 3:9] = True  # the -x face, away from its edges; its mirror is the visible +x face

    mirrored = color_voxels_from_photo(rgba, matrix, photo, camera, mirror=True)
    assert not mirrored.visible[hidden_side].any() and mirrored.visible[::-1][hidden_side].all()
    assert np.abs(mirrored.rgba[hidden_side, :3] - np.float32(FACES[0, 1])).max() < TOLERANCE

    plain = color_voxels_from_photo(rgba, matrix, photo, camera, mirror=False, hidden_rule="ray")
    origin, d = voxel_rays(np.argwhere(hidden_side), matrix, camera)
    expected, hit_point, _ = first_face(origin, d, [box])
    in_face = (hit_point - box.lo) * N, (box.hi - hit_point) * N
    away_from_edges = np.sort(np.minimum(*in_face), axis=1)[:, 1] >= 1.0  # both in-face margins >= 1 voxel
    assert away_from_edges.sum() >= 10
    got = plain.rgba[hidden_side, :3]
    assert np.abs(got[away_from_edges] - expected[away_from_edges]).max() < TOLERANCE
    assert not np.allclose(expected, FACES[0, 1])  # the two rules really differ here


def test_symmetry_score():
    occupancy = np.zeros((N, N, N), bool)
    occupancy[2:10, 0:5, 3:7] = True  # mirror i -> 11 - i keeps 2..9
    assert mirror_symmetry_score(occupancy) == 1.0 and is_mirror_symmetric(occupancy)
    shifted = np.zeros((N, N, N), bool)
    shifted[3:11] = True  # mirror covers 1..8: intersection 3..8 (6), union 1..10 (10)
    assert mirror_symmetry_score(shifted) == pytest.approx(0.6) and not is_mirror_symmetric(shifted)
    one_side = np.zeros((N, N, N), bool)
    one_side[0:5] = True
    assert mirror_symmetry_score(one_side) == 0.0
    assert mirror_symmetry_score(np.zeros((N, N, N), bool)) == 1.0


def test_photo_of_the_wrong_size_is_rejected():
    rgba = np.zeros((N, N, N, 4), np.float32)
    with pytest.raises(InputError, match="100x80 pixels"):
        color_voxels_from_photo(rgba, np.eye(4), np.zeros((80, 100, 3)), Camera(30.0, 128, 128))


@pytest.mark.parametrize("rule", HIDDEN_RULES)
def test_degenerate_inputs_give_finite_colors(rule):
    camera = Camera(30.0, width=40, height=30)
    photo = np.random.default_rng(0).uniform(size=(30, 40, 3))
    empty = np.zeros((N, N, N, 4), np.float32)
    result = color_voxels_from_photo(empty, np.eye(4), photo, camera, mirror=True, hidden_rule=rule)
    assert np.array_equal(result.rgba, empty) and not result.visible.any()
    box = np.zeros((N, N, N, 4), np.float32)
    Box((2, 0, 2), (10, 8, 10)).fill(box)
    for spec in (ObjectSpec(voxels="v", translation=(5.0, 0.0)),  # outside the photo
                 ObjectSpec(voxels="v", scale=(30.0, 30.0, 30.0)),  # the camera inside the object
                 ObjectSpec(voxels="v", scale=(1e-6, 1e-6, 1e-6))):
        result = color_voxels_from_photo(box, object_to_world(spec), photo, camera, mirror=True, hidden_rule=rule)
        colors = result.rgba[box[..., 3] > 0, :3]
        assert np.isfinite(colors).all() and colors.min() >= 0 and colors.max() <= 1
    outside = color_voxels_from_photo(box, object_to_world(ObjectSpec(voxels="v", translation=(5.0, 0.0))), photo, camera,
                                      hidden_rule=rule)
    assert not outside.visible.any()


def test_blend_gives_hidden_voxels_the_mean_of_a_striped_face_not_copies_of_its_stripes():
    """A photo of stripes one voxel wide on the face it shows: hidden voxels deep behind it get about the stripes'
    mean (the expected color of what the photo does not show), where the paper's ray rule copies the stripes."""
    n = 24
    rgba = np.zeros((n, n, n, 4), np.float32)
    rgba[4:20, 0:16, 4:20, 3] = 1.0
    camera = Camera(0.0, width=192, height=192)  # straight at the +z face
    matrix = np.eye(4)
    red, green = np.array([0.9, 0.1, 0.1]), np.array([0.1, 0.8, 0.2])
    u, v, _ = camera.project(np.array([[-0.5, 0.0, 0.5], [0.5, 0.0, 0.5]]))
    columns = np.arange(camera.width) + 0.5
    stripe = np.floor((columns - u[0]) / ((u[1] - u[0]) / n)).astype(int) % 2  # which voxel column, by parity
    photo = np.where(stripe[None, :, None] == 0, red, green) * np.ones((camera.height, 1, 1))
    deep = np.zeros((n, n, n), bool)
    deep[6:18, 2:14, 4:10] = True  # the back half, 10+ voxels behind the face, away from the sides
    mean = (red + green) / 2
    blend = color_voxels_from_photo(rgba, matrix, photo, camera)
    assert not blend.visible[deep].any()
    assert np.abs(blend.rgba[deep, :3] - mean).max() < 0.1
    ray = color_voxels_from_photo(rgba, matrix, photo, camera, hidden_rule="ray")
    assert np.abs(ray.rgba[deep, :3] - mean).max() > 0.3  # the rules really differ here


def test_an_unknown_hidden_rule_is_refused():
    with pytest.raises(InputError, match="unknown rule for hidden voxels"):
        color_voxels_from_photo(np.zeros((N, N, N, 4), np.float32), np.eye(4), np.zeros((8, 8, 3)), Camera(30.0, 8, 8),
                                hidden_rule="nearest")


@pytest.mark.parametrize("sigma", [1.5, 6.0, 24.0])
def test_pooled_blur_reads_the_whole_grids_blur(sigma):
    """The blend's blur, cropped around the voxels it reads and pooled from coarser grids kept between calls, equals
    the whole grid pooled in one step (zero past its end) and blurred, at those voxels."""
    from scipy import ndimage

    from renderer.photo import HIDDEN_TRUNCATE, _pooled_blur

    rng = np.random.default_rng(3)
    n = 37  # no block size divides it: the padding counts
    sums = (rng.random((n, n, n, 4)) * (rng.random((n, n, n, 1)) < 0.1)).astype(np.float32)
    reads = np.zeros((n, n, n), dtype=bool)
    reads[14:22, 3:9, 20:30] = rng.random((8, 6, 10)) < 0.3  # a cluster: the crop around it is smaller than the grid
    index = np.nonzero(reads)
    block = max(1, int(sigma // 3))
    padded = np.zeros((-(-n // block) * block,) * 3 + (4,), np.float32)
    padded[:n, :n, :n] = sums
    m = padded.shape[0] // block
    pooled = padded.reshape(m, block, m, block, m, block, 4).mean(axis=(1, 3, 5))
    expected = ndimage.gaussian_filter(pooled, (sigma / block,) * 3 + (0,), truncate=HIDDEN_TRUNCATE)
    expected = expected[index[0] // block, index[1] // block, index[2] // block]
    kept: dict = {}
    if block > 1:
        _pooled_blur(sums, sigma / 2, index, kept)  # a finer grid kept from a narrower blur, as the blend calls it
    np.testing.assert_allclose(_pooled_blur(sums, sigma, index, kept), expected, rtol=1e-5, atol=1e-7)
