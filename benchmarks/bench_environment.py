"""Speed against error under environment light: the voxel shader's edits, and path tracing at low sample counts.

Usage: python -m benchmarks.bench_environment [--data DIR] [--scenes N] [--repeats R] [--size S] [--model WEIGHTS]
On the demo chair under a sun and sky and under a made studio map, each edit alternates between two scenes that
differ only in it (after one render of each), through the shader's staged cache as the editor runs it; prints the
median ms per edit and the stages it reran, and for the sky a drag of the sun through positions never seen before.
With --model (an NVR+ that reads the environment), the same edits through its engine, at 256^2. With --data (an
environment test set, `nvr data generate --lighting environment`), also the MSE (0-255) and the median time of the
shader, the --model network and path tracing at 1 and 4 spp, with and without the denoiser, against the set's targets,
on its first N samples (a first render each). One JSON line at the end.
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from models.bench.environment import edit_pairs, sun_drag
from renderer.environment_maps import make_map
from renderer.objects.demo import DEMO_DIR
from renderer.pipeline import object_voxels
from renderer.scene import EnvironmentSpec, Scene, SkySpec, load_scene
from renderer.shading.staged import StagedShader


def timed_pairs(scene: Scene) -> dict[str, tuple[Scene, Scene]]:
    """The bench's environment edits (models.bench.environment.edit_pairs) and, under a sky, the sun moved between
    two skies the cache keeps."""
    pairs = edit_pairs(scene)
    env = scene.environment
    if env.sky is not None:
        pairs["sun move"] = (scene, scene.with_changes(environment=replace(env, sky=replace(
            env.sky, sun_azimuth_deg=env.sky.sun_azimuth_deg + 10.0))))
    return pairs


def shader_renderer(scene: Scene, size: int) -> tuple[Callable[[Scene], object], Callable[[], list[str]]]:
    """The staged shader as the editor runs it, and the stages its last render ran."""
    rgba = object_voxels(scene)
    shader = StagedShader()
    # The painted voxels are the same throughout: one key names them.
    return (lambda p: shader.render(p, "voxels", rgba, p.floor.color, size)), lambda: list(shader.stage_ms)


def engine_renderer(engine) -> tuple[Callable[[Scene], object], Callable[[], list[str]]]:
    """A RenderEngine (NVR+), and the stages its last render ran."""
    return engine.render, lambda: list(engine.last_report.stages_run)


def time_edits(scene: Scene, repeats: int, renderer: tuple[Callable[[Scene], object], Callable[[], list[str]]]
               ) -> dict[str, dict]:
    render, stages_run = renderer
    out = {}
    for name, pair in timed_pairs(scene).items():
        for p in pair:
            render(p)
        times, stages = [], set()
        for k in range(repeats):
            p = pair[k % 2]
            start = time.perf_counter()
            render(p)
            times.append((time.perf_counter() - start) * 1000.0)
            stages |= set(stages_run())
        out[name] = {"ms": round(statistics.median(times), 1), "stages": sorted(stages)}
        print(f"{name}: {out[name]['ms']:.1f} ms  (reran {', '.join(sorted(stages))})")
    if scene.environment.sky is not None:  # a drag: every step a sun the caches have not seen (a new sky bake)
        times, stages = [], set()
        for moved in sun_drag(scene, repeats):
            start = time.perf_counter()
            render(moved)
            times.append((time.perf_counter() - start) * 1000.0)
            stages |= set(stages_run())
        out["sun drag"] = {"ms": round(statistics.median(times), 1), "stages": sorted(stages)}
        print(f"sun drag: {out['sun drag']['ms']:.1f} ms  (a new sky each step, baked; reran {', '.join(sorted(stages))})")
    return out


def error_table(folder: Path, count: int, engine=None) -> dict[str, dict]:
    """Median ms and mean MSE of the shader, of `engine` (a RenderEngine, if given) and of low-spp path tracing
    against the set's targets."""
    from models.bench.scenes import rebuilt_mesh
    from renderer.color import to_uint8
    from renderer.io import load_image, load_json
    from renderer.pathtrace.path_tracer import PathTracer
    from renderer.scene import scene_from_dict
    from renderer.shading.shader import shade_scene
    from renderer.voxels import load_voxels

    manifest = load_json(folder / "manifest.json")
    records = {o["id"]: o for o in manifest["objects"]}
    rows: dict[str, dict[str, list[float]]] = {}

    def add(name: str, image: np.ndarray, target: np.ndarray, ms: float) -> None:
        row = rows.setdefault(name, {"mse": [], "ms": []})
        row["mse"].append(float(np.mean((to_uint8(image).astype(np.float64) - to_uint8(target)) ** 2)))
        row["ms"].append(ms)

    for sample in manifest["samples"][:count]:
        scene = scene_from_dict(sample["scene"], folder / "manifest.json")
        target, _ = load_image(folder / sample["target"])
        size = target.shape[0]
        rgba = load_voxels(scene.voxels_path())
        start = time.perf_counter()  # a first render: every stage, the environment prepared
        add("voxel shader", shade_scene(scene, rgba, scene.floor.color, size).image, target,
            (time.perf_counter() - start) * 1000.0)
        if engine is not None:
            engine.clear()  # a first render, as the shader's
            start = time.perf_counter()
            add(f"NVR+ {engine.model_name}", engine.render(scene), target, (time.perf_counter() - start) * 1000.0)
        tracer = PathTracer(scene, rebuilt_mesh(records[sample["object"]], folder), size)
        tracer.render(1, seed=1, denoise=True)  # Mitsuba compiles its kernels on a scene's first render: not timed
        for spp in (1, 4):
            for denoise in (False, True):
                result = tracer.render(spp, seed=7, denoise=denoise)
                add(f"path tracing {spp} spp" + (" + OIDN" if denoise else ""), result.image, target,
                    result.render_seconds * 1000.0)
    table = {name: {"mse": round(float(np.mean(r["mse"])), 1), "ms": round(statistics.median(r["ms"]), 1)}
             for name, r in rows.items()}
    for name, row in table.items():
        print(f"{name}: MSE {row['mse']:.1f}, {row['ms']:.0f} ms")
    return table


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default=None, help="an environment-lit test set for the error table")
    p.add_argument("--scenes", type=int, default=20, help="samples of the test set")
    p.add_argument("--repeats", type=int, default=10)
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--model", default=None, help="NVR+ weights that read the environment: time and score them too")
    args = p.parse_args()
    engine = None
    if args.model:
        from models.engine.render_engine import RenderEngine

        engine = RenderEngine.load(args.model, precision="fp32")
        if not engine.config.environment_input:
            raise SystemExit(f"{args.model}: this network does not read the environment")

    demo = load_scene(DEMO_DIR / "scene.json")
    studio = Path("/tmp") / "bench_environment_studio.hdr"
    import mitsuba as mi

    from renderer.pathtrace.mitsuba_variant import active_variant

    active_variant()
    mi.Bitmap(make_map("studio", 3)).write(str(studio))
    results = {}
    for name, env in (("sky", EnvironmentSpec(sky=SkySpec())), ("studio map", EnvironmentSpec(image=str(studio)))):
        print(f"-- demo chair under the {name}")
        scene = replace(demo, environment=env, light=replace(demo.light, enabled=False))
        results[name] = time_edits(scene, args.repeats, shader_renderer(scene, args.size))
        if engine is not None:
            print(f"-- the same through NVR+ {engine.model_name}")
            results[f"{name}, NVR+"] = time_edits(scene, args.repeats, engine_renderer(engine))
    if args.data:
        results["error"] = error_table(Path(args.data), args.scenes, engine)
    print(json.dumps({"cpu": platform.processor() or platform.machine(), "size": args.size, **results}))


if __name__ == "__main__":
    main()
