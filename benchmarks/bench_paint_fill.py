"""Bucket fills on photo colors: the demo chair colored from the demo photo (`nvr capture`), region fills at the
default tolerance from random seeds, comparing colors in RGB and perceptually (renderer/paint.py).

Usage: python -m benchmarks.bench_paint_fill [--seeds N] [--tolerance T]
Prints per seed and similarity the voxels filled, the blotches left (occupied voxels outside the region with three or
more of their six face neighbours in it) and the fill's time; one JSON line at the end.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import ndimage

from renderer.objects.demo import DEMO_DIR
from renderer.paint import fill_region_voxels, occupied_voxels
from renderer.scene import SIMILARITIES
from renderer.voxels import load_voxels


def blotches(region: np.ndarray, occupied: np.ndarray) -> int:
    """Occupied voxels outside `region` (a mask) with three or more of their six face neighbours inside it."""
    faces = ndimage.generate_binary_structure(3, 1).astype(np.uint8)
    faces[1, 1, 1] = 0
    return int((occupied & ~region & (ndimage.convolve(region.astype(np.uint8), faces, mode="constant") >= 3)).sum())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=6)
    p.add_argument("--tolerance", type=float, default=0.1)
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / "captured.json"
        subprocess.run([sys.executable, "-m", "app.cli", "capture", str(DEMO_DIR / "chair.obj"),
                        str(DEMO_DIR / "photo.png"), "--camera", str(DEMO_DIR / "photo_camera.json"), "-o", str(scene)],
                       check=True, capture_output=True)
        rgba = load_voxels(Path(tmp) / "captured_colors.npz")
    occupied = occupied_voxels(rgba)
    occupied_mask = rgba[..., 3] >= 0.5
    rows = []
    for index in np.random.default_rng(0).choice(len(occupied), args.seeds, replace=False):
        seed = tuple(int(i) for i in np.unravel_index(occupied[index], rgba.shape[:3]))
        row = {"seed": list(seed), "color": [round(float(c), 2) for c in rgba[seed][:3]]}
        for similarity in SIMILARITIES:
            fill_region_voxels(rgba, seed, args.tolerance, occupied, similarity)  # compiled before it is timed
            start = time.perf_counter()
            region = fill_region_voxels(rgba, seed, args.tolerance, occupied, similarity)
            ms = (time.perf_counter() - start) * 1000.0
            mask = np.zeros(rgba.shape[:3], dtype=bool)
            mask.reshape(-1)[region] = True
            row[similarity] = {"filled": len(region), "blotches": blotches(mask, occupied_mask), "ms": round(ms, 1)}
        rows.append(row)
        print(f"seed {row['seed']} color {row['color']}: " + "; ".join(
            f"{s} {row[s]['filled']} filled, {row[s]['blotches']} blotches, {row[s]['ms']} ms" for s in SIMILARITIES))
    print(json.dumps({"tolerance": args.tolerance, "voxels": len(occupied), "seeds": rows}))


if __name__ == "__main__":
    main()
