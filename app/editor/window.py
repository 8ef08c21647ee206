"""The OS window: a glfw window with an OpenGL 3.3 context shared by moderngl and Dear ImGui's own backends.

The glfw package uses imgui_bundle's glfw library (see app/editor/__init__.py), so the window
handle made here is the one ImGui's native glfw backend reads.

A frame that looks like the one on screen is neither drawn nor shown. With Mesa's software
OpenGL and GLX_MESA_copy_sub_buffer, the back buffer is not swapped, so it keeps the last
frame: only the boxes that changed are drawn again and copied to the screen
(app/editor/frame_damage.py); after the window changes size, one frame is swapped so that Mesa
makes the back buffer at the new size. Otherwise every new frame is drawn whole and swapped in.
"""

from __future__ import annotations

import ctypes
import time
from collections.abc import Callable, Hashable, Sequence
from pathlib import Path

import glfw
import imgui_bundle
import moderngl
import numpy as np
from imgui_bundle import imgui

from app.editor.frame_damage import Box, FrameSummary, changed_boxes, intersection, summarize
from renderer.errors import InputError

_GL_READ_FRAMEBUFFER, _GL_DRAW_FRAMEBUFFER = 0x8CA8, 0x8CA9
_GL_COLOR_BUFFER_BIT, _GL_NEAREST = 0x4000, 0x2600
FONT_FILE = Path(imgui_bundle.__file__).parent / "assets" / "fonts" / "DroidSans.ttf"
FONT_SIZE = 15.0
GLSL_VERSION = "#version 330"
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe")  # Mesa's CPU rasterisers, as GL_RENDERER names them


class WindowError(RuntimeError):
    """No window could be made (no display, no OpenGL 3.3)."""


