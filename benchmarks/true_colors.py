"""How much of a photo-colored data set's error is the coloring: a copy of the set whose voxels carry the mesh's own
colors (what a perfect coloring from the photo would give), to evaluate beside the original with `nvr eval`, and the
voxel color error of the photo coloring against those colors, on the voxels the source photo shows and on the rest.

Run from the repository root:
    python -m benchmarks.true_colors data/novel30_textured_r200 --out data/true_novel30_textured_r200
    nvr eval --data data/true_novel30_textured_r200 --renderer nvr+ --report R

`--true-on seen` (or `hidden`) gives only the voxels the source photo shows (or the others) the mesh's colors and
keeps the photo's on the rest: which of the two the error comes from.

Targets and source photos are hard links; voxels and splats are remade (the mesh from the record's category and
seeds, as `nvr data recolor` remakes it). Rerun to resume. Prints per object the mean squared voxel color error
(0-255) of the photo coloring on visible and on hidden voxels, and its mean signed error on visible ones (a bias
there is the light division's, made as the set's config says: renderer.dataset._divided_light).
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import numpy as np

from renderer.capture.pose import lit_photo_scene, load_pose
from renderer.dataset import _divided_light, _link_or_copy, _remade_mesh, _voxelised_again
from renderer.errors import InputError
from renderer.io import load_image, load_json, save_json, save_png
from renderer.photo import color_voxels_from_photo
from renderer.scene import scene_from_dict
from renderer.splat import splat_scene
from renderer.voxels import load_voxels, save_voxels

TRUE_ON = ("all", "seen", "hidden")  # which voxels take the mesh's colors


def true_color_copy(source: Path, out: Path, true_on: str = "all") -> None:
    """`out`: `source` with the `true_on` voxels of every object colored by its mesh (the rest keep the photo's),
    splats redrawn from them."""
    config = load_json(source / "config.json").get("config", {})
    resolution = int(config.get("resolution", 0))
    if config.get("setting") == "single":
        raise InputError("single-colored voxels already carry the mesh's color", source)
    for sub in ("records", "objects", "images", "splats"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    shutil.copyfile(source / "config.json", out / "config.json")
    print("object  shape  visible voxels  MSE visible  MSE hidden  mean error visible (r, g, b)")
    for record_file in sorted((source / "records").glob("o*.json")):
        if (out / "records" / record_file.name).exists():
            continue
        record = load_json(record_file)
        obj = record["object"]
        mesh = _remade_mesh(obj)
        truth = _voxelised_again(obj, resolution, mesh)
        visible = _photo_coloring_visibility(record_file.stem, obj, truth, mesh, source,
                                             config.get("delight_shader", "object voxels"))
        if true_on != "all":
            photo_colored = load_voxels(source / obj["voxels"])
            truth = np.where((visible if true_on == "seen" else ~visible)[..., None], truth, photo_colored)
        save_voxels(out / obj["voxels"], truth)
        for rel in [obj["source_image"], obj["source_camera"]] + [s["target"] for s in record["samples"]]:
            _link_or_copy(source / rel, out / rel)
        floor = tuple(float(c) for c in obj["floor_color"])
        for sample in record["samples"]:
            save_png(out / sample["splat"], splat_scene(scene_from_dict(sample["scene"]), truth, floor))
        save_json(out / "records" / record_file.name, record)
    shutil.copyfile(source / "manifest.json", out / "manifest.json")


def _photo_coloring_visibility(name: str, obj: dict, truth: np.ndarray, mesh, source: Path,
                               delight_shader: str) -> np.ndarray:
    """The voxels the source photo shows, coloring `truth`'s occupancy (of `mesh`) from it as the data set did
    (its `delight_shader`); prints that coloring's error against `truth`'s colors."""
    pose = load_pose(source / obj["source_camera"])
    albedo, known = _divided_light(load_image(source / obj["source_image"])[0],
                                   lit_photo_scene(pose, tuple(obj["floor_color"])), truth, mesh, delight_shader,
                                   int(obj["index"]))
    colored = color_voxels_from_photo(truth, pose.object_to_world(), albedo, pose.camera,
                                      mirror=bool(obj["mirror_symmetry_used"]), trusted=known)
    stored = load_voxels(source / obj["voxels"])
    if stored.shape == colored.rgba.shape and not np.allclose(stored, colored.rgba, atol=2.5 / 255):
        print(f"{name}: the stored voxels differ from a coloring made now (made by other rules?)")
    occupied = truth[..., 3] >= 0.5
    error = (colored.rgba[..., :3] - truth[..., :3]) * 255.0
    visible, hidden = occupied & colored.visible, occupied & ~colored.visible
    squared = (error**2).mean(axis=-1)
    bias = error[visible].mean(axis=0) if visible.any() else np.zeros(3)
    shape = obj.get("params", {}).get("shape", obj.get("category", "?"))
    print(f"{name}  {shape}  {int(visible.sum())}  {squared[visible].mean() if visible.any() else 0:.0f}  "
          f"{squared[hidden].mean() if hidden.any() else 0:.0f}  ({', '.join(f'{b:.1f}' for b in bias)})", flush=True)
    return colored.visible


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("source", type=Path, help="a photo-colored data set (default or textured setting)")
    parser.add_argument("--out", type=Path, required=True, help="the copy with the mesh's colors")
    parser.add_argument("--true-on", choices=TRUE_ON, default="all",
                        help="the voxels that take the mesh's colors: all, those the source photo shows, or the others")
    args = parser.parse_args()
    if args.source.resolve() == args.out.resolve():
        raise SystemExit("give another --out folder: the data set is copied, not changed")
    try:
        true_color_copy(args.source, args.out, args.true_on)
    except InputError as exc:
        raise SystemExit(str(exc)) from None


if __name__ == "__main__":
    main()
