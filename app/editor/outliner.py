"""The object list (outliner), in the viewport's top right corner as in Blender: select, rename, add, duplicate and
delete the scene's objects, each one undo step (EditorApp's commands); hide one from the viewport (its box)."""

from __future__ import annotations

from typing import Any

from imgui_bundle import imgui

from app.editor import edits
from app.editor.file_dialog import FileKind
from app.editor.layout import Rect
from renderer.limits import MAX_OBJECTS
from renderer.mesh import MESH_EXTENSIONS

WIDTH = 210
ROW_HEIGHT = 24  # a row: its eye's checkbox and its name
ROWS_SHOWN = 6  # rows before the list scrolls
SELECTED_TEXT = (1.0, 0.72, 0.35, 1.0)  # the selected row, in the viewport's outline color
ADD_FILES = FileKind("Add an object", "Meshes, .vox models", (*(f"*{suffix}" for suffix in MESH_EXTENSIONS), "*.vox"))


def draw_outliner(ui: Any, viewport: Rect) -> None:
    """The list of `ui.app`'s objects, its name field and buttons, over the viewport's top right corner."""
    app = ui.app
    scene = app.scene
    rows = min(len(scene.objects), ROWS_SHOWN)
    imgui.set_next_window_pos(imgui.ImVec2(viewport.x + viewport.width - WIDTH - 8, viewport.y + 8))
    imgui.set_next_window_size(imgui.ImVec2(WIDTH, 0))
    imgui.set_next_window_bg_alpha(0.8)
    flags = (imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_collapse
             | imgui.WindowFlags_.no_saved_settings | imgui.WindowFlags_.always_auto_resize)
    imgui.begin("Objects", None, flags)
    imgui.begin_child("object rows", imgui.ImVec2(0, rows * ROW_HEIGHT + 4))
    for index in range(len(scene.objects)):
        shown = index not in app.hidden
        changed, _ = imgui.checkbox(f"##shown{index}", shown)
        if changed:
            app.toggle_hidden(index)
        if imgui.is_item_hovered():
            imgui.set_tooltip("drawn in the viewport (the render shows every object)")
        imgui.same_line()
        chosen = index == app.selected
        if chosen:
            imgui.push_style_color(imgui.Col_.text, imgui.ImVec4(*SELECTED_TEXT))
        clicked, _ = imgui.selectable(f"{edits.object_label(scene, index)}##object{index}", chosen)
        if chosen:
            imgui.pop_style_color()
        if clicked and not chosen:
            app.select(index)
    imgui.end_child()
    _name_field(ui)
    if imgui.button("Add...") and len(scene.objects) < MAX_OBJECTS:
        ui.ask_path(ADD_FILES, "add_object_path", app.add_object)
    if imgui.is_item_hovered():
        imgui.set_tooltip("a mesh or a .vox model, placed on the floor where there is room")
    imgui.same_line()
    if imgui.button("Duplicate"):
        app.duplicate_selected()
    if imgui.is_item_hovered():
        imgui.set_tooltip("Shift+D")
    imgui.same_line()
    if imgui.button("Delete"):
        app.delete_selected()
    if imgui.is_item_hovered():
        imgui.set_tooltip("X or Delete")
    imgui.end()


def _name_field(ui: Any) -> None:
    """The selected object's name: Enter renames it (a name another object has is refused in the status line)."""
    app = ui.app
    key = (id(app.doc), app.selected, app.selected_object.name)
    if ui.fields.object_name_for != key:  # another object, or renamed by undo: the field shows its name
        ui.fields.object_name, ui.fields.object_name_for = app.selected_object.name or "", key
    imgui.set_next_item_width(WIDTH - 60)
    entered, ui.fields.object_name = imgui.input_text("name", ui.fields.object_name,
                                                      imgui.InputTextFlags_.enter_returns_true)
    if entered:
        app.rename_object(app.selected, ui.fields.object_name)
