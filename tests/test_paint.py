"""Bucket fill on object voxels and paint replay (renderer/paint.py)."""

from __future__ import annotations

import numpy as np
import pytest

from renderer.errors import InputError
from renderer.paint import apply_paint, fill_object, fill_region, occupied_voxels
from renderer.scene import PaintOp

GRAY, NEAR_GRAY, RED = (0.5, 0.5, 0.5), (0.55, 0.5, 0.5), (1.0, 0.0, 0.0)


def hand_grid() -> np.ndarray:
    """An 8^3 grid with, in gray: blob A (a 2x2x2 cube at the corner), blob B (a bar far
    from A), a voxel touching A only along an edge; and a near-gray slab face-adjacent to A."""
    rgba = np.zeros((8, 8, 8, 4), dtype=np.float32)
    rgba[0:2, 0:2, 0:2] = [*GRAY, 1.0]  # blob A
    rgba[5:8, 6, 6] = [*GRAY, 1.0]  # blob B: same color, not connected
    rgba[2, 2, 1] = [*GRAY, 1.0]  # shares only an edge with A's voxel (1, 1, 1)
    rgba[0:2, 0:2, 2] = [*NEAR_GRAY, 1.0]  # touches A face to face, 0.05 away in color
    return rgba


def painted(before: np.ndarray, after: np.ndarray) -> set[tuple[int, ...]]:
    return set(map(tuple, np.argwhere(np.any(before != after, axis=-1)).tolist()))


def test_fill_touches_exactly_the_connected_similar_region():
    rgba = hand_grid()
    original = rgba.copy()
    out = fill_region(rgba, (0, 0, 0), RED, tolerance=0.01)
    blob_a = {(i, j, k) for i in range(2) for j in range(2) for k in range(2)}
    assert painted(rgba, out) == blob_a
    np.testing.assert_array_equal(out[0, 1, 0], [*RED, 1.0])
    np.testing.assert_array_equal(rgba, original)  # input untouched


def test_tolerance_decides_whether_a_near_color_joins():
    rgba = hand_grid()
    slab = {(i, j, 2) for i in range(2) for j in range(2)}
    blob_a = {(i, j, k) for i in range(2) for j in range(2) for k in range(2)}
    assert painted(rgba, fill_region(rgba, (1, 1, 1), RED, tolerance=0.05)) == blob_a | slab  # inclusive
    assert painted(rgba, fill_region(rgba, (1, 1, 1), RED, tolerance=0.049)) == blob_a


def test_fill_from_the_other_blob_leaves_the_first_alone():
    rgba = hand_grid()
    assert painted(rgba, fill_region(rgba, (6, 6, 6), RED, tolerance=0.5)) == {(5, 6, 6), (6, 6, 6), (7, 6, 6)}


def test_bad_seeds_are_input_errors():
    rgba = hand_grid()
    with pytest.raises(InputError, match="outside the 8x8x8 object grid"):
        fill_region(rgba, (8, 0, 0), RED, 0.1)
    with pytest.raises(InputError, match="outside"):
        fill_region(rgba, (-1, 0, 0), RED, 0.1)
    with pytest.raises(InputError, match="empty voxel"):
        fill_region(rgba, (4, 4, 4), RED, 0.1)


def test_fill_object_paints_only_occupied_voxels():
    rgba = hand_grid()
    out = fill_object(rgba, RED)
    occupied = rgba[..., 3] == 1
    np.testing.assert_array_equal(out[occupied], np.tile([*RED, 1.0], (occupied.sum(), 1)))
    np.testing.assert_array_equal(out[~occupied], 0.0)
    assert not np.array_equal(rgba[occupied], out[occupied])  # the input kept its colors


def test_apply_paint_replays_in_order():
    rgba = hand_grid()
    blue, green = (0.0, 0.0, 1.0), (0.0, 1.0, 0.0)
    ops = [
        PaintOp("object", RED),
        PaintOp("region", blue, seed=(6, 6, 6), tolerance=0.0),  # all gray became red: only blob B is connected
        PaintOp("floor", green),
        PaintOp("floor", blue),
    ]
    out, floor = apply_paint(rgba, (0.5, 0.5, 0.5), ops)
    assert floor == blue
    np.testing.assert_array_equal(out[5:8, 6, 6, :3], np.tile(blue, (3, 1)))
    np.testing.assert_array_equal(out[0:2, 0:2, 0:3, :3].reshape(-1, 3), np.tile(RED, (12, 1)))
    assert apply_paint(rgba, (0.1, 0.2, 0.3), [])[1] == (0.1, 0.2, 0.3)


