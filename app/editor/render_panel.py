"""The live render beside the viewport, off the UI thread: the voxel shader or the NVR+ network.

The user picks one of the interactive renderers of models/renderers.py. Without a trained model NVR+ falls back to
the splatted image S, and the panel says so. The AsyncRenderer renders only the newest scene submitted, so a drag
never queues up stale frames.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from PIL import Image

from models.engine.async_render import AsyncRenderer
from models.engine.render_engine import default_threads
from models.renderers import (
    INTERACTIVE,
    Renderer,
    RendererOptions,
    SplatRenderer,
    correction_note,
    fixed_size,
    make_renderer,
    renderer_entry,
)
from renderer.color import to_uint8
from renderer.errors import InputError
from renderer.io import save_png
from renderer.scene import Scene
from renderer.voxel_cache import VoxelCache

NO_MODEL_LABEL = "no trained model: showing splat"
RENDER_NICENESS = 5  # render threads get about a third of the CPU share of the UI thread when both want it
# A settled image is drawn again at the panel's size once the scene has stood this long (seconds), so that the next
# edit, if it comes at once, does not wait behind it (a redraw at the panel's size takes a frame's time: docs/results.md, "Measurements behind the code").
DETAIL_DELAY_S = 0.3


@dataclass(frozen=True)
class RenderedFrame:
    image: np.ndarray  # (S, S, 3) float32 sRGB in [0, 1]
    scene: Scene  # the scene it shows
    preview: bool  # a quick render while an edit is in progress
    seconds: float  # how long it took
    detail: bool = False  # the settled image drawn again at the panel's size (LiveRender.refine)
    note: str = ""  # what the image is when the renderer drew something else than usual (RenderReport.note)


class LowPriority:
    """An engine whose renders run below the interface's CPU priority, so rendering never starves the UI.

    The first render lowers the calling thread's priority (Linux: per-thread nice); the OpenMP
    threads torch starts from that thread inherit it. Elsewhere this is a plain pass-through.
    """

    def __init__(self, engine):
        self._engine = engine
        self._lowered = False

    @property
    def last_report(self):
        return self._engine.last_report

    def render(self, scene: Scene) -> np.ndarray:
        self._lower()
        return self._engine.render(scene)

    def preview(self, scene: Scene) -> np.ndarray:
        self._lower()
        return self._engine.preview(scene)

    def render_sized(self, scene: Scene, size: int) -> np.ndarray:
        self._lower()
        return self._engine.render_sized(scene, size)

    def _lower(self) -> None:
        if not self._lowered:
            self._lowered = True
            try:
                os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), RENDER_NICENESS)
            except (AttributeError, OSError):
                pass  # not Linux, or not allowed: render at normal priority


class LiveRender:
    """Submits scenes to a worker thread and hands each newly finished frame to the UI once."""

    def __init__(self, voxels: VoxelCache, model_path: str | None = None, renderer: str = "nvr+",
                 quality: str = "full", detail_delay: float = DETAIL_DELAY_S):
        """`detail_delay`: how long a settled image stands before it is drawn again at the panel's size (`refine`)."""
        self.model_path = model_path
        self.quality = quality  # the shader's, for both renderers (renderer.shading.QUALITIES); exports stay full
        self._voxels = voxels
        self._engines: dict[str, object] = {}
        self._labels: dict[str, tuple[str, str, bool]] = {}  # renderer -> (what renders, device, as chosen)
        self.renderer = ""
        self.select(renderer)
        self._renderer = AsyncRenderer(LowPriority(_Selected(self)))
        self._scenes: dict[int, tuple[Scene, bool]] = {}  # submitted, not yet handed out: (scene, detail) by number
        self._handed = 0
        self.error: str | None = None
        self.panel_size: int | None = None  # the render panel's image side in pixels (the panel sets it as it draws)
        self.detail_delay = detail_delay
        self._settled: tuple[Scene, float] | None = None  # the last final image to draw at the panel's size, and when
        self._last_seconds = 0.0  # the time of the last render that computed anything (one that reuses all shows it)

    def select(self, renderer: str) -> None:
        """Render with `renderer` (one of models.renderers.INTERACTIVE) from the next submitted scene on."""
        if renderer not in INTERACTIVE:
            raise InputError(f"unknown renderer {renderer!r} (choose from {', '.join(INTERACTIVE)})")
        if renderer not in self._engines:
            self._engines[renderer], self._labels[renderer] = self._make_engine(renderer)
        self.renderer = renderer
        self._settled = None  # the last image was another renderer's

    @property
    def engine(self):
        return self._engines[self.renderer]

    def _make_engine(self, renderer: str) -> tuple[Renderer, tuple[str, str, bool]]:
        """The engine for `renderer` and its labels: what renders, on what device, and whether it is what was chosen."""
        options = RendererOptions(model=self.model_path, quality=self.quality, voxels=self._voxels)
        entry = renderer_entry(renderer)
        try:
            engine = entry.make(options)
        except InputError as exc:  # no trained model: the splat stands in
            print(f"nvr-editor: {NO_MODEL_LABEL}: {exc}", file=sys.stderr)
            return SplatRenderer(options), (NO_MODEL_LABEL, "cpu (splatting)", False)
        if entry.architecture is None:
            return engine, (entry.label, f"cpu{self._quality_note}", True)
        threads = f", {default_threads()} threads" if engine.device.type == "cpu" else ""
        return engine, (f"{entry.label} {engine.model_name}",
                        f"{engine.device.type}, {engine.precision}{threads}{self._quality_note}", True)

    @property
    def _quality_note(self) -> str:
        return "" if self.quality == "full" else f", {self.quality} shading"

    @property
    def label(self) -> str:
        """What renders (the model's name for NVR+)."""
        return self._labels[self.renderer][0]

    @property
    def device(self) -> str:
        return self._labels[self.renderer][1]

    @property
    def renders_any_size(self) -> bool:
        """Whether an image of another size than the live one is rendered at that size (the shader, the splat, an NVR+
        that corrects the shader's image), not resized: exports, and the panel's redraw of a settled image."""
        return self.engine.renders_any_size

    @property
    def neural(self) -> bool:
        """False when NVR+ was chosen but no model loaded (the splat stands in)."""
        return self._labels[self.renderer][2]

    def submit(self, scene: Scene, preview: bool = False) -> None:
        """Ask for `scene` (replacing any request not started yet)."""
        self._settled = None
        self._scenes[self._renderer.submit(scene, preview)] = (scene, False)

    def poll(self) -> RenderedFrame | None:
        """The newest finished frame not handed out yet, or None; a failed render sets `error`."""
        frame = self._renderer.latest()
        if frame is None or frame.sequence <= self._handed:
            return None
        self._handed = frame.sequence
        scene, detail = self._scenes.pop(frame.sequence)
        self._scenes = {k: v for k, v in self._scenes.items() if k > frame.sequence}
        if frame.image is None:
            self.error = frame.error
            return None
        if not frame.preview and not detail and not self._scenes and self._redraw_larger(frame.image):
            self._settled = (scene, time.monotonic())
        seconds = frame.report.total_ms / 1000.0 if frame.report is not None else 0.0
        if frame.report is not None and not frame.report.stages_run:  # all kept from the render before (a drag's end)
            seconds = self._last_seconds
        self._last_seconds = seconds
        note = getattr(frame.report, "note", "")
        return RenderedFrame(frame.image, scene, frame.preview, seconds, detail, note)

    def refine(self) -> None:
        """Once the last final image has stood detail_delay seconds with nothing else asked, render it again at the
        panel's size: the 256 px image, shown larger, is blurred, and the shader, an NVR+ that corrects its image
        (RenderEngine.render_sized) and the splat draw any size. Call once per UI frame."""
        if self._settled is None or time.monotonic() - self._settled[1] < self.detail_delay:
            return
        scene, _ = self._settled
        self._settled = None
        size = self.panel_size
        if size is not None and self._renderer.wait_idle(timeout=0) and not self._scenes:
            self._scenes[self._renderer.submit(scene, size=size)] = (scene, True)

    def _redraw_larger(self, image: np.ndarray) -> bool:
        """Whether `image`'s scene is to be drawn again at the panel's size: it is larger, and the engine draws any size."""
        return self.panel_size is not None and self.panel_size > image.shape[0] and self.renders_any_size

    @property
    def idle(self) -> bool:
        """Nothing waiting or rendering, every finished frame handed out, and no image waiting to be refined."""
        return self._renderer.wait_idle(timeout=0) and not self._scenes and self._settled is None

    def close(self) -> None:
        self._renderer.close()


