"""Turntables: the frames' scenes, the GIF and PNG outputs of `nvr turntable`, refusals."""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image, ImageSequence

from app.turntable import TurntableConfig, frame_scenes, render_turntable
from renderer.errors import InputError
from renderer.scene import CameraSpec, LightSpec, ObjectSpec, Scene
from renderer.voxels import save_voxels

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def scene_file(tmp_path) -> Path:
    from renderer.scene import save_scene

    rgba = np.zeros((8, 8, 8, 4), np.float32)
    rgba[1:4, 0:6, 2:6] = (0.8, 0.3, 0.2, 1.0)  # off-centre, so a turn changes the image
    save_voxels(tmp_path / "box.npz", rgba)
    scene = Scene.single(object=ObjectSpec(voxels="box.npz", rotation_deg=170.0), light=LightSpec((1.0, 2.75, 0.5)),
                  camera=CameraSpec(30.0), image_size=32, base_dir=tmp_path)
    save_scene(scene, tmp_path / "scene.json")
    return tmp_path / "scene.json"


def test_a_turn_steps_the_rotation_evenly_and_a_light_sweep_keeps_height_and_distance():
    scene = Scene.single(object=ObjectSpec(voxels="x.npz", rotation_deg=170.0), light=LightSpec((1.0, 2.75, 0.5)))
    turned = list(frame_scenes(scene, 4, "rotation"))
    assert [s.object.rotation_deg for s in turned] == pytest.approx([170.0, -100.0, -10.0, 80.0])
    swept = list(frame_scenes(scene, 4, "light"))
    assert swept[0].light.position == pytest.approx(scene.light.position)
    for s in swept:
        x, y, z = s.light.position
        assert y == 2.75 and math.hypot(x, z) == pytest.approx(math.hypot(1.0, 0.5))
    assert swept[2].light.position[0] == pytest.approx(-1.0) and swept[2].light.position[2] == pytest.approx(-0.5)


def test_frames_differ_as_the_object_turns(scene_file):
    from renderer.scene import load_scene

    images, seconds, _ = render_turntable(load_scene(scene_file), TurntableConfig(frames=4, renderer="shaded"), progress=False)
    assert len(images) == 4 == len(seconds) and images[0].shape == (32, 32, 3)
    assert np.abs(images[0].astype(float) - images[2].astype(float)).mean() > 1.0


def test_turntable_command_writes_a_gif_or_frames_and_refuses_to_overwrite(scene_file, tmp_path):
    run = [sys.executable, "-m", "app.cli", "turntable", str(scene_file), "--frames", "4", "--renderer", "splat"]
    made = subprocess.run([*run, "-o", str(tmp_path / "turn.gif")], capture_output=True, text=True, cwd=REPO)
    assert made.returncode == 0, made.stderr
    assert "first frame" in made.stdout and "a frame" in made.stdout  # the time per frame
    with Image.open(tmp_path / "turn.gif") as gif:
        assert gif.size == (32, 32) and sum(1 for _ in ImageSequence.Iterator(gif)) == 4
    again = subprocess.run([*run, "-o", str(tmp_path / "turn.gif")], capture_output=True, text=True, cwd=REPO)
    assert again.returncode == 2 and "exists" in again.stderr
    folder = subprocess.run([*run, "--sweep", "light", "-o", str(tmp_path / "frames")], capture_output=True, text=True, cwd=REPO)
    assert folder.returncode == 0, folder.stderr
    assert sorted(p.name for p in (tmp_path / "frames").iterdir()) == [f"frame_{i:04d}.png" for i in range(4)]
    refused = subprocess.run([*run, "--frames", "0", "-o", str(tmp_path / "x.gif")], capture_output=True, text=True, cwd=REPO)
    assert refused.returncode == 2 and refused.stderr.strip() == "nvr: error: --frames must be from 1 to 3600, got 0"


def test_bad_settings_are_refused():
    with pytest.raises(InputError, match="--sweep must be one of"):
        TurntableConfig(sweep="zoom").check()
