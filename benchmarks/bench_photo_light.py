"""How well capture divides a photo's light out when the photo does not say where it was: the light fitted from
the photo (renderer/capture/light_fit.py) against the true light and against keeping the photo's shading.

Photos: the capture benchmark's (benchmarks/bench_capture.py), `floor` (the project's scene, the scene camera) and
`real` (the object over a photograph, blurred, noisy, JPEG; a third through a 60 mm lens), each captured at its
true pose with its true silhouette, so that only the light differs. Measured per photo:
- color RMSE (0-255 sRGB) of the voxels the photo shows against the object's own colors: the photo's shading kept,
  the fitted light divided out, and the true light divided out (renderer.photo.unmixed_albedo; scene camera only);
- the fitted light's direction error, seen from the object's middle, in degrees;
- brightness: the captured object drawn by the voxel shader under the fitted light, at the photo's view (scene
  camera only), its mean over the object's trusted pixels against the photo's (a ratio; 1 is the photo's); and the
  same for the colors that kept the shading and for the object's own colors, both drawn under the true light (the
  last is the voxel shader's own difference from the path tracer).

Run from the repository root (the `real` photos need scikit-image: pip install -e ".[bench]"):
    python -m benchmarks.bench_photo_light --photos 30
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import statistics
import time
from pathlib import Path

import numpy as np

from benchmarks.bench_capture import color_rmse, make_photo
from models.bench.system import machine_description
from renderer.capture.capture import capture_appearance, trusted_pixels
from renderer.color import srgb_to_linear
from renderer.io import atomic_path
from renderer.scene import CameraSpec, FloorSpec, LightSpec, ObjectSpec, Scene
from renderer.shading.shader import shade_scene
from renderer.voxels import voxelize

STYLES = ("floor", "real")
DOC = Path(__file__).resolve().parents[1] / "docs" / "photo_light.md"


def direction_error_deg(found, true, pose) -> float:
    """Angle between two light positions seen from the middle of the object (its placement, half a unit up)."""
    middle = np.array([pose.translation[0], 0.5 * pose.scale[1], pose.translation[1]])
    a, b = np.subtract(found, middle), np.subtract(true, middle)
    return math.degrees(math.acos(float(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1.0, 1.0))))


def brightness_ratio(rgba: np.ndarray, photo, pose, light, trusted: np.ndarray) -> float:
    """Mean linear brightness of the captured voxels drawn by the shader under `light` at the photo's view, over
    the trusted object pixels, divided by the photo's there."""
    scene = Scene.single(object=pose.placed(ObjectSpec()), floor=FloorSpec(), light=LightSpec(tuple(light)),
                         camera=CameraSpec(pose.camera.elevation_deg), image_size=pose.camera.width)
    shaded = shade_scene(scene, rgba, scene.floor.color)
    where = trusted & (shaded.coverage >= 1.0)
    drawn = srgb_to_linear(shaded.image.astype(np.float64))[where].mean()
    return float(drawn / max(srgb_to_linear(np.asarray(photo, dtype=np.float64))[where].mean(), 1e-9))


def run(photos: int, size: int, spp: int, resolution: int) -> list[dict]:
    rows = []
    for number in range(photos):
        for style in STYLES:
            photo = make_photo(style, number, size, spp)
            truth = voxelize(photo.mesh, resolution)
            trusted = trusted_pixels(photo.true_mask)
            row = {"photo": number, "style": style, "category": photo.category, "lens_mm": photo.truth.camera.focal_mm}

            def captured(photo=photo, truth=truth, **options):
                return capture_appearance(truth, photo.mesh, photo.image, None, photo.truth, search=False,
                                          mask=photo.true_mask, **options)

            kept = captured(fit_photo_light=False)
            began = time.perf_counter()
            fitted = captured()
            row["seconds"] = time.perf_counter() - began
            row["rmse_kept"] = color_rmse(kept.rgba, truth, kept.visible)
            row["rmse_fitted"] = color_rmse(fitted.rgba, truth, fitted.visible)
            row["divided"] = fitted.fitted_light is not None
            scene_camera = not photo.long_lens
            if scene_camera:
                true_light = captured(light=photo.light)
                row["rmse_true_light"] = color_rmse(true_light.rgba, truth, true_light.visible)
                row["brightness_kept"] = brightness_ratio(kept.rgba, photo.image, photo.truth, photo.light, trusted)
                row["brightness_truth"] = brightness_ratio(truth, photo.image, photo.truth, photo.light, trusted)
            if fitted.fitted_light is not None:
                position = fitted.fitted_light.position
                row["direction_error_deg"] = direction_error_deg(position, photo.light, photo.truth)
                if scene_camera:
                    row["brightness_ratio"] = brightness_ratio(fitted.rgba, photo.image, photo.truth, position, trusted)
            rows.append(row)
            print(f"{style:5s} {number:2d} {photo.category:6s} color RMSE kept {row['rmse_kept']:5.1f}, fitted "
                  f"{row['rmse_fitted']:5.1f}, true light {row.get('rmse_true_light', float('nan')):5.1f}; direction "
                  f"{row.get('direction_error_deg', float('nan')):5.1f} deg; brightness "
                  f"{row.get('brightness_ratio', float('nan')):.3f}; {row['seconds']:.1f} s", flush=True)
    return rows


