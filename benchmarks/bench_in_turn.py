"""NVR+ against path tracing at 1 spp + OIDN, timed in turn: the Pareto target's ratio in one phase of the machine.

Usage: python -m benchmarks.bench_in_turn [--data DIR ...] [--scenes N] [--rounds R] [--precision fp32|bf16]
       [--qualities full,fast] [--model FILE]
`nvr bench` times each renderer's row apart, and on a machine whose speed swings from minute to minute the ratio of
two rows can compare two phases. Here each round times, on the first view of up to N objects of the test folders,
a block of NVR+ frames after an object move per shader quality (6 per scene, alternating the move's two scenes),
then a block of path-traced frames at 1 spp + OIDN (3 per scene), and prints the medians and each quality's share
of path tracing's time; then the median of those shares over the rounds. An NVR+ frame right after a path-traced
one runs cold (results.md, "Speed"), which the editor never sees: the first two frames of each scene are not
timed.
"""

from __future__ import annotations

import argparse
import statistics
import time

from models.bench.benchmark import SIZE, alternating_ms, edit_pairs
from models.bench.scenes import data_scenes
from models.engine.render_engine import RenderEngine
from models.evaluation.evaluate import shipped_model
from renderer.pathtrace.path_tracer import PathTracer

NVR_FRAMES = 6  # per scene and round
PT_FRAMES = 3


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", nargs="+", default=["data/test3_default_r200"], help="test data folders (nvr bench's scenes)")
    p.add_argument("--scenes", type=int, default=3)
    p.add_argument("--rounds", type=int, default=6)
    p.add_argument("--precision", choices=["fp32", "bf16"], default="fp32")
    p.add_argument("--qualities", default="full,fast", help="comma-separated shader qualities")
    p.add_argument("--model", default=None, help="NVR+ weights (.safetensors); default: the shipped model")
    args = p.parse_args()

    scenes = data_scenes(args.data, args.scenes)
    tracers = [PathTracer(bench.scene, bench.mesh, size=SIZE) for bench in scenes]
    for tracer in tracers:  # compile Mitsuba's kernels and start OIDN outside the timings
        tracer.render(spp=1, seed=0, denoise=True)
    engines = {quality: RenderEngine.load(args.model or shipped_model("nvr+"), precision=args.precision,
                                          shader_quality=quality) for quality in args.qualities.split(",")}
    pairs = [edit_pairs(bench.scene)["object move"] for bench in scenes]
    shares = {quality: [] for quality in engines}
    for round_ in range(args.rounds):
        medians = {}
        for quality, engine in engines.items():
            medians[quality] = statistics.median(ms for pair in pairs for ms in alternating_ms(engine, pair, NVR_FRAMES))
        times = []
        for tracer in tracers:
            for k in range(PT_FRAMES):
                start = time.perf_counter()
                tracer.render(spp=1, seed=k + 1, denoise=True)
                times.append((time.perf_counter() - start) * 1000.0)
        path_traced = statistics.median(times)
        for quality, ms in medians.items():
            shares[quality].append(ms / path_traced)
        print(f"round {round_ + 1}: path tracing 1 spp + OIDN {path_traced:.1f} ms; "
              + "; ".join(f"NVR+ {quality} {ms:.1f} ms ({ms / path_traced:.3f})" for quality, ms in medians.items()),
              flush=True)
    print(f"{args.precision}, share of path tracing's time, median over {args.rounds} rounds: "
          + "; ".join(f"{quality} {statistics.median(s):.3f} ({min(s):.3f}-{max(s):.3f})" for quality, s in shares.items()))


if __name__ == "__main__":
    main()
