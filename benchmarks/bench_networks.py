"""Forward time of the networks on this CPU: full frame and light edit (everything after the light merge).

Usage: python benchmarks/bench_networks.py [--config compact|paper|shader_refiner|half_res_refiner] [--arch nvr|nvr_plus]
       [--set FIELD=JSON ...] [--repeats N] [--no-prepare]
fp32, eval mode, batch 1, on the inference copy (models/networks/inference.py: BatchNorm folded,
channels-last) unless --no-prepare. Two measurements, because other processes share the CPU:
wall-clock with torch.set_num_threads(2) over N runs (median, and minimum beside it), and the
CPU time of the same call on 1 thread (median), which contention barely changes.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import models.engine  # noqa: E402, F401 - sets OpenMP's waiting before torch loads OpenMP

# isort: split

import torch  # noqa: E402
from torch.utils.flop_counter import FlopCounterMode  # noqa: E402

from models.bench.benchmark import network_calls  # noqa: E402
from models.networks.config import CONFIGS, NVRConfig  # noqa: E402
from models.networks.inference import prepare_for_inference  # noqa: E402
from models.networks.nvr import build_model  # noqa: E402


def gflop(fn: Callable[[], object]) -> float:
    """Floating-point operations of one call (2 per multiply-add), in billions."""
    with FlopCounterMode(display=False) as counter:
        fn()
    return counter.get_total_flops() / 1e9


def wall_ms(fn: Callable[[], object], repeats: int, threads: int = 2) -> tuple[float, float]:
    """(median, minimum) wall time in ms over `repeats` calls on `threads` threads, after a warm-up call."""
    torch.set_num_threads(threads)
    fn()
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        samples.append((time.perf_counter() - start) * 1000.0)
    return statistics.median(samples), min(samples)


def cpu_ms(fn: Callable[[], object], repeats: int) -> float:
    """Median CPU time in ms of one call on a single thread (insensitive to other processes)."""
    torch.set_num_threads(1)
    fn()
    samples = []
    for _ in range(repeats):
        start = time.thread_time()
        fn()
        samples.append((time.thread_time() - start) * 1000.0)
    return statistics.median(samples)


def measure(config: NVRConfig, architecture: str, repeats: int, prepare: bool) -> dict[str, float]:
    torch.manual_seed(0)
    model = build_model(architecture, config).eval()
    params = sum(p.numel() for p in model.parameters())
    if prepare:
        model = prepare_for_inference(model)
    full, light_edit = network_calls(model, config)  # the light edit reruns the splat branch if it reads the light
    with torch.inference_mode():
        result = {"params_M": params / 1e6, "gflop_full": gflop(full), "gflop_light_edit": gflop(light_edit)}
        result["ms_full_median"], result["ms_full_min"] = wall_ms(full, repeats)
        result["ms_light_median"], result["ms_light_min"] = wall_ms(light_edit, repeats * 3)
        result["cpu1_ms_full"], result["cpu1_ms_light"] = cpu_ms(full, repeats), cpu_ms(light_edit, repeats * 3)
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", choices=CONFIGS, default="compact")
    parser.add_argument("--arch", choices=("nvr", "nvr_plus"), action="append")
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=JSON", help="override a config field")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--no-prepare", action="store_true", help="time the plain eval model")
    args = parser.parse_args()
    overrides = {k: json.loads(v) for k, v in (item.split("=", 1) for item in args.set)}
    config = CONFIGS[args.config](**overrides)
    for architecture in args.arch or ("nvr", "nvr_plus"):
        result = measure(config, architecture, args.repeats, not args.no_prepare)
        print(json.dumps({"config": args.config, "arch": architecture, **overrides,
                          **{k: round(v, 2) for k, v in result.items()}}))


if __name__ == "__main__":
    main()
