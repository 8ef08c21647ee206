"""Write the demo assets in assets/demo/: a generated chair, a scene that shows it, and a photo of it.

Run `python -m renderer.objects.demo`; the same code always writes the same files, so the
assets are traceable to this seed:
    chair.obj           a generated chair in the `default` appearance, with vertex colors
    scene.json          the scene `make run` opens (format version 2)
    photo.png           a path-traced "photo" of the chair from another view and light,
    photo_camera.json   and the camera that took it (the format the data generator writes)
"""

from __future__ import annotations

import sys
from pathlib import Path

from renderer.io import atomic_path, save_json, save_png
from renderer.objects.appearance import apply_appearance
from renderer.objects.generate import generate_object
from renderer.scene import CameraSpec, FloorSpec, LightSpec, ObjectSpec, Scene, save_scene

DEMO_CATEGORY = "chair"
DEMO_SEED = 10  # a swivel chair: wooden seat and slatted back, metal armrests and star base (train split)
DEMO_DIR = Path(__file__).resolve().parents[2] / "assets" / "demo"
DEMO_PATH = DEMO_DIR / "chair.obj"

DEMO_SCENE = Scene.single(
    object=ObjectSpec(mesh="chair.obj", rotation_deg=30.0),
    floor=FloorSpec((0.53, 0.64, 0.78)),
    light=LightSpec((1.0, 2.75, 0.5)),
    camera=CameraSpec(30.0),
    image_size=256,
)
PHOTO_VIEW = {"elevation_deg": 20.0, "rotation_deg": -40.0, "light": (-1.2, 2.9, 1.0)}
PHOTO_SPP = 64


def write_demo(path: Path = DEMO_PATH) -> Path:
    """Generate the demo chair, color it with per-part materials, and save it as OBJ with vertex colors."""
    obj = generate_object(DEMO_CATEGORY, DEMO_SEED)
    mesh, _, _ = apply_appearance(obj, "default", DEMO_SEED, "train")
    with atomic_path(path) as tmp:
        mesh.export(tmp, file_type="obj", include_normals=False, include_texture=False)
    return path


def write_demo_scene(folder: Path = DEMO_DIR) -> Path:
    from dataclasses import replace

    path = folder / "scene.json"
    save_scene(replace(DEMO_SCENE, base_dir=folder), path)
    return path


def write_demo_photo(folder: Path = DEMO_DIR) -> Path:
    """Path-trace the demo chair from PHOTO_VIEW and save the photo and its camera."""
    from dataclasses import replace

    from renderer.camera import Camera
    from renderer.capture.pose import PhotoPose
    from renderer.pathtrace.path_tracer import render_pathtraced
    from renderer.pipeline import object_mesh

    scene = replace(DEMO_SCENE, base_dir=folder)
    scene = scene.with_changes(
        object=replace(scene.object, rotation_deg=PHOTO_VIEW["rotation_deg"]),
        light=LightSpec(PHOTO_VIEW["light"]),
        camera=CameraSpec(PHOTO_VIEW["elevation_deg"]),
    )
    result = render_pathtraced(scene, object_mesh(scene), spp=PHOTO_SPP, seed=0, denoise=True)
    save_png(folder / "photo.png", result.image)
    pose = PhotoPose(Camera.from_scene(scene), PHOTO_VIEW["rotation_deg"], scene.object.translation, scene.object.scale)
    save_json(folder / "photo_camera.json", {**pose.to_dict(), "light": list(PHOTO_VIEW["light"])})
    return folder / "photo.png"


if __name__ == "__main__":
    if len(sys.argv) > 1:
        print(write_demo(Path(sys.argv[1])))
    else:
        for written in (write_demo(), write_demo_scene(), write_demo_photo()):
            print(written)
