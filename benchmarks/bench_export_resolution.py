"""Large exports against the object's voxel resolution: the demo chair at 1024 px, voxelised at 100^3, 200^3 and
256^3, by the voxel shader and the shipped NVR+ (the shader's image at the size, corrected), against path tracing at
1024 px.

Usage: python -m benchmarks.bench_export_resolution [--size S] [--spp P] [--figure OUT.png]
Prints MSE (0-255) and DSSIM per renderer and resolution, and the seconds of each render; `--figure`: the middle
quarter of the NVR+ images at each resolution and of the path-traced target, side by side at their own pixels.
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace

import numpy as np
import torch

from models.engine.render_engine import RenderEngine
from models.evaluation.metrics import dssim, mse_255
from models.networks.shipped import shipped_weights
from renderer.io import save_png
from renderer.objects.demo import DEMO_DIR
from renderer.pathtrace import render_pathtraced
from renderer.pipeline import object_voxels, painted_voxels
from renderer.reference_object import object_mesh
from renderer.scene import load_scene, replaced
from renderer.shading import shade_scene

RESOLUTIONS = (100, 200, 256)


def _metrics(image: np.ndarray, target: np.ndarray) -> tuple[float, float]:
    a, b = (torch.from_numpy(np.ascontiguousarray(x.transpose(2, 0, 1)))[None] for x in (image, target))
    return float(mse_255(a, b)[0]), float(dssim(a, b)[0])


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", type=int, default=1024)
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--figure", default=None)
    args = p.parse_args()

    demo = load_scene(DEMO_DIR / "scene.json")
    start = time.perf_counter()
    target = render_pathtraced(demo, object_mesh(demo), args.size, spp=args.spp, denoise=True).image
    print(f"path tracing at {args.size} px, {args.spp} spp + OIDN: {time.perf_counter() - start:.1f} s")
    engine = RenderEngine.load(shipped_weights("nvr_plus"))
    rows, crops = {}, []
    for resolution in RESOLUTIONS:
        scene = replaced(demo, object=replace(demo.object, resolution=resolution))
        rgba, floor = painted_voxels(scene, object_voxels(scene))
        start = time.perf_counter()
        shaded = shade_scene(scene, rgba, floor, args.size).image
        shader_s = time.perf_counter() - start
        engine.render(scene)
        start = time.perf_counter()
        corrected = engine.render_sized(scene, args.size)
        nvr_s = time.perf_counter() - start
        for name, image, seconds in (("voxel shader", shaded, shader_s), ("NVR+", corrected, nvr_s)):
            mse, ds = _metrics(np.clip(image, 0.0, 1.0).astype(np.float32), target)
            rows[f"{name} at {resolution}^3"] = {"mse": round(mse, 2), "dssim": round(ds, 4), "s": round(seconds, 2)}
            print(f"{name} at {resolution}^3: MSE {mse:.2f}, DSSIM {ds:.4f}, {seconds:.1f} s")
        quarter = slice(args.size // 4, 3 * args.size // 4)
        crops.append(np.clip(corrected, 0.0, 1.0)[quarter, quarter])
    if args.figure:
        quarter = slice(args.size // 4, 3 * args.size // 4)
        save_png(args.figure, np.concatenate([*crops, target[quarter, quarter]], axis=1))
    print(json.dumps({"size": args.size, "spp": args.spp, **rows}))


if __name__ == "__main__":
    main()
