"""The voxel shader's compiled kernels alone, on the very calls an object move makes, and against another checkout's.

Usage: python -m benchmarks.bench_shader_kernels [--data DIR ...] [--scenes N] [--repeats R] [--quality full|fast]
       [--against OTHER/renderer/shading/kernels.py]
Renders each bench scene with the staged shader (as `nvr bench` does), records the arguments of every kernel call
of one object move, then times each call alone `repeats` times (its output arrays fresh each time) and prints, per
kernel and scene, the fastest and the median ms. With --against, the other file's kernels run the same calls in turn
with these (one of each, then the next repeat), in one process: on a machine whose speed swings within minutes, the
only comparison that holds; their outputs are compared too (a change meant to keep the images must give the same
arrays; trace_surface's `deepest` may differ past a ray's full coverage, where it no longer counts). The other file
is copied to a temporary folder first, so its compiled cache never mixes with this one's.
"""

from __future__ import annotations

import argparse
import importlib.util
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path
from types import ModuleType

import numpy as np

from models.bench.benchmark import _PaintedShader, move_pair
from models.bench.scenes import data_scenes
from renderer.shading import kernels

KERNELS = ("trace_surface", "mark_surface_pixels", "surface_normals_and_voxels", "filtered_colors",
           "occlusion_along", "build_shadow_maps", "light_visibility", "light_form_factors", "composite")


def recorded_calls(scene_folders: list[str], count: int, quality: str) -> list[tuple[str, str, list]]:
    """(scene, kernel, arguments copied) of every KERNELS call of one object move per scene, in call order."""
    calls: list[tuple[str, str, list]] = []
    originals = {name: getattr(kernels, name) for name in KERNELS}
    for bench in data_scenes(scene_folders, count):
        shader, (before, after) = _PaintedShader(bench, quality=quality), move_pair(bench.scene)
        shader.render(before)

        def recording(name):
            def call(*args):
                calls.append((bench.name, name, [a.copy() if isinstance(a, np.ndarray) else a for a in args]))  # noqa: B023
                return originals[name](*args)
            return call

        for name in KERNELS:
            setattr(kernels, name, recording(name))
        try:
            shader.render(after)
        finally:
            for name, kernel in originals.items():
                setattr(kernels, name, kernel)
    return calls


def other_kernels(path: Path, folder: Path) -> ModuleType:
    """Another checkout's kernels module, loaded from a copy in `folder` (its own numba cache)."""
    copy = shutil.copy(path, folder / "other_kernels.py")
    spec = importlib.util.spec_from_file_location("other_kernels", copy)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def timed(kernel, args: list) -> tuple[float, list[np.ndarray]]:
    """ms of one call on fresh copies of `args`, and the arrays it returned or wrote."""
    fresh = [a.copy() if isinstance(a, np.ndarray) else a for a in args]
    start = time.perf_counter()
    result = kernel(*fresh)
    ms = (time.perf_counter() - start) * 1000.0
    outputs = list(result) if isinstance(result, tuple) else [result] if result is not None else fresh
    return ms, [a for a in outputs if isinstance(a, np.ndarray)]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", nargs="+", default=["data/test3_default_r200"], help="test data folders (nvr bench's scenes)")
    p.add_argument("--scenes", type=int, default=3)
    p.add_argument("--repeats", type=int, default=40)
    p.add_argument("--quality", choices=["full", "fast"], default="full", help="the voxel shader's")
    p.add_argument("--against", type=Path, default=None, help="another checkout's renderer/shading/kernels.py")
    args = p.parse_args()

    calls = recorded_calls(args.data, args.scenes, args.quality)
    with tempfile.TemporaryDirectory(prefix="nvr-kernels-") as folder:
        other = other_kernels(args.against, Path(folder)) if args.against else None
        print("scene | kernel (call) | fastest ms | median ms" + (" | other's fastest | other's median | same output"
                                                                  if other else ""))
        seen: dict[tuple[str, str], int] = {}
        for scene, name, kernel_args in calls:
            index = seen[(scene, name)] = seen.get((scene, name), -1) + 1
            kernels_in_turn = [getattr(kernels, name)] + ([getattr(other, name)] if other else [])
            times: list[list[float]] = [[] for _ in kernels_in_turn]
            for _ in range(args.repeats + 1):  # the first round compiles or loads
                outputs = []
                for k, kernel in enumerate(kernels_in_turn):
                    ms, out = timed(kernel, kernel_args)
                    times[k].append(ms)
                    outputs.append(out)
            row = f"{scene} | {name} ({index}) | {min(times[0][1:]):.3f} | {statistics.median(times[0][1:]):.3f}"
            if other:
                same = all(np.array_equal(a, b, equal_nan=True) for a, b in zip(*outputs))
                row += f" | {min(times[1][1:]):.3f} | {statistics.median(times[1][1:]):.3f} | {'yes' if same else 'no'}"
            print(row, flush=True)


if __name__ == "__main__":
    main()