def flood_fill(rgba: np.ndarray, seed: tuple[int, int, int], tolerance: float) -> set[tuple[int, ...]]:
    """The region by a plain breadth-first walk over face neighbours (independent of renderer/paint.py)."""
    reference = rgba[seed][:3]
    region, frontier = {seed}, [seed]
    while frontier:
        voxel = frontier.pop()
        for axis in range(3):
            for step in (-1, 1):
                near = list(voxel)
                near[axis] += step
                near = tuple(near)
                if (near not in region and all(0 <= i < n for i, n in zip(near, rgba.shape))
                        and rgba[near][3] >= 0.5 and np.abs(rgba[near][:3] - reference).max() <= tolerance + 1e-6):
                    region.add(near)
                    frontier.append(near)
    return region


@pytest.mark.parametrize("trial", range(20))
def test_fill_equals_a_flood_fill_on_random_grids_with_and_without_kept_occupancy(trial):
    rng = np.random.default_rng(trial)
    rgba = np.zeros((7, 7, 7, 4), np.float32)
    occupied = rng.random((7, 7, 7)) < rng.uniform(0.2, 0.8)
    rgba[occupied, 3] = 1.0
    rgba[occupied, :3] = rng.choice([0.0, 0.3, 0.32, 1.0], size=(occupied.sum(), 3))
    seed = tuple(int(i) for i in np.argwhere(occupied)[rng.integers(occupied.sum())])
    tolerance = float(rng.choice([0.0, 0.02, 0.5]))
    expected = flood_fill(rgba, seed, tolerance)
    assert painted(rgba, fill_region(rgba, seed, GRAY, tolerance)) == expected  # gray is none of the grid's colors
    kept = occupied_voxels(rgba)
    np.testing.assert_array_equal(fill_region(rgba, seed, RED, tolerance, kept), fill_region(rgba, seed, RED, tolerance))


@pytest.mark.parametrize("trial", range(10))
def test_replaying_from_the_last_object_fill_equals_replaying_every_stroke(trial):
    """apply_paint skips the strokes a later whole-object fill paints over; the result is the full replay's."""
    from renderer.paint import paint_voxels, stroke_voxels

    rng = np.random.default_rng(trial)
    rgba = np.zeros((6, 6, 6, 4), dtype=np.float32)
    rgba[..., 3] = rng.random((6, 6, 6)) < 0.6
    rgba[..., :3] = rng.random((6, 6, 6, 3)).round(1) * rgba[..., 3:]
    occupied = np.argwhere(rgba[..., 3] > 0.5)
    ops = []
    for _ in range(12):
        color = tuple(float(c) for c in rng.random(3).round(2))
        kind = rng.choice(["region", "object", "floor"], p=[0.6, 0.2, 0.2])
        seed = tuple(int(i) for i in occupied[rng.integers(len(occupied))]) if kind == "region" else None
        ops.append(PaintOp(str(kind), color, seed=seed, tolerance=0.3))
    expected, floor = rgba.copy(), (0.5, 0.5, 0.5)
    for op in ops:  # every stroke, in order
        if op.target == "floor":
            floor = op.color
        else:
            expected = paint_voxels(expected, stroke_voxels(expected, op), op.color)
    painted, floor_color = apply_paint(rgba, (0.5, 0.5, 0.5), ops)
    np.testing.assert_array_equal(painted, expected)
    assert floor_color == tuple(floor)


def test_a_scene_of_many_whole_object_fills_replays_one_and_too_many_strokes_are_refused(tmp_path, monkeypatch):
    import json

    import renderer.paint
    from renderer.limits import MAX_PAINT_STROKES
    from renderer.pipeline import painted_voxels
    from renderer.scene import scene_from_dict
    from renderer.voxels import save_voxels

    rgba = np.zeros((32, 32, 32, 4), dtype=np.float32)
    rgba[8:24, 0:20, 8:24] = (0.5, 0.5, 0.5, 1.0)
    save_voxels(tmp_path / "box.npz", rgba)
    fills = [{"target": "object", "color": [i % 2 * 1.0, 0.2, 0.3]} for i in range(MAX_PAINT_STROKES - 1)]
    data = {"version": 1, "object": {"voxels": "box.npz"}, "paint": fills + [{"target": "floor", "color": [1, 1, 0]}]}
    scene = scene_from_dict(data, tmp_path / "scene.json")
    replayed = []
    stroke_voxels = renderer.paint.stroke_voxels
    monkeypatch.setattr(renderer.paint, "stroke_voxels", lambda *a: replayed.append(a[1]) or stroke_voxels(*a))
    painted, floor = painted_voxels(scene, rgba)
    assert replayed == [scene.paint[-1]]  # the last whole-object fill alone, not ten thousand
    assert tuple(painted[10, 5, 10, :3]) == pytest.approx((0.0, 0.2, 0.3)) and floor == (1.0, 1.0, 0.0)
    data["paint"].append({"target": "floor", "color": [0, 0, 0]})
    with pytest.raises(InputError, match=f"at most {MAX_PAINT_STROKES}"):
        scene_from_dict(json.loads(json.dumps(data)), tmp_path / "scene.json")


