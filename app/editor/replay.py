"""Replay files: a JSON list of actions the editor performs one per frame, for tests and demos.

High-level actions call the same commands as the interface:
    {"action": "drag_light", "to": [x, y, z], "steps": 8}     preview on the way, one undo step
    {"action": "move_object", "translation": [x, z]}          also "rotate_object" {"deg"}, "scale_object" {"scale"}
                                                              (the selected object, as every object tool)
    {"action": "select", "index": 1}                          {"action": "rename", "name": "table"} (the selected)
    {"action": "add_object", "path": "table.obj", "up": "y"}  a mesh or .vox, where the floor has room, selected
    {"action": "duplicate"} {"action": "delete"}              the selected object (as Shift+D, X)
    {"action": "hide", "index": 0}                           hide from the viewport, or show again (the list's box)
    {"action": "set_elevation", "deg": 20}                    {"action": "set_floor_color", "color": [r, g, b]}
    {"action": "use_sky"} {"action": "set_sky", "elevation": 35, "azimuth": 120, "turbidity": 3}
    {"action": "load_environment", "path": "studio.hdr"}     {"action": "no_environment"} (the ambient light again)
    {"action": "turn_environment", "deg": 90, "strength": 1.5} either      {"action": "area_light", "on": false}
    {"action": "load_floor_texture", "path": "wood.png"}     {"action": "floor_texture_scale", "scale": 0.5}
    {"action": "no_floor_texture"}                            the plain floor color again
    {"action": "floor_shape", "shape": "disk"}                "square" or "disk"
    {"action": "material", "preset": "metal", "roughness": 0.2}   a preset (matte, plastic, ceramic, rubber, metal)
                                                              and/or roughness, specular, metallic
    {"action": "paint", "voxel": [i, j, k], "color": [r, g, b], "tolerance": 0.1, "similarity": "rgb"}
    {"action": "fill_object", "color": [...]}                 {"action": "fill_floor", "color": [...]}
    {"action": "undo"} {"action": "redo"}
    {"action": "open", "path": ...} (a scene, mesh or .vox) {"action": "save", "path": ...} {"action": "export", "path": ..., "size": 512, "voxels": 256}
    {"action": "export_side_by_side", "path": ...}            an existing file is replaced only after "answer" "Replace"
    {"action": "import_vox", "path": ...} {"action": "export_vox", "path": ...}   MagicaVoxel models
    {"action": "export_turntable", "path": "t.gif", "frames": 8, "sweep": "light"}   in the background
    {"action": "reference_render", "spp": 16}                 path trace the scene beside the live render
    {"action": "renderer", "name": "nvr+"}                    the render panel's renderer ("shaded" or "nvr+")
    {"action": "load_mesh", "path": ..., "up": "y"}
    {"action": "load_photo", "photo": ..., "camera": ...}      the Photo tab's Load photo (opens the tab); "camera" optional
    {"action": "align_photo", "from_scratch": false}           Align (refine from this pose) / Align from scratch
    {"action": "turn_photo", "dx": 40, "dy": 0}                as a drag on the photo ("shift_photo": Shift+drag), pixels
    {"action": "zoom_photo", "steps": 1}                       as the wheel over the photo
    {"action": "set_photo_pose", "rotation_deg": 30, "elevation_deg": 20, "translation": [x, z], "scale": [x, y, z]}
                                                              the pose fields (any of them)
    {"action": "color_from_photo"} {"action": "match_photo_view"}   one undo step each
    {"action": "photo_light", "divide": false}               coloring keeps the photo's shading (true: fits its light)
    {"action": "use_photo_light"}                             the scene's light to the fitted one: one undo step
    {"action": "photo_box", "box": [x0, y0, x1, y1]}           the object's box in photo pixels (null clears it)
    {"action": "photo_stroke", "at": [x, y], "radius": 4, "kind": "background"}   a stroke ("object" or "background")
    {"action": "show_photo_mask"}                             segment with the hints and show the mask
    {"action": "screenshot", "path": ...}                     {"action": "answer", "choice": "Restore"}
    {"action": "tool", "name": "paint"}                       {"action": "wait", "frames": 10}
    {"action": "paint_color", "color": [r, g, b]}             the bucket's color
    {"action": "close"}                                       as the window's close button
    {"action": "resize", "size": [w, h]}                      as a window manager resizes it (X ConfigureWindow)
Raw input goes through the window backend's own event handlers, as real input does (mouse
buttons and modifiers go to ImGui's input queue directly, see _mouse_button):
    {"action": "mouse_move", "pos": [x, y]}   window pixels
    {"action": "mouse_down", "button": 0, "mods": ["shift"]} {"action": "mouse_up", "button": 0}
                                              buttons 0 left, 1 right, 2 middle; mods held until mouse_up
    {"action": "scroll", "dy": 1, "mods": ["ctrl"]}
    {"action": "key", "key": "g", "mods": ["ctrl", "shift"]}   press and release
    {"action": "type", "text": "chair.obj"}   characters, as typed into the focused text field
Before each action the replay waits until the editor is idle (jobs done, render up to date),
so a screenshot always shows the finished result of what came before.
"""