class Window:
    """A window whose frames are drawn with moderngl (3D) and ImGui (interface)."""

    def __init__(self, title: str, width: int, height: int):
        if not glfw.init():
            raise WindowError("cannot initialise glfw (is DISPLAY set?)")
        glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 3)
        glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 3)
        glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
        glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
        self.handle = glfw.create_window(width, height, title, None, None)
        if not self.handle:
            glfw.terminate()
            raise WindowError("cannot create an OpenGL 3.3 window")
        glfw.make_context_current(self.handle)
        glfw.swap_interval(0)
        self.last_input = time.monotonic()
        self._watch_input()
        self._on_screen: FrameSummary | None = None  # the frame the screen shows, None when unknown
        self._to_show: list[Box] | None = []  # what `present` must show: [] nothing, None the whole back buffer
        # The window size the back buffer was last made for. Mesa's software OpenGL re-makes the back buffer
        # at a new window size only after a swap, so copying a box of a larger window out of it fails
        # (X_ShmPutImage BadValue, which ends the process): after a resize, one frame is swapped.
        self._buffer_size: tuple[int, int] | None = None
        self._swap_due = False
        glfw.set_window_refresh_callback(self.handle, self._forget_screen)  # uncovered or resized: draw it all
        self.ctx = moderngl.create_context()
        imgui.create_context()
        io = imgui.get_io()
        io.set_ini_filename(None)  # the layout is fixed; nothing to remember
        if FONT_FILE.is_file():
            io.fonts.add_font_from_file_ttf(str(FONT_FILE), FONT_SIZE)
        imgui.style_colors_dark()
        style = imgui.get_style()
        style.window_rounding = 0.0
        style.frame_rounding = 3.0
        imgui.backends.glfw_init_for_opengl(ctypes.cast(self.handle, ctypes.c_void_p).value, True)
        imgui.backends.opengl3_init(GLSL_VERSION)
        self._bind_framebuffer = _gl_function("glBindFramebuffer", ctypes.c_uint, ctypes.c_uint)
        self._blit_framebuffer = _gl_function("glBlitFramebuffer", *[ctypes.c_int] * 8, ctypes.c_uint, ctypes.c_uint)
        # Software OpenGL only: a GPU draws a whole frame in well under a millisecond, and a swap waits for the display.
        software = any(name in self.ctx.info["GL_RENDERER"] for name in SOFTWARE_RENDERERS)
        self._copy_sub_buffer = _copy_sub_buffer(self.handle) if software else None  # None: frames drawn whole, swapped

    @property
    def size(self) -> tuple[int, int]:
        return glfw.get_framebuffer_size(self.handle)

    @property
    def close_requested(self) -> bool:
        return bool(glfw.window_should_close(self.handle))

    def keep_open(self) -> None:
        """Undo a close request (e.g. to ask about unsaved changes first)."""
        glfw.set_window_should_close(self.handle, False)

    def _watch_input(self) -> None:
        """Note the time of every input event; ImGui's backend, installed afterwards, chains to these callbacks."""
        def seen(*_args) -> None:
            self.last_input = time.monotonic()

        for install in (glfw.set_cursor_pos_callback, glfw.set_mouse_button_callback, glfw.set_scroll_callback,
                        glfw.set_key_callback, glfw.set_char_callback, glfw.set_window_size_callback):
            install(self.handle, seen)

    def begin_frame(self, wait_seconds: float = 0.0) -> None:
        """Start a frame; with `wait_seconds` > 0, first sleep until an input event arrives or that time passes."""
        if wait_seconds > 0:
            glfw.wait_events_timeout(wait_seconds)
        else:
            glfw.poll_events()
        imgui.backends.opengl3_new_frame()
        imgui.backends.glfw_new_frame()
        imgui.new_frame()

    def _forget_screen(self, *_args) -> None:
        self._on_screen = None

    def end_frame(self, underlay: tuple[moderngl.Framebuffer, int, int] | None = None,
                  images: Sequence[tuple[Box, Hashable]] = (), force: bool = False) -> bool:
        """Draw the interface into the back buffer (`screenshot` reads it, `present` shows it); returns whether it drew.

        `underlay` (framebuffer, x, y) is copied to window pixel (x, y) first, under the interface:
        with software OpenGL a copy costs a third of drawing the same image as a textured quad.
        `images` are the boxes where images appear (the underlay, textures in the interface) with
        a version that changes with their pixels. `force` draws the whole frame, for a screenshot.
        """
        imgui.render()
        draw_data = imgui.get_draw_data()
        uploads_due = any(t.status != imgui.ImTextureStatus.ok for t in draw_data.textures)
        frame = None if uploads_due else summarize(draw_data, self.size, images)
        resized = self.size != self._buffer_size
        boxes = None if force or resized or frame is None else changed_boxes(self._on_screen, frame)
        if boxes == []:
            return False  # looks like the frame on screen
        if self._copy_sub_buffer is None or resized:
            boxes = None  # a swap shows the whole back buffer
            self._swap_due = True
        self._on_screen = frame
        self.ctx.screen.use()
        width, height = self.size
        self.ctx.viewport = (0, 0, width, height)  # the panels cover the whole window: no clear needed
        for box in [(0, 0, width, height)] if boxes is None else boxes:
            if underlay is not None:
                self._copy(*underlay, box)
            _render_inside(draw_data, box)
        self._to_show = boxes if self._to_show == [] or boxes is None else None
        return True

    def _copy(self, framebuffer: moderngl.Framebuffer, x: int, y: int, box: Box) -> None:
        """Copy the part of `framebuffer` that falls inside `box` when its corner is put at window pixel (x, y)."""
        w, h = framebuffer.size
        inside = intersection((x, y, x + w, y + h), box)
        if inside is None:
            return
        x0, y0, x1, y1 = inside
        rows = self.size[1]  # OpenGL rows count from the bottom, in the window and in the framebuffer
        self._bind_framebuffer(_GL_READ_FRAMEBUFFER, framebuffer.glo)
        self._bind_framebuffer(_GL_DRAW_FRAMEBUFFER, 0)
        self._blit_framebuffer(x0 - x, y + h - y1, x1 - x, y + h - y0, x0, rows - y1, x1, rows - y0,
                               _GL_COLOR_BUFFER_BIT, _GL_NEAREST)
        self._bind_framebuffer(_GL_READ_FRAMEBUFFER, 0)

    def screenshot(self) -> np.ndarray:
        """The drawn but not yet shown frame as (H, W, 3) uint8, top row first."""
        width, height = self.size
        data = self.ctx.screen.read(viewport=(0, 0, width, height), components=3)
        return np.frombuffer(data, dtype=np.uint8).reshape(height, width, 3)[::-1]

    def present(self) -> None:
        """Show what `end_frame` drew since the last call (nothing when it drew nothing)."""
        boxes, self._to_show = self._to_show, []
        if boxes == []:
            return
        if self._swap_due:
            glfw.swap_buffers(self.handle)
            self._swap_due = False
            if self._copy_sub_buffer is not None and self._buffer_size != self.size:
                self._on_screen = None  # the next frame is drawn whole, into the back buffer made for the new size
            self._buffer_size = self.size
            return
        width, height = self.size
        for x0, y0, x1, y1 in [(0, 0, width, height)] if boxes is None else boxes:
            self._copy_sub_buffer(x0, height - y1, x1 - x0, y1 - y0)  # GLX counts rows from the bottom

    def close(self) -> None:
        imgui.backends.opengl3_shutdown()
        imgui.backends.glfw_shutdown()
        imgui.destroy_context()
        glfw.destroy_window(self.handle)
        glfw.terminate()


