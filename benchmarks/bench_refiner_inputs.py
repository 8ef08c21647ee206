"""What the trained shader refiner reads from each of its inputs: MSE and DSSIM on the test split with one input
replaced by its average over the test images (a constant: the network sees nothing of it), the rest unchanged.

This is an ablation of the trained network, not of training: a network trained without an input would learn to
do without it, so a row says how much this network relies on the input, an upper bound on what the input buys.
Retraining a variant per input takes hours each on this machine. The "shader alone" row is the image the
network corrects; the output is still the shaded image corrected, so knocking out the shaded image as an input
leaves it in the output.

Run from the repository root after making the test split (docs/results.md says how):
    python -m benchmarks.bench_refiner_inputs [--model PATH] [--data ...] [--every 2]
Prints a Markdown table, one row per input knocked out, MSE (0-255) / DSSIM per setting.
"""

from __future__ import annotations

import argparse
from collections import defaultdict

import models.engine  # noqa: F401 - sets OpenMP's waiting before torch loads OpenMP

# isort: split

import numpy as np
import torch

from models.evaluation.metrics import dssim, mse_255
from models.networks.checkpoint import load_model
from models.networks.nvr import reads_shading
from models.networks.shipped import SHIPPED_WEIGHTS
from models.training.data import VoxelRenderSet
from renderer.shading import BUFFER_CHANNELS

# The shader buffers' channels by the group their names start with ("albedo r" -> albedo), and each group's row.
BUFFER_GROUPS = {group: [i for i, name in enumerate(BUFFER_CHANNELS) if name.split()[0] == group]
                 for group in dict.fromkeys(name.split()[0] for name in BUFFER_CHANNELS)}
IMAGE = BUFFER_GROUPS["image"]
BUFFER_ROWS = {"image": "no shaded image as an input (it is still corrected)", "albedo": "no albedo",
               "normal": "no normals", "depth": "no depth", "visibility": "no light visibility (shadows)",
               "occlusion": "no sky visibility (occlusion)", "coverage": "no coverage"}
# Knock-outs: (row name, input, channels of the shader buffers or None for the whole input).
KNOCKOUTS = [
    ("no voxels (an empty grid)", "voxels", None),
    ("no light position (the average light)", "light", None),
    ("no splat", "splat", None),
    *[(BUFFER_ROWS[group], "shading", channels) for group, channels in BUFFER_GROUPS.items()],
]


def _average(samples: list[dict[str, torch.Tensor]], key: str) -> torch.Tensor:
    """The input's average over the samples: per channel over every pixel for images, per number for the light."""
    stacked = torch.stack([s[key] for s in samples])
    return stacked.mean(dim=0) if stacked.dim() == 2 else stacked.mean(dim=(0, 2, 3), keepdim=True)[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=str(SHIPPED_WEIGHTS["nvr_plus"]))
    parser.add_argument("--data", nargs="+", default=["data/test_single", "data/test_default", "data/test_textured"])
    parser.add_argument("--every", type=int, default=2, help="use every N-th sample")
    args = parser.parse_args()
    model, config, _ = load_model(args.model)
    if not reads_shading(model.architecture, config):
        raise SystemExit(f"{args.model}: not a shader refiner (its config reads no shader buffers)")
    dataset = VoxelRenderSet(args.data, grid_size=config.grid_size, shading=True,
                             shading_grid_factor=config.shading_grid_factor)
    indices = range(0, len(dataset), args.every)
    samples = [dataset[i] for i in indices]
    settings = [dataset.settings[i] for i in indices]
    averages = {key: _average(samples, key) for key in ("light", "splat", "shading")}
    rows: dict[str, dict[str, list[tuple[float, float]]]] = defaultdict(lambda: defaultdict(list))
    with torch.no_grad():
        for sample, setting in zip(samples, settings):
            target, scores = sample["target"][None], {}
            inputs = {key: sample[key][None] for key in ("voxels", "light", "splat", "shading")}
            shaded = inputs["shading"][:, IMAGE]
            latent = model.encode_voxels(inputs["voxels"])  # each stage once; a knock-out reruns only what reads it
            features = model.encode_splat(inputs["splat"], None, inputs["shading"])
            scores["shader alone (no correction)"] = shaded
            scores["full network"] = model.render_from_latent(latent, inputs["light"], features, shaded)
            for row, key, channels in KNOCKOUTS:
                changed = dict(inputs)
                if key == "voxels":
                    changed[key] = torch.zeros_like(inputs[key])
                elif channels is None:
                    changed[key] = averages[key].expand_as(inputs[key][0])[None]
                else:
                    changed[key] = inputs[key].clone()
                    changed[key][:, channels] = averages[key][channels].expand_as(changed[key][0, channels])
                # The output corrects the true shaded image whatever the network was shown.
                row_latent = model.encode_voxels(changed["voxels"]) if key == "voxels" else latent
                row_features = (model.encode_splat(changed["splat"], None, changed["shading"])
                                if key in ("splat", "shading") else features)
                scores[row] = model.render_from_latent(row_latent, changed["light"], row_features, shaded)
            for row, prediction in scores.items():
                prediction = prediction.clamp(0.0, 1.0)
                rows[row][setting].append((float(mse_255(prediction, target)[0]), float(dssim(prediction, target)[0])))
    names = sorted(set(settings))
    print(f"{len(samples)} test images, {args.model}; MSE (0-255) / DSSIM per setting\n")
    print("| network input | " + " | ".join(names) + " |")
    print("|---|" + "---:|" * len(names))
    for row, per_setting in rows.items():
        cells = [f"{np.mean([m for m, _ in per_setting[s]]):.1f} / {np.mean([d for _, d in per_setting[s]]):.4f}"
                 for s in names]
        print(f"| {row} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
