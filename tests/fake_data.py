"""A tiny synthetic data folder in the format of renderer/dataset.py, made without the path tracer.

Training tests need a folder that loads like a real one; they do not need real renders.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from renderer.io import save_json, save_png
from renderer.scene import CameraSpec, FloorSpec, LightSpec, ObjectSpec, Scene
from renderer.voxels import save_voxels


def make_fake_dataset(folder: Path, samples: int = 4, size: int = 32, resolution: int = 16, seed: int = 0) -> Path:
    """Write `samples` samples of one box object with random views, noise-free images that depend on the light."""
    rng = np.random.default_rng(seed)
    (folder / "objects").mkdir(parents=True)
    (folder / "images").mkdir()
    (folder / "splats").mkdir()
    rgba = np.zeros((resolution,) * 3 + (4,), np.float32)
    rgba[4:12, 0:10, 4:12] = (0.8, 0.3, 0.2, 1.0)
    save_voxels(folder / "objects/o00000.npz", rgba)
    records = []
    for k in range(samples):
        light = (float(rng.uniform(-1.5, 1.5)), 2.75, float(rng.uniform(-1.5, 1.5)))
        scene = Scene.single(
            object=ObjectSpec(voxels="objects/o00000.npz", rotation_deg=float(rng.uniform(-90, 90))),
            floor=FloorSpec((0.5, 0.6, 0.7)), light=LightSpec(light), camera=CameraSpec(30.0), image_size=size,
        )
        ramp = np.linspace(0.2, 0.8, size)[None, :, None] * np.ones((size, 1, 3))
        target = np.clip(ramp + 0.1 * light[0], 0, 1)
        save_png(folder / f"images/s{k}.png", target)
        save_png(folder / f"splats/s{k}.png", ramp)
        records.append({"id": f"s{k}", "object": "o00000", "scene": scene.to_dict(),
                        "target": f"images/s{k}.png", "splat": f"splats/s{k}.png"})
    save_json(folder / "manifest.json", {"format": 1, "config": {"setting": "single"}, "samples": records})
    return folder
