"""Painted object voxels for the live engine, each stroke list painted from the longest one painted before.

A scene keeps all its paint strokes, so painting from scratch costs one fill per stroke, and
more with every stroke the user adds. Kept results make the editor's common steps one fill at
most: a new stroke extends the last list, recoloring or undoing the last stroke returns to the
list before it. Paint never changes occupancy, so the object's occupied voxels are found once.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

from renderer.paint import Color, apply_paint, fill_object, occupied_voxels
from renderer.scene import PaintOp

KEPT = 2  # painted lists remembered (each N^3 x 16 bytes): the current one and the one before its last stroke
# (and one more such array, the last forgotten, for the next fill to write into)


class PaintReplay:
    """Object voxels after a base color and object/region strokes, for one unpainted object at a time."""

    def __init__(self, rgba: np.ndarray):
        self.rgba = rgba  # the unpainted object voxels
        self.occupied = occupied_voxels(rgba)
        self._painted: OrderedDict[tuple, np.ndarray] = OrderedDict()
        self._returned: np.ndarray | None = None  # what `painted` returned last: its caller may still read it
        self._unused: np.ndarray | None = None  # a forgotten list's array, reused by the next fill

    def painted(self, color: Color | None, strokes: tuple[PaintOp, ...]) -> np.ndarray:
        """The voxels filled with `color` (None: their own colors) and then painted by `strokes` (no floor strokes)."""
        done = next((k for k in range(len(strokes), -1, -1) if (color, strokes[:k]) in self._painted), None)
        if done is None:
            rgba = self.rgba if color is None else fill_object(self.rgba, color, self.occupied)
            self._keep((color, ()), rgba)
            done = 0
        rgba = self._painted[(color, strokes[:done])]
        self._painted.move_to_end((color, strokes[:done]))
        for k in range(done, len(strokes)):
            rgba, _ = apply_paint(rgba, (0.0, 0.0, 0.0), strokes[k:k + 1], self.occupied, self._spare())
            self._keep((color, strokes[:k + 1]), rgba)
        self._returned = rgba
        return rgba

    def _keep(self, key: tuple, rgba: np.ndarray) -> None:
        self._painted[key] = rgba
        while len(self._painted) > KEPT:
            _, forgotten = self._painted.popitem(last=False)
            if forgotten is not self.rgba:
                self._unused = forgotten

    def _spare(self) -> np.ndarray | None:
        """The array of the painted list forgotten last, for the next fill to write into (a copy into used memory
        is twice as fast as into new), unless it is the result returned last (its caller may still read that one
        until this call returns). It is never the array painted from: that list was used last, so it is kept."""
        spare, self._unused = self._unused, None
        return None if spare is self._returned else spare
