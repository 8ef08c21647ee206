"""NVR+ against path tracing at 1 spp + OIDN, timed in turn: the Pareto target's ratio in one phase of the machine.

Usage: python -m benchmarks.bench_in_turn [--data DIR ...] [--scenes N] [--rounds R] [--precision fp32|bf16]
       [--qualities full,fast] [--model FILE]
`nvr bench` times each renderer's row apart, and on a machine whose speed swings from minute to minute the ratio of
two rows can compare two phases. Here each round times, on the first view of up to N objects of the test folders,
a block of NVR+ frames after an object move per shader quality, then a block of path-traced frames at 1 spp + OIDN
(models.bench.benchmark.bench_in_turn, which `nvr bench` runs for the shipped NVR+ in fp32), and prints the medians
and each quality's share of path tracing's time; then the median of those shares over the rounds. Here: another
precision or model, more rounds.
"""

from __future__ import annotations

import argparse
import statistics

from models.bench.benchmark import SIZE, bench_in_turn, move_pair
from models.bench.scenes import data_scenes
from models.engine.render_engine import RenderEngine
from models.networks.shipped import shipped_weights
from renderer.pathtrace.path_tracer import PathTracer


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
    engines = {quality: RenderEngine.load(args.model or shipped_weights("nvr_plus"), precision=args.precision,
                                          shader_quality=quality) for quality in args.qualities.split(",")}
    shares = bench_in_turn(engines, tracers, [move_pair(bench.scene) for bench in scenes], args.rounds,
                           progress=lambda line: print(line, flush=True))
    print(f"{args.precision}, share of path tracing's time, median over {args.rounds} rounds: "
          + "; ".join(f"{quality} {statistics.median(s):.3f} ({min(s):.3f}-{max(s):.3f})" for quality, s in shares.items()))


if __name__ == "__main__":
    main()
