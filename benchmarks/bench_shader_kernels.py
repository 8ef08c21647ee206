"""The voxel shader's compiled kernels alone, on the very calls an object move makes, and against another checkout's.

Usage: python -m benchmarks.bench_shader_kernels [--data DIR ...] [--scenes N] [--repeats R] [--quality full|fast]
       [--against OTHER_CHECKOUT]
Renders each bench scene with the staged shader (as `nvr bench` does), records the arguments of every kernel call
of one object move, then times each call alone `repeats` times (its output arrays fresh each time) and prints, per
kernel and scene, the fastest and the median ms. With --against, the other checkout's kernels run the same calls in
turn with these (one of each, then the next repeat), in one process: on a machine whose speed swings within minutes,
the only comparison that holds. Their outputs are compared too: a change meant to keep the images must give the same
arrays (trace_surface's `deepest` may differ past a ray's full coverage, where it no longer counts). The other
checkout's stage modules (renderer/shading/geometry.py, surface.py, lighting.py) are copied to a temporary folder
first, so their compiled cache never mixes with this one's; what they import (fields.py, quality.py) is this one's.
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
from renderer.shading import lighting, surface

# The kernels an object move calls, by the stage module that holds (and calls) them.
KERNELS = {"trace_surface": surface, "mark_surface_pixels": surface, "surface_normals_and_voxels": surface,
           "filtered_colors": surface, "occlusion_along": surface, "build_shadow_maps": lighting,
           "light_visibility": lighting, "light_form_factors": lighting, "composite": lighting}


def recorded_calls(scene_folders: list[str], count: int, quality: str) -> list[tuple[str, str, list]]:
    """(scene, kernel, arguments copied) of every KERNELS call of one object move per scene, in call order."""
    calls: list[tuple[str, str, list]] = []
    originals = {name: getattr(module, name) for name, module in KERNELS.items()}
    for bench in data_scenes(scene_folders, count):
        shader, (before, after) = _PaintedShader(bench, quality=quality), move_pair(bench.scene)
        shader.render(before)

        def recording(name):
            def call(*args):
                calls.append((bench.name, name, [a.copy() if isinstance(a, np.ndarray) else a for a in args]))  # noqa: B023
                return originals[name](*args)
            return call

        for name, module in KERNELS.items():
            setattr(module, name, recording(name))
        try:
            shader.render(after)
        finally:
            for name, kernel in originals.items():
                setattr(KERNELS[name], name, kernel)
    return calls


def other_kernels(checkout: Path, folder: Path) -> dict[str, ModuleType]:
    """Another checkout's stage modules by this one's module name, each loaded from a copy in `folder` (its own numba
    cache)."""
    loaded = {}
    for module in set(KERNELS.values()):
        stage = module.__name__.rsplit(".", 1)[1]
        copy = shutil.copy(checkout / "renderer" / "shading" / f"{stage}.py", folder / f"other_{stage}.py")
        spec = importlib.util.spec_from_file_location(f"other_{stage}", copy)
        other = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = other
        spec.loader.exec_module(other)
        loaded[module.__name__] = other
    return loaded


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
    p.add_argument("--against", type=Path, default=None, help="another checkout's root folder")
    args = p.parse_args()

    calls = recorded_calls(args.data, args.scenes, args.quality)
    with tempfile.TemporaryDirectory(prefix="nvr-kernels-") as folder:
        other = other_kernels(args.against, Path(folder)) if args.against else None
        print("scene | kernel (call) | fastest ms | median ms" + (" | other's fastest | other's median | same output"
                                                                  if other else ""))
        seen: dict[tuple[str, str], int] = {}
        for scene, name, kernel_args in calls:
            index = seen[(scene, name)] = seen.get((scene, name), -1) + 1
            module = KERNELS[name]
            kernels_in_turn = [getattr(module, name)] + ([getattr(other[module.__name__], name)] if other else [])
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
