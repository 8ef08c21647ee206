"""The engine's paint replay (models/engine/paint_replay.py): painting in place, undoing what strokes overwrote,
equals painting from scratch."""

from __future__ import annotations

import numpy as np
import pytest

import models.engine.paint_replay as paint_replay
from models.engine.paint_replay import PaintReplay
from renderer.errors import InputError
from renderer.paint import apply_paint, fill_object, stroke_voxels
from renderer.scene import PaintOp

RED, GREEN, BLUE = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)


def two_blobs() -> np.ndarray:
    """A 6^3 grid: a gray 2x2x2 cube at the corner and a gray bar apart from it."""
    rgba = np.zeros((6, 6, 6, 4), np.float32)
    rgba[0:2, 0:2, 0:2] = (0.5, 0.5, 0.5, 1.0)
    rgba[4, 1:5, 4] = (0.5, 0.5, 0.5, 1.0)
    return rgba


def from_scratch(rgba: np.ndarray, color, strokes) -> np.ndarray:
    base = rgba if color is None else fill_object(rgba, color)
    return apply_paint(base, (0.0, 0.0, 0.0), strokes)[0]


@pytest.fixture
def fills(monkeypatch) -> list:
    """Records the strokes the replay paints (searches the voxels of)."""
    painted = []

    def counting(rgba, op, occupied=None):
        painted.append(op)
        return stroke_voxels(rgba, op, occupied)

    monkeypatch.setattr(paint_replay, "stroke_voxels", counting)
    return painted


def test_each_step_equals_a_replay_from_scratch_and_paints_at_most_one_stroke(fills):
    rgba = two_blobs()
    replay = PaintReplay(rgba)
    corner = PaintOp("region", RED, seed=(0, 0, 0))
    bar = PaintOp("region", GREEN, seed=(4, 2, 4))
    recolored_bar = PaintOp("region", BLUE, seed=(4, 2, 4))
    steps = [  # (object color, strokes, strokes the replay must paint)
        (None, (corner,), [corner]),
        (None, (corner, bar), [bar]),  # a new stroke
        (None, (corner, recolored_bar), [recolored_bar]),  # the last stroke changed
        (None, (corner,), []),  # undo: what the bar overwrote is put back
        (None, (corner, bar), [bar]),  # the first bar again: one fill
        (None, (corner,), []),  # undo once more
        ((0.2, 0.2, 0.2), (corner,), [corner]),  # a new base color repaints
    ]
    steps += [(None, (corner, bar), [corner, bar]),  # the voxels' own colors again
              (None, (corner, recolored_bar), [recolored_bar])]  # another last stroke, no undo between
    arrays = set()
    for color, strokes, expected in steps:
        fills.clear()
        out = replay.painted(color, strokes)
        assert fills == expected
        np.testing.assert_array_equal(out, from_scratch(rgba, color, strokes))
        arrays.add(id(out))
    assert len(arrays) == 1  # one array, painted in place
    corner_after_bar = replay.painted(None, (corner, recolored_bar))
    assert tuple(corner_after_bar[4, 2, 4, :3]) == BLUE and tuple(corner_after_bar[0, 0, 0, :3]) == RED
    np.testing.assert_array_equal(rgba, two_blobs())  # the unpainted voxels are never changed


def test_no_strokes_is_the_base_color_or_the_voxels_themselves():
    rgba = two_blobs()
    replay = PaintReplay(rgba)
    assert replay.painted(None, ()) is rgba
    red = replay.painted(RED, ())
    assert tuple(red[4, 1, 4, :3]) == RED and not red[3, 3, 3].any()  # occupied voxels only


def test_a_stroke_that_cannot_be_painted_leaves_the_voxels_as_the_caller_last_saw_them():
    rgba = two_blobs()
    replay = PaintReplay(rgba)
    corner = PaintOp("region", RED, seed=(0, 0, 0))
    bar = PaintOp("region", GREEN, seed=(4, 2, 4))
    out = replay.painted(None, (corner, bar))
    on_empty = PaintOp("region", BLUE, seed=(3, 3, 3))  # an empty voxel
    with pytest.raises(InputError, match="empty voxel"):
        replay.painted(None, (corner, on_empty))  # the bar is undone before the failing stroke
    np.testing.assert_array_equal(out, from_scratch(rgba, None, (corner, bar)))
    np.testing.assert_array_equal(replay.painted(None, (corner,)), from_scratch(rgba, None, (corner,)))
