"""The scenes `nvr bench` renders: the demo scene and procedural objects, or samples of a test data folder.

Each comes with the mesh the path tracer renders; the engine and the splat read the scene's own
mesh file (procedural objects are written as OBJ with vertex colors) or voxel file (data folders,
whose voxels were colored from a photo as the paper's protocol does).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from renderer.errors import InputError
from renderer.io import atomic_path
from renderer.objects import apply_appearance, generate_object
from renderer.objects.demo import DEMO_DIR
from renderer.pipeline import object_mesh
from renderer.scene import CameraSpec, FloorSpec, LightSpec, ObjectSpec, Scene, load_scene, scene_from_dict

# (category, appearance setting, seed, placement, light, elevation): one object per appearance setting.
PROCEDURAL_VIEWS = [
    ("chair", "default", 3, dict(rotation_deg=30.0, translation=(0.1, -0.1)), (1.0, 2.75, 0.5), 30.0),
    ("table", "textured", 5, dict(rotation_deg=-40.0, translation=(-0.2, 0.2)), (-1.2, 2.6, -1.0), 15.0),
    ("sofa", "single", 7, dict(rotation_deg=70.0), (0.4, 3.0, 1.3), 45.0),
]


@dataclass(frozen=True)
class BenchScene:
    name: str
    scene: Scene
    mesh: trimesh.Trimesh  # in object coordinates, for the path tracer


def procedural_scenes(folder: Path, count: int) -> list[BenchScene]:
    """The demo scene, then procedural objects written as OBJ files into `folder`: `count` scenes in all."""
    demo = load_scene(DEMO_DIR / "scene.json")
    scenes = [BenchScene("demo chair", demo, object_mesh(demo))]
    for category, setting, seed, placement, light, elevation in PROCEDURAL_VIEWS[: max(0, count - 1)]:
        mesh, floor, _ = apply_appearance(generate_object(category, seed), setting, seed, "test")
        with atomic_path(folder / f"{category}.obj") as tmp:
            mesh.export(tmp, file_type="obj", include_normals=False, include_texture=False)
        scene = Scene.single(object=ObjectSpec(mesh=f"{category}.obj", **placement), floor=FloorSpec(floor),
                      light=LightSpec(light), camera=CameraSpec(elevation), base_dir=folder)
        scenes.append(BenchScene(f"{category} ({setting})", scene, object_mesh(scene)))
    return scenes


def data_scenes(folders: list[str | Path], count: int) -> list[BenchScene]:
    """The first view of up to `count` objects of test data folders (renderer/dataset.py), meshes rebuilt from their seeds."""
    from models.training.data import read_manifest

    scenes: list[BenchScene] = []
    for folder in map(Path, folders):
        manifest = read_manifest(folder)
        objects = {o["id"]: o for o in manifest.get("objects", [])}
        seen = set()
        for sample in manifest["samples"]:
            if len(scenes) >= count:
                return scenes
            if sample["object"] in seen or sample["object"] not in objects:
                continue
            seen.add(sample["object"])
            record = objects[sample["object"]]
            scene = scene_from_dict(sample["scene"], folder / "manifest.json")
            scenes.append(BenchScene(f"{folder.name}/{sample['id']}", scene, rebuilt_mesh(record, folder)))
    if not scenes:
        raise InputError("no samples with object records found", folders[0] if folders else None)
    return scenes


def rebuilt_mesh(record: dict, folder: Path) -> trimesh.Trimesh:
    """The colored mesh of a data set's object, from the category, seed and appearance in its record."""
    appearance = record["appearance"]
    mesh, floor, _ = apply_appearance(generate_object(record["category"], record["seed"]), appearance["setting"],
                                      appearance["seed"], appearance["split"])
    if not np.allclose(floor, record["floor_color"], atol=1e-6):
        raise InputError(f"cannot rebuild object {record['id']}: made by another version of the generator", folder)
    return mesh