def test_opencv_lab_is_cielab_of_srgb():
    # The perceptual fill takes CIELAB from OpenCV: sRGB in [0, 1] (gamma decoded), D65 white, L in [0, 100].
    # Reference values of the sRGB primaries and white (CIE 1976 L*a*b*, as colour-science tables give them).
    import cv2

    srgb = np.array([[[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]]], dtype=np.float32)
    lab = cv2.cvtColor(srgb, cv2.COLOR_RGB2Lab)[0]
    np.testing.assert_allclose(lab, [[53.24, 80.09, 67.20], [87.73, -86.18, 83.18], [32.30, 79.19, -107.86],
                                     [100.0, 0.0, 0.0]], atol=0.3)


def textured_slab(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A 24 x 4 x 24 slab of brown voxels shaded up to 20 % darker and noisy channel by channel (as photo colors
    are), with a blue stripe across it; and the stripe's mask."""
    rgba = np.zeros((24, 6, 24, 4), dtype=np.float32)
    shade = 1.0 - 0.2 * np.linspace(0.0, 1.0, 24)[:, None, None]  # light falling off across the slab
    brown = np.array([0.6, 0.4, 0.25]) * shade[..., None] + rng.normal(0.0, 0.03, (24, 4, 24, 3))
    rgba[:, 1:5, :, :3] = np.clip(brown, 0.0, 1.0)
    stripe = np.zeros((24, 6, 24), dtype=bool)
    stripe[:, 1:5, 10:13] = True
    rgba[stripe, :3] = np.clip(np.array([0.25, 0.35, 0.7]) + rng.normal(0.0, 0.03, (stripe.sum(), 3)), 0.0, 1.0)
    rgba[:, 1:5, :, 3] = 1.0
    return rgba, stripe


def test_a_perceptual_fill_covers_a_shaded_noisy_part_and_stops_at_another_hue():
    rng = np.random.default_rng(5)
    rgba, stripe = textured_slab(rng)
    brown_left = (rgba[..., 3] >= 0.5) & ~stripe
    brown_left[:, :, 10:] = False  # the stripe cuts the slab in two: a fill from the left stays left
    color = (1.0, 0.0, 1.0)
    for seed in [(0, 2, 0), (23, 3, 5)]:  # in the lit corner and in the shaded one
        out = fill_region(rgba, seed, color, 0.1, similarity="perceptual")
        filled = np.all(out[..., :3] == color, axis=-1)
        assert not (filled & ~brown_left).any() and (brown_left & ~filled).sum() <= 5  # of 960
    # The same stroke comparing RGB leaves blotches across the same part (and the light fall-off beyond reach).
    rgb = np.all(fill_region(rgba, (0, 2, 0), color, 0.1)[..., :3] == color, axis=-1)
    assert (brown_left & ~rgb).sum() > 100
    # From the stripe, the perceptual fill takes the stripe alone.
    out = fill_region(rgba, (5, 2, 11), color, 0.1, similarity="perceptual")
    np.testing.assert_array_equal(np.all(out[..., :3] == color, axis=-1), stripe)


def test_a_perceptual_stroke_replays_and_an_unknown_similarity_is_refused():
    rgba, stripe = textured_slab(np.random.default_rng(6))
    op = PaintOp("region", (1.0, 0.0, 1.0), (5, 2, 11), 0.1, "perceptual")
    replayed, _ = apply_paint(rgba, (0.5, 0.5, 0.5), [op])
    np.testing.assert_array_equal(np.all(replayed[..., :3] == op.color, axis=-1), stripe)
    with pytest.raises(InputError, match="similarity"):
        fill_region(rgba, (5, 2, 11), (1.0, 0.0, 1.0), 0.1, similarity="hsv")
