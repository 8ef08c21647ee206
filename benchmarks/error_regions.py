"""Where the NVR+ and the voxel shader it corrects (the network's input: without the object's reflection in the floor)
put their squared error: on the object, along its silhouette, on the floor.

Run from the repository root after making the test split (docs/results.md says how):
    python -m benchmarks.error_regions [--data DIR...] [--every 3] [--mesh-coverage]
Prints a Markdown table per setting: the MSE (0-255) of each renderer split into what each region adds to it (the
columns sum to the whole): the object's inside, a band of BAND pixels either side of its silhouette (thin parts lie
wholly in it), the floor within NEAR pixels of the object (its shadow and reflection), and the rest. Regions follow the
shader's coverage. `--mesh-coverage` also compares that coverage with the mesh's own, 8 x 8 rays a pixel cast at the
mesh (renderer.capture.silhouette, the photo capture's silhouettes): the mean squared difference, how far the shader's
silhouette lies outside the mesh's on average (pixels; negative: inside), and the shader's silhouette-band error when
its edge pixels are mixed by the mesh's coverage instead of its own (each side's color taken from the nearest pixel
wholly on that side): how much of that band is the silhouette's place and how much the shading near it.
"""

from __future__ import annotations

import argparse
from collections import defaultdict
from pathlib import Path

# isort: split
import models.engine  # noqa: F401 - before torch, so OMP_WAIT_POLICY is set when torch loads OpenMP

# isort: split
import numpy as np
from scipy import ndimage

from models.bench.scenes import rebuilt_mesh
from models.engine.render_engine import RenderEngine
from models.threads import limit_blas_threads
from models.training.data import read_manifest
from renderer.camera import Camera
from renderer.capture.pose import PhotoPose
from renderer.capture.silhouette import SilhouetteRenderer
from renderer.io import load_image
from renderer.pipeline import object_voxels, painted_voxels
from renderer.scene import Scene, scene_from_dict
from renderer.shading import shade_scene

BAND = 2  # pixels either side of the silhouette
NEAR = 25  # pixels of floor around the object
REGIONS = ("object", "silhouette band", "floor near", "floor far")
SUPERSAMPLING = 8


def regions(coverage: np.ndarray) -> dict[str, np.ndarray]:
    """Masks of the four regions (they tile the image) from the shader's object coverage (H, W)."""
    drawn = coverage > 0.0
    band = ndimage.binary_dilation(drawn, iterations=BAND) & ~ndimage.binary_erosion(coverage >= 1.0, iterations=BAND)
    inside = drawn & ~band
    near = ndimage.binary_dilation(drawn, iterations=NEAR) & ~band & ~inside
    return {"object": inside, "silhouette band": band, "floor near": near, "floor far": ~(inside | band | near)}


def mesh_coverage(silhouettes: SilhouetteRenderer, scene: Scene, size: int) -> np.ndarray:
    """The share of each pixel (H, W) the mesh covers, seen by the scene's camera: SUPERSAMPLING^2 rays a pixel."""
    o = scene.object
    camera = Camera.from_scene(scene, size * SUPERSAMPLING)
    fine = silhouettes.mask(PhotoPose(camera, o.rotation_deg, o.translation, o.scale)).astype(np.float32)
    return fine.reshape(size, SUPERSAMPLING, size, SUPERSAMPLING).mean(axis=(1, 3))


def silhouette_offset(coverage: np.ndarray, truth: np.ndarray) -> float:
    """How far `coverage`'s silhouette lies outside `truth`'s on average (pixels): the area between them over the
    length of the true silhouette."""
    solid = truth > 0.5
    length = (ndimage.binary_dilation(solid) ^ ndimage.binary_erosion(solid)).sum() / 2.0
    return float(coverage.sum() - truth.sum()) / max(length, 1.0)


