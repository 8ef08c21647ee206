"""The render panel's Reference: the scene as edited, path traced in the background, and its MSE to the live image."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from app.editor.editor_parts import EditorWithViews
from app.editor.jobs import Progress
from app.editor.window import upload_image
from renderer.scene import Scene

if TYPE_CHECKING:
    from app.editor.render_panel import RenderedFrame

REFERENCE_SPP = 64  # with OIDN: the project's reference quality (docs/pathtrace_spp.md)


@dataclass(frozen=True)
class Reference:
    """A path-traced image of a scene, shown beside the live render."""

    image: np.ndarray
    scene: Scene
    label: str


class ReferenceRender:
    """The last reference image and its texture; the error against a frame is computed once per pair."""

    def __init__(self, app: EditorWithViews) -> None:
        self.app = app
        self.shown: Reference | None = None
        self.texture = None
        self._error: tuple = (None, None, None)  # (frame, reference, their MSE)

    def start(self, spp: int = REFERENCE_SPP) -> None:
        """Path trace the committed scene (edits included) in the background, to show beside the live render."""
        from renderer.pathtrace.path_tracer import PathTracer
        from renderer.reference_object import reference_objects

        scene = self.app.doc.history.current

        def work(progress: Progress) -> Reference:
            start = time.perf_counter()
            traced_scene, meshes = reference_objects(scene)
            progress(0.15)
            tracer = PathTracer(traced_scene, meshes)
            progress(0.3)
            result = tracer.render(spp, seed=0, denoise=True)
            return Reference(result.image, scene, f"path traced, {result.spp} spp + OIDN, {time.perf_counter() - start:.1f} s")

        def done(reference: Reference) -> None:
            self.shown = reference
            self.texture = upload_image(self.app.window.ctx, self.texture, reference.image)
            self.app.say(f"reference render ready ({reference.label})")

        self.app.jobs.start("Path tracing the reference", work, done)

    def close(self) -> None:
        """Stop showing the reference."""
        self.shown = None

    def error(self, frame: RenderedFrame | None) -> float | None:
        """MSE (0-255 scale) between `frame` and the reference, when both show the same scene at one size."""
        reference = self.shown
        if self._error[0] is not frame or self._error[1] is not reference:
            same = (frame is not None and reference is not None and not frame.preview and frame.scene == reference.scene
                    and frame.image.shape == reference.image.shape)
            error = float(np.mean((frame.image.astype(np.float64) - reference.image) ** 2) * 255.0**2) if same else None
            self._error = (frame, reference, error)
        return self._error[2]