def _median(rows: list[dict], key: str) -> float:
    values = [r[key] for r in rows if key in r and np.isfinite(r[key])]
    return statistics.median(values) if values else float("nan")


def _cell(value: float, form: str) -> str:
    return "-" if not np.isfinite(value) else format(value, form)


def write_report(rows: list[dict], args: argparse.Namespace) -> None:
    lines = [
        "# Dividing out a photo's light fitted from the photo",
        "",
        f"`python -m benchmarks.bench_photo_light --photos {args.photos} --size {args.size} --spp {args.spp}` on "
        f"{datetime.date.today()}, {machine_description()['cpu']}; {args.note}.",
        "",
        "The capture benchmark's photos (benchmarks/bench_capture.py), captured at their true pose with their true "
        "silhouette, so that only the light differs. Color RMSE (0-255 sRGB, the voxels the photo shows against the "
        "object's own colors): the photo's shading kept, the light fitted from the photo and divided out, the true "
        "light divided out (scene camera only). Direction: the fitted light's angle from the true one, seen from the "
        "object's middle. Brightness: the captured object drawn by the voxel shader under the fitted light, over the "
        "photo's object pixels, against the photo (1 is the photo's; scene camera only); beside it the same for the colors "
        "that kept the photo's shading (shaded twice) and for the object's own colors (the voxel shader's own difference "
        "from the path tracer), both drawn under the true light. Medians.",
        "",
        "| photos | count | light divided out | color RMSE, shading kept | fitted light | true light "
        "| direction error (deg) | within 20 deg | brightness ratio | within 10 % | shading kept: brightness "
        "| true colors: brightness | fit time (s) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    groups = {"floor (scene camera)": lambda r: r["style"] == "floor",
              "real, 40 mm": lambda r: r["style"] == "real" and abs(r["lens_mm"] - 40.0) < 1e-6,
              "real, 60 mm": lambda r: r["style"] == "real" and abs(r["lens_mm"] - 40.0) >= 1e-6}
    for name, keep in groups.items():
        chosen = [r for r in rows if keep(r)]
        if not chosen:
            continue
        directions = [r["direction_error_deg"] for r in chosen if "direction_error_deg" in r]
        ratios = [r["brightness_ratio"] for r in chosen if "brightness_ratio" in r]
        within = (f"{100 * np.mean(np.array(directions) <= 20.0):.0f} %" if directions else "-")
        bright = (f"{100 * np.mean(np.abs(np.array(ratios) - 1.0) <= 0.1):.0f} %" if ratios else "-")
        lines.append(
            f"| {name} | {len(chosen)} | {sum(r['divided'] for r in chosen)} | {_cell(_median(chosen, 'rmse_kept'), '.1f')} "
            f"| {_cell(_median(chosen, 'rmse_fitted'), '.1f')} | {_cell(_median(chosen, 'rmse_true_light'), '.1f')} "
            f"| {_cell(_median(chosen, 'direction_error_deg'), '.1f')} | {within} "
            f"| {_cell(_median(chosen, 'brightness_ratio'), '.3f')} | {bright} "
            f"| {_cell(_median(chosen, 'brightness_kept'), '.3f')} | {_cell(_median(chosen, 'brightness_truth'), '.3f')} "
            f"| {_cell(_median(chosen, 'seconds'), '.1f')} |")
    lines.append("")
    with atomic_path(DOC) as tmp:
        tmp.write_text("\n".join(lines))
    with atomic_path(DOC.with_suffix(".json")) as tmp:
        tmp.write_text(json.dumps({"rows": rows}, indent=1, default=float))
    print(f"wrote {DOC} and {DOC.with_suffix('.json')}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--photos", type=int, default=30, help="photos per style")
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--resolution", type=int, default=100, help="object voxels per side")
    parser.add_argument("--note", default="idle machine", help="what else ran on the machine")
    args = parser.parse_args()
    write_report(run(args.photos, args.size, args.spp, args.resolution), args)


if __name__ == "__main__":
    main()
