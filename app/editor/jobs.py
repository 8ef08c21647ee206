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


class JobRunner:
    """One background job at a time; its result goes to its handler on the UI thread, its error to `say`."""

    def __init__(self, say: Callable[..., None]) -> None:
        self._say = say
        self.current: BackgroundJob | None = None  # the job under way (or done and not yet handed over)
        self._on_result: Callable[[Any], None] | None = None
        self._on_error: Callable[[], None] | None = None

    def start(self, title: str, work: Callable[[Progress], Any], on_result: Callable[[Any], None],
              on_error: Callable[[], None] | None = None) -> BackgroundJob | None:
        """Run `work(progress)` in the background; `on_result` gets its result on the UI thread (`finish`), and
        `on_error`, if given, is called there after a failure is shown. The job, or None when another is under way."""
        if self.current is not None and not self.current.done:
            self._say(f"busy: {self.current.title}", error=True)
            return None
        self.current = BackgroundJob(title, work)
        self._on_result, self._on_error = on_result, on_error
        return self.current

    def finish(self) -> None:
        """Once per frame: hand a finished job's result to its handler, or show its error."""
        if self.current is None or not self.current.done:
            return
        job, self.current = self.current, None
        if job.error:
            self._say(job.error, error=True)
            if self._on_error is not None:
                self._on_error()
        else:
            self._on_result(job.result)
