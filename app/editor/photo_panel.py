"""The Photo tab: load a photo, align the object to it by hand or with the search, color the object, take its view.

The photo is shown with the object's silhouette outlined over it (PhotoAlignment.overlay), as a
texture uploaded again only when the pose or the shape changed: while the tab is open, over the whole viewport
(Ctrl+wheel zooms about the mouse, middle-drag pans), or, with that turned off, inside the tab. On the image, left-drag turns
the object (up and down raises and lowers the camera), Shift+left-drag moves it on the floor and
the wheel scales it; the numeric fields below set the same pose exactly. While a drag is under
way the overlay is drawn at a smaller size, so every frame of the drag stays cheap (ray casting
the silhouette costs about four times as much at twice the side); it is
drawn at full size again when the mouse is released.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Protocol

import moderngl
from imgui_bundle import imgui

from app.editor import edits
from app.editor.app import EditorApp
from app.editor.file_dialog import FileKind
from app.editor.frame_damage import Box
from app.editor.photo_capture import PhotoAlignment
from app.editor.window import upload_image
from renderer.capture.pose import PhotoPose

PHOTO_FILES = FileKind("Open a photo", "Images", ("*.png", "*.jpg", "*.jpeg"))
CAMERA_FILES = FileKind("Open the photo's camera file", "Camera files", ("*.json",))
GRAY = imgui.ImVec4(0.65, 0.65, 0.68, 1.0)
MIN_IMAGE_HEIGHT = 120  # the photo fills the tab's height below the buttons, but no less than this
IMAGE_SHARE = 0.55  # ... and at most this share of its width: the pose fields stand beside it
POSE_LABEL_WIDTH = 62  # room for the pose fields' labels
DRAG_SIDE = 160  # long side of the overlay while a drag is under way
VIEW_DRAG_SIDE = 320  # the same for the photo over the viewport
MAX_VIEW_SIDE = 1600  # the overlay's long side over the viewport at most (zoomed further, the texture is enlarged)
MAX_ZOOM = 16.0  # over the viewport, the photo fitted to it and enlarged up to this
ZOOM_PER_STEP = 1.25  # per Ctrl+wheel step
BACKDROP = imgui.ImVec4(0.1, 0.1, 0.11, 1.0)  # around the photo over the viewport
HINT_SHADE, HINT_BAND = imgui.ImVec4(0.0, 0.0, 0.0, 0.55), 26  # behind the hint line at the view's top, its height
STROKE_RADIUS = 0.02  # of the photo's shorter side
DRAG_HINTS = {
    "pose": "On the photo: drag turns the object, Shift+drag moves it, the wheel scales it",
    "box": "On the photo: drag a box around the object; Align takes what is outside as background",
    "strokes": "On the photo: paint where the object surely is (green); Shift: where the background is (red)",
}
Browse = Callable[[str, FileKind, str], None]  # draws a Browse button for a path field: (key, kind, field name)


class PhotoFields(Protocol):
    """The text typed into the Photo tab's path fields (kept with the window's other fields, panels.Fields)."""

    photo_path: str
    camera_path: str


class PhotoPanel:
    """Draws the Photo tab for an EditorApp; keeps the overlay's texture."""

    def __init__(self, app: EditorApp):
        self.app = app
        self.texture: moderngl.Texture | None = None
        self.uploads = 0  # counts the images written to the texture (the window redraws the image when it changes)
        self._uploaded_for: tuple | None = None  # (alignment, its revision, overlay side) of the texture's image
        self._files_shown_for: PhotoAlignment | None = None  # the files section folds once when a photo is loaded
        self.shown: tuple[Box, tuple] | None = None  # where the overlay was drawn this frame, and its version
        self.drag_mode = "pose"  # what a drag on the photo does: "pose" the object, draw its "box", paint "strokes"
        self._box_start: tuple[float, float] | None = None  # photo pixels where the box drag began
        self.in_viewport = True  # while the tab is open, the photo covers the viewport (else it is drawn in the tab)
        self.zoom = 1.0  # over the viewport: 1 fits the photo to it
        self.centre = (0.5, 0.5)  # the photo's point (fractions of its width and height) at the viewport's centre
        self._panning = False

    def fills_viewport(self) -> bool:
        """Whether the photo is drawn over the viewport this frame (the Photo tab open, a photo loaded)."""
        return self.in_viewport and self.app.tools_tab == "Photo" and self.app.photo.alignment is not None

    def draw_in_viewport(self, origin: imgui.ImVec2, width: int, height: int) -> None:
        """The photo and its overlay over the viewport's `width` x `height` at `origin`, zoomed and panned, taking
        the same gestures as in the tab; Ctrl+wheel zooms about the mouse, middle-drag pans."""
        alignment = self.app.photo.alignment
        h, w = alignment.rgb.shape[:2]
        scale = min(width / w, height / h) * self.zoom
        shown_w, shown_h = w * scale, h * scale
        left = origin.x + width / 2 - self.centre[0] * shown_w
        top = origin.y + height / 2 - self.centre[1] * shown_h
        corner = imgui.ImVec2(origin.x + width, origin.y + height)
        imgui.set_cursor_screen_pos(origin)
        imgui.invisible_button("photo view", imgui.ImVec2(width, height),
                               imgui.ButtonFlags_.mouse_button_left | imgui.ButtonFlags_.mouse_button_middle)
        left_down = imgui.is_mouse_down(imgui.MouseButton_.left)
        image_origin = imgui.ImVec2(left, top)
        if not (self._panning or imgui.is_mouse_down(imgui.MouseButton_.middle)):  # the middle button pans only
            self._photo_gestures(alignment, image_origin, w / shown_w)
        self._view_gestures(origin, width, height, shown_w, shown_h)
        dragging = imgui.is_item_active() and left_down
        side = VIEW_DRAG_SIDE if dragging else min(MAX_VIEW_SIDE, round(max(shown_w, shown_h)))
        self._upload(alignment, max(side, 1))
        draw = imgui.get_window_draw_list()
        draw.add_rect_filled(origin, corner, imgui.get_color_u32(BACKDROP))
        draw.push_clip_rect(origin, corner, True)
        draw.add_image(imgui.ImTextureRef(self.texture.glo), image_origin,
                       imgui.ImVec2(left + shown_w, top + shown_h))
        _draw_box(draw, alignment, image_origin, scale)
        draw.pop_clip_rect()
        draw.add_rect_filled(origin, imgui.ImVec2(corner.x, origin.y + HINT_BAND), imgui.get_color_u32(HINT_SHADE))
        imgui.set_cursor_screen_pos(imgui.ImVec2(origin.x + 8, origin.y + 6))
        imgui.text_colored(GRAY, f"{DRAG_HINTS[self.drag_mode]}.  Ctrl+wheel zooms ({self.zoom:.2g}x), "
                                 "middle-drag pans.")
        self.shown = ((int(origin.x), int(origin.y), int(corner.x), int(corner.y)),
                      (self.uploads, alignment.box, self.zoom, self.centre))

    def _view_gestures(self, origin: imgui.ImVec2, width: int, height: int, shown_w: float, shown_h: float) -> None:
        """Ctrl+wheel zooms about the mouse (the photo's point under it stays under it); middle-drag pans."""
        io = imgui.get_io()
        if imgui.is_item_hovered() and io.key_ctrl and io.mouse_wheel:
            zoom = min(max(self.zoom * ZOOM_PER_STEP ** io.mouse_wheel, 1.0), MAX_ZOOM)
            # The mouse's offset from the view's centre, in fractions of the photo, shrinks by the zoom's ratio.
            mx = (io.mouse_pos.x - origin.x - width / 2) / shown_w
            my = (io.mouse_pos.y - origin.y - height / 2) / shown_h
            ratio = self.zoom / zoom
            self.set_view(zoom, (self.centre[0] + mx * (1.0 - ratio), self.centre[1] + my * (1.0 - ratio)))
        if imgui.is_item_hovered() and imgui.is_mouse_clicked(imgui.MouseButton_.middle):
            self._panning = True
        if self._panning:
            if imgui.is_mouse_down(imgui.MouseButton_.middle):
                self.set_view(self.zoom, (self.centre[0] - io.mouse_delta.x / shown_w,
                                          self.centre[1] - io.mouse_delta.y / shown_h))
            else:
                self._panning = False

    def set_view(self, zoom: float, centre: tuple[float, float]) -> None:
        """Zoom (1: fitted) and the photo's point at the view's centre, kept so that the photo covers the centre."""
        self.zoom = min(max(float(zoom), 1.0), MAX_ZOOM)
        self.centre = (min(max(float(centre[0]), 0.0), 1.0), min(max(float(centre[1]), 0.0), 1.0))

    def draw(self, fields: PhotoFields, browse: Browse) -> None:
        """The tab's contents, for this frame."""
        self._files(fields, browse)
        alignment = self.app.photo.alignment
        if alignment is None:
            imgui.text_colored(GRAY, "Load a photo of the object to align the object to it.")
            return
        self._commands()
        _, self.in_viewport = imgui.checkbox("Photo over the viewport", self.in_viewport)
        if self.in_viewport:  # what a drag on the photo does comes before the numbers, which may scroll away
            imgui.same_line()
            if imgui.small_button("fit"):
                self.set_view(1.0, (0.5, 0.5))
            self._drag_mode(alignment)
            self._pose_fields(alignment.pose)
        else:
            self._overlay(alignment)
            imgui.same_line()
            imgui.begin_group()  # the numbers beside the photo
            self._pose_fields(alignment.pose)
            imgui.end_group()
            self._drag_mode(alignment)
        if alignment.mask is not None:
            imgui.text_colored(GRAY, "Darkened: background. Amber: the object's rim, whose colors are not taken.")

    def _drag_mode(self, alignment: PhotoAlignment) -> None:
        """What a drag on the photo does: pose the object, draw its box, or paint strokes (object; Shift:
        background); and the segmentation these hints give, shown over the photo."""
        for mode, label in (("pose", "pose"), ("box", "box"), ("strokes", "strokes")):
            if imgui.radio_button(label, self.drag_mode == mode):
                self.drag_mode = mode
            if imgui.is_item_hovered():
                imgui.set_tooltip(DRAG_HINTS[mode])
            imgui.same_line()
        if imgui.small_button("mask"):
            self.app.photo.show_mask()
        if imgui.is_item_hovered():
            imgui.set_tooltip("Segment the photo with the box and strokes and show it: the background is darkened")
        if alignment.box is not None or alignment.strokes.any() or alignment.mask is not None:
            imgui.same_line()
            if imgui.small_button("clear"):
                alignment.clear_hints()

    def _files(self, fields: PhotoFields, browse: Browse) -> None:
        """Photo and camera file, and Load; folded away when a photo has just been loaded, to leave it the room."""
        alignment = self.app.photo.alignment
        if alignment is not self._files_shown_for:
            imgui.set_next_item_open(alignment is None)
            self._files_shown_for = alignment
        if not imgui.collapsing_header("Photo files", imgui.TreeNodeFlags_.default_open):
            return
        _, fields.photo_path = imgui.input_text("photo", fields.photo_path)
        browse("photo", PHOTO_FILES, "photo_path")
        _, fields.camera_path = imgui.input_text_with_hint("camera file", "optional", fields.camera_path)
        browse("camera", CAMERA_FILES, "camera_path")
        if imgui.button("Load photo") and fields.photo_path:
            self.app.photo.load(fields.photo_path, fields.camera_path or None)

    def _commands(self) -> None:
        """What can be done with the loaded photo: the two searches, coloring, taking its view."""
        photo = self.app.photo
        if imgui.button("Align (refine from this pose)"):
            photo.align()
        imgui.same_line()
        if imgui.button("Align from scratch"):
            photo.align(from_scratch=True)
        if imgui.button("Color the object"):
            photo.color_object()
        imgui.same_line()
        if imgui.button("Match the scene to the photo's view"):
            photo.match_view()
        if photo.job is not None and photo.job is self.app.jobs.current:  # a search or a coloring under way
            job = photo.job
            imgui.progress_bar(job.progress, imgui.ImVec2(-1, 0), f"{job.title} {job.progress:.0%}")
        alignment = photo.alignment
        _, alignment.divide_light = imgui.checkbox("Divide out the photo's light", alignment.divide_light)
        if imgui.is_item_hovered():
            imgui.set_tooltip("Coloring fits the light that shaded the photo and divides it out of the colors; "
                              "off, the colors keep the photo's shading")
        fitted = alignment.fitted_light
        if fitted is not None:  # on the same row, to leave the photo its room
            x, y, z = fitted.position
            imgui.same_line()
            imgui.text_colored(GRAY, f"fitted at [{x:.1f}, {y:.1f}, {z:.1f}]")
            if imgui.is_item_hovered():
                imgui.set_tooltip(f"The light that shaded the photo: the square light at [{x:.2f}, {y:.2f}, {z:.2f}], "
                                  f"the ambient light x{fitted.ambient:.2f}")
            imgui.same_line()
            if imgui.small_button("use"):
                photo.use_fitted_light()
            if imgui.is_item_hovered():
                imgui.set_tooltip("Move the scene's light to where the photo's light was fitted")
        elif alignment.light_note:
            imgui.text_colored(GRAY, f"Light: {alignment.light_note}")

    def _overlay(self, alignment: PhotoAlignment) -> None:
        """The photo with the silhouette's outline, taking the mouse gestures that pose it."""
        h, w = alignment.rgb.shape[:2]
        style = imgui.get_style()
        room = (imgui.get_window_height() - imgui.get_cursor_pos_y() - style.window_padding.y  # not scrolled
                - imgui.get_frame_height_with_spacing())  # the drag mode's row below the photo
        widest = IMAGE_SHARE * imgui.get_content_region_avail().x
        width = max(1, int(min(widest, max(MIN_IMAGE_HEIGHT, room) * w / h)))
        height = max(1, round(width * h / w))
        origin = imgui.get_cursor_screen_pos()
        imgui.invisible_button("photo overlay", imgui.ImVec2(width, height))
        self._photo_gestures(alignment, origin, w / width)
        self._upload(alignment, DRAG_SIDE if imgui.is_item_active() else max(width, height))
        corner = imgui.ImVec2(origin.x + width, origin.y + height)
        draw = imgui.get_window_draw_list()
        draw.add_image(imgui.ImTextureRef(self.texture.glo), origin, corner)
        _draw_box(draw, alignment, origin, width / w)
        self.shown = ((int(origin.x), int(origin.y), int(corner.x), int(corner.y)), (self.uploads, alignment.box))

    def _photo_gestures(self, alignment: PhotoAlignment, origin: imgui.ImVec2, photo_per_pixel: float) -> None:
        """What a drag on the photo shown from `origin` does, by the drag mode (photo_per_pixel: photo pixels a screen
        pixel)."""
        if self.drag_mode == "box":
            self._box_gesture(alignment, origin, photo_per_pixel)
        elif self.drag_mode == "strokes":
            self._stroke_gesture(alignment, origin, photo_per_pixel)
        else:
            self._gestures()

    def _gestures(self) -> None:
        """Left-drag turns, Shift+left-drag shifts (screen pixels), the wheel zooms, over the last item."""
        io, photo = imgui.get_io(), self.app.photo
        dx, dy = io.mouse_delta.x, io.mouse_delta.y
        if imgui.is_item_active() and (dx or dy):
            photo.adjust(lambda a: a.shift(dx, dy) if io.key_shift else a.turn(dx, dy))
        if imgui.is_item_hovered():
            imgui.set_item_key_owner(imgui.Key.mouse_wheel_y)  # the wheel scales the object, not the tab
            steps = io.mouse_wheel
            if steps and not io.key_ctrl:  # Ctrl+wheel zooms the photo over the viewport instead
                photo.adjust(lambda a: a.zoom(steps))

    def _box_gesture(self, alignment: PhotoAlignment, origin: imgui.ImVec2, photo_per_pixel: float) -> None:
        """Left-drag on the photo draws the object's box (in photo pixels): the search then takes what is outside
        as background."""
        mouse = imgui.get_io().mouse_pos
        here = ((mouse.x - origin.x) * photo_per_pixel, (mouse.y - origin.y) * photo_per_pixel)
        if imgui.is_item_activated():
            self._box_start = here
        if imgui.is_item_active() and self._box_start is not None:
            alignment.set_box((*self._box_start, *here))
        if imgui.is_item_deactivated():
            self._box_start = None

    def _stroke_gesture(self, alignment: PhotoAlignment, origin: imgui.ImVec2, photo_per_pixel: float) -> None:
        """Left-drag paints where the object surely is; with Shift, where the background surely is."""
        if imgui.is_item_active():
            mouse, io = imgui.get_io().mouse_pos, imgui.get_io()
            h, w = alignment.rgb.shape[:2]
            alignment.stroke((mouse.x - origin.x) * photo_per_pixel, (mouse.y - origin.y) * photo_per_pixel,
                             STROKE_RADIUS * min(h, w), object_=not io.key_shift)

    def _upload(self, alignment: PhotoAlignment, side: int) -> None:
        """Draw the overlay into the texture, when the pose, the shape or the size changed since the last time."""
        wanted = (alignment, alignment.revision, side)
        if self.texture is not None and self._uploaded_for == wanted:
            return
        self.texture = upload_image(self.app.window.ctx, self.texture, alignment.overlay(side))
        self._uploaded_for = wanted
        self.uploads += 1

    def _pose_fields(self, pose: PhotoPose) -> None:
        """The pose in numbers (rotation and elevation in degrees, floor position, scale): each field sets it exactly."""
        imgui.push_item_width(max(60.0, imgui.get_content_region_avail().x - POSE_LABEL_WIDTH))
        changed, r = imgui.drag_float("rotation##photo", pose.rotation_deg, 0.5, -180.0, 180.0, "%.1f deg")
        self._set_pose(changed, lambda p: replace(p, rotation_deg=r))
        changed, e = imgui.drag_float("elevation##photo", pose.camera.elevation_deg, 0.5, 0.0, edits.MAX_ELEVATION,
                                      "%.1f deg")
        self._set_pose(changed, lambda p: replace(p, camera=replace(p.camera, elevation_deg=e)))
        changed, t = imgui.drag_float2("x, z##photo", list(pose.translation), 0.005, -edits.MAX_POSITION,
                                       edits.MAX_POSITION, "%.3f")
        self._set_pose(changed, lambda p: replace(p, translation=tuple(t)))
        changed, sc = imgui.drag_float3("scale##photo", list(pose.scale), 0.01, edits.MIN_SCALE, edits.MAX_SCALE, "%.2f")
        self._set_pose(changed, lambda p: replace(p, scale=tuple(sc)))
        imgui.pop_item_width()

    def _set_pose(self, changed: bool, make_pose: Callable[[PhotoPose], PhotoPose]) -> None:
        if changed:
            self.app.photo.adjust(lambda a: a.set_pose(make_pose(a.pose)))

    def close(self) -> None:
        if self.texture is not None:
            self.texture.release()
            self.texture = None


def _draw_box(draw: imgui.ImDrawList, alignment: PhotoAlignment, origin: imgui.ImVec2, scale: float) -> None:
    """The user's box (photo pixels) over the photo drawn from `origin` at `scale` screen pixels a photo pixel."""
    if alignment.box is not None:
        x0, y0, x1, y1 = (v * scale for v in alignment.box)
        draw.add_rect(imgui.ImVec2(origin.x + x0, origin.y + y0), imgui.ImVec2(origin.x + x1, origin.y + y1),
                      imgui.get_color_u32(imgui.ImVec4(1.0, 0.85, 0.2, 1.0)), thickness=2.0)
