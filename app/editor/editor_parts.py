"""What the editor's parts (files, the reference, autosave, the photo tool) use of the editor: its seam.

EditorApp (app/editor/app.py) has all of it; a part is given the editor and reads only this, so the parts and
the hub do not import each other, and a part is tested with a stand-in.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from renderer.scene import Scene

if TYPE_CHECKING:
    from app.editor.document import Document
    from app.editor.jobs import JobRunner
    from app.editor.render_panel import LiveRender
    from app.editor.viewport import ViewportRenderer
    from app.editor.window import Window
    from renderer.voxel_cache import VoxelCache


class Editor(Protocol):
    """The document and its voxels, the status line and questions, undoable edits and background jobs."""

    doc: Document
    voxels: VoxelCache
    jobs: JobRunner

    def say(self, text: str, error: bool = False) -> None: ...

    def ask(self, title: str, text: str, choices: tuple[str, ...], on_choice: Callable[[str], None]) -> None: ...

    def edit(self, make_scene: Callable[[Scene], Scene], preview: bool = False) -> bool: ...

    def replace_document(self, document: Document) -> None: ...


class EditorWithViews(Editor, Protocol):
    """The same, with the window, the views and the render panel (what files and the reference read)."""

    window: Window
    live: LiveRender
    viewport: ViewportRenderer
    view: object  # a renderer.camera.Camera or orbit_view.OrbitView
    floor_color: tuple[float, float, float]
    requested_tab: str | None
    autosave: object  # app.editor.autosave.Autosave

    @property
    def scene(self) -> Scene: ...

    @property
    def synced(self) -> bool: ...

    def warn_missing_materials(self, mesh: Path | None) -> None: ...
