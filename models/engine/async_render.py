"""Rendering off the UI thread: the newest edit wins, and an older image never replaces a newer one.

`submit(scene, preview)` numbers each request and returns at once. One worker thread renders
the newest request; a request still waiting when a newer one arrives is dropped unrendered.
Each finished frame carries its request's number and is kept (and passed to `on_frame`) only if
it is newer than the frame already shown. While the user drags, submit with preview=True (the
engine's fast preview); on release submit the final scene with preview=False; `size` asks for the
final image at another size than the engine's own (its render_sized).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from renderer.errors import InputError
from renderer.scene import Scene


class Engine(Protocol):
    """What the worker needs of models.engine.render_engine.RenderEngine."""

    last_report: object

    def render(self, scene: Scene) -> np.ndarray: ...

    def preview(self, scene: Scene) -> np.ndarray: ...

    def render_sized(self, scene: Scene, size: int) -> np.ndarray: ...


@dataclass(frozen=True)
class Frame:
    """A finished request: its number, the image (None if it failed), and the engine's report or the error."""

    sequence: int
    preview: bool
    image: np.ndarray | None
    report: object | None = None
    error: str | None = None


class AsyncRenderer:
    """Renders submitted scenes on one worker thread. `on_frame` runs on that thread (hand the frame to the UI)."""

    def __init__(self, engine: Engine, on_frame: Callable[[Frame], None] | None = None):
        self.engine = engine
        self.on_frame = on_frame
        self._cond = threading.Condition()
        self._pending: tuple[int, Scene, bool, int | None] | None = None
        self._latest: Frame | None = None
        self._submitted = 0
        self._busy = False
        self._closed = False
        self._worker = threading.Thread(target=self._run, name="nvr-render", daemon=True)
        self._worker.start()

    def submit(self, scene: Scene, preview: bool = False, size: int | None = None) -> int:
        """Queue `scene` (the final image at `size`, if given), replacing any request not yet started; returns its
        sequence number."""
        with self._cond:
            if self._closed:
                raise RuntimeError("the renderer is closed")
            self._submitted += 1
            self._pending = (self._submitted, scene, preview, size)
            self._cond.notify_all()
            return self._submitted

    def latest(self) -> Frame | None:
        """The newest finished frame so far."""
        with self._cond:
            return self._latest

    def wait_for(self, sequence: int, timeout: float | None = None) -> Frame | None:
        """Wait until a frame numbered `sequence` or newer is finished (a dropped request is answered by a newer one)."""
        with self._cond:
            self._cond.wait_for(lambda: self._latest is not None and self._latest.sequence >= sequence, timeout)
            return self._latest

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Wait until nothing is pending or rendering; False on timeout."""
        with self._cond:
            return self._cond.wait_for(lambda: self._pending is None and not self._busy, timeout)

    def close(self) -> None:
        """Finish the frame being rendered, drop what is pending, stop the worker."""
        with self._cond:
            self._closed = True
            self._pending = None
            self._cond.notify_all()
        self._worker.join()

    def _run(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: self._pending is not None or self._closed)
                if self._closed:
                    return
                sequence, scene, preview, size = self._pending
                self._pending, self._busy = None, True
            frame = self._render(sequence, scene, preview, size)
            with self._cond:
                shown = self._latest is None or frame.sequence > self._latest.sequence
                if shown:
                    self._latest = frame
                self._busy = False
                self._cond.notify_all()
            if shown and self.on_frame is not None:
                self.on_frame(frame)

    def _render(self, sequence: int, scene: Scene, preview: bool, size: int | None) -> Frame:
        try:
            if preview:
                image = self.engine.preview(scene)
            else:
                image = self.engine.render(scene) if size is None else self.engine.render_sized(scene, size)
        except InputError as exc:  # a bad scene file or mesh: show the message
            return Frame(sequence, preview, None, error=str(exc))
        except Exception as exc:  # a failed frame must not stop the worker; the UI shows the error
            return Frame(sequence, preview, None, error=f"{type(exc).__name__}: {exc}")
        return Frame(sequence, preview, image, self.engine.last_report)
