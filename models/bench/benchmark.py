"""`nvr bench`: every renderer of the project on the same scenes in one process, speed against error.

Renderers: path tracing at 1, 4, 16, 64 and 256 spp, raw and denoised by OIDN; splatting; the voxel
shader (its stages cached as in the editor); NVR
and NVR+ through the live engine for every weights file (--model, else assets/models/*.safetensors);
for timing only, the compact networks when they have no weights yet and the paper configuration,
with random weights. For each: median time per frame at 256^2 and its interquartile range over
all scenes and repeats (the shader's and the trained networks' rows timed in step, scene by scene:
bench_in_step), peak memory (models/bench/system.py), and MSE, DSSIM and the perceptual
distance against a raw path-traced reference of the same scene (1024 spp; --quick: 32).
Also: the engine's latency per edit type with the object crop and with the full grid, the shipped NVR+'s
frame timed in turn with path tracing at 1 spp + OIDN (bench_in_turn: the Pareto target's ratio), the FLOPs
per frame of each network configuration, and the share of a measured fp32 matmul peak they imply; the same scenes
under a sun and sky with glossy objects (models/bench/environment.py); and edit latencies against the number of
objects in a scene (models/bench/objects.py).

A network's time per frame is a re-render after an object move along the floor (resampling, voxel
branch, splat and shading; the mesh is voxelised once per scene): what a drag in the editor costs per
step. Path tracing's is sampling plus denoising with the Mitsuba scene already built; splatting's is
the splat of painted voxels; the shader's, like a network's, a re-render after an object move.
"""

from __future__ import annotations

import datetime
import os
import re
import statistics
import tempfile
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

# isort: split
import models.engine  # noqa: F401 - before torch, so OMP_WAIT_POLICY is set when torch loads OpenMP

# isort: split
import numpy as np
import torch
from torch.utils.flop_counter import FlopCounterMode

from models.bench.environment import MATERIALS, SKY, describe, edit_ms, environment_scene
from models.bench.objects import bench_object_counts
from models.bench.plot import Point, draw_speed_vs_error, pareto_front
from models.bench.scenes import BenchScene, data_scenes, procedural_scenes
from models.bench.system import PeakMemory, cpu_snapshot, machine_description, other_load
from models.engine.render_engine import RenderEngine, resolve_precision
from models.evaluation.metrics import ImageMetrics
from models.networks.checkpoint import check_weights_file, load_model
from models.networks.config import (
    IMAGE_CHANNELS,
    CompactConfig,
    HalfResolutionRefinerConfig,
    NVRConfig,
    PaperConfig,
    ShaderRefinerConfig,
)
from models.networks.inference import prepare_for_inference
from models.networks.nvr import SHADING_CHANNELS, build_model, reads_floor_light, reads_shading
from models.networks.shipped import ASSET_MODELS, SHIPPED_WEIGHTS
from models.renderers import RENDERERS, make_renderer, network_entry
from renderer.errors import InputError
from renderer.io import save_json
from renderer.pathtrace.mitsuba_variant import LIBLLVM_ENV, LLVM_VARIANT, active_variant
from renderer.pathtrace.path_tracer import PathTracer
from renderer.pipeline import object_voxels, painted_voxels
from renderer.scene import GRID_SIZE, SHADER_GRID_SIZE, CameraSpec, FloorSpec, LightSpec, PaintOp, Scene
from renderer.shading import quality_named
from renderer.shading.staged import StagedShader
from renderer.splat import splat_scene

SIZE = 256
REFERENCE_SEED = 1_000_003
DOCS = Path(__file__).resolve().parents[2] / "docs"


