"""How well the voxel shader draws scenes of several objects, against path tracing: scenes of 2 to 4 procedural
objects (their own mesh colors, 200^3 voxels) standing close together, at random lights and elevations. Prints the MSE (0-255) over
the image, on the objects where no other object shadows them, and inside each object's shadow on the others (pixels
of an object that the path tracer draws at most 85 % as bright as when the object stands alone), and the same
objects' error when each stands alone.

    python -m benchmarks.objects_accuracy [--scenes 12] [--spp 64] [--size 256]
"""

from __future__ import annotations

import argparse
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from models.bench.objects import CATEGORIES
from models.renderers import RendererOptions, make_renderer
from renderer.io import atomic_path
from renderer.objects import apply_appearance, generate_object
from renderer.pipeline import painted_objects
from renderer.scene import ELEVATION_RANGE, CameraSpec, FloorSpec, LightSpec, ObjectSpec, Scene
from renderer.shading.staged import ObjectVoxels, StagedShader

SHADOW_RATIO = 0.85  # an object's pixel at most this bright (luminance) with the others as alone is in their shadow
FLOOR_COLORS = ((0.53, 0.64, 0.78), (0.75, 0.7, 0.6), (0.45, 0.5, 0.45))


def footprint(scale: float) -> float:
    """Radius of the circle that holds an object's footprint at a uniform `scale`, whatever its turn."""
    return 0.5 * float(np.hypot(scale, scale))


def random_scene(folder: Path, rng: np.random.Generator, index: int) -> Scene:
    """2 to 4 objects of scale 0.45-0.75 on the floor within the view, each beside another with a gap of 0.02 to 0.25
    between their footprints (never touching), at a light and elevation from the training ranges."""
    count = int(rng.integers(2, 5))
    objects: list[ObjectSpec] = []
    while len(objects) < count:
        k = len(objects)
        category = CATEGORIES[int(rng.integers(len(CATEGORIES)))]
        seed = 100 + 10 * index + k
        path = folder / f"{category}{seed}.obj"
        if not path.exists():
            mesh, _, _ = apply_appearance(generate_object(category, seed), "default", seed, "test")
            with atomic_path(path) as tmp:
                mesh.export(tmp, file_type="obj", include_normals=False, include_texture=False)
        scale = float(rng.uniform(0.45, 0.75))
        if objects:  # beside an object placed before, a small gap between their footprints: close enough to shadow
            neighbour = objects[int(rng.integers(len(objects)))]
            angle, gap = rng.uniform(0.0, 2.0 * np.pi), rng.uniform(0.02, 0.25)
            reach = footprint(scale) + footprint(neighbour.scale[0]) + gap
            place = (neighbour.translation[0] + reach * float(np.cos(angle)),
                     neighbour.translation[1] + reach * float(np.sin(angle)))
        else:
            place = (float(rng.uniform(-0.3, 0.3)), float(rng.uniform(-0.3, 0.1)))
        inside = abs(place[0]) < 1.1 and -1.0 < place[1] < 0.6  # in view
        if inside and all(np.hypot(place[0] - o.translation[0], place[1] - o.translation[1])
                          > footprint(scale) + footprint(o.scale[0]) for o in objects):
            objects.append(ObjectSpec(mesh=path.name, scale=(scale,) * 3, translation=place,
                                      rotation_deg=float(rng.uniform(-90, 90)), name=f"o{k}"))
    light = (float(rng.uniform(-1.5, 1.5)), float(rng.uniform(2.5, 3.0)), float(rng.uniform(-1.5, 1.5)))
    return Scene(objects=tuple(objects), floor=FloorSpec(FLOOR_COLORS[index % len(FLOOR_COLORS)]),
                 light=LightSpec(light), camera=CameraSpec(float(rng.uniform(*ELEVATION_RANGE))), base_dir=folder)


def shaded(scene: Scene, size: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """The shader's image of the scene, and each object's coverage when it stands alone."""
    shader = StagedShader()
    painted = painted_objects(scene)
    objects = [ObjectVoxels(o, ("v", k), rgba, ("s", k)) for k, (o, rgba) in enumerate(zip(scene.objects, painted))]
    image = shader.run_objects(scene, objects, scene.floor.color, size).image
    alone = [StagedShader().run_objects(replace(scene, objects=(o.spec,)), [o], scene.floor.color, size).coverage
             for o in objects]
    return image, alone


def luminance(image: np.ndarray) -> np.ndarray:
    return image @ np.array([0.2126, 0.7152, 0.0722])


def mse(a: np.ndarray, b: np.ndarray, where: np.ndarray | None = None) -> float:
    squared = ((a.astype(np.float64) - b) * 255.0) ** 2
    return float(squared.mean() if where is None else squared[where].mean()) if where is None or where.any() else np.nan


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=12)
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--size", type=int, default=256)
    args = parser.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="objects_accuracy_"))
    tracer = make_renderer("pathtrace", RendererOptions(spp=args.spp, denoise=True))
    rng = np.random.default_rng(0)
    totals: dict[str, list[tuple[float, int]]] = {"image": [], "lit objects": [], "shadowed by others": [],
                                                  "objects alone": []}
    print("| scene | objects | image | objects, unshadowed | inside the others' shadows (pixels) | objects alone |")
    print("|---:|---:|---:|---:|---:|---:|")
    for index in range(args.scenes):
        scene = replace(random_scene(folder, rng, index), image_size=args.size)
        target = tracer.render(scene)
        image, coverage = shaded(scene, args.size)
        lit_mask = np.zeros(image.shape[:2], dtype=bool)
        shadow_mask = np.zeros_like(lit_mask)
        alone_errors = []
        for k, o in enumerate(scene.objects):
            alone = replace(scene, objects=(o,))
            target_alone = tracer.render(alone)
            own = coverage[k] > 0.5
            others = np.zeros_like(own)
            for j, cover in enumerate(coverage):
                if j != k:
                    others |= cover > 0.05
            visible = own & ~others  # the object's pixels no other object stands in front of (or near the edge of)
            dark = luminance(target) < SHADOW_RATIO * luminance(target_alone)
            shadow_mask |= visible & dark
            lit_mask |= visible & ~dark
            shader_alone, _ = shaded(alone, args.size)
            alone_errors.append((mse(shader_alone, target_alone, own), int(own.sum())))
        alone_error = sum(e * n for e, n in alone_errors) / max(sum(n for _, n in alone_errors), 1)
        row = {"image": (mse(image, target), image.shape[0] * image.shape[1]),
               "lit objects": (mse(image, target, lit_mask), int(lit_mask.sum())),
               "shadowed by others": (mse(image, target, shadow_mask), int(shadow_mask.sum())),
               "objects alone": (alone_error, sum(n for _, n in alone_errors))}
        for key, value in row.items():
            if value[1]:
                totals[key].append(value)
        print(f"| {index} | {len(scene.objects)} | {row['image'][0]:.1f} | {row['lit objects'][0]:.1f} | "
              f"{row['shadowed by others'][0]:.1f} ({row['shadowed by others'][1]}) | {row['objects alone'][0]:.1f} |",
              flush=True)
    means = {key: sum(e * n for e, n in values) / max(sum(n for _, n in values), 1) for key, values in totals.items()}
    print(f"| all | | {means['image']:.1f} | {means['lit objects']:.1f} | {means['shadowed by others']:.1f} | "
          f"{means['objects alone']:.1f} |")


if __name__ == "__main__":
    main()