from __future__ import annotations

import ctypes
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import glfw
from imgui_bundle import imgui

from app.editor import edits
from renderer.errors import InputError
from renderer.io import load_json
from renderer.scene import PaintOp

MODIFIER_KEYS = {"ctrl": glfw.KEY_LEFT_CONTROL, "shift": glfw.KEY_LEFT_SHIFT, "alt": glfw.KEY_LEFT_ALT}
MODIFIER_BITS = {"ctrl": glfw.MOD_CONTROL, "shift": glfw.MOD_SHIFT, "alt": glfw.MOD_ALT}
MODIFIER_IMGUI = {"ctrl": imgui.Key.mod_ctrl, "shift": imgui.Key.mod_shift, "alt": imgui.Key.mod_alt}


def load_replay(path: str | Path) -> list[dict[str, Any]]:
    """Read and check a replay file: a list of objects with a known "action"."""
    actions = load_json(path)
    if not isinstance(actions, list):
        raise InputError("a replay file must hold a JSON list of actions", path)
    for i, action in enumerate(actions):
        if not isinstance(action, dict) or not isinstance(action.get("action"), str):
            raise InputError(f"action {i} must be an object with an \"action\" name", path)
        if action["action"] not in ACTIONS:
            raise InputError(f"action {i}: unknown action {action['action']!r} (known: {', '.join(sorted(ACTIONS))})", path)
    return actions


class Replay:
    """Feeds the actions to an app, one step per frame, waiting for the app to be idle between actions."""

    def __init__(self, actions: list[dict[str, Any]]):
        self._pending = list(actions)
        self._running: Iterator[None] | None = None
        self._current: dict[str, Any] | None = None

    @property
    def done(self) -> bool:
        return not self._pending and self._running is None

    def step(self, app) -> None:
        """Advance by one frame; call before the frame's input is read."""
        if self._running is None:
            if not self._pending or app.busy:
                return
            self._current = self._pending.pop(0)
            self._running = _run(app, self._current)
        try:
            next(self._running)
        except StopIteration:
            self._running = None
        except (KeyError, TypeError, ValueError) as exc:
            self._running = None
            app.say(f"replay: bad action {self._current}: {type(exc).__name__}: {exc}", error=True)


def _run(app, action: dict[str, Any]) -> Iterator[None]:
    result = ACTIONS[action["action"]](app, action)
    if isinstance(result, Iterator):  # an action spread over several frames
        yield from result


# --- high-level actions -----------------------------------------------------------------------


def _color(action: dict[str, Any]) -> tuple[float, float, float]:
    r, g, b = (float(c) for c in action["color"])
    return r, g, b


def _material(scene, action: dict[str, Any]):
    """A preset by "preset", or the scene's material with the given "roughness", "specular", "metallic"."""
    material = edits.MATERIAL_PRESETS[action["preset"]] if "preset" in action else scene.object.material  # one-object view
    return replace(material, **{k: float(action[k]) for k in ("roughness", "specular", "metallic") if k in action})


def _drag_light(app, action) -> Iterator[None]:
    start = app.scene.light.position
    target = tuple(float(c) for c in action["to"])
    steps = max(1, int(action.get("steps", 6)))
    for k in range(1, steps + 1):
        point = tuple(a + (b - a) * k / steps for a, b in zip(start, target))
        app.edit(lambda s, p=point: edits.move_light(s, p), preview=True)
        yield
    app.commit_preview()


def _paint(app, action) -> None:
    if "color" in action:
        app.paint_color = _color(action)
    app.tolerance = float(action.get("tolerance", app.tolerance))
    app.similarity = str(action.get("similarity", app.similarity))
    app.paint_region(tuple(int(v) for v in action["voxel"]))


def _fill(target: str):
    def run(app, action) -> None:
        app.edit_object(lambda s: edits.paint(s, PaintOp(target, _color(action))))
    return run


def _set_photo_pose(app, action) -> None:
    """The pose fields: each key given replaces that part of the photo's pose."""
    def posed(pose):
        if "rotation_deg" in action:
            pose = replace(pose, rotation_deg=float(action["rotation_deg"]))
        if "elevation_deg" in action:
            pose = replace(pose, camera=replace(pose.camera, elevation_deg=float(action["elevation_deg"])))
        if "translation" in action:
            x, z = (float(v) for v in action["translation"])
            pose = replace(pose, translation=(x, z))
        if "scale" in action:
            sx, sy, sz = (float(v) for v in action["scale"])
            pose = replace(pose, scale=(sx, sy, sz))
        return pose

    app.photo.adjust(lambda alignment: alignment.set_pose(posed(alignment.pose)))


