"""The live engine on another device (a CUDA GPU) against the CPU: same images, and each edit's latency.

Usage: python -m benchmarks.bench_device [--device cuda] [--precision fp32 bf16] [--scenes N] [--repeats N]
       [--report OUT.md]
For the demo scene and procedural objects (models/bench/scenes.py): the shipped NVR+ rendered on the
device in each precision against the CPU in fp32 (largest pixel difference and MSE on the 0-255 scale),
and the median latency of each edit type through the engine (models/bench/benchmark.py's edit pairs),
on the device and on the CPU. Needs no path tracer, so it runs where only the engine's packages are.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import models.engine  # noqa: E402, F401 - sets OpenMP's waiting before torch loads OpenMP

# isort: split

import numpy as np  # noqa: E402
import torch  # noqa: E402

from models.bench.benchmark import BenchSettings, bench_edits  # noqa: E402
from models.bench.scenes import procedural_scenes  # noqa: E402
from models.bench.system import machine_description  # noqa: E402
from models.engine.render_engine import RenderEngine  # noqa: E402
from renderer.io import atomic_path  # noqa: E402

EDITS = ("light", "paint", "floor color", "object move", "object turn", "camera")


def compare(image: np.ndarray, reference: np.ndarray) -> dict[str, float]:
    """Largest difference and MSE on the 0-255 scale, and whether every value is finite."""
    difference = (image.astype(np.float64) - reference.astype(np.float64)) * 255.0
    return {"max_diff": float(np.abs(difference).max()), "mse": float((difference**2).mean()),
            "finite": bool(np.isfinite(image).all())}


def run(device: str, precisions: list[str], scenes: int, repeats: int) -> dict:
    """Images and edit latencies of the shipped NVR+ on `device` in each precision and on the CPU in fp32."""
    settings = BenchSettings(repeats=repeats, edit_repeats=repeats, full_grid_edits=False)
    results: dict = {"machine": machine_description(), "device": device, "scenes": []}
    if device.startswith("cuda"):
        results["gpu"] = torch.cuda.get_device_name(device)
    with tempfile.TemporaryDirectory(prefix="nvr-device-") as workdir:
        benches = procedural_scenes(Path(workdir), scenes)
        cpu = RenderEngine.load(None, precision="fp32", device="cpu")
        engines = {p: RenderEngine.load(None, precision=p, device=device) for p in precisions}
        for bench in benches:
            reference = cpu.render(bench.scene)
            row = {"scene": bench.name, "cpu fp32": {"edits_ms": _edit_medians(bench_edits(cpu, bench, settings))}}
            for precision, engine in engines.items():
                row[f"{device} {precision}"] = {**compare(engine.render(bench.scene), reference),
                                                 "edits_ms": _edit_medians(bench_edits(engine, bench, settings))}
            results["scenes"].append(row)
            print(json.dumps(row), flush=True)
    return results


def _edit_medians(edits: dict) -> dict[str, float]:
    return {name: round(edits[name]["ms"], 2) for name in EDITS}


def report(results: dict) -> str:
    """A markdown table: per scene and engine, the image difference from the CPU and each edit's median ms."""
    lines = [f"CPU: {results['machine']['cpu']}" + (f"; GPU: {results['gpu']}" if "gpu" in results else ""), "",
             "| scene | engine | max diff / MSE vs CPU fp32 (0-255) | " + " | ".join(f"{e} ms" for e in EDITS) + " |",
             "|---|---|---|" + "---|" * len(EDITS)]
    for row in results["scenes"]:
        for name, values in row.items():
            if name == "scene":
                continue
            diff = "-" if "mse" not in values else f"{values['max_diff']:.2f} / {values['mse']:.4f}"
            times = " | ".join(f"{values['edits_ms'][e]:.1f}" for e in EDITS)
            lines.append(f"| {row['scene']} | {name} | {diff} | {times} |")
    medians = {}
    for name in {k for row in results["scenes"] for k in row if k != "scene"}:
        medians[name] = {e: statistics.median(row[name]["edits_ms"][e] for row in results["scenes"]) for e in EDITS}
    lines += ["", "Median over the scenes (ms): " + "; ".join(
        f"{name}: " + ", ".join(f"{e} {v:.1f}" for e, v in m.items()) for name, m in sorted(medians.items()))]
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda")
    parser.add_argument("--precision", nargs="+", default=["fp32", "bf16"], choices=("fp32", "bf16"))
    parser.add_argument("--scenes", type=int, default=4)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--report", type=Path, help="write the table here (markdown) and the numbers beside it (.json)")
    args = parser.parse_args()
    results = run(args.device, args.precision, args.scenes, args.repeats)
    text = report(results)
    print(text)
    if args.report:
        with atomic_path(args.report) as tmp:
            tmp.write_text(text)
        with atomic_path(args.report.with_suffix(".json")) as tmp:
            tmp.write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
