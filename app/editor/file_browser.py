"""A file browser drawn in the editor's own window, for systems without zenity or kdialog: Browse works everywhere.

It has the system dialog's interface (app/editor/file_dialog.py's FileDialog: `poll` once a frame, then `path`), so
the tools use either. A folder's entries are listed by `entries`, a pure function: folders first, then the files
that match the kind's patterns, hidden ones left out.
"""

from __future__ import annotations

import fnmatch
import os
from pathlib import Path

from imgui_bundle import imgui

from app.editor.file_dialog import FileKind


def entries(folder: Path, patterns: tuple[str, ...]) -> tuple[list[str], list[str]]:
    """The folder's subfolders and its files matching any of `patterns` (case-insensitive), sorted, hidden ones
    left out. An unreadable folder raises OSError."""
    folders, files = [], []
    with os.scandir(folder) as scan:
        for entry in scan:
            if entry.name.startswith("."):
                continue
            try:
                is_dir = entry.is_dir()
            except OSError:
                continue
            if is_dir:
                folders.append(entry.name)
            elif any(fnmatch.fnmatch(entry.name.lower(), p.lower()) for p in patterns):
                files.append(entry.name)
    return sorted(folders, key=str.lower), sorted(files, key=str.lower)


class FileBrowser:
    """A modal file browser for `kind`, starting at the file or folder `start`. `poll` draws it; it returns True once
    the user chose a file (`path`) or cancelled (`path` None)."""

    def __init__(self, kind: FileKind, start: str = "") -> None:
        self.kind = kind
        self.path: str | None = None
        self.error: str | None = None
        start_path = Path(start).expanduser() if start else Path.cwd()
        self.folder = (start_path if start_path.is_dir() else start_path.parent).resolve()
        if not self.folder.is_dir():
            self.folder = Path.cwd()
        self.name = "" if start_path.is_dir() else start_path.name
        self._problem: str | None = None
        self._opened = False
        self._done = False
        self._listing = self._list()

    def _list(self) -> tuple[list[str], list[str]]:
        try:
            self._problem = None
            return entries(self.folder, self.kind.patterns)
        except OSError as exc:
            self._problem = f"cannot read {self.folder}: {exc.strerror or exc}"
            return [], []

    def _enter(self, folder: Path) -> None:
        self.folder = folder.resolve()
        self._listing = self._list()

    def _choose(self) -> None:
        typed = Path(self.name).expanduser()
        chosen = typed if typed.is_absolute() else self.folder / typed
        if chosen.is_dir():
            self._enter(chosen)
            self.name = ""
        elif self.name and (self.kind.save or chosen.is_file()):
            self.path, self._done = str(chosen), True
        else:
            self._problem = f"no file {chosen}"

    def poll(self) -> bool:
        if self._done:
            return True
        title = f"{self.kind.title}###file browser"
        if not self._opened:
            imgui.open_popup(title)
            self._opened = True
        viewport = imgui.get_main_viewport()
        imgui.set_next_window_pos(viewport.get_center(), imgui.Cond_.appearing, imgui.ImVec2(0.5, 0.5))
        imgui.set_next_window_size(imgui.ImVec2(640, 460), imgui.Cond_.appearing)
        if not imgui.begin_popup_modal(title)[0]:
            self._done = True
            return True
        imgui.text_wrapped(str(self.folder))
        if imgui.button("Up") and self.folder.parent != self.folder:
            self._enter(self.folder.parent)
        imgui.same_line()
        imgui.text_disabled(f"{self.kind.name}: {' '.join(self.kind.patterns)}")
        folders, files = self._listing
        imgui.begin_child("entries", imgui.ImVec2(0, -70), imgui.ChildFlags_.borders)
        for name in folders:
            if imgui.selectable(f"[{name}]", False, imgui.SelectableFlags_.allow_double_click)[0]:
                self._enter(self.folder / name)
                break
        for name in files:
            clicked, _ = imgui.selectable(name, name == self.name, imgui.SelectableFlags_.allow_double_click)
            if clicked:
                self.name = name
                if imgui.is_mouse_double_clicked(imgui.MouseButton_.left):
                    self._choose()
        imgui.end_child()
        if imgui.is_window_appearing():
            imgui.set_keyboard_focus_here()
        entered, self.name = imgui.input_text("file name", self.name, imgui.InputTextFlags_.enter_returns_true)
        if self._problem:
            imgui.text_colored(imgui.ImVec4(1.0, 0.42, 0.38, 1.0), self._problem)
        if imgui.button("Save" if self.kind.save else "Open") or entered:
            self._choose()
        imgui.same_line()
        if imgui.button("Cancel") or (imgui.is_key_pressed(imgui.Key.escape, False) and not self._done):
            self._done = True
        if self._done:
            imgui.close_current_popup()
        imgui.end_popup()
        return self._done

    def close(self) -> None:
        self._done = True
