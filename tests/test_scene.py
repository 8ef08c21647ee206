"""Scene files: parsing, validation of impossible values, training-range warnings, round trips."""

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from renderer.dataset import sample_layout
from renderer.errors import InputError
from renderer.scene import LightSpec, ObjectSpec, PaintOp, load_scene, range_warnings, save_scene, scene_from_dict

EXAMPLE = {
    "version": 1,
    "object": {"mesh": "chair.obj", "up": "y", "resolution": 100, "color": [0.8, 0.2, 0.2],
               "translation": [0.0, 0.0], "rotation_deg": 30.0, "scale": [1.0, 1.0, 1.0]},
    "floor": {"color": [0.53, 0.64, 0.78]},
    "light": {"position": [1.0, 2.75, 0.5]},
    "camera": {"elevation_deg": 30.0},
    "image_size": 256,
}


def modified(path: str, value):
    data = json.loads(json.dumps(EXAMPLE))
    *parents, last = path.split(".")
    node = data
    for key in parents:
        node = node[key]
    node[last] = value
    return data


def test_example_from_the_contract_parses_with_its_values():
    scene = scene_from_dict(EXAMPLE)
    assert scene.object.mesh == "chair.obj"
    assert scene.object.color == (0.8, 0.2, 0.2)
    assert scene.object.rotation_deg == 30.0
    assert scene.light.position == (1.0, 2.75, 0.5)
    assert scene.camera.elevation_deg == 30.0
    assert range_warnings(scene) == []


def test_round_trip_through_a_file_keeps_everything(tmp_path):
    (tmp_path / "chair.obj").write_text("")
    scene = scene_from_dict(EXAMPLE, tmp_path / "a.json")
    scene = scene.with_changes(paint=(PaintOp("region", (0.1, 0.2, 0.3), (1, 2, 3), 0.05),
                                      PaintOp("region", (0.3, 0.2, 0.1), (3, 2, 1), 0.1, "perceptual")))
    save_scene(scene, tmp_path / "b.json")
    again = load_scene(tmp_path / "b.json")
    assert again == scene
    # A stroke comparing RGB (the only kind before the perceptual fill) is written as it was, without "similarity".
    written = json.loads((tmp_path / "b.json").read_text())["objects"][0]["paint"]
    assert "similarity" not in written[0] and written[1]["similarity"] == "perceptual"
    assert again.mesh_path().resolve() == (tmp_path / "chair.obj").resolve()


def test_saving_elsewhere_rewrites_relative_paths(tmp_path):
    (tmp_path / "sub").mkdir()
    scene = scene_from_dict(EXAMPLE, tmp_path / "a.json")
    save_scene(scene, tmp_path / "sub" / "b.json")
    assert json.loads((tmp_path / "sub" / "b.json").read_text())["objects"][0]["mesh"] == "../chair.obj"


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        ("object.scale", [1.0, 0.0, 1.0], "object.scale: must be positive"),
        ("object.scale", [1.0, -2.0, 1.0], "object.scale: must be positive"),
        ("light.position", [0.0, 0.0, 0.0], "above the floor"),
        ("light.position", [0.0, -1.0, 0.0], "above the floor"),
        ("image_size", 8, "image_size: must be in [16"),
        ("image_size", "big", "image_size: must be an integer"),
        ("camera.elevation_deg", 90.0, "camera.elevation_deg"),
        ("object.rotation_deg", "x", "object.rotation_deg: must be a number"),
        ("object.up", "x", "object.up"),
        ("object.color", [2.0, 0.0, 0.0], "object.color"),
        ("object.translation", [0.0], "object.translation: must be a list of 2"),
        ("version", 3, "unsupported scene version"),
        ("paint", [{"target": "region", "color": [0, 0, 0], "seed": [1, 1, 1], "similarity": "hsv"}],
         "paint[0].similarity: must be one of rgb, perceptual"),
    ],
)
def test_impossible_values_are_rejected_with_the_key_named(path, value, message):
    with pytest.raises(InputError) as err:
        scene_from_dict(modified(path, value), "s.json")
    assert message in str(err.value)
    assert str(err.value).startswith("s.json: ")
    assert "\n" not in str(err.value)


def test_nan_and_infinity_are_rejected():
    for bad in (math.nan, math.inf):
        with pytest.raises(InputError):
            scene_from_dict(modified("object.rotation_deg", bad))
    scene = scene_from_dict(EXAMPLE)
    with pytest.raises(InputError):
        scene.with_changes(light=LightSpec((0.0, math.nan, 0.0)))


def test_values_outside_the_training_range_warn_and_name_the_range():
    scene = scene_from_dict(modified("camera.elevation_deg", 70.0))
    assert range_warnings(scene) == ["camera.elevation_deg = 70 is outside the training range [5, 50]"]
    scene = scene_from_dict(modified("light.position", [2.0, 4.0, 0.0]))
    assert len(range_warnings(scene)) == 2


def test_layouts_of_several_objects_as_trained_warn_of_nothing():
    # The shipped network trained on the data generator's layouts too: their sizes and places are in range.
    rng = np.random.default_rng(5)
    blank = [ObjectSpec(mesh="chair.obj", name=f"o{k}") for k in range(2)]
    for _ in range(50):
        scene = scene_from_dict(EXAMPLE).with_changes(objects=sample_layout(rng, blank))
        assert range_warnings(scene) == []
    # Smaller than any layout's (0.45 less 10 % per axis) or beyond its floor (|x| <= 0.9, -0.9 <= z <= 0.5) warns.
    chair = scene_from_dict(EXAMPLE).objects[0]
    scene = scene_from_dict(EXAMPLE).with_changes(objects=(
        chair, replace(chair, name="small", scale=(0.4, 0.6, 0.6), translation=(0.9, -0.95))))
    assert range_warnings(scene) == ["objects[1].translation.z = -0.95 is outside the training range [-0.9, 0.5]",
                                     "objects[1].scale.x = 0.4 is outside the training range [0.405, 1.25]"]


def test_broken_json_names_file_and_line(tmp_path):
    path = tmp_path / "broken.json"
    path.write_text('{"version": 1,\n "object": }')
    with pytest.raises(InputError) as err:
        load_scene(path)
    assert "broken.json" in str(err.value) and "line 2" in str(err.value)


def test_missing_scene_file_is_reported():
    with pytest.raises(InputError, match="file not found"):
        load_scene("/nonexistent/scene.json")
