"""The object voxels behind each scene, kept so undo, redo and repeated edits do not voxelise or repaint again.

Object voxels depend on the object's source (mesh or voxel file, resolution, up axis, base
color); painted voxels on that and the paint strokes. A stroke list that extends a cached one
is painted from the cached result, so one more bucket fill costs one fill, not a replay.
Safe to use from the UI thread and a background job at once.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from pathlib import Path

import numpy as np

from renderer.paint import Color, apply_paint
from renderer.pipeline import object_voxels
from renderer.scene import PaintOp, Scene
from renderer.voxels import ProgressCallback

SOURCES_KEPT = 4  # objects remembered (undo across a few mesh loads stays instant)
PAINTINGS_KEPT = 24  # painted states remembered (undo across strokes stays instant)

SourceKey = tuple


def source_key(scene: Scene) -> SourceKey:
    """What the object's voxels depend on, with file paths made absolute."""
    o = scene.object

    def absolute(path: Path | None) -> str | None:
        return None if path is None else str(path.resolve())

    return (absolute(scene.mesh_path()), absolute(scene.voxels_path()), o.up, o.resolution, o.color)


class VoxelCache:
    """Object voxels per source and painted voxels per (source, strokes), least recently used dropped first."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._objects: OrderedDict[SourceKey, np.ndarray] = OrderedDict()
        self._painted: OrderedDict[tuple[SourceKey, tuple[PaintOp, ...]], np.ndarray] = OrderedDict()

    def has_object(self, scene: Scene) -> bool:
        with self._lock:
            return source_key(scene) in self._objects

    def object_rgba(self, scene: Scene, progress: ProgressCallback | None = None) -> np.ndarray:
        """The unpainted object voxels (read-only array); voxelises on a miss, reporting `progress`."""
        key = source_key(scene)
        with self._lock:
            if key in self._objects:
                self._objects.move_to_end(key)
                return self._objects[key]
        rgba = object_voxels(scene, progress=progress)
        rgba.flags.writeable = False
        with self._lock:
            self._objects[key] = rgba
            while len(self._objects) > SOURCES_KEPT:
                self._objects.popitem(last=False)
        return rgba

    def painted(self, scene: Scene) -> tuple[np.ndarray, Color]:
        """The object voxels after the scene's paint strokes (read-only array), and the floor color."""
        key = source_key(scene)
        strokes = tuple(op for op in scene.paint if op.target != "floor")
        base = self.object_rgba(scene)
        with self._lock:
            done, rgba = self._longest_cached_prefix(key, strokes, base)
        if done < len(strokes):
            rgba, _ = apply_paint(rgba, scene.floor.color, strokes[done:])
            rgba.flags.writeable = False
            with self._lock:
                self._painted[(key, strokes)] = rgba
                while len(self._painted) > PAINTINGS_KEPT:
                    self._painted.popitem(last=False)
        floor_strokes = [op for op in scene.paint if op.target == "floor"]
        _, floor_color = apply_paint(rgba, scene.floor.color, floor_strokes)
        return rgba, floor_color

    def _longest_cached_prefix(self, key: SourceKey, strokes: tuple[PaintOp, ...],
                               base: np.ndarray) -> tuple[int, np.ndarray]:
        """(number of strokes already applied, voxels after them); (0, base) when nothing fits."""
        for done in range(len(strokes), 0, -1):
            entry = self._painted.get((key, strokes[:done]))
            if entry is not None:
                self._painted.move_to_end((key, strokes[:done]))
                return done, entry
        return 0, base
