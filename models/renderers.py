"""Every renderer of NVR Studio by one name: the one table the CLI, the turntable, the editor's panel, eval and bench read.

A renderer turns scenes into images and keeps what it computed between calls (its stages, its voxels), so a sequence
of edited scenes costs what the edits change. All of them follow the `Renderer` protocol.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Literal, Protocol

from renderer.errors import InputError
from renderer.stage_cache import RenderReport

if TYPE_CHECKING:  # the CLI reads the table's names before any renderer loads: nothing heavy at import
    import numpy as np

    from renderer.scene import Scene
    from renderer.voxel_cache import VoxelCache

RendererKind = Literal["network", "shader", "splat", "pathtrace"]


class Renderer(Protocol):
    """Scenes in, float32 sRGB images (S, S, 3) out; state kept between calls."""

    renders_any_size: bool  # False: only its own output_size (a network that draws the image itself)
    last_report: RenderReport | None  # what the last call ran, and its timings
    description: str  # what renders, for status lines and reports

    def render(self, scene: Scene) -> np.ndarray:
        """The scene at its live size: the scene's image size, a network's own output size."""

    def preview(self, scene: Scene) -> np.ndarray:
        """A quick image while an edit is in progress (the renderers that have none render in full)."""

    def render_sized(self, scene: Scene, size: int) -> np.ndarray:
        """The scene at `size` pixels, keeping the live size's cached stages."""


@dataclass
class RendererOptions:
    """What a renderer may be built with; each renderer reads the fields it needs."""

    model: str | None = None  # network weights; None: the shipped model
    precision: str = "auto"  # network arithmetic: auto, fp32, bf16
    device: str = "auto"  # network device: auto, cpu, cuda
    quality: str = "full"  # the voxel shader's (renderer.shading.QUALITIES), for the shader and NVR+
    spp: int = 64  # path tracing: samples per pixel
    seed: int = 0  # path tracing: random seed
    denoise: bool = True  # path tracing: Intel Open Image Denoise
    voxels: VoxelCache = field(default_factory=lambda: _voxel_cache())  # the scenes' object voxels, shared with the caller


@dataclass(frozen=True)
class RendererEntry:
    name: str  # the one spelling: --renderer, the scene files, replay files, reports
    label: str  # what it is, in words: the panel's menu, the bench's rows and plots
    kind: RendererKind
    make: Callable[[RendererOptions], Renderer]
    summary: str  # what draws the image, for --help
    architecture: str | None = None  # a network's architecture (models.networks), which its weights must hold
    interactive: bool = False  # offered by the editor's render panel


def _voxel_cache() -> VoxelCache:
    from renderer.voxel_cache import VoxelCache

    return VoxelCache()


def _timed(renderer: Renderer, stages: dict[str, float], start: float, preview: bool) -> None:
    renderer.last_report = RenderReport(tuple(stages), dict(stages), (time.perf_counter() - start) * 1000.0, preview)


class SplatRenderer:
    """The splatted surface voxels over the empty floor (paper 3.4), the networks' input."""

    renders_any_size = True
    description = "the splatted surface voxels"

    def __init__(self, options: RendererOptions) -> None:
        self._voxels = options.voxels
        self.last_report: RenderReport | None = None

    def render(self, scene: Scene, preview: bool = False) -> np.ndarray:
        from renderer.splat import splat_objects

        start = time.perf_counter()
        painted = [self._voxels.painted(scene.alone(i))[0] for i in range(len(scene.objects))]
        image = splat_objects(scene, painted, scene.floor.color)
        _timed(self, {"splat": (time.perf_counter() - start) * 1000.0}, start, preview)
        return image

    def preview(self, scene: Scene) -> np.ndarray:
        return self.render(scene, preview=True)

    def render_sized(self, scene: Scene, size: int) -> np.ndarray:
        return self.render(replace(scene, image_size=size))


class ShaderRenderer:
    """The voxel shader (renderer/shading/), its stages cached: a light move reruns only the light's."""

    renders_any_size = True

    def __init__(self, options: RendererOptions) -> None:
        from renderer.shading import quality_named
        from renderer.shading.staged import StagedShader

        self._voxels = options.voxels
        self._shader = StagedShader(quality=quality_named(options.quality))
        self._lock = threading.Lock()  # the editor's exports and its render thread share the stages
        self.description = "voxel shader" + ("" if options.quality == "full" else f", {options.quality} shading")
        self.last_report: RenderReport | None = None

    def render(self, scene: Scene, preview: bool = False, size: int | None = None) -> np.ndarray:
        """The scene at its image size, or at `size` without keeping the stages that depend on the size."""
        from renderer.shading.staged import ObjectVoxels
        from renderer.voxel_cache import source_key

        start = time.perf_counter()
        objects = []
        for o, one in zip(scene.objects, map(scene.alone, range(len(scene.objects)))):
            rgba, _ = self._voxels.painted(one)
            shape = source_key(one)  # paint keeps the occupancy: the shader keeps what the camera sees
            objects.append(ObjectVoxels(o, (shape, o.paint), rgba, shape))
        with self._lock:
            self._shader.cache.begin()
            image = self._shader.run_objects(scene, objects, scene.floor.color, size or scene.image_size,
                                             keep=size is None).image
            stages = dict(self._shader.stage_ms)
        _timed(self, stages, start, preview)
        return image

    def preview(self, scene: Scene) -> np.ndarray:
        return self.render(scene, preview=True)

    def render_sized(self, scene: Scene, size: int) -> np.ndarray:
        """At the scene's own size, the live render (its stages kept); at another, a one-off image."""
        return self.render(scene) if size == scene.image_size else self.render(scene, size=size)


