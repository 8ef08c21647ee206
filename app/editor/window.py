"""The OS window: a glfw window with an OpenGL 3.3 context shared by moderngl and Dear ImGui's own backends.

The glfw package uses imgui_bundle's glfw library (see app/editor/__init__.py), so the window
handle made here is the one ImGui's native glfw backend reads.
"""

from __future__ import annotations

import ctypes
import time
from pathlib import Path

import glfw
import imgui_bundle
import moderngl
import numpy as np
from imgui_bundle import imgui

_GL_READ_FRAMEBUFFER, _GL_DRAW_FRAMEBUFFER = 0x8CA8, 0x8CA9
_GL_COLOR_BUFFER_BIT, _GL_NEAREST = 0x4000, 0x2600
FONT_FILE = Path(imgui_bundle.__file__).parent / "assets" / "fonts" / "DroidSans.ttf"
FONT_SIZE = 15.0
GLSL_VERSION = "#version 330"


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

    def end_frame(self, underlay: tuple[moderngl.Framebuffer, int, int] | None = None) -> None:
        """Draw the interface into the back buffer (`screenshot` reads it, `present` shows it).

        `underlay` (framebuffer, x, y) is copied to window pixel (x, y) first, under the interface:
        with software OpenGL a copy costs a third of drawing the same image as a textured quad.
        """
        imgui.render()
        self.ctx.screen.use()
        width, height = self.size
        self.ctx.viewport = (0, 0, width, height)  # the panels cover the whole window: no clear needed
        if underlay is not None:
            self._copy(*underlay)
        imgui.backends.opengl3_render_draw_data(imgui.get_draw_data())

    def _copy(self, framebuffer: moderngl.Framebuffer, x: int, y: int) -> None:
        w, h = framebuffer.size
        bottom = self.size[1] - y - h  # OpenGL rows count from the bottom
        self._bind_framebuffer(_GL_READ_FRAMEBUFFER, framebuffer.glo)
        self._bind_framebuffer(_GL_DRAW_FRAMEBUFFER, 0)
        self._blit_framebuffer(0, 0, w, h, x, bottom, x + w, bottom + h, _GL_COLOR_BUFFER_BIT, _GL_NEAREST)
        self._bind_framebuffer(_GL_READ_FRAMEBUFFER, 0)

    def screenshot(self) -> np.ndarray:
        """The drawn but not yet shown frame as (H, W, 3) uint8, top row first."""
        width, height = self.size
        data = self.ctx.screen.read(viewport=(0, 0, width, height), components=3)
        return np.frombuffer(data, dtype=np.uint8).reshape(height, width, 3)[::-1]

    def present(self) -> None:
        glfw.swap_buffers(self.handle)

    def close(self) -> None:
        imgui.backends.opengl3_shutdown()
        imgui.backends.glfw_shutdown()
        imgui.destroy_context()
        glfw.destroy_window(self.handle)
        glfw.terminate()


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
