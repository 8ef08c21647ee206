"""`nvr bench`'s rows under environment light: the bench's scenes lit by a sun and sky alone (the area light off), each
object glossy (ceramic, metal, plastic in turn), rendered by path tracing at low sample counts, the voxel shader and
NVR+, against a path-traced reference; and each renderer's latency per environment edit.

No network is trained for environment light yet: NVR+ shows the voxel shader's image through the engine (its row
times what the editor shows), and says so in its setting.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from models.bench.scenes import BenchScene
from models.engine.render_engine import RenderEngine
from renderer.pathtrace.path_tracer import PathTracer
from renderer.pipeline import object_voxels, painted_voxels
from renderer.scene import EnvironmentSpec, MaterialSpec, Scene, SkySpec
from renderer.shading.staged import StagedShader

SIZE = 256
SKY = SkySpec(sun_elevation_deg=35.0, sun_azimuth_deg=120.0, turbidity=3.0)
# One per scene in turn: the editor's ceramic, metal and plastic presets.
MATERIALS = (MaterialSpec(0.12, 0.6, 0.0), MaterialSpec(0.25, 0.5, 1.0), MaterialSpec(0.35, 0.5, 0.0))
OTHER_MATERIAL = MaterialSpec(0.5, 0.5, 0.0)  # what a material edit switches to


def environment_scene(scene: Scene, index: int) -> Scene:
    """`scene` under the sky alone, its object in the index-th of MATERIALS."""
    return scene.with_changes(environment=EnvironmentSpec(sky=SKY), light=replace(scene.light, enabled=False),
                              object=replace(scene.object, material=MATERIALS[index % len(MATERIALS)]))


def describe(value: SkySpec | MaterialSpec) -> str:
    """A sky or a material in words, for the report."""
    if isinstance(value, SkySpec):
        return (f"sun at {value.sun_elevation_deg:g} degrees elevation and {value.sun_azimuth_deg:g} azimuth, "
                f"turbidity {value.turbidity:g}")
    return f"roughness {value.roughness:g}, specular {value.specular:g}, metallic {value.metallic:g}"


def sun_drag(scene: Scene, steps: int) -> list[Scene]:
    """`scene` with its sun moved 2 degrees in azimuth at each of `steps` steps: a drag through skies never seen
    before (alternating two skies would time the cache that keeps them)."""
    env = scene.environment
    return [scene.with_changes(environment=replace(env, sky=replace(env.sky, sun_azimuth_deg=(
        env.sky.sun_azimuth_deg + 2.0 * (k + 1)) % 360.0))) for k in range(steps)]


def edit_pairs(scene: Scene) -> dict[str, tuple[Scene, Scene]]:
    """Two scenes per environment edit that differ only in it (the issue's targets name these; the sun's drag is
    sun_drag)."""
    env, o = scene.environment, scene.object
    return {
        "environment turn": (scene, scene.with_changes(environment=replace(env, rotation_deg=env.rotation_deg + 15.0))),
        "strength": (scene, scene.with_changes(environment=replace(env, strength=env.strength * 1.2))),
        "material": (scene, scene.with_changes(object=replace(o, material=OTHER_MATERIAL))),
        "object move": (scene, scene.with_changes(object=replace(o, translation=(o.translation[0] + 0.15,
                                                                                 o.translation[1] - 0.1)))),
    }


@dataclass
class _Shader:
    """The staged voxel shader of one scene's painted voxels, rendering like an engine."""

    name: str
    rgba: np.ndarray
    floor: tuple[float, float, float]
    shader: StagedShader

    def render(self, scene: Scene) -> np.ndarray:
        return self.shader.render(scene, self.name, self.rgba, self.floor, SIZE).image


def bench_environment(scenes: list[BenchScene], engine: RenderEngine, spps: tuple[int, ...], reference_spp: int,
                      repeats: int, score: Callable[[np.ndarray, np.ndarray], dict[str, float]],
                      alternating_ms: Callable[[Any, tuple[Scene, Scene], int], list[float]]) -> dict[str, Any]:
    """The rows (renderer, setting, median ms per frame, errors: mean over the scenes of `score(image, reference)`) and
    the median ms of each edit of edit_pairs for the shader and NVR+ (`alternating_ms`, as the bench times edits).
    A frame's time is path tracing's sampling plus denoising, and the shader's and NVR+'s a re-render after an object
    move."""
    lit = [replace(b, scene=environment_scene(b.scene, i)) for i, b in enumerate(scenes)]
    tracers = [PathTracer(b.scene, b.mesh, size=SIZE) for b in lit]
    references = [t.render(spp=reference_spp, seed=1_000_003).image for t in tracers]

    def mean_score(images: list[np.ndarray]) -> dict[str, float]:
        values = [score(i, r) for i, r in zip(images, references)]
        return {k: float(np.mean([v[k] for v in values])) for k in values[0]}

    rows = []
    for tracer in tracers:  # compile Mitsuba's kernels and start OIDN outside the timings
        tracer.render(spp=1, seed=0, denoise=True)
    for spp in spps:
        for denoise in (False, True):
            times, images = [], []
            for tracer in tracers:
                for repeat in range(repeats):
                    start = time.perf_counter()
                    result = tracer.render(spp=spp, seed=repeat + 1, denoise=denoise)
                    times.append(_ms_since(start))
                images.append(result.image)
            rows.append({"renderer": "path tracing", "setting": f"{spp} spp" + (" + OIDN" if denoise else ""),
                         "ms": statistics.median(times), **mean_score(images)})
    shaders = [_Shader(b.name, *painted_voxels(b.scene, object_voxels(b.scene)), StagedShader()) for b in lit]
    edits: dict[str, dict[str, float]] = {"voxel shader": {}, "NVR+": {}}
    for label, renderers in (("voxel shader", shaders), ("NVR+", [engine] * len(lit))):
        images, frames = [], []
        for renderer, bench in zip(renderers, lit):
            images.append(renderer.render(bench.scene))
            pairs = edit_pairs(bench.scene)
            frames += alternating_ms(renderer, pairs["object move"], repeats)
            for name, pair in pairs.items():
                edits[label].setdefault(name, [])
                edits[label][name] += alternating_ms(renderer, pair, repeats)
            renderer.render(bench.scene)
            edits[label].setdefault("sun move", [])
            for step in sun_drag(bench.scene, repeats):
                start = time.perf_counter()
                renderer.render(step)
                edits[label]["sun move"].append(_ms_since(start))
        setting = "staged, as in the editor" if label == "voxel shader" else f"{engine.model_name}: the shader's image"
        rows.append({"renderer": label, "setting": setting, "ms": statistics.median(frames), **mean_score(images)})
    return {"scenes": [b.name for b in lit], "materials": [describe(MATERIALS[i % len(MATERIALS)]) for i in range(len(lit))],
            "sky": describe(SKY), "reference_spp": reference_spp, "rows": rows,
            "edits": {label: {name: statistics.median(times) for name, times in by_edit.items()}
                      for label, by_edit in edits.items()}}


def _ms_since(start: float) -> float:
    return (time.perf_counter() - start) * 1000.0
