"""UI frame times for the status bar and the headless run's summary."""

from __future__ import annotations

import time
from collections import deque
from dataclasses import dataclass, field


@dataclass
class FrameStats:
    """UI frame times (wall time per frame, and the part spent working rather than pacing), split by
    whether the live render was working during the frame."""

    wall: dict[bool, list[float]] = field(default_factory=lambda: {True: [], False: []})
    work: dict[bool, list[float]] = field(default_factory=lambda: {True: [], False: []})
    drawn_work: dict[bool, list[float]] = field(default_factory=lambda: {True: [], False: []})  # frames that changed
    renders: list[float] = field(default_factory=list)  # seconds each shown render took
    recent: deque = field(default_factory=lambda: deque(maxlen=240))  # (monotonic time, work seconds) of active frames

    def add(self, wall_seconds: float, work_seconds: float, rendering: bool, drawn: bool) -> None:
        self.recent.append((time.monotonic(), work_seconds))
        self.wall[rendering].append(wall_seconds)
        self.work[rendering].append(work_seconds)
        if drawn:
            self.drawn_work[rendering].append(work_seconds)

    def current_text(self, window_seconds: float = 1.0) -> str:
        """The UI's work per frame over the last second of active frames, or "idle" when nothing was drawing
        (an idle window sleeps until input comes: its frame rate says nothing)."""
        since = time.monotonic() - window_seconds
        work = sorted(w for t, w in self.recent if t >= since)
        if not work:
            return "UI idle"
        return f"UI {1000.0 * work[len(work) // 2]:.1f} ms/frame"

    def summary(self) -> str:
        parts = []
        for rendering, name in ((True, "while rendering"), (False, "idle")):
            wall, work, drawn = self.wall[rendering], self.work[rendering], self.drawn_work[rendering]
            if wall:
                parts.append(f"{name}: {len(wall) / sum(wall):.1f} fps over {len(wall)} frames "
                             f"({1000.0 * sum(work) / len(work):.1f} ms of work per frame; {len(drawn)} drawn"
                             + (f", {1000.0 * sum(drawn) / len(drawn):.1f} ms each" if drawn else "") + ")")
        slowest = max((w for rendering in (True, False) for w in self.work[rendering]), default=None)
        if slowest is not None:
            parts.append(f"slowest frame {1000.0 * slowest:.0f} ms of work")
        if self.renders:
            parts.append(f"render median {1000.0 * sorted(self.renders)[len(self.renders) // 2]:.0f} ms "
                         f"over {len(self.renders)} renders")
        return "UI " + "; ".join(parts)
