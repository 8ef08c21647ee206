"""Images per hour of `nvr data generate` on this machine, at 128^2 and 256^2, for the chosen spp.

Run: python -m benchmarks.bench_datagen [--objects 3] [--views 5] [--spp 16]
Counts target images (each object also renders one appearance source image, included in the time).
Nothing else should run while it measures.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from renderer.dataset import DataConfig, generate_dataset


def images_per_hour(size: int, objects: int, views: int, spp: int, setting: str, workers: int) -> tuple[float, float]:
    """(images per hour, seconds per object) for one fresh data set of the given shape."""
    config = DataConfig(setting=setting, objects=objects, views=views, size=size, spp=spp, denoise=True)
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        generate_dataset(Path(folder) / "set", config, workers=workers, progress=False)
        seconds = time.perf_counter() - start
    return objects * views / seconds * 3600.0, seconds / objects


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", type=int, default=3)
    parser.add_argument("--views", type=int, default=5)
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    print(f"{'size':>5} {'setting':>9} {'images/hour':>12} {'s/object':>9}  ({args.objects} objects x {args.views} views, "
          f"{args.spp} spp + OIDN, {args.workers} workers)")
    for size in (128, 256):
        for setting in ("single", "textured"):
            rate, per_object = images_per_hour(size, args.objects, args.views, args.spp, setting, args.workers)
            print(f"{size:>5} {setting:>9} {rate:>12.0f} {per_object:>9.1f}")


if __name__ == "__main__":
    main()