def _photo_gesture(name: str, *keys: str):
    """A gesture on the photo (turn, shift, zoom) with the action's numbers as its arguments."""
    def run(app, action) -> None:
        values = [float(action[key]) for key in keys]
        app.photo.adjust(lambda alignment: getattr(alignment, name)(*values))
    return run


def _resize(app, action) -> Iterator[None]:
    """Ask the X server for a new window size, then let frames pass until the window has it."""
    width, height = (int(v) for v in action["size"])
    glfw.set_window_size(app.window.handle, width, height)
    for _ in range(100):
        if tuple(app.window.size) == (width, height):
            break
        yield
    yield  # one frame drawn at the new size before the next action


def _wait(app, action) -> Iterator[None]:
    for _ in range(int(action.get("frames", 1))):
        yield


def _load_photo(app, action) -> None:
    app.requested_tab = "Photo"  # where a user's Load photo button is
    app.photo.load(action["photo"], action.get("camera"))


def _set_tool(app, action) -> None:
    if action["name"] not in ("select", "paint"):
        raise ValueError(f"tool must be select or paint, got {action['name']!r}")
    app.tool = action["name"]
    if app.tool == "paint":
        app.requested_tab = "Paint"  # as a user picks the bucket: in the Paint tab


# --- raw input through the glfw backend's callbacks ----------------------------------------------


def _window(app) -> int:
    return ctypes.cast(app.window.handle, ctypes.c_void_p).value


def _mouse_move(app, action) -> None:
    x, y = (float(v) for v in action["pos"])
    imgui.backends.glfw_cursor_enter_callback(_window(app), 1)
    imgui.backends.glfw_cursor_pos_callback(_window(app), x, y)


def _mouse_button(down: bool):
    """A button event; mouse_down's "mods" (e.g. ["shift"]) are held until mouse_up.

    ImGui's glfw backend reads modifiers from the real keyboard (glfwGetKey) on every button
    event, which a replay cannot press; so buttons and modifiers go to ImGui's input queue
    directly, modifiers first so both arrive in the same frame.
    """
    def run(app, action) -> None:
        io = imgui.get_io()
        if down:
            for m in action.get("mods", []):
                io.add_key_event(MODIFIER_IMGUI[str(m).lower()], True)
        io.add_mouse_button_event(int(action.get("button", 0)), down)
        if not down:
            for key in MODIFIER_IMGUI.values():
                io.add_key_event(key, False)
    return run


def _scroll(app, action) -> Iterator[None]:
    """The wheel, with its "mods" (e.g. ["ctrl"]) held from the frame before to the frame after."""
    mods = [str(m).lower() for m in action.get("mods", [])]
    io = imgui.get_io()
    for m in mods:
        io.add_key_event(MODIFIER_IMGUI[m], True)
    if mods:
        yield
    imgui.backends.glfw_scroll_callback(_window(app), 0.0, float(action.get("dy", 1.0)))
    yield
    for m in mods:
        io.add_key_event(MODIFIER_IMGUI[m], False)


def _key(app, action) -> Iterator[None]:
    """Press the modifiers and the key in one frame, release them in the next."""
    name = str(action["key"]).upper()
    key = getattr(glfw, f"KEY_{name}", None)
    if key is None:
        raise ValueError(f"unknown key {action['key']!r}")
    mods = [str(m).lower() for m in action.get("mods", [])]
    bits = sum(MODIFIER_BITS[m] for m in mods)
    window = _window(app)
    for m in mods:
        imgui.backends.glfw_key_callback(window, MODIFIER_KEYS[m], 0, glfw.PRESS, bits)
    imgui.backends.glfw_key_callback(window, key, 0, glfw.PRESS, bits)
    for m in mods:  # the backend read the modifiers from the real keyboard: tell ImGui they are down
        imgui.get_io().add_key_event(MODIFIER_IMGUI[m], True)
    yield
    imgui.backends.glfw_key_callback(window, key, 0, glfw.RELEASE, bits)
    for m in mods:
        imgui.backends.glfw_key_callback(window, MODIFIER_KEYS[m], 0, glfw.RELEASE, 0)
    yield


def _type(app, action) -> None:
    for character in str(action["text"]):
        imgui.backends.glfw_char_callback(_window(app), ord(character))


