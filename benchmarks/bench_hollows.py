"""Hollow objects seen into their openings (issue: a cup rendered closed): a cup lying on its side with its opening
towards the camera, the same cup standing, a bowl and a pipe lying, made here as meshes of revolution, rendered by the
voxel shader and the shipped NVR+ against the path tracer.

Usage: python -m benchmarks.bench_hollows [--spp P] [--figure OUT.png]
Prints per scene the MSE (0-255) and DSSIM of each renderer and the pixels inside the object's outline that show
floor through it (partly covered, two pixels or more from an uncovered one); `--figure`: target, shader, NVR+ per row.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import numpy as np
import trimesh
from scipy import ndimage

from models.engine.render_engine import RenderEngine
from models.evaluation.metrics import dssim, mse_255
from models.networks.shipped import shipped_weights
from renderer.io import save_png
from renderer.pathtrace import render_pathtraced
from renderer.pipeline import object_voxels, painted_voxels
from renderer.reference_object import object_mesh
from renderer.scene import load_scene
from renderer.shading import shade_scene


def hollow_meshes() -> dict[str, trimesh.Trimesh]:
    """A cup (radius 0.4, height 1, walls 0.05 thick, open at +z), a hemispherical bowl and a pipe, each along z."""
    cup = trimesh.creation.revolve(np.array([[0, 0], [0.4, 0], [0.4, 1.0], [0.35, 1.0], [0.35, 0.06], [0, 0.06]]),
                                   sections=96)
    angles = np.linspace(0.0, np.pi / 2, 24)
    outer = np.column_stack([0.5 * np.sin(angles), 0.5 - 0.5 * np.cos(angles)])
    inner = np.column_stack([0.45 * np.sin(angles), 0.5 - 0.45 * np.cos(angles)])[::-1]
    bowl = trimesh.creation.revolve(np.vstack([[0, 0], outer[1:], inner[:-1], [0, 0.05]]), sections=96)
    pipe = trimesh.creation.annulus(r_min=0.3, r_max=0.38, height=1.0, sections=96)
    return {"cup": cup, "bowl": bowl, "pipe": pipe}


# name: (mesh, up axis, camera elevation); "up" y lays the mesh's z axis towards the camera.
SCENES = {"cup on its side": ("cup", "y", 20.0), "cup standing": ("cup", "z", 45.0), "bowl": ("bowl", "z", 50.0),
          "pipe on its side": ("pipe", "y", 15.0)}


def _metrics(image: np.ndarray, target: np.ndarray) -> tuple[float, float]:
    import torch  # after models.engine, which sets OpenMP's waiting before torch loads

    a, b = (torch.from_numpy(np.ascontiguousarray(x.transpose(2, 0, 1)))[None] for x in (image, target))
    return float(mse_255(a, b)[0]), float(dssim(a, b)[0])


def floor_through(coverage: np.ndarray) -> int:
    """Pixels inside the outline partly covered, two pixels or more from an uncovered one (the anti-aliased edge)."""
    covered = coverage > 0.0
    near_empty = ndimage.binary_dilation(~covered, np.ones((3, 3), dtype=bool), iterations=2)
    return int(((coverage < 1.0) & covered & ~near_empty).sum())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--spp", type=int, default=256)
    p.add_argument("--figure", default=None)
    args = p.parse_args()
    engine = RenderEngine.load(shipped_weights("nvr_plus"))
    rows, figure = {}, []
    with tempfile.TemporaryDirectory() as tmp:
        for name, mesh in hollow_meshes().items():
            mesh.export(Path(tmp) / f"{name}.obj")
        for name, (mesh, up, elevation) in SCENES.items():
            path = Path(tmp) / "scene.json"
            path.write_text(json.dumps({
                "version": 1, "object": {"mesh": f"{mesh}.obj", "up": up, "resolution": 200, "color": [0.8, 0.3, 0.2]},
                "camera": {"elevation_deg": elevation}, "image_size": 256}))
            scene = load_scene(path)
            target = render_pathtraced(scene, object_mesh(scene), 256, spp=args.spp, seed=0).image
            rgba, floor = painted_voxels(scene, object_voxels(scene))
            shaded = shade_scene(scene, rgba, floor)
            corrected = engine.render(scene)
            row = {"floor through": floor_through(shaded.coverage)}
            for renderer, image in (("shader", shaded.image), ("NVR+", corrected)):
                mse, ds = _metrics(np.clip(image, 0.0, 1.0).astype(np.float32), target)
                row[renderer] = {"mse": round(mse, 1), "dssim": round(ds, 4)}
            rows[name] = row
            print(f"{name}: shader MSE {row['shader']['mse']}, NVR+ MSE {row['NVR+']['mse']}, "
                  f"{row['floor through']} pixels of floor through the object")
            figure.append(np.concatenate([target, np.clip(shaded.image, 0, 1), np.clip(corrected, 0, 1)], axis=1))
    if args.figure:
        save_png(args.figure, np.concatenate(figure, axis=0))
    print(json.dumps({"spp": args.spp, **rows}))


if __name__ == "__main__":
    main()
