"""`nvr bench` against the number of objects: scenes of 1, 2, 4 and 8 procedural objects (200^3 voxels each, chairs,
tables, sofas and stools in turn), and per renderer the median ms of a light move, moving one object and painting one
object (models/bench/benchmark.py runs them; benchmarks/bench_objects.py alone).
"""

from __future__ import annotations

import statistics
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from renderer.io import atomic_path
from renderer.objects import apply_appearance, generate_object
from renderer.scene import LightSpec, ObjectSpec, PaintOp, Scene

CATEGORIES = ("chair", "table", "sofa", "stool")
SPACING = 0.75  # world units between neighbouring objects' centres (scale 0.6: footprints of at most 0.85 across)
SCALE = 0.6
# The several-objects issue's targets at 4 objects, ms (through NVR+), and the growth of a move from 1 to 8 objects.
TARGETS_MS = {"light edit": 40.0, "move one object": 90.0, "paint one object": 60.0}
MOVE_GROWTH_TARGET = 1.5


def objects_scene(folder: Path, count: int) -> Scene:
    """`count` procedural objects on a grid two rows deep, centred on the look-at point (meshes written to `folder`)."""
    folder.mkdir(parents=True, exist_ok=True)
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


def object_edits(scene: Scene, step: int) -> dict[str, Scene]:
    """The three edits of the first object and the light, a little different at every step (so no render is
    served from the last one)."""
    first = scene.objects[0]
    lx, ly, lz = scene.light.position
    moved = replace(first, translation=(first.translation[0] + 0.01 * (step % 2 + 1), first.translation[1]))
    painted = replace(first, paint=(PaintOp("object", (0.2 + 0.1 * (step % 5), 0.5, 0.3)),))
    return {
        "light edit": replace(scene, light=LightSpec((lx + 0.05 * (step % 2 + 1), ly, lz))),
        "move one object": replace(scene, objects=(moved, *scene.objects[1:])),
        "paint one object": replace(scene, objects=(painted, *scene.objects[1:])),
    }


def bench_object_counts(renderers: dict[str, Any], folder: Path, counts: tuple[int, ...],
                        repeats: int) -> list[dict[str, Any]]:
    """Per renderer (by label: anything with `render(scene)`) and object count, the median ms of each edit, each
    timed from the unedited scene; the first round warms the stages' code paths and is not counted."""
    rows = []
    for label, renderer in renderers.items():
        for count in counts:
            scene = objects_scene(folder, count)
            renderer.render(scene)  # voxelise and compile: not timed
            times: dict[str, list[float]] = {}
            for step in range(repeats + 1):
                for edit, edited in object_edits(scene, step).items():
                    renderer.render(scene)
                    start = time.perf_counter()
                    renderer.render(edited)
                    if step:
                        times.setdefault(edit, []).append((time.perf_counter() - start) * 1000.0)
            rows.append({"renderer": label, "objects": count,
                         "ms": {edit: statistics.median(values) for edit, values in times.items()}})
    return rows
