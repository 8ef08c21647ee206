"""The object voxels behind each scene, kept so undo, redo and repeated edits do not voxelise or repaint again.

Object voxels depend on the object's source (mesh or voxel file, resolution, up axis, base
color); painted voxels on that and the paint strokes. A stroke list that extends a cached one
is painted from the cached result, so one more bucket fill costs one fill, not a replay.
Painted states are kept up to a memory budget (a 200^3 object's voxels take 128 MB). A stroke paints into a
spare array whose pages are already mapped: the array of a forgotten state that nothing else holds any more, or
one prepared on another thread after the object loads and after each stroke (a fill into fresh memory is several times slower,
most of it the kernel mapping the pages: docs/results.md, "Measurements behind the code").
Safe to use from the UI thread and a background job at once.
"""

from __future__ import annotations

import sys
import threading
from collections import OrderedDict
from collections.abc import Callable
from pathlib import Path

import numpy as np

from renderer.limits import MAX_OBJECTS
from renderer.paint import Color, apply_paint, needed_strokes, occupied_voxels
from renderer.pipeline import object_voxels
from renderer.scene import PaintOp, Scene
from renderer.voxels import ProgressCallback

SOURCES_KEPT = MAX_OBJECTS + 4  # objects remembered: a full scene's, and undo across a few mesh loads stays instant
PAINTINGS_KEPT = 24  # painted states remembered (undo across strokes stays instant)
PAINTED_BYTES_KEPT = 512 * 2**20  # ... and at most this much of them (4 states of a 200^3 object, 24 at 110^3)

SourceKey = tuple


def source_key(scene: Scene) -> SourceKey:
    """What the object's voxels depend on, with file paths made absolute."""
    o = scene.object

    def absolute(path: Path | None) -> str | None:
        return None if path is None else str(path.resolve())

    return (absolute(scene.mesh_path()), absolute(scene.voxels_path()), o.up, o.resolution, o.color)


def in_background(task: Callable[[], None]) -> None:
    """Run `task` on a daemon thread of its own."""
    threading.Thread(target=task, name="voxel-cache-spare", daemon=True).start()


class VoxelCache:
    """Object voxels per source and painted voxels per (source, strokes), least recently used dropped first.
    `run_later`: how the spare array for the next stroke is prepared (in_background; a test may run it at once)."""

    def __init__(self, run_later: Callable[[Callable[[], None]], None] = in_background) -> None:
        self._lock = threading.Lock()
        self._objects: OrderedDict[SourceKey, np.ndarray] = OrderedDict()
        self._occupied: dict[SourceKey, np.ndarray] = {}  # each kept object's occupied voxels, found at its first stroke
        # (paint never changes them; finding them scans the whole grid)
        self._painted: OrderedDict[tuple[SourceKey, tuple[PaintOp, ...]], np.ndarray] = OrderedDict()
        self._spare: np.ndarray | None = None  # an array nothing else holds, its pages mapped, to paint into
        self._run_later = run_later
        self._preparing = False  # a spare is being prepared

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
                forgotten, _ = self._objects.popitem(last=False)
                self._occupied.pop(forgotten, None)
        self._prepare_spare(rgba.shape)  # for the first stroke
        return rgba

    def painted(self, scene: Scene) -> tuple[np.ndarray, Color]:
        """The object voxels after the scene's paint strokes (read-only array), and the floor color."""
        key = source_key(scene)
        strokes = tuple(needed_strokes(scene.paint))
        base = self.object_rgba(scene)
        with self._lock:
            done, rgba = self._longest_cached_prefix(key, strokes, base)
        if done < len(strokes):
            with self._lock:
                out = self._take_spare(rgba)
                occupied = self._occupied.get(key)
            if occupied is None:
                occupied = occupied_voxels(base)
                with self._lock:
                    if key in self._objects:
                        self._occupied[key] = occupied
            rgba, _ = apply_paint(rgba, scene.floor.color, strokes[done:], occupied=occupied, out=out)
            rgba.flags.writeable = False
            with self._lock:
                self._painted[(key, strokes)] = rgba
                self._forget_beyond_budget()
            self._prepare_spare(rgba.shape)  # for the next stroke
        return rgba, scene.floor.color

    def _longest_cached_prefix(self, key: SourceKey, strokes: tuple[PaintOp, ...],
                               base: np.ndarray) -> tuple[int, np.ndarray]:
        """(number of strokes already applied, voxels after them); (0, base) when nothing fits. Looks through the few
        kept paintings of this object (not every prefix: a scene may hold thousands of strokes)."""
        best = None
        for cached_key in self._painted:
            found, done = cached_key[1], len(cached_key[1])
            if cached_key[0] == key and done <= len(strokes) and (best is None or done > len(best[1])) \
                    and strokes[:done] == found:
                best = cached_key
        if best is None:
            return 0, base
        self._painted.move_to_end(best)
        return len(best[1]), self._painted[best]

    def _forget_beyond_budget(self) -> None:
        """Drop the least recently used painted states beyond PAINTINGS_KEPT and PAINTED_BYTES_KEPT (the newest always
        stays); the last dropped array becomes the spare if nothing else holds it."""
        while len(self._painted) > 1 and (len(self._painted) > PAINTINGS_KEPT or
                                          sum(a.nbytes for a in self._painted.values()) > PAINTED_BYTES_KEPT):
            _, forgotten = self._painted.popitem(last=False)
            # References: `forgotten` and getrefcount's argument. More: the viewport, a render or a view still reads it.
            if sys.getrefcount(forgotten) == 2 and forgotten.base is None:
                self._spare = forgotten
            del forgotten

    def _prepare_spare(self, shape: tuple[int, ...]) -> None:
        """Unless a spare of this shape is there or on its way, have `run_later` make one and map its pages."""
        with self._lock:
            if self._preparing or (self._spare is not None and self._spare.shape == shape):
                return
            self._preparing = True

        def prepare() -> None:
            try:
                spare = np.empty(shape, dtype=np.float32)
                np.copyto(spare, 0.0)  # touches every page (numpy lets other threads run meanwhile)
            except MemoryError:  # only time is lost: the next stroke maps fresh memory itself
                spare = None
            with self._lock:
                self._preparing = False
                if spare is not None and (self._spare is None or self._spare.shape != shape):
                    self._spare = spare

        self._run_later(prepare)

    def _take_spare(self, like: np.ndarray) -> np.ndarray | None:
        """The spare array, writable, if it has `like`'s shape and type and nothing else took hold of it meanwhile."""
        spare, self._spare = self._spare, None
        if spare is None or spare.shape != like.shape or spare.dtype != np.float32 or sys.getrefcount(spare) != 2:
            return None
        spare.flags.writeable = True
        return spare
