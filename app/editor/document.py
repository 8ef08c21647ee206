"""The scene being edited: what is shown, its undo history, where it is saved and whether it changed since.

`scene` is what the window shows. An edit in progress (a drag) is a preview: shown and
rendered, not yet in the history. Committing makes it one undo step; cancelling returns to
the last committed scene.
"""

from __future__ import annotations

from pathlib import Path

from app.editor.history import History
from renderer.errors import InputError
from renderer.scene import Scene, load_scene


class Document:
    """One open scene with its history; `revision` grows whenever the shown scene changes."""

    def __init__(self, scene: Scene, path: Path | None = None, changed: bool = False):
        """`changed`: the scene holds work no file has (a restored autosave); a new scene does not until edited."""
        self.history = History(scene)
        self.scene = scene
        self.path = path
        self.saved = None if changed else scene
        self.revision = 0

    @classmethod
    def open(cls, path: str | Path) -> Document:
        """Load a scene file (InputError on a bad file, or on a scene of several objects, which the editor cannot
        edit yet: `nvr render` draws them)."""
        scene = load_scene(path)
        if len(scene.objects) > 1:
            raise InputError(f"the editor edits scenes of one object; this one holds {len(scene.objects)} "
                             "(nvr render draws it)", path)
        return cls(scene, Path(path))

    @property
    def dirty(self) -> bool:
        """True when the shown scene differs from the saved file (or from the new scene it started as)."""
        return self.scene != self.saved

    @property
    def previewing(self) -> bool:
        return self.scene is not self.history.current

    def preview(self, scene: Scene) -> None:
        """Show `scene` while an edit is in progress, without an undo step."""
        self._show(scene)

    def commit(self, scene: Scene | None = None) -> bool:
        """Record `scene` (default: the previewed one) as one undo step and show it."""
        was_preview = self.previewing
        scene = self.scene if scene is None else scene
        changed = self.history.commit(scene)
        self._show(self.history.current)
        if was_preview:
            self.revision += 1  # the same scene, now final: worth a full render
        return changed

    def cancel_preview(self) -> None:
        self._show(self.history.current)

    def undo(self) -> bool:
        self.cancel_preview()
        done = self.history.undo()
        self._show(self.history.current)
        return done

    def redo(self) -> bool:
        self.cancel_preview()
        done = self.history.redo()
        self._show(self.history.current)
        return done

    def mark_saved(self, path: str | Path) -> None:
        """Record that the committed scene now lives in `path` (the caller wrote it)."""
        self.cancel_preview()
        self.path, self.saved = Path(path), self.scene

    def _show(self, scene: Scene) -> None:
        if scene is self.scene:
            return
        changed = scene != self.scene or scene.base_dir != self.scene.base_dir
        self.scene = scene
        if changed:
            self.revision += 1
