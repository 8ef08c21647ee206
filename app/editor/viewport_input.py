"""Mouse and keys in the viewport, after Blender and MagicaVoxel.

- Middle-drag (or right-drag) orbits, Shift + that drag pans, the wheel zooms.
- Left-drag on the light square moves the light over the ground; with Shift held the drag
  changes its height instead. The render follows while dragging; releasing commits one undo step.
- G, R, S grab, rotate or scale the object; X, Y, Z limit the change to one axis; a left click
  or Enter confirms, a right click or Esc cancels.
- With the bucket tool, a left click on a voxel fills its connected region of similar color; otherwise a left
  click on an object selects it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from imgui_bundle import imgui

from app.editor import edits
from app.editor.orbit_view import orbit, pan_in_viewport, viewport_camera, zoom
from app.editor.picking import hits_light, nearest_object, pick_voxel, ray_at_height
from renderer.camera import Camera
from renderer.scene import Scene

LIGHT_HEIGHT_PER_PIXEL = 0.01
TRANSFORM_KEYS = {imgui.Key.g: "grab", imgui.Key.r: "rotate", imgui.Key.s: "scale"}
AXIS_KEYS = {imgui.Key.x: 0, imgui.Key.y: 1, imgui.Key.z: 2}
HINTS = {
    "grab": "Grab: move the mouse over the floor",
    "rotate": "Rotate: circle the mouse around the object",
    "scale": "Scale: move the mouse away from or towards the object",
}


@dataclass
class Transform:
    """A G/R/S operation in progress."""

    kind: str
    start_scene: Scene
    start_mouse: tuple[float, float]
    axis: int | None = None


@dataclass
class LightDrag:
    """A drag of the light square: the floor point under the light follows the mouse, so the light moves by
    what the mouse covers on the floor (it sits above the camera: rays to its own plane run off to infinity)."""

    start_scene: Scene
    start_mouse: np.ndarray  # viewport pixels where the drag (or its last re-anchoring) began
    anchor: np.ndarray  # where the floor point under the light appeared then, viewport pixels


class ViewportInput:
    """Turns mouse and keys over the viewport image into view changes and edits of the app's scene."""

    def __init__(self) -> None:
        self.camera: Camera | None = None
        self.transform: Transform | None = None
        self.light_drag: LightDrag | None = None
        self.navigating: int | None = None  # mouse button of an orbit/pan drag
        self.hovered_voxel: tuple[int, int, int] | None = None
        self.light_hovered = False

    @property
    def interacting(self) -> bool:
        """A drag or a G/R/S operation is in progress."""
        return self.transform is not None or self.light_drag is not None or self.navigating is not None

    @property
    def hint(self) -> str:
        if self.transform is not None:
            axis = "" if self.transform.axis is None else f", {'XYZ'[self.transform.axis]} axis only"
            return f"{HINTS[self.transform.kind]}{axis}. Click or Enter: confirm; right click or Esc: cancel"
        if self.light_drag is not None:
            return "Moving the light (hold Shift to change its height)"
        return "Middle/right drag: orbit, +Shift: pan, wheel: zoom. G/R/S: grab/rotate/scale, drag the light square"

    def update(self, app, mouse: tuple[float, float], size: tuple[int, int], hovered: bool) -> None:
        """One frame of input; `mouse` is in viewport pixels, `hovered` whether the mouse is over the viewport."""
        app.view = self._navigate(app.view, hovered, size)
        self.camera = viewport_camera(app.view, *size)
        origin, direction = self.camera.pixel_rays(np.array(mouse[0]), np.array(mouse[1]))
        ray = (origin, np.asarray(direction))
        if self.transform is not None:
            self._update_transform(app, mouse, ray)
            return
        if self.light_drag is not None:
            self._update_light_drag(app, mouse)
            return
        self.light_hovered = hovered and app.scene.light.enabled and hits_light(*ray, app.scene.light.position)
        self.hovered_voxel = self._voxel_under(app, ray) if hovered and app.bucket_active else None
        if not hovered:
            return
        if imgui.is_mouse_clicked(imgui.MouseButton_.left):
            if self.hovered_voxel is not None and imgui.get_io().key_alt:
                app.pick_color(self.hovered_voxel)  # the eyedropper, as in MagicaVoxel
            elif self.hovered_voxel is not None:
                app.paint_region(self.hovered_voxel)
            elif self.light_hovered:
                self._start_light_drag(app, mouse)
            elif not app.bucket_active:  # a click on an object selects it
                index = self._object_under(app, ray)
                if index is not None and index != app.selected:
                    app.select(index)
        io = imgui.get_io()
        if not io.want_text_input:
            for key, kind in TRANSFORM_KEYS.items():
                if imgui.is_key_pressed(key, False) and not io.key_ctrl:
                    self.transform = Transform(kind, app.object_view(app.doc.history.current), mouse)

    # --- navigation -----------------------------------------------------------------------

    def _navigate(self, view: Camera, hovered: bool, size: tuple[int, int]) -> Camera:
        io = imgui.get_io()
        if self.navigating is None and hovered:
            for button in (imgui.MouseButton_.middle, imgui.MouseButton_.right):
                if imgui.is_mouse_clicked(button) and self.transform is None:
                    self.navigating = button
        if self.navigating is not None:
            if not imgui.is_mouse_down(self.navigating):
                self.navigating = None
            else:
                dx, dy = io.mouse_delta.x, io.mouse_delta.y
                view = pan_in_viewport(view, dx, dy, *size) if io.key_shift else orbit(view, dx, dy)
        if hovered and io.mouse_wheel:
            view = zoom(view, io.mouse_wheel)
        return view

    # --- picking --------------------------------------------------------------------------

    def _voxel_under(self, app, ray) -> tuple[int, int, int] | None:
        """The selected object's voxel under the mouse (the bucket's)."""
        if app.jobs.current is not None or app.shown_occupancy is None:
            return None
        return pick_voxel(app.shown_occupancy, app.selected_object, *ray)

    def _object_under(self, app, ray) -> int | None:
        """The index of the object whose voxel the mouse ray meets first, None if it meets none."""
        shown = [(i, s.occupancy) for i, s in enumerate(app.shown)
                 if s is not None and i < len(app.scene.objects) and i not in app.hidden]
        return nearest_object([(app.scene.objects[i], occupied) for i, occupied in shown], *ray, [i for i, _ in shown])

    # --- the light ------------------------------------------------------------------------

    def _start_light_drag(self, app, mouse: tuple[float, float]) -> None:
        anchor = self._under_light_px(app.scene)
        if anchor is not None:
            self.light_drag = LightDrag(app.doc.history.current, np.asarray(mouse, dtype=np.float64), anchor)

    def _under_light_px(self, scene: Scene) -> np.ndarray | None:
        """Where the floor point straight under the light appears in the viewport (None: behind the camera)."""
        x, _, z = scene.light.position
        u, v, depth = self.camera.project(np.array([x, 0.0, z]))
        return None if float(depth) <= 0.0 else np.array([float(u), float(v)])

    def _update_light_drag(self, app, mouse: tuple[float, float]) -> None:
        drag = self.light_drag
        if not imgui.is_mouse_down(imgui.MouseButton_.left):
            self.light_drag = None
            app.commit_preview()
            return
        if imgui.is_key_pressed(imgui.Key.escape):
            self.light_drag = None
            app.cancel_preview()
            return
        light = list(app.scene.light.position)
        mouse = np.asarray(mouse, dtype=np.float64)
        if imgui.get_io().key_shift:
            light[1] = edits.clamp(light[1] - imgui.get_io().mouse_delta.y * LIGHT_HEIGHT_PER_PIXEL,
                                   edits.MIN_LIGHT_HEIGHT, edits.MAX_LIGHT_HEIGHT)
            anchor = self._under_light_px(app.scene)
            if anchor is not None:  # releasing Shift goes on from here
                drag.start_mouse, drag.anchor = mouse, anchor
        else:
            target = drag.anchor + (mouse - drag.start_mouse)
            origin, direction = self.camera.pixel_rays(np.array(target[0]), np.array(target[1]))
            hit = ray_at_height(origin, np.asarray(direction), 0.0)
            if hit is None:  # above the horizon: the light stays where it was
                return
            light[0], light[2] = (edits.clamp(c, -edits.MAX_POSITION, edits.MAX_POSITION) for c in hit[[0, 2]])
        app.edit(lambda s: edits.move_light(s, tuple(light)), preview=True)

    # --- grab, rotate, scale --------------------------------------------------------------

    def _update_transform(self, app, mouse: tuple[float, float], ray) -> None:
        t = self.transform
        for key, axis in AXIS_KEYS.items():
            if imgui.is_key_pressed(key, False):
                t.axis = None if t.axis == axis else axis
        if imgui.is_key_pressed(imgui.Key.escape) or imgui.is_mouse_clicked(imgui.MouseButton_.right):
            self.transform = None
            app.cancel_preview()
            return
        confirm = imgui.is_mouse_clicked(imgui.MouseButton_.left) or imgui.is_key_pressed(imgui.Key.enter)
        scene = self._transformed(t, mouse, ray)
        if scene is not None:
            app.edit_object(lambda _: scene, preview=True)
        if confirm:
            self.transform = None
            app.commit_preview()

    def _transformed(self, t: Transform, mouse: tuple[float, float], ray) -> Scene | None:
        o = t.start_scene.object  # the selected object's one-object view (EditorApp.object_view)
        if t.kind == "grab":
            start_origin, start_dir = self.camera.pixel_rays(np.array(t.start_mouse[0]), np.array(t.start_mouse[1]))
            start, now = ray_at_height(start_origin, np.asarray(start_dir), 0.0), ray_at_height(*ray, 0.0)
            if start is None or now is None:
                return None
            delta = (now - start)[[0, 2]]
            if t.axis is not None:
                delta = delta * (np.array([t.axis == 0, t.axis == 2]))
            moved = np.clip(np.asarray(o.translation) + delta, -edits.MAX_POSITION, edits.MAX_POSITION)
            return edits.place_object(t.start_scene, translation=tuple(moved))
        centre = self._object_centre_px(t.start_scene)
        start_vec = np.asarray(t.start_mouse) - centre
        now_vec = np.asarray(mouse) - centre
        if t.kind == "rotate":
            turned = math.atan2(-now_vec[1], now_vec[0]) - math.atan2(-start_vec[1], start_vec[0])
            return edits.place_object(t.start_scene, rotation_deg=o.rotation_deg + math.degrees(turned))
        factor = float(np.linalg.norm(now_vec) / max(np.linalg.norm(start_vec), 1.0))
        scale = np.asarray(o.scale) * (factor if t.axis is None else np.where(np.arange(3) == t.axis, factor, 1.0))
        return edits.place_object(t.start_scene, scale=tuple(np.clip(scale, edits.MIN_SCALE, edits.MAX_SCALE)))

    def _object_centre_px(self, scene: Scene) -> np.ndarray:
        """Where the middle of the object's vertical axis appears in the viewport."""
        tx, tz = scene.object.translation
        u, v, _ = self.camera.project(np.array([tx, 0.5 * scene.object.scale[1], tz]))
        return np.array([float(u), float(v)])
