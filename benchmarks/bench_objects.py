"""Edit latency against the number of objects, alone (`nvr bench` runs the same): a light move, moving one object,
painting one object, in scenes of 1, 2, 4 and 8 procedural objects of 200^3 voxels, through the voxel shader and
NVR+. Run it with nothing else on the cores.

    python -m benchmarks.bench_objects [--counts 1 2 4 8] [--repeats 5] [--renderers shaded nvr+]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from models.bench.objects import bench_object_counts
from models.renderers import make_renderer


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--counts", type=int, nargs="+", default=[1, 2, 4, 8])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--renderers", nargs="+", default=["shaded", "nvr+"])
    args = parser.parse_args()
    renderers = {name: make_renderer(name) for name in args.renderers}
    rows = bench_object_counts(renderers, Path(tempfile.mkdtemp(prefix="bench_objects_")), tuple(args.counts),
                               args.repeats)
    print("| renderer | objects | light edit | move one object | paint one object |\n|---|---:|---:|---:|---:|")
    for row in rows:
        ms = row["ms"]
        print(f"| {row['renderer']} | {row['objects']} | {ms['light edit']:.1f} ms | {ms['move one object']:.1f} ms | "
              f"{ms['paint one object']:.1f} ms |")


if __name__ == "__main__":
    main()
