"""How far bfloat16 rendering is from float32, and what it saves: the shipped networks on test scenes.

Usage: python benchmarks/bench_precision.py [--data DIR ...] [--scenes N] [--repeats R]
For each shipped network (assets/models) both precisions render the first view of up to N objects
of the test folders; prints the largest pixel difference and the MSE between them (0-255), and the
median ms of a full render after an object move and of a light edit in each precision.
models/engine/render_engine.py's BF16_BOUND is the bound the tests hold bf16 to.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from models.bench.benchmark import alternating_ms, move_pair  # noqa: E402 - models.bench.benchmark imports models.engine.render_engine before torch
from models.bench.scenes import data_scenes  # noqa: E402
from models.engine.render_engine import BF16_BOUND, RenderEngine, cpu_can_run_bfloat16  # noqa: E402
from models.networks.shipped import shipped_weights  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", nargs="+", default=["data/test_single", "data/test_default", "data/test_textured"])
    parser.add_argument("--scenes", type=int, default=9)
    parser.add_argument("--repeats", type=int, default=6)
    args = parser.parse_args()
    if not cpu_can_run_bfloat16():
        sys.exit("bench_precision: this CPU cannot run bf16 convolutions")
    scenes = data_scenes(args.data, args.scenes)
    print(f"{len(scenes)} scenes; bound: max {BF16_BOUND['max_abs']}, MSE {BF16_BOUND['mse']} (0-255)")
    for architecture in ("nvr_plus", "nvr"):
        engines = {p: RenderEngine.load(shipped_weights(architecture), architecture, precision=p) for p in ("fp32", "bf16")}
        largest, mses = 0.0, []
        times: dict[str, dict[str, list[float]]] = {p: {"frame": [], "light": []} for p in engines}
        for bench in scenes:
            images = {p: e.render(bench.scene) for p, e in engines.items()}
            difference = (images["bf16"].astype(np.float64) - images["fp32"]) * 255.0
            largest, mses = max(largest, float(np.abs(difference).max())), mses + [float(np.mean(difference**2))]
            x, y, z = bench.scene.light.position
            moved_light = replace(bench.scene, light=replace(bench.scene.light, position=(-x, y, z)))
            for p, engine in engines.items():
                times[p]["frame"] += alternating_ms(engine, move_pair(bench.scene), args.repeats)
                times[p]["light"] += alternating_ms(engine, (bench.scene, moved_light), args.repeats)
        timing = ", ".join(f"{p}: frame {statistics.median(t['frame']):.1f} ms, light edit {statistics.median(t['light']):.1f} ms"
                           for p, t in times.items())
        print(f"{architecture}: bf16 - fp32 largest difference {largest:.2f}, MSE mean {np.mean(mses):.3f} "
              f"max {max(mses):.3f}; {timing}")


if __name__ == "__main__":
    main()
