"""Where an edit's time goes: the shipped NVR+'s latency per edit type and the median of each engine stage it reran.

Usage: python -m benchmarks.bench_edit_stages [--data DIR ...] [--scenes N] [--repeats R] [--precision fp32|bf16]
       [--quality full|fast] [--edits light,object move,camera] [--model FILE]
Each edit alternates between two scenes that differ only in it (nvr bench's pairs), on the first view of up to N
objects of the test folders, after one render of each; prints the median ms per edit over all scenes and the
median of each stage's own time (a stage's time includes the stages it called, as the engine reports them), then
the same as one JSON line, to compare runs. To see a CPU without AVX512 or bfloat16 on one that has them, cap the
instruction sets for the whole process and compare with an uncapped run in turn:
ONEDNN_MAX_CPU_ISA=AVX2 ATEN_CPU_CAPABILITY=avx2 NUMBA_CPU_NAME=haswell python -m benchmarks.bench_edit_stages
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from collections import defaultdict

from models.bench.benchmark import edit_pairs
from models.bench.scenes import data_scenes
from models.engine.onednn import onednn_isa_cap
from models.engine.render_engine import RenderEngine
from models.networks.shipped import shipped_weights


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", nargs="+", default=["data/test3_default_r200"], help="test data folders (nvr bench's scenes)")
    p.add_argument("--scenes", type=int, default=3)
    p.add_argument("--repeats", type=int, default=10, help="timed edits per scene")
    p.add_argument("--precision", choices=["fp32", "bf16"], default="fp32")
    p.add_argument("--quality", choices=["full", "fast"], default="full", help="the voxel shader's")
    p.add_argument("--edits", default="light,object move,camera", help="comma-separated edit types of nvr bench")
    p.add_argument("--model", default=None, help="NVR+ weights (.safetensors); default: the shipped model")
    args = p.parse_args()

    import torch

    engine = RenderEngine.load(args.model or shipped_weights("nvr_plus"), precision=args.precision, shader_quality=args.quality)
    scenes = data_scenes(args.data, args.scenes)
    results = {}
    pairs = [edit_pairs(bench.scene) for bench in scenes]  # each voxelises its object once
    for edit in args.edits.split(","):
        times, stages = [], defaultdict(list)
        for scene_pairs in pairs:
            pair = scene_pairs[edit]
            engine.render(pair[0])
            engine.render(pair[1])
            for k in range(args.repeats):
                start = time.perf_counter()
                engine.render(pair[k % 2])
                times.append((time.perf_counter() - start) * 1000.0)
                for stage, ms in engine.last_report.stage_ms.items():
                    stages[stage].append(ms)
        results[edit] = {"ms": round(statistics.median(times), 2),
                         "stages": {s: round(statistics.median(v), 2) for s, v in stages.items()}}
        print(f"{edit}: {results[edit]['ms']:.1f} ms  " + "  ".join(f"{s} {ms:.2f}" for s, ms in results[edit]["stages"].items()))
    print(json.dumps({"precision": args.precision, "quality": args.quality, "onednn_cap": onednn_isa_cap(),
                      "torch_kernels": torch.backends.cpu.get_cpu_capability(), "edits": results}))


if __name__ == "__main__":
    main()