class _Selected:
    """The engine of the renderer the user chose, looked up at each render (the worker thread's view)."""

    def __init__(self, live: LiveRender):
        self._live = live
        self._last = None

    @property
    def last_report(self):
        return None if self._last is None else self._last.last_report

    def render(self, scene: Scene) -> np.ndarray:
        self._last = self._live.engine
        return self._last.render(scene)

    def preview(self, scene: Scene) -> np.ndarray:
        self._last = self._live.engine
        return self._last.preview(scene)

    def render_sized(self, scene: Scene, size: int) -> np.ndarray:
        self._last = self._live.engine
        return self._last.render_sized(scene, size)


def final_render(scene: Scene, model_path: str | None = None, renderer: str = "nvr+",
                 voxels: VoxelCache | None = None) -> tuple[np.ndarray, str]:
    """The panel renderer's image of `scene` at the scene's size and what made it: the voxel shader's; the NVR+'s (a
    network that corrects the shader's image renders any size, one that draws it itself its own 256 px); or the splat
    when no model loads."""
    options = RendererOptions(model=model_path, voxels=voxels or VoxelCache())  # the editor's: not voxelised again
    try:
        engine = make_renderer(renderer, options)
    except InputError:
        if model_path is not None:
            raise
        return SplatRenderer(options).render(scene), "splat, no trained model"
    entry, size = renderer_entry(renderer), fixed_size(engine) or scene.image_size
    name = entry.label if entry.architecture is None else f"{renderer} {engine.model_name}"
    return engine.render_sized(scene, size), name + correction_note(engine, size)


def export_render(scene: Scene, path: str | Path, model_path: str | None = None, renderer: str = "nvr+",
                  voxels: VoxelCache | None = None, size: int | None = None) -> str:
    """Write the panel renderer's image of `scene` at `size` (default the scene's); returns what was used. The voxel
    shader and an NVR+ that corrects its image render any size; a network's 256 px image of another size is resized
    (Lanczos), and says so."""
    size = size or scene.image_size
    image, used = final_render(replace(scene, image_size=size), model_path, renderer, voxels)
    native = image.shape[0]
    if native != size:
        image = np.asarray(Image.fromarray(to_uint8(image)).resize((size, size), Image.Resampling.LANCZOS))
        used += f", {'upscaled' if size > native else 'downscaled'} from {native} px"
    save_png(path, image)
    return used
