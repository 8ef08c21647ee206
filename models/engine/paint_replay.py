"""Painted object voxels for the live engine: one array painted in place, each stroke undone from what it overwrote.

A scene keeps all its paint strokes, so painting from scratch costs one fill per stroke, and
more with every stroke the user adds. The replay keeps one painted array and, for each stroke
painted into it, the voxels the stroke changed and their colors before: a new stroke paints
its region, recoloring or undoing the last stroke puts back what it overwrote first. Each step
costs the stroke's region and the search for it, not the grid: copying a 200^3 object's voxels
(128 MB) for each stroke was a third of a paint edit, and one array is kept instead of three.
Paint never changes occupancy, so the object's occupied voxels are found once.

The array returned is painted again by the next call: a caller reads it before asking for other strokes (the
engine's stages read it during one render, and keep what they made from it, not the array).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from renderer.errors import InputError
from renderer.grid import occupied_spans
from renderer.paint import Color, fill_object, needed_strokes, occupied_voxels, paint_voxels, stroke_voxels
from renderer.scene import PaintOp


@dataclass(frozen=True)
class _Painted:
    """A stroke painted into the array: the voxels it changed (flat indices) and their colors (K, 3) before it."""

    stroke: PaintOp
    voxels: np.ndarray
    before: np.ndarray


class PaintReplay:
    """Object voxels after a base color and object/region strokes, for one unpainted object at a time."""

    def __init__(self, rgba: np.ndarray):
        self.rgba = rgba  # the unpainted object voxels (never changed)
        self.occupied = occupied_voxels(rgba)
        self.box = occupied_spans(np.asarray(rgba)[..., 3] >= 0.5)  # the occupied voxels' (start, stop) per axis
        self._array: np.ndarray | None = None  # painted in place
        self._color: Color | None = None  # the base color in it (None: the voxels' own)
        self._strokes: list[_Painted] = []  # the strokes in it, in order

    def painted(self, color: Color | None, strokes: tuple[PaintOp, ...]) -> np.ndarray:
        """The voxels filled with `color` (None: their own colors) and then painted by `strokes` (no floor strokes)."""
        strokes = tuple(needed_strokes(strokes))
        if color is None and not strokes:
            return self.rgba
        before = (self._color, tuple(p.stroke for p in self._strokes))
        try:
            return self._paint_to(color, strokes)
        except InputError:
            if self._array is not None:
                self._paint_to(*before)  # back to what the caller saw last: those strokes painted before
            raise

    def _paint_to(self, color: Color | None, strokes: tuple[PaintOp, ...]) -> np.ndarray:
        if self._array is None or color != self._color:  # a new base color repaints from the unpainted voxels
            if self._array is None:
                self._array = np.array(self.rgba, dtype=np.float32, copy=True)
            else:
                np.copyto(self._array, self.rgba)
            if color is not None:
                fill_object(self._array, color, self.occupied, out=self._array)
            self._color, self._strokes = color, []
        kept = 0
        while kept < min(len(strokes), len(self._strokes)) and self._strokes[kept].stroke == strokes[kept]:
            kept += 1
        flat = self._array.reshape(-1, 4)
        while len(self._strokes) > kept:  # undo the strokes that differ, the last first
            undone = self._strokes.pop()
            flat[undone.voxels, :3] = undone.before
        for stroke in strokes[kept:]:
            voxels = stroke_voxels(self._array, stroke, self.occupied)
            self._strokes.append(_Painted(stroke, voxels, flat[voxels, :3].copy()))
            paint_voxels(self._array, voxels, stroke.color, out=self._array)
        return self._array
