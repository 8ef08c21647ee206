"""Undo and redo as two stacks of immutable scenes: every committed edit is one step."""

from __future__ import annotations

from renderer.scene import Scene

MAX_STEPS = 500  # older steps are forgotten; scenes are small, this bounds memory anyway


class History:
    """The committed scene plus the scenes to go back (undo) and forward (redo) to."""

    def __init__(self, scene: Scene):
        self.current = scene
        self._undo: list[Scene] = []
        self._redo: list[Scene] = []

    def commit(self, scene: Scene) -> bool:
        """Make `scene` current as a new step; clears the redo stack. False if nothing changed."""
        if scene == self.current and scene.base_dir == self.current.base_dir:
            return False
        self._undo.append(self.current)
        del self._undo[:-MAX_STEPS]
        self._redo.clear()
        self.current = scene
        return True

    def undo(self) -> bool:
        """Step back one edit; False when there is none."""
        if not self._undo:
            return False
        self._redo.append(self.current)
        self.current = self._undo.pop()
        return True

    def redo(self) -> bool:
        """Step forward again after an undo; False when there is nothing to redo."""
        if not self._redo:
            return False
        self._undo.append(self.current)
        self.current = self._redo.pop()
        return True

    @property
    def can_undo(self) -> bool:
        return bool(self._undo)

    @property
    def can_redo(self) -> bool:
        return bool(self._redo)
