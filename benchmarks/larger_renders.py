"""NVR+ images larger than the network's 256 px, against path tracing at that size: the voxel shader's image at the
size corrected by the network's correction (RenderEngine.render_sized: what `nvr render --size`, the editor's export
and `nvr turntable --size` make), the network's 256 px image resized with Lanczos as an 8-bit image, and the
shader's own image at the size (with the object's reflection in the floor, as `--renderer shaded` draws it).

Usage: python -m benchmarks.larger_renders [--data DIR ...] [--objects N] [--size S] [--spp P] [--figure OUT.png]
The first view of up to N objects per test folder (nvr bench's scenes: the data set's photo-colored voxels, meshes
rebuilt from their seeds), path traced at S px with P spp + OIDN as the data sets' targets are. Prints each view's MSE
(0-255) and DSSIM per renderer, then per folder and over all views, and the median seconds of a larger render after
the 256 px render of the same scene (its cached stages kept, as after an edit in the editor). `--figure`: for the first
view of each folder, a row of resized, corrected and target at the size, each cut to the half of the image around
the object (where the shader covers it), so the pixels are the images' own.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from collections import defaultdict

import numpy as np
from PIL import Image

from models.bench.scenes import data_scenes
from models.engine.render_engine import RenderEngine
from models.evaluation.metrics import dssim, mse_255
from renderer.color import to_uint8
from renderer.io import save_png
from renderer.pathtrace import render_pathtraced
from renderer.pipeline import object_voxels, painted_voxels
from renderer.shading import shade_scene

DATA = ["data/test_single_r200", "data/test_default_r200_p512", "data/test_textured_r200_p512",
        "data/novel30_single_r200", "data/novel30_textured_r200_p512"]
RENDERERS = ("corrected at the size", "256 px resized", "voxel shader")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", nargs="+", default=DATA, help="test data folders")
    p.add_argument("--objects", type=int, default=10, help="objects per folder (their first view)")
    p.add_argument("--size", type=int, default=512)
    p.add_argument("--spp", type=int, default=16, help="the path-traced targets' samples per pixel (+ OIDN)")
    p.add_argument("--precision", choices=["fp32", "bf16"], default="fp32")
    p.add_argument("--figure", default=None, help="PNG: resized, corrected and target, a row per folder")
    args = p.parse_args()
    import torch  # after models.engine (imported with models.bench), which sets OpenMP's waiting first

    engine = RenderEngine.load(None, precision=args.precision)
    scores: dict[str, dict[str, list]] = defaultdict(lambda: defaultdict(list))
    seconds, rows = [], []
    for folder in args.data:
        for k, bench in enumerate(data_scenes([folder], args.objects)):
            scene = bench.scene
            target = render_pathtraced(scene, bench.mesh, size=args.size, spp=args.spp, seed=0, denoise=True).image
            native = engine.render(scene)
            start = time.perf_counter()
            corrected = engine.render_sized(scene, args.size)
            seconds.append(time.perf_counter() - start)
            resized = np.asarray(Image.fromarray(to_uint8(native)).resize((args.size, args.size),
                                                                          Image.Resampling.LANCZOS)) / 255.0
            rgba, floor = painted_voxels(scene, object_voxels(scene))
            shader = shade_scene(scene, rgba, floor, args.size, engine.config.shading_grid_size)
            images = dict(zip(RENDERERS, (corrected, resized, shader.image)))
            line = {"view": bench.name}
            for name, image in images.items():
                pair = [torch.from_numpy(np.ascontiguousarray(np.clip(x, 0.0, 1.0).transpose(2, 0, 1)))[None]
                        for x in (image, target)]
                mse, structure = float(mse_255(*pair)[0]), float(dssim(*pair)[0])
                scores[folder][name].append((mse, structure))
                line[name] = [round(mse, 2), round(structure, 4)]
            print(json.dumps(line), flush=True)
            if k == 0:
                window = _around_the_object(shader.coverage, args.size // 2)
                rows.append(np.concatenate([image[window] for image in (resized, np.clip(corrected, 0, 1), target)],
                                           axis=1))
    print(f"\n{args.size} px against path tracing at {args.spp} spp + OIDN (MSE 0-255 / DSSIM), {args.precision}:")
    everything: dict[str, list] = defaultdict(list)
    for folder, by_renderer in scores.items():
        print(f"{folder} ({len(by_renderer[RENDERERS[0]])} views): " + ", ".join(
            f"{name} {_mean(values)}" for name, values in by_renderer.items()))
        for name, values in by_renderer.items():
            everything[name] += values
    print("all: " + ", ".join(f"{name} {_mean(values)}" for name, values in everything.items()))
    print(f"a {args.size} px render after the 256 px one: median {statistics.median(seconds):.2f} s "
          f"({min(seconds):.2f}-{max(seconds):.2f})")
    if args.figure:
        save_png(args.figure, np.concatenate(rows, axis=0))


def _around_the_object(coverage: np.ndarray, side: int) -> tuple[slice, slice]:
    """The `side`^2 window of the image centred on the object's box (the image's centre if nothing is covered)."""
    rows, cols = np.nonzero(coverage > 0.0)
    size = coverage.shape[0]
    centre = [(a.min() + a.max()) // 2 if len(a) else size // 2 for a in (rows, cols)]
    starts = [min(max(c - side // 2, 0), size - side) for c in centre]
    return slice(starts[0], starts[0] + side), slice(starts[1], starts[1] + side)


def _mean(values: list[tuple[float, float]]) -> str:
    return f"{np.mean([v[0] for v in values]):.2f} / {np.mean([v[1] for v in values]):.4f}"


if __name__ == "__main__":
    main()
