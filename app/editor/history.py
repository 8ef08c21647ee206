"""Undo and redo as two stacks of immutable scenes, each with the object selected in it: every committed edit (a
selection too) is one step."""

from __future__ import annotations

from renderer.scene import Scene

MAX_STEPS = 500  # older steps are forgotten; scenes are small, this bounds memory anyway


class History:
    """The committed scene and selected object, plus the steps to go back (undo) and forward (redo) to."""

    def __init__(self, scene: Scene, selected: int = 0):
        self.current = scene
        self.selected = selected  # index of the selected object in `current`
        self._undo: list[tuple[Scene, int]] = []
        self._redo: list[tuple[Scene, int]] = []

    def commit(self, scene: Scene, selected: int | None = None) -> bool:
        """Make `scene` (and the object `selected`, default: the one selected now) current as a new step; clears the
        redo stack. False if nothing changed."""
        selected = self.selected if selected is None else selected
        if scene == self.current and scene.base_dir == self.current.base_dir and selected == self.selected:
            return False
        self._undo.append((self.current, self.selected))
        del self._undo[:-MAX_STEPS]
        self._redo.clear()
        self.current, self.selected = scene, selected
        return True

    def undo(self) -> bool:
        """Step back one edit; False when there is none."""
        if not self._undo:
            return False
        self._redo.append((self.current, self.selected))
        self.current, self.selected = self._undo.pop()
        return True

    def redo(self) -> bool:
        """Step forward again after an undo; False when there is nothing to redo."""
        if not self._redo:
            return False
        self._undo.append((self.current, self.selected))
        self.current, self.selected = self._redo.pop()
        return True

    @property
    def can_undo(self) -> bool:
        return bool(self._undo)

    @property
    def can_redo(self) -> bool:
        return bool(self._redo)