def recomposited(image: np.ndarray, coverage: np.ndarray, new_coverage: np.ndarray) -> np.ndarray:
    """`image` (H, W, 3) with every pixel that either coverage counts as partly covered mixed by `new_coverage` from
    the nearest pixel wholly on the object and the nearest wholly off it (per `coverage`)."""
    full, empty = coverage >= 0.999, coverage <= 0.001
    on_object = image[tuple(ndimage.distance_transform_edt(~full, return_distances=False, return_indices=True))]
    off_object = image[tuple(ndimage.distance_transform_edt(~empty, return_distances=False, return_indices=True))]
    mixed = on_object * new_coverage[..., None] + off_object * (1.0 - new_coverage[..., None])
    kept = (full & (new_coverage >= 0.999)) | (empty & (new_coverage <= 0.001))
    return np.where(kept[..., None], image, mixed)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", nargs="+",
                        default=["data/test_single_r200", "data/test_default_r200_p512", "data/test_textured_r200_p512"])
    parser.add_argument("--every", type=int, default=3, help="use every N-th view")
    parser.add_argument("--model", help="NVR+ weights (default: the shipped model)")
    parser.add_argument("--mesh-coverage", action="store_true", help="compare the shader's coverage with the mesh's")
    args = parser.parse_args()
    limit_blas_threads()
    engine = RenderEngine.load(args.model)
    errors: dict[tuple[str, str], list[dict[str, float]]] = defaultdict(list)
    coverage_rows: dict[str, list[tuple[float, float]]] = defaultdict(list)
    for folder in map(Path, args.data):
        manifest = read_manifest(folder)
        setting = manifest["config"]["setting"]
        records = {o["id"]: o for o in manifest["objects"]}
        silhouettes: dict[str, SilhouetteRenderer] = {}
        for sample in manifest["samples"][::args.every]:
            scene = scene_from_dict(sample["scene"], folder / "manifest.json")
            target, _ = load_image(folder / sample["target"])
            size = target.shape[0]
            rgba, floor = painted_voxels(scene, object_voxels(scene))
            shaded = shade_scene(scene, rgba, floor, size, reflection=False)  # what the NVR+ corrects
            masks = regions(shaded.coverage)
            for name, image in (("NVR+", engine.render(scene)), ("voxel shader", np.clip(shaded.image, 0.0, 1.0))):
                squared = (((image - target) * 255.0) ** 2).mean(axis=2)
                errors[(setting, name)].append({r: float(squared[m].sum()) / squared.size for r, m in masks.items()})
            if args.mesh_coverage:
                if sample["object"] not in silhouettes:  # one object's views follow each other
                    silhouettes = {sample["object"]: SilhouetteRenderer(rebuilt_mesh(records[sample["object"]], folder))}
                truth = mesh_coverage(silhouettes[sample["object"]], scene, size)
                band = masks["silhouette band"]
                band_error = [float(((((image - target) * 255.0) ** 2).mean(axis=2)[band]).sum()) / band.size
                              for image in (recomposited(shaded.image, shaded.coverage, coverage)
                                            for coverage in (shaded.coverage, truth))]
                coverage_rows[setting].append((float(((shaded.coverage - truth) ** 2).mean()),
                                               silhouette_offset(shaded.coverage, truth), *band_error))
    print(f"MSE (0-255) by region, one view in {args.every}; the regions sum to the whole\n")
    print("| setting | renderer | images | whole | " + " | ".join(REGIONS) + " |")
    print("|---|---|---:|---:|" + "---:|" * len(REGIONS))
    for (setting, name), rows in sorted(errors.items()):
        parts = [np.mean([row[r] for row in rows]) for r in REGIONS]
        print(f"| {setting} | {name} | {len(rows)} | {sum(parts):.2f} | " + " | ".join(f"{p:.2f}" for p in parts) + " |")
    if coverage_rows:
        print("\n| setting | images | coverage against the mesh's: mean squared difference | mean outward offset (px) "
              "| shader's band MSE, edges mixed by its coverage | by the mesh's |")
        print("|---|---:|---:|---:|---:|---:|")
        for setting, rows in sorted(coverage_rows.items()):
            squared, offset, own, mesh = np.mean(rows, axis=0)
            print(f"| {setting} | {len(rows)} | {squared:.5f} | {offset:+.3f} | {own:.2f} | {mesh:.2f} |")


if __name__ == "__main__":
    main()
