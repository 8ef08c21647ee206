"""Work off the UI thread: a one-shot job with progress (voxelising a mesh, coloring from a photo).

The job runs in a daemon thread; the UI polls `done`, `progress`, `result` and `error` once
a frame, so the window keeps drawing while it works. Bad input (InputError) ends up in
`error` as a message, never as a crash.
"""

from __future__ import annotations

import threading
import traceback
from collections.abc import Callable
from typing import Any

from renderer.errors import InputError

Progress = Callable[[float], None]


class BackgroundJob:
    """Runs `work(progress)` once in a thread; `progress` reports a fraction in [0, 1]."""

    def __init__(self, title: str, work: Callable[[Progress], Any]):
        self.title = title
        self.progress = 0.0
        self.result: Any = None
        self.error: str | None = None
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._run, args=(work,), name=f"job: {title}", daemon=True)
        self._thread.start()

    @property
    def done(self) -> bool:
        return self._done.is_set()

    def _report(self, fraction: float) -> None:
        self.progress = min(max(float(fraction), 0.0), 1.0)

    def _run(self, work: Callable[[Progress], Any]) -> None:
        try:
            self.result = work(self._report)
            self.progress = 1.0
        except InputError as exc:
            self.error = str(exc)
        except Exception as exc:  # a bug must reach the user as a message, and the scene must survive it
            traceback.print_exc()
            self.error = f"{self.title} failed: {type(exc).__name__}: {exc}"
        finally:
            self._done.set()