class PathTraceRenderer:
    """Mitsuba 3 path tracing from the mesh, colored from the painted voxels: the reference."""

    renders_any_size = True

    def __init__(self, options: RendererOptions) -> None:
        self._options = options
        self._reference: tuple[tuple, Scene, list] | None = None  # (what it was made from, scene, meshes)
        self.description = f"path tracer, {options.spp} spp" + (" + OIDN" if options.denoise else "")
        self.last_report: RenderReport | None = None

    def render(self, scene: Scene) -> np.ndarray:
        return self.render_sized(scene, scene.image_size)

    def preview(self, scene: Scene) -> np.ndarray:
        return self.render(scene)

    def render_sized(self, scene: Scene, size: int) -> np.ndarray:
        from renderer.pathtrace.path_tracer import render_pathtraced

        start = time.perf_counter()
        reference, meshes = self._colored(scene)
        # The reference differs from the scene only in the objects' colors: their meshes' own.
        traced = replace(scene, objects=tuple(replace(o, color=r.color) for o, r in zip(scene.objects, reference.objects)))
        o = self._options
        result = render_pathtraced(traced, meshes, size=size, spp=o.spp, seed=o.seed, denoise=o.denoise)
        self.description = f"path tracer, mitsuba {result.variant}, {o.spp} spp" + (" + OIDN" if o.denoise else "")
        _timed(self, {"pathtrace": (time.perf_counter() - start) * 1000.0}, start, False)
        return result.image

    def _colored(self, scene: Scene) -> tuple[Scene, list]:
        """The scene and one mesh per object with the paint and captured colors on the meshes, made once per set of
        objects and their paint."""
        from renderer.reference_object import reference_objects
        from renderer.voxel_cache import source_key

        key = tuple((source_key(scene.alone(i)), o.paint) for i, o in enumerate(scene.objects))
        if self._reference is None or self._reference[0] != key:
            self._reference = (key, *reference_objects(scene))
        return self._reference[1], self._reference[2]


def _network(architecture: str) -> Callable[[RendererOptions], Renderer]:
    def make(options: RendererOptions) -> Renderer:
        from models.engine.render_engine import RenderEngine

        return RenderEngine.load(options.model, architecture=architecture, precision=options.precision,
                                 device=options.device, shader_quality=options.quality,
                                 object_source=options.voxels.object_rgba)

    return make


RENDERERS: dict[str, RendererEntry] = {entry.name: entry for entry in (
    RendererEntry("nvr+", "NVR+", "network", _network("nvr_plus"),
                  "the editor's image: the shaded voxels corrected by the network (any size)",
                  architecture="nvr_plus", interactive=True),
    RendererEntry("shaded", "voxel shader", "shader", ShaderRenderer,
                  "the voxels lit physically: soft shadows, lit floor (any size)", interactive=True),
    RendererEntry("nvr", "NVR", "network", _network("nvr"), "the paper's network without the splat (256 px)",
                  architecture="nvr"),
    RendererEntry("splat", "splatting", "splat", SplatRenderer, "the surface voxels' colors"),
    RendererEntry("pathtrace", "path tracing", "pathtrace", PathTraceRenderer, "the mesh in Mitsuba 3, the reference"),
)}
INTERACTIVE = tuple(name for name, entry in RENDERERS.items() if entry.interactive)
EVALUATED = tuple(name for name, entry in RENDERERS.items() if entry.kind != "pathtrace")  # eval's reference


def renderer_entry(name: str) -> RendererEntry:
    """The table's entry of `name`; an unknown name is refused with the known ones."""
    if name not in RENDERERS:
        raise InputError(f"unknown renderer {name!r} (choose from {', '.join(RENDERERS)})")
    return RENDERERS[name]


def network_entry(architecture: str) -> RendererEntry:
    """The entry of the network renderer whose weights hold `architecture`."""
    return next(e for e in RENDERERS.values() if e.architecture == architecture)


def make_renderer(name: str, options: RendererOptions | None = None) -> Renderer:
    """A renderer of the table, built with `options` (defaults: the shipped weights, full quality)."""
    return renderer_entry(name).make(options or RendererOptions())


def fixed_size(renderer: Renderer) -> int | None:
    """The one size a renderer draws (a network that draws the image itself), None if it draws any size."""
    return None if renderer.renders_any_size else renderer.output_size  # type: ignore[attr-defined]


def correction_note(renderer: Renderer, size: int) -> str:
    """", corrected at N px" when a network corrects the shader's `size` px image with what it computes at its own N."""
    own = getattr(renderer, "output_size", None)  # only a network works at a size of its own
    return f", corrected at {own} px" if renderer.renders_any_size and own not in (None, size) else ""
