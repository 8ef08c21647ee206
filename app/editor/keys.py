"""Every key and mouse binding of the editor, listed once: the Help window shows this table, docs/editor.md follows it.

Also the keys that act on the viewport's view (Blender's numpad views, F to frame the object), on the object list
(Blender's Shift+D, X and Delete), and Tab, which users of other editors try: it says why it does nothing.
"""

from __future__ import annotations

from typing import Any

from imgui_bundle import imgui

BINDINGS = (
    ("middle- or right-drag", "orbit the viewport"),
    ("Shift + that drag", "pan: the point under the mouse follows it"),
    ("wheel", "zoom"),
    ("numpad 1 / 3 / 7", "look from the front / right / top; with Ctrl from the back / left / below"),
    ("F, numpad .", "frame the object"),
    ("Home", "look through the render camera"),
    ("left-drag the light square", "move the light; with Shift its height"),
    ("drag the border left of the render", "widen or narrow the render and tools column"),
    ("G, R, S", "grab, rotate, scale the selected object; then X, Y or Z for one axis"),
    ("click an object, or its row in the object list", "select it: the tools act on it"),
    ("Shift+D, X or Delete", "duplicate, delete the selected object"),
    ("click or Enter / right click or Escape", "confirm / cancel a grab, rotate or scale"),
    ("click a voxel (Paint tab)", "bucket fill; with Alt, pick its color"),
    ("Ctrl+Z, Ctrl+Shift+Z or Ctrl+Y", "undo, redo"),
    ("Ctrl+N, Ctrl+O", "new scene, open a scene"),
    ("Ctrl+S, Ctrl+Shift+S", "save, save as"),
    ("Ctrl+E", "export the render"),
    ("Ctrl+Q", "quit"),
    ("Escape", "close the reference render, or this list"),
    ("F1", "this list (Help menu)"),
)
VIEW_KEYS = ((imgui.Key.keypad1, "front", "back"), (imgui.Key.keypad3, "right", "left"),
             (imgui.Key.keypad7, "top", "bottom"))


def view_keys(app: Any, transforming: bool) -> None:
    """Numpad views, F or numpad . to frame the selected object; Delete or X deletes it, Shift+D duplicates it; Tab
    says what it would do elsewhere. Not while text is typed, a question is open or a grab, rotate or scale runs (X
    is its axis key then)."""
    io = imgui.get_io()
    if io.want_text_input or app.prompt is not None or transforming:
        return
    for key, side, opposite in VIEW_KEYS:
        if imgui.is_key_pressed(key, False):
            app.look_from(opposite if io.key_ctrl else side)
    if io.key_ctrl:
        return
    if imgui.is_key_pressed(imgui.Key.f, False) or imgui.is_key_pressed(imgui.Key.keypad_decimal, False):
        app.frame_object()
    elif imgui.is_key_pressed(imgui.Key.delete, False) or imgui.is_key_pressed(imgui.Key.x, False):
        app.delete_selected()
    elif io.key_shift and imgui.is_key_pressed(imgui.Key.d, False):
        app.duplicate_selected()
    elif imgui.is_key_pressed(imgui.Key.tab, False):
        app.say("no edit mode: paint voxels in the Paint tab, move the object with G, R and S", error=True)


class HelpWindow:
    """The keyboard shortcuts window: F1 or Help > Keyboard shortcuts opens and closes it, Escape or its button
    closes it."""

    def __init__(self) -> None:
        self.shown = False

    def toggle_on_f1(self) -> None:
        if not imgui.get_io().want_text_input and imgui.is_key_pressed(imgui.Key.f1, False):
            self.shown = not self.shown

    def draw(self, escape_is_free: bool) -> None:
        if not self.shown:
            return
        if escape_is_free and not imgui.get_io().want_text_input and imgui.is_key_pressed(imgui.Key.escape, False):
            self.shown = False
            return
        imgui.set_next_window_size(imgui.ImVec2(620, 0), imgui.Cond_.appearing)
        visible, opened = imgui.begin("Keyboard shortcuts", True, imgui.WindowFlags_.no_collapse)
        self.shown = bool(opened)
        if visible and imgui.begin_table("bindings", 2, imgui.TableFlags_.row_bg):
            for keys, what in BINDINGS:
                imgui.table_next_row()
                imgui.table_next_column()
                imgui.text(keys)
                imgui.table_next_column()
                imgui.text_wrapped(what)
            imgui.end_table()
        imgui.end()