ACTIONS = {
    "drag_light": _drag_light,
    "move_object": lambda app, a: app.edit_object(lambda s: edits.place_object(s, translation=tuple(a["translation"]))),
    "rotate_object": lambda app, a: app.edit_object(lambda s: edits.place_object(s, rotation_deg=float(a["deg"]))),
    "scale_object": lambda app, a: app.edit_object(lambda s: edits.place_object(s, scale=tuple(a["scale"]))),
    "set_elevation": lambda app, a: app.edit(lambda s: edits.set_elevation(s, float(a["deg"]))),
    "set_floor_color": lambda app, a: app.edit(lambda s: edits.set_floor_color(s, _color(a))),
    "use_sky": lambda app, a: app.edit(edits.use_sky),
    "set_sky": lambda app, a: app.edit(lambda s: edits.set_sky(s, float(a["elevation"]), float(a["azimuth"]),
                                                               float(a.get("turbidity", 3.0)))),
    "load_environment": lambda app, a: app.edit(lambda s: edits.use_environment_image(s, a["path"])),
    "no_environment": lambda app, a: app.edit(lambda s: edits.set_environment(s, None)),
    "load_floor_texture": lambda app, a: app.edit(lambda s: edits.use_floor_texture(s, a["path"])),
    "floor_texture_scale": lambda app, a: app.edit(lambda s: edits.set_floor_texture_scale(s, float(a["scale"]))),
    "no_floor_texture": lambda app, a: app.edit(edits.clear_floor_texture),
    "floor_shape": lambda app, a: app.edit(lambda s: edits.set_floor_shape(s, a["shape"])),
    "turn_environment": lambda app, a: app.edit(lambda s: edits.turn_environment(
        s, rotation_deg=a.get("deg"), strength=a.get("strength"))),
    "area_light": lambda app, a: app.edit(lambda s: edits.switch_area_light(s, bool(a["on"]))),
    "material": lambda app, a: app.edit_object(lambda s: edits.set_material(s, _material(s, a))),
    "paint": _paint,
    "fill_object": _fill("object"),
    "fill_floor": _fill("floor"),
    "select": lambda app, a: app.select(int(a["index"])),
    "rename": lambda app, a: app.rename_object(app.selected, str(a["name"])),
    "add_object": lambda app, a: app.add_object(a["path"], up=a.get("up", "y")),
    "duplicate": lambda app, a: app.duplicate_selected(),
    "hide": lambda app, a: app.toggle_hidden(int(a["index"])),
    "delete": lambda app, a: app.delete_selected(),
    "undo": lambda app, a: app.undo(),
    "redo": lambda app, a: app.redo(),
    "open": lambda app, a: app.files.open(a["path"]),
    "save": lambda app, a: app.files.save(a.get("path")),
    "export": lambda app, a: app.files.export(a["path"], size=a.get("size"), voxels=a.get("voxels")),
    "export_side_by_side": lambda app, a: app.files.export_side_by_side(a["path"]),
    "import_vox": lambda app, a: app.files.import_vox(a["path"]),
    "reference_render": lambda app, a: app.reference.start(int(a.get("spp", 64))),
    "export_turntable": lambda app, a: app.files.export_turntable(a["path"], int(a.get("frames", 36)), a.get("sweep", "rotation")),
    "export_vox": lambda app, a: app.files.export_vox(a["path"]),
    "renderer": lambda app, a: app.choose_renderer(a["name"]),
    "load_mesh": lambda app, a: app.files.load_mesh(a["path"], up=a.get("up", "y")),
    "load_photo": _load_photo,
    "align_photo": lambda app, a: app.photo.align(from_scratch=bool(a.get("from_scratch", False))),
    "turn_photo": _photo_gesture("turn", "dx", "dy"),
    "shift_photo": _photo_gesture("shift", "dx", "dy"),
    "zoom_photo": _photo_gesture("zoom", "steps"),
    "set_photo_pose": _set_photo_pose,
    "photo_box": lambda app, a: app.photo.alignment.set_box(None if a.get("box") is None else tuple(a["box"])),
    "photo_stroke": lambda app, a: app.photo.alignment.stroke(*a["at"], float(a.get("radius", 4)),
                                                              object_=a.get("kind", "object") == "object"),
    "show_photo_mask": lambda app, a: app.photo.show_mask(),
    "color_from_photo": lambda app, a: app.photo.color_object(),
    "match_photo_view": lambda app, a: app.photo.match_view(),
    "photo_light": lambda app, a: app.photo.set_divide_light(bool(a["divide"])),
    "use_photo_light": lambda app, a: app.photo.use_fitted_light(),
    "screenshot": lambda app, a: app.screenshots.request(a["path"]),
    "answer": lambda app, a: app.answer(a["choice"]),
    "tool": _set_tool,
    "paint_color": lambda app, a: setattr(app, "paint_color", _color(a)),
    "close": lambda app, a: glfw.set_window_should_close(app.window.handle, True),
    "wait": _wait,
    "resize": _resize,
    "mouse_move": _mouse_move,
    "mouse_down": _mouse_button(True),
    "mouse_up": _mouse_button(False),
    "scroll": _scroll,
    "key": _key,
    "type": _type,
}
