"""The scene being edited: what is shown, which object is selected, its undo history, where it is saved and whether
it changed since.

`scene` is what the window shows. An edit in progress (a drag) is a preview: shown and
rendered, not yet in the history. Committing makes it one undo step; cancelling returns to
the last committed scene. Selecting an object is a step too (undo brings the selection back), but leaves the file
as it is.
"""

from __future__ import annotations

from pathlib import Path

from app.editor.history import History
from renderer.scene import Scene, load_scene


class Document:
    """One open scene with its history; `revision` grows whenever the shown scene or the selection changes."""

    def __init__(self, scene: Scene, path: Path | None = None, changed: bool = False):
        """`changed`: the scene holds work no file has (a restored autosave); a new scene does not until edited."""
        self.history = History(scene)
        self.scene = scene
        self.selected = 0  # index of the selected object in `scene`: the object the tools act on
        self.path = path
        self.saved = None if changed else scene
        self.revision = 0

    @classmethod
    def open(cls, path: str | Path) -> Document:
        """Load a scene file (InputError on a bad file)."""
        return cls(load_scene(path), Path(path))

    @property
    def dirty(self) -> bool:
        """True when the shown scene differs from the saved file (or from the new scene it started as)."""
        return self.scene != self.saved

    @property
    def previewing(self) -> bool:
        return self.scene is not self.history.current

    def preview(self, scene: Scene) -> None:
        """Show `scene` while an edit is in progress, without an undo step."""
        self._show(scene, self.selected)

    def commit(self, scene: Scene | None = None, selected: int | None = None) -> bool:
        """Record `scene` (default: the previewed one) and the object `selected` in it (default: the selected one,
        or the last when there are fewer) as one undo step and show them."""
        was_preview = self.previewing
        scene = self.scene if scene is None else scene
        selected = min(self.selected if selected is None else selected, len(scene.objects) - 1)
        changed = self.history.commit(scene, selected)
        self._show(self.history.current, self.history.selected)
        if was_preview:
            self.revision += 1  # the same scene, now final: worth a full render
        return changed

    def select(self, index: int) -> bool:
        """Select object `index` of the committed scene, as one undo step (False if it was selected already)."""
        self.cancel_preview()
        return self.commit(self.history.current, index)

    def cancel_preview(self) -> None:
        self._show(self.history.current, self.history.selected)

    def undo(self) -> bool:
        self.cancel_preview()
        done = self.history.undo()
        self._show(self.history.current, self.history.selected)
        return done

    def redo(self) -> bool:
        self.cancel_preview()
        done = self.history.redo()
        self._show(self.history.current, self.history.selected)
        return done

    def mark_saved(self, path: str | Path) -> None:
        """Record that the committed scene now lives in `path` (the caller wrote it)."""
        self.cancel_preview()
        self.path, self.saved = Path(path), self.scene

    def _show(self, scene: Scene, selected: int) -> None:
        if scene is self.scene and selected == self.selected:
            return
        changed = scene != self.scene or scene.base_dir != self.scene.base_dir or selected != self.selected
        self.scene, self.selected = scene, selected
        if changed:
            self.revision += 1