@dataclass(frozen=True)
class BenchSettings:
    spps: tuple[int, ...] = (1, 4, 16, 64, 256)
    reference_spp: int = 1024
    repeats: int = 5  # timed frames per scene (fewer above 16 spp, see repeats_for)
    edit_repeats: int = 15  # timed frames per edit type (the latency targets: a median that one slow frame cannot move)
    scenes: int = 4
    paper: bool = True  # time the paper configuration (seconds per frame on a CPU)
    full_grid_edits: bool = True  # also time every edit without the object crop
    matmul_size: int = 2048
    in_turn_rounds: int = 6  # rounds of the shipped NVR+ timed in turn with path tracing (bench_in_turn)
    in_step_rounds: int = 4  # rounds over the scenes of the shader's and the networks' rows (bench_in_step)
    environment_spps: tuple[int, ...] = (1, 4)  # path tracing's rows under environment light (bench_environment)
    object_counts: tuple[int, ...] = (1, 2, 4, 8)  # scenes of this many objects, their edits timed (bench_object_counts)

    def repeats_for(self, spp: int) -> int:
        return self.repeats if spp <= 16 else max(1, self.repeats // (2 if spp <= 64 else 5))


FULL = BenchSettings()
QUICK = BenchSettings(spps=(1, 4), reference_spp=32, repeats=3, edit_repeats=3, scenes=1, paper=False, full_grid_edits=False,
                      matmul_size=1024, in_turn_rounds=1, in_step_rounds=1, object_counts=(1, 2))


@dataclass
class Row:
    """One renderer and setting: time per frame (ms), peak memory (MB) and errors (None: timing only)."""

    family: str
    setting: str
    ms: float
    ms_q25: float
    ms_q75: float
    peak_mb: float
    mse: float | None = None
    dssim: float | None = None
    perceptual: float | None = None
    precision: str = "fp32"  # a network's arithmetic ("bf16" or "fp32"); the other renderers run no bfloat16

    @property
    def label(self) -> str:
        return f"{self.family} {self.setting}".strip()


def pareto_labels(rows: list[Row], without_bf16: bool = False) -> list[str]:
    """The labels of the rows with an error on the Pareto front of time against MSE; `without_bf16`: of the rows a CPU
    without bfloat16 runs (float32 networks and the other renderers), the CPU the targets are set for, where no
    bfloat16 row would stand in front of them."""
    kept = [r for r in rows if r.mse is not None and not (without_bf16 and r.precision == "bf16")]
    return [p.label for p in pareto_front([_point(r) for r in kept])]


def run_bench(settings: BenchSettings, data: list[str] | None = None, model_paths: list[str] | None = None,
              note: str = "") -> dict[str, Any]:
    """Run everything and return the numbers (JSON-ready); see the module docstring."""
    started, cpu_before, load_before = time.perf_counter(), cpu_snapshot(), os.getloadavg()
    memory = PeakMemory()
    metrics = ImageMetrics()
    with tempfile.TemporaryDirectory(prefix="nvr-bench-") as workdir:
        scenes = data_scenes(data, settings.scenes) if data else procedural_scenes(Path(workdir), settings.scenes)
        tracers = [PathTracer(b.scene, b.mesh, size=SIZE) for b in scenes]
        references = [t.render(spp=settings.reference_spp, seed=REFERENCE_SEED).image for t in tracers]

        score = _scorer(metrics, references)
        rows = bench_pathtracing(tracers, settings, memory, score)
        rows.append(bench_splatting(scenes, settings, memory, score))
        # The voxel shader as in the editor; of the network's grid (the object voxels merged in pairs): faster, further
        # from the path tracer; at its fast quality (renderer.shading.FAST_QUALITY): faster, further off.
        shader, fast_shader = ShaderContender(SHADER_GRID_SIZE), ShaderContender(SHADER_GRID_SIZE, "fast")
        shaders = [shader, ShaderContender(GRID_SIZE), fast_shader]
        trained = [_load_engine(path, precision) for path in _weights_files(model_paths) for precision in _precisions()]
        # A shader refiner that reads a finer grid's shading, also on its own grid's: faster, less accurate.
        trained += [_load_engine(path, _precisions()[0], shading_grid_factor=1) for path in _weights_files(model_paths)
                    if _shades_a_finer_grid(path)]
        # And a network that reads the shader, given the shader's fast quality (which it was not trained on).
        trained += [_load_engine(path, precision, shader_quality="fast") for path in _weights_files(model_paths)
                    if _reads_the_shader(path) for precision in _precisions()]
        contenders = shaders + [NetworkContender(engine) for engine in trained]
        bench_in_step(contenders, scenes, settings, memory)
        timed = {contender: contender.row(score) for contender in contenders}
        rows += timed.values()
        timing_only = _random_engines(settings, trained)
        for engine in timing_only:
            rows.append(bench_timing_only(engine, scenes, settings, memory))
        # The edit latencies are the shipped NVR+'s when it is benched (else any compact NVR+), in float32: the
        # targets are for CPUs without bfloat16, and float32 is what they run.
        shipped = SHIPPED_WEIGHTS["nvr_plus"]
        candidates = sorted(trained + timing_only, key=lambda e: e.precision != "fp32")
        live = next((e for e in candidates if e.weights == shipped and e.own_shading_grid and e.shader_quality == "full"),
                    None) or next((e for e in candidates if e.architecture == "nvr_plus" and e.config.name == "compact"), None)
        edits = bench_edits(live, scenes[0], settings)
        environment = bench_environment(scenes, live, settings, memory, metrics)
        objects = bench_object_counts({"NVR+": live, "voxel shader": make_renderer("shaded")},
                                      Path(workdir) / "objects", settings.object_counts, settings.repeats)
        # The Pareto target's ratio, timed in turn with path tracing: the shipped NVR+ in float32 at both shader
        # qualities (the rows above are timed apart from path tracing, and this machine's speed may differ between them).
        fast = next((e for e in trained if e.precision == "fp32" and e.shader_quality == "fast"
                     and e.weights == shipped and e.own_shading_grid), None)
        in_turn = None
        if live.precision == "fp32" and live.weights == shipped and fast is not None:
            engines = {"full": live, "fast": fast}
            in_turn = {"rows": {name: f"{_family(e)} {_trained_setting(e)}" for name, e in engines.items()},
                       "shares": bench_in_turn(engines, tracers, [move_pair(b.scene) for b in scenes],
                                               settings.in_turn_rounds)}
        networks = bench_networks(settings)
    peak = matmul_peak_gflops(settings.matmul_size)
    for net in networks:
        net["frame_fraction_of_peak"] = net["gflop_frame"] / net["frame_ms"] * 1000.0 / peak
        net["light_fraction_of_peak"] = net["gflop_light_edit"] / net["light_edit_ms"] * 1000.0 / peak
    rival = next(r for r in rows if r.family == RENDERERS["pathtrace"].label and r.setting == "1 spp + OIDN")
    return {
        "nvrplus_light_edit_ms": edits["light"]["ms"],
        "nvrplus_frame_ms": edits["object move"]["ms"],
        "pathtrace_1spp_oidn_ms": rival.ms,
        "shader_frame_ms": timed[shader].ms,
        "shader_grid": timed[shader].setting,
        "shader_light_edit_ms": statistics.median(shader.light_times),
        "shader_fast_frame_ms": timed[fast_shader].ms,
        "shader_fast_light_edit_ms": statistics.median(fast_shader.light_times),
        "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        "quick": settings == QUICK,
        "seconds": time.perf_counter() - started,
        "note": note,
        "machine": machine_description() | {"path tracer": _path_tracer_description()},
        "load": {"loadavg_before": list(load_before), "loadavg_after": list(os.getloadavg()),
                 "other_processes": [asdict(p) for p in other_load(cpu_before, cpu_snapshot())]},
        "memory_method": memory.method,
        "size": SIZE,
        "reference_spp": settings.reference_spp,
        "in_step_rounds": settings.in_step_rounds,
        "scenes": [b.name for b in scenes],
        "renderers": [asdict(r) | {"label": r.label} for r in rows],
        "pareto_front": pareto_labels(rows),
        "pareto_front_without_bf16": pareto_labels(rows, without_bf16=True),
        "edits": edits,
        "environment": environment,
        "objects": objects,
        "in_turn": in_turn,
        "networks": networks,
        "matmul_peak_gflops": peak,
    }


# --- renderers -------------------------------------------------------------------------------------


def bench_pathtracing(tracers: list[PathTracer], settings: BenchSettings, memory: PeakMemory,
                      score: Callable[[list[np.ndarray]], dict]) -> list[Row]:
    for tracer in tracers:  # compile Mitsuba's kernels and start OIDN outside the timings
        tracer.render(spp=1, seed=0, denoise=True)
    rows = []
    for spp in settings.spps:
        for denoise in (False, True):
            memory.start()
            times, images = [], []
            for tracer in tracers:
                for repeat in range(settings.repeats_for(spp)):
                    start = time.perf_counter()
                    result = tracer.render(spp=spp, seed=repeat + 1, denoise=denoise)
                    times.append(_ms_since(start))
                images.append(result.image)
            setting = f"{spp} spp" + (" + OIDN" if denoise else "")
            rows.append(Row(RENDERERS["pathtrace"].label, setting, *_spread(times), memory.peak_mb(), **score(images)))
    return rows


def bench_environment(scenes: list[BenchScene], engine: RenderEngine, settings: BenchSettings, memory: PeakMemory,
                      metrics: ImageMetrics) -> dict[str, Any]:
    """The scenes under a sun and sky with glossy objects (models/bench/environment.py): path tracing's rows at
    `settings.environment_spps`, the staged shader's and NVR+'s (a frame after an object move; an NVR+ that does not
    read the environment shows the shader's image), against a path-traced reference; and each one's median ms per
    environment edit."""
    lit = [replace(b, scene=environment_scene(b.scene, i)) for i, b in enumerate(scenes)]
    tracers = [PathTracer(b.scene, b.mesh, size=SIZE) for b in lit]
    score = _scorer(metrics, [t.render(spp=settings.reference_spp, seed=REFERENCE_SEED).image for t in tracers])
    rows = bench_pathtracing(tracers, replace(settings, spps=settings.environment_spps), memory, score)
    edits = {}
    for family, renderer_for, setting in (
            (RENDERERS["shaded"].label, _PaintedShader, "staged, as in the editor"),
            (_family(engine), lambda bench: engine,
             engine.model_name + ("" if engine.config.environment_input else ": the shader's image"))):
        memory.start()
        images, times = [], {}
        for bench in lit:
            renderer = renderer_for(bench)
            images.append(renderer.render(bench.scene))
            for name, ms in edit_ms(renderer, bench.scene, settings.repeats, alternating_ms).items():
                times[name] = times.get(name, []) + ms
        rows.append(Row(family, setting, *_spread(times["object move"]), memory.peak_mb(), **score(images)))
        edits[family] = {name: statistics.median(ms) for name, ms in times.items()}
    return {"scenes": [b.name for b in lit], "materials": [describe(MATERIALS[i % len(MATERIALS)]) for i in range(len(lit))],
            "sky": describe(SKY), "reference_spp": settings.reference_spp,
            "rows": [asdict(r) | {"label": r.label} for r in rows], "edits": edits}


def bench_splatting(scenes: list[BenchScene], settings: BenchSettings, memory: PeakMemory,
                    score: Callable[[list[np.ndarray]], dict]) -> Row:
    memory.start()
    times, images = [], []
    for bench in scenes:
        rgba, floor = painted_voxels(bench.scene, object_voxels(bench.scene))
        images.append(splat_scene(bench.scene, rgba, floor, size=SIZE))
        times += _time_ms(lambda: splat_scene(bench.scene, rgba, floor, size=SIZE), settings.repeats)  # noqa: B023
    return Row(RENDERERS["splat"].label, "", *_spread(times), memory.peak_mb(), **score(images))


class Contender(ABC):
    """A renderer timed in step with the others (bench_in_step), and what was measured of it."""

    light_edit = False  # whether a light edit is timed too

    def __init__(self) -> None:
        self.images: list[np.ndarray] = []  # one per bench scene, untimed
        self.times: list[float] = []  # ms of frames after an object move
        self.light_times: list[float] = []  # ms of light edits, if timed
        self.peak_mb = 0.0  # the most memory one scene's first render took above the level before it

    @abstractmethod
    def renderer_for(self, bench: BenchScene) -> Any:
        """What renders `bench`'s scenes (anything with render(scene) -> image)."""

    @abstractmethod
    def row(self, score: Callable[[list[np.ndarray]], dict]) -> Row:
        """The table's row of what was measured, its errors from `score` of the images."""


class ShaderContender(Contender):
    """The voxel shader of a `grid_size`^3 grid at a `quality` (renderer.shading.QUALITIES) with its stages cached as
    in the editor, the voxels painted (untimed) for each scene it is given; its light edit (the light stage alone) is
    timed too."""

    light_edit = True

    def __init__(self, grid_size: int, quality: str = "full") -> None:
        super().__init__()
        self.grid_size, self.quality = grid_size, quality

    def renderer_for(self, bench: BenchScene) -> _PaintedShader:
        return _PaintedShader(bench, self.grid_size, self.quality)

    def row(self, score: Callable[[list[np.ndarray]], dict]) -> Row:
        setting = f"{self.grid_size}^3 grid" + ("" if self.quality == "full" else f", {self.quality}")
        return Row(RENDERERS["shaded"].label, setting, *_spread(self.times), self.peak_mb, **score(self.images))


class NetworkContender(Contender):
    """A trained network through the live engine (resampling, voxel branch on the object's crop, splat, shading)."""

    def __init__(self, engine: RenderEngine) -> None:
        super().__init__()
        self.engine = engine

    def renderer_for(self, bench: BenchScene) -> RenderEngine:
        return self.engine

    def row(self, score: Callable[[list[np.ndarray]], dict]) -> Row:
        return Row(_family(self.engine), _trained_setting(self.engine), *_spread(self.times), self.peak_mb,
                   **score(self.images), precision=self.engine.precision)


def bench_in_step(contenders: list[Contender], scenes: list[BenchScene], settings: BenchSettings,
                  memory: PeakMemory) -> None:
    """Time every contender's frame after an object move (and its light edit, where it asks) in step: scene by scene,
    all of them on one scene before the next, in turn forwards and backwards, and the scenes over again in each of
    `settings.in_step_rounds` rounds. On a machine whose speed swings from minute to minute (and a network's time
    from one second to the next), rows the Pareto front compares are timed in the same minutes, and each row's median
    spans them all: timed one row after another, the distilled NVR+'s fp32 frame once came out slower than its
    teacher's, which runs a block more, and timed in step over the scenes once, its frame at the shader's full quality
    faster than at the fast one. The first round first renders each one's image of each scene, untimed: its errors,
    and its peak memory."""
    for round_ in range(settings.in_step_rounds):
        for index, bench in enumerate(scenes):
            renderers = []
            for contender in contenders:
                if round_ == 0:
                    memory.start()
                renderer = contender.renderer_for(bench)
                if round_ == 0:
                    contender.images.append(renderer.render(bench.scene))
                    contender.peak_mb = max(contender.peak_mb, memory.peak_mb())
                renderers.append(renderer)
            in_turn = list(zip(contenders, renderers))
            for contender, renderer in in_turn[::-1] if (round_ * len(scenes) + index) % 2 else in_turn:
                contender.times += alternating_ms(renderer, move_pair(bench.scene), settings.repeats)
                if contender.light_edit:
                    contender.light_times += alternating_ms(renderer, light_pair(bench.scene), settings.repeats)


class _PaintedShader:
    """The staged voxel shader of one bench scene's painted voxels, rendering like an engine."""

    def __init__(self, bench: BenchScene, grid_size: int = SHADER_GRID_SIZE, quality: str = "full"):
        self._rgba, self._floor = painted_voxels(bench.scene, object_voxels(bench.scene))
        self._key = bench.name
        self._shader = StagedShader(grid_size, quality_named(quality))

    def render(self, scene: Scene) -> np.ndarray:
        return self._shader.render(scene, self._key, self._rgba, self._floor, SIZE).image


def bench_timing_only(engine: RenderEngine, scenes: list[BenchScene], settings: BenchSettings,
                      memory: PeakMemory) -> Row:
    """A network with random weights, for its time alone: a re-render after an object move."""
    memory.start()
    times = []
    repeats = settings.repeats if engine.config.name != "paper" else 2  # the paper's widths take seconds a frame
    for bench in scenes:
        engine.render(bench.scene)
        times += alternating_ms(engine, move_pair(bench.scene), repeats)
    return Row(_family(engine), f"{engine.config.name}, {engine.precision} (random weights: timing only)",
               *_spread(times), memory.peak_mb(), precision=engine.precision)


def _family(engine: RenderEngine) -> str:
    return network_entry(engine.architecture).label


def _trained_setting(engine: RenderEngine) -> str:
    """The setting column of a trained network's row (its label: family and setting)."""
    return f"{engine.model_name}, {engine.precision}"


def bench_edits(engine: RenderEngine, bench: BenchScene, settings: BenchSettings) -> dict[str, dict]:
    """Latency of each edit type through the engine, with the object crop and (unless quick) with the full grid."""
    out = {}
    for name, pair in edit_pairs(bench.scene).items():
        times = alternating_ms(engine, pair, settings.edit_repeats)
        report = engine.last_report
        row = {"ms": statistics.median(times), "ms_q25": _spread(times)[1], "ms_q75": _spread(times)[2],
               "stages": list(report.stages_run), "grid_fraction": report.grid_fraction,
               "voxel_branch_ms": report.stage_ms.get("gather", 0.0) + report.stage_ms.get("voxel_branch", 0.0)}
        if settings.full_grid_edits:
            engine.crop = False
            full = alternating_ms(engine, pair, settings.edit_repeats)
            row["full_grid_ms"] = statistics.median(full)
            row["full_grid_voxel_branch_ms"] = sum(engine.last_report.stage_ms.get(s, 0.0) for s in ("gather", "voxel_branch"))
            engine.crop = True
            engine.clear()
        out[name] = row
    return {"model": f"{engine.model_name}, {engine.precision}", "scene": bench.name, **out}


def edit_pairs(scene: Scene) -> dict[str, tuple[Scene, Scene]]:
    """Two scenes per edit type that differ only in that edit: rendering them in turn measures the edit.

    The paint stroke is a region fill around the object's middle occupied voxel (in voxel order).
    """
    occupied = np.argwhere(object_voxels(scene)[..., 3] >= 0.5)
    paint_seed = tuple(int(i) for i in occupied[len(occupied) // 2])
    x, y, z = scene.light.position
    return {
        "light": (scene, scene.with_changes(light=LightSpec((x - 0.6, y, z + 0.4)))),
        "paint": tuple(scene.with_changes(paint=(*scene.paint, PaintOp("region", color, seed=paint_seed)))
                       for color in ((0.9, 0.2, 0.2), (0.2, 0.2, 0.9))),
        "floor color": (scene, scene.with_changes(floor=FloorSpec((0.8, 0.7, 0.3)))),
        "object move": move_pair(scene),
        "object turn": turn_pair(scene),
        "object scale": scale_pair(scene),
        "camera": (scene, scene.with_changes(camera=CameraSpec(scene.camera.elevation_deg + 5.0))),
    }


def move_pair(scene: Scene) -> tuple[Scene, Scene]:
    """The scene and the scene with its object moved along the floor by (0.15, -0.1): a drag in the editor."""
    o = scene.object
    return scene, scene.with_changes(object=replace(o, translation=(o.translation[0] + 0.15, o.translation[1] - 0.1)))


def light_pair(scene: Scene) -> tuple[Scene, Scene]:
    """The scene and the scene with its light moved by (0.1, 0, 0.05): a step of a light drag."""
    x, y, z = scene.light.position
    return scene, scene.with_changes(light=LightSpec((x + 0.1, y, z + 0.05)))


def turn_pair(scene: Scene) -> tuple[Scene, Scene]:
    """The scene and the scene with its object turned by 20 degrees about the vertical."""
    return scene, scene.with_changes(object=replace(scene.object, rotation_deg=scene.object.rotation_deg + 20.0))


def scale_pair(scene: Scene) -> tuple[Scene, Scene]:
    """The scene and the scene with its object scaled by 1.05 on every axis (a step of a scale drag; on the bench
    chairs it can change how many object voxels the network's grid merges, so the merge reruns as in a drag)."""
    return scene, scene.with_changes(object=replace(scene.object, scale=tuple(1.05 * s for s in scene.object.scale)))


def alternating_ms(engine: RenderEngine | _PaintedShader, pair: tuple[Scene, Scene], repeats: int) -> list[float]:
    """Render the pair's scenes in turn (after one of each to fill the caches); ms per render."""
    engine.render(pair[1])
    engine.render(pair[0])
    times = []
    for k in range(repeats):
        start = time.perf_counter()
        engine.render(pair[(k + 1) % 2])
        times.append(_ms_since(start))
    return times


IN_TURN_NVR_FRAMES = 6  # per scene and round
IN_TURN_PT_FRAMES = 3


def bench_in_turn(engines: dict[str, RenderEngine], tracers: list[PathTracer], pairs: list[tuple[Scene, Scene]],
                  rounds: int, progress: Callable[[str], None] | None = None) -> dict[str, list[float]]:
    """Each engine's frame after an object move as a share of path tracing's at 1 spp + OIDN, per round: a round
    times a block of frames per engine (IN_TURN_NVR_FRAMES per scene, alternating each pair's scenes), then a block of
    path-traced ones (IN_TURN_PT_FRAMES per scene), so that both see the same phase of a machine whose speed swings
    from minute to minute. An NVR+ frame right after a path-traced one runs cold, which the editor never sees:
    alternating_ms renders each pair once before it times. `progress` gets a line per round."""
    for tracer in tracers:  # compile Mitsuba's kernels and start OIDN outside the timings
        tracer.render(spp=1, seed=0, denoise=True)
    shares: dict[str, list[float]] = {name: [] for name in engines}
    for round_ in range(rounds):
        medians = {name: statistics.median(ms for pair in pairs for ms in alternating_ms(engine, pair, IN_TURN_NVR_FRAMES))
                   for name, engine in engines.items()}
        times = []
        for tracer in tracers:
            for k in range(IN_TURN_PT_FRAMES):
                start = time.perf_counter()
                tracer.render(spp=1, seed=k + 1, denoise=True)
                times.append(_ms_since(start))
        path_traced = statistics.median(times)
        for name, ms in medians.items():
            shares[name].append(ms / path_traced)
        if progress is not None:
            progress(f"round {round_ + 1}: path tracing 1 spp + OIDN {path_traced:.1f} ms; "
                     + "; ".join(f"NVR+ {name} {ms:.1f} ms ({ms / path_traced:.3f})" for name, ms in medians.items()))
    return shares


# --- networks: FLOPs and the matmul peak ---------------------------------------------------------------


def bench_networks(settings: BenchSettings) -> list[dict[str, Any]]:
    """Per configuration and architecture: GFLOP of a full-grid frame and of a light edit, and their times."""
    configs: list[NVRConfig] = ([ShaderRefinerConfig(), HalfResolutionRefinerConfig(), CompactConfig()]
                                + ([PaperConfig()] if settings.paper else []))
    out = []
    for config in configs:
        # The shader refiner's configuration differs from the compact one only in NVR+'s splat branch.
        for architecture in ("nvr_plus",) if config.shading_input else ("nvr_plus", "nvr"):
            torch.manual_seed(0)
            model = build_model(architecture, config).eval()
            counted = network_calls(prepare_for_inference(model), config)  # FlopCounterMode knows these convolutions
            timed = network_calls(RenderEngine(model, precision="fp32").model, config)  # the engine's copy, fp32 like the peak
            repeats = settings.repeats if config.name != "paper" else 2
            with torch.inference_mode():
                out.append({
                    "config": config.name, "architecture": network_entry(architecture).label,
                    "gflop_frame": _gflop(counted[0]), "gflop_light_edit": _gflop(counted[1]),
                    "frame_ms": statistics.median(_time_ms(timed[0], repeats)),
                    "light_edit_ms": statistics.median(_time_ms(timed[1], repeats)),
                })
    return out


def network_calls(model, config: NVRConfig) -> tuple[Callable[[], Any], Callable[[], Any]]:
    """A full forward pass on a 10%-occupied grid and the light edit after it (render_from_latent, and the splat
    branch again if it reads the lit floor or the shader's buffers, which depend on the light)."""
    g, s = config.grid_size, config.output_size
    generator = torch.Generator().manual_seed(0)
    voxels = (torch.rand(g, g, g, 4, generator=generator) < 0.1).float().permute(3, 0, 1, 2)[None]
    light = torch.tensor([[0.3, 0.9, -0.8]])
    plus = model.architecture == "nvr_plus"
    splat = torch.rand(1, 3, s, s, generator=generator) if plus else None
    floor_light = torch.rand(1, 3, s, s, generator=generator) if reads_floor_light(model.architecture, config) else None
    shading = (torch.rand(1, SHADING_CHANNELS, s, s, generator=generator) if reads_shading(model.architecture, config)
               else None)
    shaded = None if shading is None else shading[:, :IMAGE_CHANNELS].contiguous()
    branch = {} if shading is None else {"shading": shading}
    with torch.inference_mode():
        latent = model.encode_voxels(voxels)
        features = model.encode_splat(splat, floor_light, **branch) if plus else None
    light_dependent = floor_light is not None or shading is not None

    def light_edit():
        splat_features = model.encode_splat(splat, floor_light, **branch) if light_dependent else features
        return model.render_from_latent(latent, light, splat_features, **({} if shaded is None else {"shaded": shaded}))

    return (lambda: model(voxels, light, splat, floor_light, **branch)), light_edit


def _gflop(call: Callable[[], Any]) -> float:
    """Floating-point operations of one call (a multiply-add counts 2), in billions."""
    with FlopCounterMode(display=False) as counter:
        call()
    return counter.get_total_flops() / 1e9


def matmul_peak_gflops(n: int, repeats: int = 5) -> float:
    """Best fp32 GFLOP/s of an n x n matrix product on the engine's threads (the CPU's practical peak)."""
    a, b = torch.randn(n, n), torch.randn(n, n)
    best = min(_time_ms(lambda: torch.mm(a, b), repeats))
    return 2.0 * n**3 / (best / 1000.0) / 1e9


# --- engines ------------------------------------------------------------------------------------------


def _weights_files(paths: list[str] | None) -> list[Path]:
    if paths:
        return [Path(p) for p in paths]
    return sorted(ASSET_MODELS.glob("*.safetensors")) if ASSET_MODELS.is_dir() else []


def _path_tracer_description() -> str:
    """Mitsuba's version and variant: the scalar variant (no libLLVM >= 16 found) traces many times slower."""
    import mitsuba as mi

    variant = active_variant()
    library = os.environ.get(LIBLLVM_ENV) if variant == LLVM_VARIANT else None
    return f"Mitsuba {mi.__version__}, {variant}" + (f" ({Path(library).name})" if library else
                                                    " (no libLLVM >= 16 found: install libllvm19 for the fast variant)")


def _precisions() -> list[str]:
    """The engine's default precision first (the one the editor uses), then float32 if that is not it."""
    default = resolve_precision("auto")
    return [default] + (["fp32"] if default != "fp32" else [])


def _reads_the_shader(path: Path) -> bool:
    """Whether the weights file holds a network that reads the voxel shader's image and buffers."""
    _, config, _ = check_weights_file(path)
    return config.shading_input


def _shades_a_finer_grid(path: Path) -> bool:
    """Whether the weights file holds a shader refiner that reads the shading of a grid finer than its own."""
    _, config, _ = check_weights_file(path)
    return config.shading_input and config.shading_grid_factor > 1


def _load_engine(path: Path, precision: str, shading_grid_factor: int | None = None,
                 shader_quality: str = "full") -> RenderEngine:
    model, config, _ = load_model(path)
    if config.output_size != SIZE:
        raise InputError(f"renders {config.output_size}^2; the benchmark compares at {SIZE}^2", path)
    grid = "" if shading_grid_factor is None else f", shading the {config.grid_size * shading_grid_factor}^3 grid"
    quality = "" if shader_quality == "full" else f", {shader_quality} shading"
    blocks = config.post_light_blocks  # a distilled network (nvr distill) has fewer than its configuration's
    lean = "" if blocks == type(config).post_light_blocks else f", {blocks} block{'s' * (blocks != 1)} after the light"
    return RenderEngine(model, model_name=f"{config.name}{lean}{grid}{quality} ({path.name})", precision=precision,
                        shading_grid_factor=shading_grid_factor, shader_quality=shader_quality, weights=path)


def _random_engines(settings: BenchSettings, trained: list[RenderEngine]) -> list[RenderEngine]:
    """Random-weight engines for timing: compact ones without trained weights, and the paper's."""
    have = {(e.architecture, e.config.name) for e in trained}
    configs = [CompactConfig()] + ([PaperConfig()] if settings.paper else [])
    engines = []
    for config in configs:
        for architecture in (e.architecture for e in RENDERERS.values() if e.architecture):
            if (architecture, config.name) not in have:
                torch.manual_seed(0)
                engines.append(RenderEngine(build_model(architecture, config).eval()))
    return engines


# --- small helpers ----------------------------------------------------------------------------------------


def _time_ms(call: Callable[[], Any], repeats: int) -> list[float]:
    """Wall times in ms of `repeats` calls after one warm-up call."""
    call()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        call()
        times.append(_ms_since(start))
    return times


def _ms_since(start: float) -> float:
    return (time.perf_counter() - start) * 1000.0


def _spread(times: list[float]) -> tuple[float, float, float]:
    """Median, first and third quartile."""
    q25, median, q75 = np.percentile(times, [25, 50, 75])
    return float(median), float(q25), float(q75)


def _scorer(metrics: ImageMetrics, references: list[np.ndarray]) -> Callable[[list[np.ndarray]], dict[str, float]]:
    """The mean over the scenes of each metric of images (one a scene) against `references`."""
    def score(images: list[np.ndarray]) -> dict[str, float]:
        values = [metrics(_batch(i), _batch(r)) for i, r in zip(images, references)]
        return {k: float(np.mean([float(v[k][0]) for v in values])) for k in ("mse", "dssim", "perceptual")}
    return score


def _batch(image: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(image.transpose(2, 0, 1)))[None]


def _point(row: Row) -> Point:
    return Point(row.label, row.family, row.ms, row.mse)


REPORT_FILES = ("benchmarks.md", "benchmarks.json", "speed_vs_error.png")
NATIVE_BF16_SUFFIX = "_avx512_bf16"  # the project page's report of a CPU with native bfloat16


def report_files(folder: Path) -> tuple[Path, Path, Path]:
    """Where a run writes its report, numbers and figure (REPORT_FILES) in `folder`. In the project's docs a CPU with
    native bfloat16 writes its own (benchmarks_avx512_bf16.md, ...), beside the page of the CPU without it that the
    speed targets are set for, which it must not replace."""
    from models.engine.onednn import cpu_has_native_bfloat16

    suffix = NATIVE_BF16_SUFFIX if folder.resolve() == DOCS and cpu_has_native_bfloat16() else ""
    return tuple(folder / name.replace(".", f"{suffix}.", 1) for name in REPORT_FILES)


def write_outputs(results: dict[str, Any], folder: Path) -> None:
    """The Markdown report, the JSON numbers and the speed-against-error figure, in one folder (report_files)."""
    from models.bench.report import write_report

    folder.mkdir(parents=True, exist_ok=True)
    report, numbers, figure = report_files(folder)
    rows = [r for r in results["renderers"] if r["mse"] is not None]
    # The figure's labels leave out the weights file names, which the table gives.
    draw_speed_vs_error([Point(re.sub(r" \([^)]*\.safetensors\)", "", r["label"]), r["family"], r["ms"], r["mse"])
                         for r in rows], figure)
    write_report(results, report, figure)
    save_json(numbers, results)