def _render_inside(draw_data: imgui.ImDrawData, box: Box) -> None:
    """Draw the ImGui frame, only inside `box`: each command's clip rectangle is cut to it for the call."""
    clips = []
    for draw_list in draw_data.cmd_lists:
        commands = draw_list.cmd_buffer
        for command in (commands[i] for i in range(commands.size())):  # indexing gives the command itself, iterating a copy
            clip = command.clip_rect  # a view of the command's field
            clips.append((command, (clip.x, clip.y, clip.z, clip.w)))
            x0, y0, x1, y1 = max(clip.x, box[0]), max(clip.y, box[1]), min(clip.z, box[2]), min(clip.w, box[3])
            command.clip_rect = imgui.ImVec4(x0, y0, max(x0, x1), max(y0, y1))  # empty: the backend skips it
    imgui.backends.opengl3_render_draw_data(draw_data)
    for command, clip in clips:
        command.clip_rect = imgui.ImVec4(*clip)


def _copy_sub_buffer(handle) -> Callable[[int, int, int, int], None] | None:
    """glXCopySubBufferMESA bound to this window (x, y from the bottom left, width, height), or None where it is missing."""
    if glfw.get_platform() != glfw.PLATFORM_X11 or not glfw.extension_supported("GLX_MESA_copy_sub_buffer"):
        return None
    address = glfw.get_proc_address("glXCopySubBufferMESA")
    if not address:
        return None
    copy = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_ulong, *[ctypes.c_int] * 4)(address)
    display, drawable = glfw.get_x11_display(), glfw.get_glx_window(handle)
    return lambda x, y, w, h: copy(display, drawable, x, y, w, h)


def _gl_function(name: str, *argtypes):
    """An OpenGL entry point moderngl does not offer, from the current context."""
    address = glfw.get_proc_address(name)
    if not address:
        raise WindowError(f"OpenGL function {name} is missing")
    return ctypes.CFUNCTYPE(None, *argtypes)(address)


def upload_image(ctx: moderngl.Context, texture: moderngl.Texture | None, image: np.ndarray) -> moderngl.Texture:
    """An RGB texture holding `image` ((H, W, 3) float sRGB or uint8), reusing `texture` when the size fits."""
    from renderer.color import to_uint8

    pixels = image if image.dtype == np.uint8 else to_uint8(image)
    h, w = pixels.shape[:2]
    if texture is None or texture.size != (w, h):
        if texture is not None:
            texture.release()
        texture = ctx.texture((w, h), 3)
    texture.write(np.ascontiguousarray(pixels).tobytes())
    return texture


class Screenshots:
    """Screenshots of the whole window asked for during a frame, saved once it is drawn and before it is shown."""

    def __init__(self, window: Window, say: Callable[..., None]) -> None:
        self._window = window
        self._say = say
        self._paths: list[Path] = []

    def request(self, path: str | Path) -> None:
        """Save the whole window at the end of this frame."""
        self._paths.append(Path(path))

    @property
    def due(self) -> bool:
        """A screenshot waits for this frame, which must then be drawn even if it looks like the last one."""
        return bool(self._paths)

    def take(self) -> None:
        """Save the screenshots asked for this frame (the frame is drawn but not yet shown)."""
        from renderer.io import save_png

        for path in self._paths:
            try:
                save_png(path, self._window.screenshot())
            except InputError as exc:
                self._say(str(exc), error=True)
        self._paths.clear()
