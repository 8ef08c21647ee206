"""The interface drawn each frame with Dear ImGui: menu, viewport, live render, tools, status bar, questions.

Numeric fields preview their value while being dragged or typed and commit one undo step
when released, like every other edit.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from imgui_bundle import imgui

from app.editor import edits, state
from app.editor.app import MESSAGE_SECONDS, PALETTE, EditorApp
from app.editor.file_browser import FileBrowser
from app.editor.file_dialog import FileDialog, FileKind, dialog_command, dialog_program
from app.editor.files import shipped
from app.editor.frame_damage import Box
from app.editor.keys import HelpWindow, view_keys
from app.editor.layout import RIGHT_WIDTH, Layout, Rect, layout_for
from app.editor.light_panel import EnvironmentPreview, draw_floor, draw_lighting, draw_material
from app.editor.orbit_view import viewport_camera
from app.editor.outliner import ADD_FILES, draw_outliner
from app.editor.photo_panel import GRAY, PhotoPanel
from app.editor.viewport_input import ViewportInput
from models.renderers import INTERACTIVE, RENDERERS
from renderer.errors import InputError
from renderer.limits import MAX_OBJECTS, MAX_RESOLUTION
from renderer.mesh import MESH_EXTENSIONS
from renderer.paint import fill_region_voxels
from renderer.scene import range_warnings

BORDER_GRIP = 8  # the width, in pixels, of the strip along the column border that drags it
FIXED = (imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_collapse
         | imgui.WindowFlags_.no_bring_to_front_on_focus | imgui.WindowFlags_.no_saved_settings)
RED = imgui.ImVec4(1.0, 0.42, 0.38, 1.0)
AMBER = imgui.ImVec4(1.0, 0.75, 0.3, 1.0)
GREEN = imgui.ImVec4(0.5, 0.85, 0.5, 1.0)
MESH_FILES = FileKind("Open a mesh", "Meshes", ("*.obj", "*.ply", "*.stl", "*.off", "*.glb", "*.gltf"))
SCENE_FILES = FileKind("Open a scene, a mesh or a MagicaVoxel model", "Scenes, meshes, .vox models",
                       ("*.json", *(f"*{suffix}" for suffix in MESH_EXTENSIONS), "*.vox"))
NEW_SCENE_FILE = FileKind("Save the scene as", "Scenes", ("*.json",), save=True)
NEW_PNG_FILE = FileKind("Export as", "PNG images", ("*.png",), save=True)
NEW_GIF_FILE = FileKind("Export the turntable as", "GIF animations", ("*.gif",), save=True)
VOX_FILES = FileKind("Import a MagicaVoxel model", "MagicaVoxel models", ("*.vox",))
NEW_VOX_FILE = FileKind("Export the voxels as", "MagicaVoxel models", ("*.vox",), save=True)
EXPORT_SIZES = (None, 512, 1024, 2048)  # None: the scene's size
RATE_REFRESH_SECONDS = 0.5  # the frame-time text changes at most this often: a window that looks the same is not redrawn
PREVIEW_DELAY_SECONDS = 0.15  # the bucket rests this long on a voxel before its region is tinted
PREVIEW_MIX = 0.6  # how far the tint goes towards the paint color


@dataclass
class Fields:
    """Text typed into the path fields."""

    scene_path: str = ""
    save_path: str = ""
    export_path: str = "render.png"
    side_by_side_path: str = "viewport_and_render.png"
    turntable_path: str = "turntable.gif"
    export_size: int = 0  # index into EXPORT_SIZES
    export_finer: bool = False  # voxelise the mesh at MAX_RESOLUTION for exports
    vox_in_path: str = ""
    vox_out_path: str = "object.vox"
    mesh_path: str = ""
    mesh_up: int = 0  # 0: y up, 1: z up
    photo_path: str = ""
    camera_path: str = ""
    environment_path: str = ""
    floor_texture_path: str = ""
    show_environment_field: bool = False  # the environment image's path field, before an image is loaded
    add_object_path: str = ""
    object_name: str = ""  # the selected object's name, as typed
    object_name_for: tuple | None = None  # the document, object and name the name field was last set from


OUTPUT_FIELDS = ("export_path", "side_by_side_path", "turntable_path", "vox_out_path")  # written beside the scene


class Interface:
    """Draws the whole window for an EditorApp and routes what the user does to its commands."""

    def __init__(self, app: EditorApp):
        self.app = app
        self.fields = Fields(scene_path=str(app.doc.path or ""))
        self._outputs_for: Path | None | bool = False  # the scene file the output fields follow (False: none yet)
        self._follow_scene_file()
        self.viewport_input = ViewportInput()
        self.help = HelpWindow()
        self.right_width = RIGHT_WIDTH  # the render and tools column's, as the user drags the border
        self._border_drag = False
        self.border_hot = False  # the mouse is on the column border, or drags it
        self.photo_panel = PhotoPanel(app)
        self.environment_preview = EnvironmentPreview()
        self.underlay = None
        self.images = ()  # where the viewport and the render appear, with their versions (see Window.end_frame)
        self._popup_title: str | None = None
        self.field_error: tuple[str, str] | None = None  # (field, why its typed value was refused)
        self._document = app.doc  # the document the field error belongs to
        self.dialog_program = dialog_program()  # None: the editor's own file browser (app/editor/file_browser.py)
        self._file_dialog = None  # an open dialog, the field its answer goes to, and what to do with it (or None)
        self._recent: list[Path] = []  # the File menu's recent scenes
        self._mesh_shown: Path | None = None  # the object mesh the mesh field was last set to
        self._hover: tuple = (None, 0.0)  # the bucket's voxel (with tolerance, color, voxels) and since when
        self._preview_key = None  # what the viewport's tinted region shows, None when it shows the voxels as they are
        self._rate_text, self._rate_time = "", 0.0

    def _forget_old_document(self) -> None:
        """A field's refused value belongs to the scene it was typed for: Open, New or a restore forgets it."""
        if self._document is not self.app.doc:
            self._document, self.field_error = self.app.doc, None

    def _follow_scene_file(self) -> None:
        """Save as and the exports default to the open scene's folder: when the scene file changes (Open, New, Save
        as), each output field keeps its file name and moves beside the new scene."""
        path = self.app.doc.path
        if path == self._outputs_for:
            return
        self._outputs_for, f, folder = path, self.fields, _output_folder(path)
        f.save_path = str(_save_as_default(path))
        for name in OUTPUT_FIELDS:
            setattr(f, name, str(folder / Path(getattr(f, name)).name))

    def draw(self) -> None:
        app = self.app
        self._follow_scene_file()
        self._forget_old_document()
        width, height = app.window.size
        panels = layout_for(width, height, self.right_width)
        escape_is_free = not self.viewport_input.interacting  # else Esc cancels the drag or the G/R/S in progress
        self._menu()
        self._column_border(panels, width)
        self.photo_panel.shown = None  # set again if the photo is drawn (over the viewport or in the Photo tab)
        self._viewport(panels.viewport)
        if not self.photo_panel.fills_viewport():
            draw_outliner(self, panels.viewport)
        self._render_panel(panels.render, panels.render_image)
        self._tools(panels.tools)
        self._status(panels.status)
        self._reference_window(panels.viewport, escape_is_free)
        self.help.toggle_on_f1()
        self.help.draw(escape_is_free)
        self._prompt()
        self._shortcuts()
        view_keys(app, self.viewport_input.interacting)
        self._poll_file_dialog()
        framebuffer, x, y = self.underlay
        self.images = ((_box(Rect(x, y, *framebuffer.size)), app.viewport.version),
                       (_box(panels.render_image), app.render_uploads))
        if self.photo_panel.shown is not None:
            self.images += (self.photo_panel.shown,)

    # --- menu and shortcuts --------------------------------------------------------------

    def _menu(self) -> None:
        app = self.app
        if not imgui.begin_main_menu_bar():
            return
        if imgui.begin_menu("File"):
            if imgui.menu_item_simple("New", "Ctrl+N"):
                app.files.new_scene()
            if imgui.menu_item_simple("Open...", "Ctrl+O"):
                self.ask_path(SCENE_FILES, "scene_path", app.files.open)
            if imgui.begin_menu("Open recent", enabled=bool(self._recent)):
                for path in self._recent:
                    if imgui.menu_item_simple(str(path)):
                        app.files.open_scene(path)
                imgui.end_menu()
            if imgui.menu_item_simple("Save", "Ctrl+S"):
                app.files.save()
            if imgui.menu_item_simple("Save as...", "Ctrl+Shift+S"):
                self.ask_path(NEW_SCENE_FILE, "save_path", app.files.save)
            imgui.separator()
            if imgui.menu_item_simple("Export render", "Ctrl+E"):
                app.files.export(self.fields.export_path, size=EXPORT_SIZES[self.fields.export_size],
                             voxels=self._export_voxels())
            if imgui.menu_item_simple("Export viewport and render"):
                app.files.export_side_by_side(self.fields.side_by_side_path)
            if imgui.menu_item_simple("Export turntable"):
                app.files.export_turntable(self.fields.turntable_path)
            imgui.separator()
            if imgui.menu_item_simple("Import .vox..."):
                self.ask_path(VOX_FILES, "vox_in_path", app.files.import_vox)
            if imgui.menu_item_simple("Export .vox"):
                app.files.export_vox(self.fields.vox_out_path)
            imgui.separator()
            if imgui.menu_item_simple("Quit", "Ctrl+Q"):
                app.request_quit()
            imgui.end_menu()
        else:
            self._recent = state.recent_scenes()  # read while the menu is closed, not every frame it is open
        if imgui.begin_menu("Object"):
            if imgui.menu_item_simple("Add...", enabled=len(app.scene.objects) < MAX_OBJECTS):
                self.ask_path(ADD_FILES, "add_object_path", app.add_object)
            if imgui.menu_item_simple("Duplicate", "Shift+D"):
                app.duplicate_selected()
            if imgui.menu_item_simple("Delete", "X, Delete", enabled=len(app.scene.objects) > 1):
                app.delete_selected()
            imgui.end_menu()
        if imgui.begin_menu("View"):
            if imgui.menu_item_simple("Through the render camera", "Home"):
                app.view_through_render_camera()
            if imgui.menu_item_simple("Reset view"):
                app.reset_view()
            imgui.separator()
            for label, side, key in (("Front", "front", "Numpad 1"), ("Right", "right", "Numpad 3"),
                                     ("Top", "top", "Numpad 7")):
                if imgui.menu_item_simple(label, key):
                    app.look_from(side)
            if imgui.menu_item_simple("Frame the object", "F"):
                app.frame_object()
            imgui.end_menu()
        if imgui.begin_menu("Edit"):
            if imgui.menu_item_simple("Undo", "Ctrl+Z", enabled=app.doc.history.can_undo):
                app.undo()
            if imgui.menu_item_simple("Redo", "Ctrl+Shift+Z", enabled=app.doc.history.can_redo):
                app.redo()
            imgui.end_menu()
        if imgui.begin_menu("Help"):
            if imgui.menu_item_simple("Keyboard shortcuts", "F1"):
                self.help.shown = True
            imgui.end_menu()
        title = app.doc.path.name if app.doc.path else "untitled"
        imgui.text_colored(GRAY, f"   {title}{' *' if app.doc.dirty else ''}")
        imgui.end_main_menu_bar()

    def _shortcuts(self) -> None:
        app, io = self.app, imgui.get_io()
        if not io.want_text_input and app.prompt is None and imgui.is_key_pressed(imgui.Key.home, False):
            app.view_through_render_camera()
        if io.want_text_input or not io.key_ctrl or app.prompt is not None:
            return
        if imgui.is_key_pressed(imgui.Key.z, False):
            app.redo() if io.key_shift else app.undo()
        elif imgui.is_key_pressed(imgui.Key.y, False):
            app.redo()
        elif imgui.is_key_pressed(imgui.Key.s, False):
            if io.key_shift:
                self.ask_path(NEW_SCENE_FILE, "save_path", app.files.save)
            elif app.doc.path is None:
                self.ask_path(NEW_SCENE_FILE, "save_path", app.files.save)
            else:
                app.files.save()
        elif imgui.is_key_pressed(imgui.Key.n, False):
            app.files.new_scene()
        elif imgui.is_key_pressed(imgui.Key.o, False):
            self.ask_path(SCENE_FILES, "scene_path", app.files.open)
        elif imgui.is_key_pressed(imgui.Key.e, False):
            app.files.export(self.fields.export_path, size=EXPORT_SIZES[self.fields.export_size],
                             voxels=self._export_voxels())
        elif imgui.is_key_pressed(imgui.Key.q, False):
            app.request_quit()

    def _column_border(self, panels: Layout, width: int) -> None:
        """The border between the viewport and the right column: dragging it sizes the columns (the render panel
        grows with its column, and a settled render is drawn again at the panel's size). Found by the mouse's place,
        not by a window of its own: the panels either side would take the click."""
        io = imgui.get_io()
        x, top, body = panels.render.x, panels.viewport.y, panels.viewport.height
        near = abs(io.mouse_pos.x - x) <= BORDER_GRIP / 2 and top <= io.mouse_pos.y < top + body
        if self._border_drag:
            if imgui.is_mouse_down(imgui.MouseButton_.left):
                self.right_width = int(width - io.mouse_pos.x)
            else:
                self._border_drag = False
        elif (near and imgui.is_mouse_clicked(imgui.MouseButton_.left) and self.app.prompt is None
              and not imgui.is_any_item_active() and not self.viewport_input.interacting):
            self._border_drag = True
        self.border_hot = near or self._border_drag  # the viewport leaves the mouse to the border then
        if self.border_hot:
            imgui.set_mouse_cursor(imgui.MouseCursor_.resize_ew)

    # --- viewport -----------------------------------------------------------------------

    def _viewport(self, rect: Rect) -> None:
        app = self.app
        _place(rect)
        imgui.push_style_var(imgui.StyleVar_.window_padding, imgui.ImVec2(0, 0))
        imgui.begin("Viewport", None, FIXED | imgui.WindowFlags_.no_title_bar | imgui.WindowFlags_.no_scrollbar
                    | imgui.WindowFlags_.no_scroll_with_mouse | imgui.WindowFlags_.no_background)
        imgui.pop_style_var()
        size = imgui.get_content_region_avail()
        w, h = max(int(size.x), 1), max(int(size.y), 1)
        origin = imgui.get_cursor_screen_pos()
        inputs = self.viewport_input
        framebuffer = app.viewport.draw(w, h, viewport_camera(app.view, w, h), app.scene, app.floor_color,
                                        light_active=inputs.light_drag is not None or inputs.light_hovered,
                                        picked_voxel=inputs.hovered_voxel,
                                        moving=inputs.interacting or app.doc.previewing, selected=app.selected,
                                        hidden=app.hidden)
        self.underlay = (framebuffer, int(origin.x), int(origin.y))  # copied under the interface (Window.end_frame)
        if self.photo_panel.fills_viewport():  # the photo being aligned covers the view, with its own gestures
            self.photo_panel.draw_in_viewport(origin, w, h)
            imgui.end()
            return
        imgui.invisible_button("viewport", imgui.ImVec2(w, h), imgui.ButtonFlags_.mouse_button_left
                               | imgui.ButtonFlags_.mouse_button_right | imgui.ButtonFlags_.mouse_button_middle)
        hovered = imgui.is_item_hovered() and app.prompt is None and not self.border_hot
        mouse = imgui.get_io().mouse_pos
        inputs.update(app, (mouse.x - origin.x, mouse.y - origin.y), (w, h), hovered)
        self._bucket_preview(inputs.hovered_voxel)
        imgui.set_cursor_screen_pos(imgui.ImVec2(origin.x + 8, origin.y + 6))
        imgui.text_colored(GRAY, inputs.hint)
        _range_note(app.scene, imgui.ImVec2(origin.x + 8, origin.y + h - (60 if app.jobs.current is not None else 30)))
        if inputs.light_hovered or inputs.light_drag is not None:
            imgui.set_mouse_cursor(imgui.MouseCursor_.resize_all)
        if hovered and app.bucket_active:
            imgui.set_mouse_cursor(imgui.MouseCursor_.hand)  # with the paint drop below: the bucket
        if inputs.hovered_voxel is not None:  # the bucket cursor: the color a click would pour
            draw = imgui.get_window_draw_list()
            color = imgui.get_color_u32(imgui.ImVec4(*app.paint_color, 1.0))
            draw.add_circle_filled(imgui.ImVec2(mouse.x + 12, mouse.y + 12), 7.0, color)
            draw.add_circle(imgui.ImVec2(mouse.x + 12, mouse.y + 12), 7.0, imgui.get_color_u32(imgui.ImVec4(1, 1, 1, 1)))
        if app.jobs.current is not None:
            imgui.set_cursor_screen_pos(imgui.ImVec2(origin.x + 8, origin.y + h - 34))
            imgui.progress_bar(app.jobs.current.progress, imgui.ImVec2(min(360, w - 16), 0), f"{app.jobs.current.title} {app.jobs.current.progress:.0%}")
        imgui.end()

    def _bucket_preview(self, voxel: tuple[int, int, int] | None) -> None:
        """Tint the region a click would fill once the bucket rests on a voxel for PREVIEW_DELAY_SECONDS, so a
        tolerance that leaves speckles shows before the click; the tint goes when the cursor leaves."""
        app, now = self.app, time.monotonic()
        rgba = app.shown_rgba
        wanted = None if voxel is None or rgba is None else (voxel, app.tolerance, app.similarity,
                                                             tuple(app.paint_color), id(rgba))
        if wanted != self._hover[0]:
            self._hover = (wanted, now)
        target = wanted if wanted is not None and now - self._hover[1] >= PREVIEW_DELAY_SECONDS else None
        if target == self._preview_key:
            return
        if target is None:
            if rgba is not None:
                app.viewport.recolor(rgba)
            self._preview_key = None
            return
        try:
            region = fill_region_voxels(rgba, voxel, app.tolerance, similarity=app.similarity)
        except InputError:
            return
        tint = (1.0 - PREVIEW_MIX) * rgba.reshape(-1, 4)[region, :3] + PREVIEW_MIX * np.asarray(app.paint_color)
        app.viewport.recolor(rgba, (region, tint))
        self._preview_key = target

    # --- live render --------------------------------------------------------------------

    def _render_panel(self, rect: Rect, image: Rect) -> None:
        app = self.app
        _place(rect)
        imgui.begin("Render", None, FIXED | imgui.WindowFlags_.no_scrollbar)
        self._renderer_choice()
        imgui.same_line()
        if imgui.small_button("Reference"):
            app.reference.start()
        if imgui.is_item_hovered():
            imgui.set_tooltip("Path trace the scene (edits included) in the background and show it beside this render")
        imgui.same_line()
        frame = app.shown_frame
        if frame is None:
            imgui.text_colored(AMBER, "rendering...")
        else:
            stale = frame.scene != app.submitted
            if stale:
                imgui.text_colored(AMBER, "STALE")
            elif frame.preview:
                imgui.text_colored(AMBER, "PREVIEW")
            else:
                imgui.text_colored(GREEN, "UP TO DATE")
            imgui.same_line()
            if frame.note:  # the renderer drew something else than usual (a scene its network is not trained for)
                imgui.text_colored(AMBER, f"shader only, {frame.seconds * 1000:.0f} ms")
                if imgui.is_item_hovered():
                    imgui.set_tooltip(frame.note)
            else:
                imgui.text_colored(GRAY, f"last render {frame.seconds * 1000:.0f} ms")
        if not app.live.neural:
            imgui.same_line()
            imgui.text_colored(AMBER, app.live.label)
        app.live.panel_size = int(min(image.width, image.height))  # what a settled image is drawn again at
        if app.render_texture is not None:
            imgui.set_cursor_screen_pos(imgui.ImVec2(image.x, image.y))
            imgui.image(imgui.ImTextureRef(app.render_texture.glo), imgui.ImVec2(image.width, image.height))
        imgui.end()

    def _renderer_choice(self) -> None:
        """The renderer of the panel (and of exports): the voxel shader or NVR+."""
        live = self.app.live
        names = list(INTERACTIVE)
        imgui.set_next_item_width(150)
        changed, index = imgui.combo("##renderer", names.index(live.renderer), [RENDERERS[n].label for n in names])
        if changed and names[index] != live.renderer:
            self.app.choose_renderer(names[index])

    # --- tools --------------------------------------------------------------------------

    def _tools(self, rect: Rect) -> None:
        _place(rect)
        imgui.begin("Tools", None, FIXED)
        app = self.app
        if imgui.begin_tab_bar("tool tabs"):
            for name, draw in (("Object", self._object_tab), ("Light & camera", self._light_tab),
                               ("Paint", self._paint_tab), ("Photo", self._photo_tab), ("File", self._file_tab)):
                flags = imgui.TabItemFlags_.set_selected if app.requested_tab == name else 0
                opened, _ = imgui.begin_tab_item(name, None, flags)
                if opened:
                    app.tools_tab = name
                    draw()
                    imgui.end_tab_item()
            imgui.end_tab_bar()
        app.requested_tab = None
        imgui.end()

    def edit_field(self, key: str, changed: bool, make_scene, of_object: bool = False) -> None:
        """Preview an edited numeric field; commit one undo step when the field is released. A value the
        scene cannot take is refused: the message shows under the field and the previous value stays. `of_object`:
        the field is the selected object's (`make_scene` edits the scene holding it alone: EditorApp.edit_object)."""
        if changed:
            edit = self.app.edit_object if of_object else self.app.edit
            if edit(make_scene, preview=True):
                self.field_error = None if self.field_error and self.field_error[0] == key else self.field_error
            else:
                self.field_error = (key, self.app.message.text if self.app.message else "value refused")
        if imgui.is_item_deactivated_after_edit():
            self.app.commit_preview()
        if self.field_error is not None and self.field_error[0] == key:
            imgui.push_style_color(imgui.Col_.text, RED)
            imgui.text_wrapped(self.field_error[1])
            imgui.pop_style_color()

    def _object_tab(self) -> None:
        o = self.app.selected_object
        changed, t = imgui.drag_float2("position x, z", list(o.translation), 0.01, -edits.MAX_POSITION, edits.MAX_POSITION, "%.3f")
        self.edit_field("position", changed, lambda s: edits.place_object(s, translation=tuple(t)), of_object=True)
        changed, r = imgui.drag_float("rotation (deg)", o.rotation_deg, 0.5, -180.0, 180.0, "%.1f")
        self.edit_field("rotation", changed, lambda s: edits.place_object(s, rotation_deg=r), of_object=True)
        changed, sc = imgui.drag_float3("scale x, y, z", list(o.scale), 0.01, edits.MIN_SCALE, edits.MAX_SCALE, "%.3f")
        self.edit_field("scale", changed, lambda s: edits.place_object(s, scale=tuple(sc)), of_object=True)
        imgui.separator()
        f = self.fields
        mesh = self.app.scene.file(o.mesh)
        if mesh != self._mesh_shown:  # the field shows the object's mesh (after loading, opening, undo)
            f.mesh_path, self._mesh_shown = str(mesh.resolve()) if mesh else "", mesh
        _, f.mesh_path = imgui.input_text("mesh file", f.mesh_path)
        self.browse_button("mesh", MESH_FILES, "mesh_path")
        _, f.mesh_up = imgui.combo("up axis", f.mesh_up, ["y up", "z up"])
        if imgui.button("Load and voxelise") and f.mesh_path:
            self.app.files.load_mesh(f.mesh_path, up="yz"[f.mesh_up])
        imgui.separator()
        draw_material(self)

    def _light_tab(self) -> None:
        scene = self.app.scene
        draw_lighting(self)
        imgui.separator()
        changed, e = imgui.slider_float("camera elevation", scene.camera.elevation_deg, 0.0, edits.MAX_ELEVATION, "%.1f deg")
        self.edit_field("elevation", changed, lambda s: edits.set_elevation(s, e))
        draw_floor(self)
        imgui.text_colored(GRAY, "Drag the light square in the viewport; Shift+drag sets its height.")

    def _paint_tab(self) -> None:
        app = self.app
        if imgui.radio_button("select / move light", app.tool == "select"):
            app.tool = "select"
        imgui.same_line()
        if imgui.radio_button("bucket fill", app.tool == "paint"):
            app.tool = "paint"
        for i, color in enumerate(PALETTE):
            if i % 12:
                imgui.same_line()
            if imgui.color_button(f"palette {i}", imgui.ImVec4(*color, 1.0), 0, imgui.ImVec2(22, 22)):
                app.paint_color = color
                app.tool = "paint"
        _, c = imgui.color_edit3("paint color", list(app.paint_color))
        app.paint_color = tuple(c)
        _, app.tolerance = imgui.slider_float("tolerance", app.tolerance, 0.0, 1.0, "%.2f")
        _, perceptual = imgui.checkbox("perceptual colors", app.similarity == "perceptual")
        app.similarity = "perceptual" if perceptual else "rgb"
        if imgui.is_item_hovered():
            imgui.set_tooltip("Compare colors as the eye does, each voxel's averaged with its neighbours: a fill\n"
                              "covers a textured or photo-colored part without leaving blotches. Off: exact RGB.")
        if imgui.button("Fill whole object"):
            app.fill_object()
        imgui.same_line()
        if imgui.button("Fill floor"):
            app.fill_floor()

    def _photo_tab(self) -> None:
        self.photo_panel.draw(self.fields, self.browse_button)

    def _file_tab(self) -> None:
        f, app = self.fields, self.app
        for key, kind, field_name, label, act in (
                ("open", SCENE_FILES, "scene_path", "Open", app.files.open),
                ("save", NEW_SCENE_FILE, "save_path", "Save as", app.files.save),
                ("export", NEW_PNG_FILE, "export_path", "Export PNG",
                 lambda p: app.files.export(p, size=EXPORT_SIZES[f.export_size], voxels=self._export_voxels())),
                ("side by side", NEW_PNG_FILE, "side_by_side_path", "Export viewport + render", app.files.export_side_by_side),
                ("turntable", NEW_GIF_FILE, "turntable_path", "Export turntable", app.files.export_turntable),
                ("import vox", VOX_FILES, "vox_in_path", "Import .vox", app.files.import_vox),
                ("export vox", NEW_VOX_FILE, "vox_out_path", "Export .vox", app.files.export_vox)):
            imgui.set_next_item_width(200)
            _, path = imgui.input_text(f"##{key}", getattr(f, field_name))
            setattr(f, field_name, path)
            self.browse_button(key, kind, field_name)
            imgui.same_line()
            if imgui.button(label) and path:
                act(path)
            if key == "export":
                imgui.set_next_item_width(200)
                any_size = app.live.renders_any_size
                scene_size = f"{app.scene.image_size} px (the scene's)"
                _, f.export_size = imgui.combo("export size", f.export_size,
                                               [scene_size] + [f"{s} px" + ("" if any_size else " (upscaled)")
                                                               for s in EXPORT_SIZES[1:]])
                o = app.selected_object
                imgui.text_colored(GRAY, f"the object's voxels: {o.resolution}^3")
                if o.mesh is not None and o.resolution < MAX_RESOLUTION:
                    imgui.same_line()
                    _, f.export_finer = imgui.checkbox(f"voxelise at {MAX_RESOLUTION}^3 to export", f.export_finer)

    def _export_voxels(self) -> int | None:
        """The voxels an export draws the object with: MAX_RESOLUTION when the File tab asks for finer ones."""
        o = self.app.selected_object
        return MAX_RESOLUTION if self.fields.export_finer and o.mesh is not None and o.resolution < MAX_RESOLUTION else None

    def browse_button(self, key: str, kind: FileKind, field_name: str) -> None:
        """A Browse button after a path field: the chosen file fills the field."""
        imgui.same_line()
        if imgui.button(f"Browse##{key}") and self._file_dialog is None:
            self._file_dialog = (self._dialog(kind, getattr(self.fields, field_name)), field_name, None)

    def ask_path(self, kind: FileKind, field_name: str, then) -> None:
        """A file for a menu command, from a file dialog (`then` gets it)."""
        if self._file_dialog is None:
            self._file_dialog = (self._dialog(kind, getattr(self.fields, field_name)), field_name, then)

    def _dialog(self, kind: FileKind, start: str) -> FileDialog | FileBrowser:
        """The system's file dialog when one is installed, else the editor's own browser."""
        if self.dialog_program is None:
            return FileBrowser(kind, start)
        return FileDialog(dialog_command(self.dialog_program, kind, start))

    def _poll_file_dialog(self) -> None:
        if self._file_dialog is None:
            return
        dialog, field_name, then = self._file_dialog
        if not dialog.poll():
            return
        self._file_dialog = None
        if dialog.error:
            self.app.say(dialog.error, error=True)
        elif dialog.path:
            setattr(self.fields, field_name, dialog.path)
            if then is not None:
                then(dialog.path)

    def close(self) -> None:
        """Close a file dialog left open; release the photo's and the environment's textures."""
        if self._file_dialog is not None:
            self._file_dialog[0].close()
        self.photo_panel.close()
        self.environment_preview.close()

    # --- the reference render -------------------------------------------------------------

    def _reference_window(self, viewport: Rect, escape_is_free: bool) -> None:
        """The path-traced reference over the viewport's top right, inside it whatever its label's length: its error
        against the live render first, then the image. Its close button, or Escape, closes it."""
        app, reference = self.app, self.app.reference
        if reference.shown is None or reference.texture is None:
            return
        io = imgui.get_io()
        if escape_is_free and not io.want_text_input and app.prompt is None and imgui.is_key_pressed(imgui.Key.escape):
            reference.close()
            return
        side = min(256, viewport.width // 2, viewport.height - 80)
        width = side + 2 * imgui.get_style().window_padding.x
        imgui.set_next_window_pos(imgui.ImVec2(viewport.x + viewport.width - width - 8, viewport.y + 8), imgui.Cond_.always)
        imgui.set_next_window_size(imgui.ImVec2(width, 0), imgui.Cond_.always)
        opened, keep = imgui.begin("Reference", True, FIXED | imgui.WindowFlags_.no_scrollbar)
        if opened:
            imgui.push_text_wrap_pos(0.0)  # wrap at the window's edge: a long model name never widens it
            error = reference.error(app.shown_frame)
            if error is not None:
                imgui.text_wrapped(f"MSE {error:.1f} (0-255) against {app.live.label}")
            else:
                imgui.text_colored(AMBER, "the scene changed since: press Reference again")
            imgui.image(imgui.ImTextureRef(reference.texture.glo), imgui.ImVec2(side, side))
            imgui.text_colored(GRAY, reference.shown.label)
            imgui.pop_text_wrap_pos()
        imgui.end()
        if not keep:
            reference.close()

    # --- status bar and questions -------------------------------------------------------

    def _status(self, rect: Rect) -> None:
        app = self.app
        _place(rect)
        imgui.push_style_var(imgui.StyleVar_.window_padding, imgui.ImVec2(8, 4))
        imgui.begin("Status", None, FIXED | imgui.WindowFlags_.no_title_bar | imgui.WindowFlags_.no_scrollbar)
        imgui.pop_style_var()
        frame = app.shown_frame
        render_ms = f"{frame.seconds * 1000:.0f} ms/render" if frame else "-"
        info = f"{app.live.label}  |  {app.live.device}  |  {self._frame_time_text()}  |  {render_ms}"
        message = app.message
        if message is not None and (message.error or time.monotonic() - message.shown_at < MESSAGE_SECONDS):
            # The message comes first and is cut to the room left by the status; all of it on hover (and on stderr).
            room = imgui.get_content_region_avail().x - imgui.calc_text_size(info).x - 24
            text = _fit(message.text, room)
            imgui.text_colored(RED if message.error else GREEN, text)
            if text != message.text and imgui.is_item_hovered():
                imgui.set_tooltip(message.text)
            imgui.same_line()
        imgui.set_cursor_pos_x(max(imgui.get_cursor_pos_x(), imgui.get_window_width() - imgui.calc_text_size(info).x - 8))
        imgui.text_colored(GRAY, info)
        imgui.end()

    def _frame_time_text(self) -> str:
        """The UI's work per drawn frame, or "idle"; refreshed at most every RATE_REFRESH_SECONDS so an idle
        window is not redrawn for a changing number."""
        now = time.monotonic()
        if now - self._rate_time >= RATE_REFRESH_SECONDS:
            self._rate_text, self._rate_time = self.app.stats.current_text(), now
        return self._rate_text

    def _prompt(self) -> None:
        prompt = self.app.prompt
        if prompt is None:
            self._close_answered_popup()
            return
        self._popup_title = prompt.title
        if not imgui.is_popup_open(prompt.title):
            imgui.open_popup(prompt.title)
        width, height = self.app.window.size
        imgui.set_next_window_pos(imgui.ImVec2(width / 2, height / 2), imgui.Cond_.always, imgui.ImVec2(0.5, 0.5))
        opened, _ = imgui.begin_popup_modal(prompt.title, None, imgui.WindowFlags_.always_auto_resize)
        if opened:
            imgui.text(prompt.text)
            for i, choice in enumerate(prompt.choices):
                if i:
                    imgui.same_line()
                if imgui.button(choice, imgui.ImVec2(100, 0)):
                    imgui.close_current_popup()
                    self.app.answer(choice)
            imgui.end_popup()

    def _close_answered_popup(self) -> None:
        """Close the question's popup when it was answered elsewhere (a replay file)."""
        if self._popup_title is not None and imgui.is_popup_open(self._popup_title):
            if imgui.begin_popup_modal(self._popup_title)[0]:
                imgui.close_current_popup()
                imgui.end_popup()
        self._popup_title = None


def _box(rect: Rect) -> Box:
    return rect.x, rect.y, rect.x + rect.width, rect.y + rect.height


def _place(rect: Rect) -> None:
    imgui.set_next_window_pos(imgui.ImVec2(rect.x, rect.y), imgui.Cond_.always)
    imgui.set_next_window_size(imgui.ImVec2(rect.width, rect.height), imgui.Cond_.always)


def _fit(text: str, width: float) -> str:
    """`text` cut (with an ellipsis) to fit `width` pixels of the current font."""
    if imgui.calc_text_size(text).x <= width:
        return text
    low, high = 0, len(text)
    while low < high:
        mid = (low + high + 1) // 2
        if imgui.calc_text_size(text[:mid] + "...").x <= width:
            low = mid
        else:
            high = mid - 1
    return text[:low] + "..."


def _range_note(scene, position: imgui.ImVec2) -> None:
    """Amber text at `position` when the scene leaves the network's training ranges (it extrapolates there)."""
    warnings = range_warnings(scene)
    if not warnings:
        return
    more = f" (and {len(warnings) - 1} more)" if len(warnings) > 1 else ""
    imgui.set_cursor_screen_pos(position)
    imgui.text_colored(AMBER, f"Outside the training range: {warnings[0]}{more}")
    if imgui.is_item_hovered():
        imgui.set_tooltip("The network was trained inside these ranges and extrapolates outside them:\n" + "\n".join(warnings))


def _output_folder(path: Path | None) -> Path:
    """Where exports go by default: beside the scene file, or the working folder for a scene shipped with the
    product (or none)."""
    if path is None or shipped(path):
        return Path(".").resolve()
    return path.resolve().parent


def _save_as_default(path: Path | None) -> Path:
    """The Save-as field's first value: the scene's own file, or for a scene that ships with the product
    (or none) a file of that name in the working folder."""
    if path is None:
        return Path("scene.json").resolve()
    return Path(path.name).resolve() if shipped(path) else path.resolve()
