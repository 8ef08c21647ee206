"""Edit latency against the number of objects: a light move, moving one object, painting one object, in scenes of 1,
2, 4 and 8 procedural objects (200^3 voxels each), through the voxel shader and NVR+ (which shows the shader's
image for several objects). Prints a markdown table of medians; run it with nothing else on the cores.

    python -m benchmarks.bench_objects [--counts 1 2 4 8] [--repeats 5] [--renderers shaded nvr+]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from models.renderers import make_renderer
from renderer.io import atomic_path
from renderer.objects import apply_appearance, generate_object
from renderer.scene import LightSpec, ObjectSpec, PaintOp, Scene

CATEGORIES = ("chair", "table", "sofa", "stool")
SPACING = 0.75  # world units between neighbouring objects' centres (scale 0.6: footprints of at most 0.85 across)
SCALE = 0.6


def objects_scene(folder: Path, count: int) -> Scene:
    """`count` procedural objects on a grid two rows deep, centred on the look-at point."""
    objects = []
    columns = max(1, (count + 1) // 2)
    for k in range(count):
        category = CATEGORIES[k % len(CATEGORIES)]
        path = folder / f"{category}{k}.obj"
        if not path.exists():
            mesh, _, _ = apply_appearance(generate_object(category, 11 + k), "default", 11 + k, "test")
            with atomic_path(path) as tmp:
                mesh.export(tmp, file_type="obj", include_normals=False, include_texture=False)
        row, column = divmod(k, columns)
        x = (column - (columns - 1) / 2) * SPACING
        z = 0.0 if count == 1 else (row - 0.5) * SPACING
        objects.append(ObjectSpec(mesh=path.name, translation=(x, z), rotation_deg=25.0 * k,
                                  scale=(SCALE, SCALE, SCALE), name=f"{category}{k}"))
    return Scene(objects=tuple(objects), base_dir=folder)


def edits(scene: Scene, step: int) -> dict[str, Scene]:
    """The three edits, each a little different at every step (so nothing is served from the last render)."""
    first = scene.objects[0]
    lx, ly, lz = scene.light.position
    moved = replace(first, translation=(first.translation[0] + 0.01 * (step % 2 + 1), first.translation[1]))
    color = (0.2 + 0.1 * (step % 5), 0.5, 0.3)
    painted = replace(first, paint=(PaintOp("object", color),))
    return {
        "light": replace(scene, light=LightSpec((lx + 0.05 * (step % 2 + 1), ly, lz))),
        "move one": replace(scene, objects=(moved, *scene.objects[1:])),
        "paint one": replace(scene, objects=(painted, *scene.objects[1:])),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--counts", type=int, nargs="+", default=[1, 2, 4, 8])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--renderers", nargs="+", default=["shaded", "nvr+"])
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="bench_objects_"))
    rows = []
    for name in args.renderers:
        for count in args.counts:
            renderer = make_renderer(name)
            scene = objects_scene(folder, count)
            renderer.render(scene)  # voxelise and compile: not timed
            times: dict[str, list[float]] = {}
            for step in range(args.repeats + 1):
                for edit, edited in edits(scene, step).items():
                    renderer.render(scene)  # back to the start: the edit is timed from it
                    start = time.perf_counter()
                    renderer.render(edited)
                    if step:  # the first round warms the stages' code paths
                        times.setdefault(edit, []).append((time.perf_counter() - start) * 1000.0)
            rows.append((name, count, {edit: statistics.median(values) for edit, values in times.items()}))
            print(f"{name}, {count} objects: " + ", ".join(f"{e} {t:.1f} ms" for e, t in rows[-1][2].items()),
                  flush=True)
    print("\n| renderer | objects | light edit | move one object | paint one object |\n|---|---:|---:|---:|---:|")
    for name, count, medians in rows:
        print(f"| {name} | {count} | {medians['light']:.1f} ms | {medians['move one']:.1f} ms | "
              f"{medians['paint one']:.1f} ms |")


if __name__ == "__main__":
    main()
