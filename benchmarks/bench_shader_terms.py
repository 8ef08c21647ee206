"""What each term of the voxel shader buys: MSE and DSSIM on the test split with one term taken out.

Run from the repository root after making the test split (docs/results.md says how):
    python -m benchmarks.bench_shader_terms [--data DIR...] [--every 1]   # default: the test split of docs/results.md
Prints a Markdown table: the full shader, then each ablation, per setting.
"""

from __future__ import annotations

import argparse
from collections import defaultdict
from contextlib import contextmanager
from dataclasses import replace

import numpy as np
import torch

from models.evaluation.metrics import dssim, mse_255
from models.training.data import VoxelRenderSet
from renderer.shading import FULL_QUALITY, geometry, lighting, quality, shade_objects, surface

STAGES = (geometry, surface, lighting)  # the modules whose values and kernels an ablation replaces


def _lit_everywhere(receivers, bias, lights, depth, bounds, nearest, spread, out):
    out[:] = 1.0


@contextmanager
def patched(**values):
    """Replace a value or kernel in every stage module that reads it, for the duration of a `with` block."""
    before = [(module, name, getattr(module, name)) for name in values for module in STAGES if hasattr(module, name)]
    for module, name, _ in before:
        setattr(module, name, values[name])
    try:
        yield
    finally:
        for module, name, value in before:
            setattr(module, name, value)


# Each ablation: the values or kernels it replaces, and the shader quality it renders at (the full one, or a term of it
# taken out).
ABLATIONS = {
    "full shader": ({},),
    "no shadows (every point sees the whole light)": ({"light_visibility": _lit_everywhere},),
    "hull silhouettes (no thinning towards the mesh)": ({"COVERAGE_FULL": 1e-6},),
    "no ambient occlusion": ({"OCCLUSION_WEIGHTS": np.zeros(4, np.float32),
                               "FLOOR_OCCLUSION_WEIGHTS": np.zeros(4, np.float32)},),
    "no light bounced from the floor": ({"FLOOR_BOUNCE": 0.0},),
    "less smooth normals (from the surface's own field)": ({"NORMAL_SIGMA": quality.DISTANCE_SIGMA},),
    "normals not averaged over the tangent plane's disc": ({}, replace(FULL_QUALITY, normal_rings=0)),
    "no reflection of the object in the floor": ({"REFLECTION_SCALE": 0.0},),
    "each point colored by one voxel (not averaged over the pixel's footprint)": ({}, replace(FULL_QUALITY, color_spread=0.0)),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", nargs="+",
                        default=["data/test_single_r200", "data/test_default_r200_p512", "data/test_textured_r200_p512"])
    parser.add_argument("--every", type=int, default=1, help="use every N-th sample")
    parser.add_argument("--shading-grid", type=int, default=256,
                        help="shade the object voxels merged as for this grid (renderer.grid.shader_pool_factors)")
    args = parser.parse_args()
    dataset = VoxelRenderSet(args.data)
    samples = [(dataset[i]["target"], dataset.scene(i), dataset.object_voxels(i), dataset.settings[i])
               for i in range(0, len(dataset), args.every)]
    settings = sorted({s for *_, s in samples})
    print(f"{len(samples)} test images; MSE (0-255) / DSSIM per setting\n")
    print("| shader | " + " | ".join(settings) + " |")
    print("|---|" + "---:|" * len(settings))
    for name, (values, *chosen) in ABLATIONS.items():
        scores = defaultdict(list)
        with patched(**values):
            for target, scene, painted, setting in samples:
                image = shade_objects(scene, painted, scene.floor.color, target.shape[-1], args.shading_grid,
                                    quality=chosen[0] if chosen else FULL_QUALITY).image
                prediction = torch.from_numpy(np.ascontiguousarray(image.transpose(2, 0, 1)))[None]
                target = target[None]
                scores[setting].append((float(mse_255(prediction, target)[0]), float(dssim(prediction, target)[0])))
        cells = [f"{np.mean([m for m, _ in scores[s]]):.1f} / {np.mean([d for _, d in scores[s]]):.4f}" for s in settings]
        print(f"| {name} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
