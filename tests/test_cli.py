"""The `nvr` command line end to end: outputs, and one-line errors with exit code 2 on bad input."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "assets" / "demo"


def nvr(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "app.cli", *map(str, args)], capture_output=True, text=True, cwd=cwd)


def assert_user_error(result: subprocess.CompletedProcess, *fragments: str) -> None:
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("nvr: error: "), result.stderr
    for fragment in fragments:
        assert fragment in lines[0]


@pytest.fixture()
def scene_dir(tmp_path) -> Path:
    for name in ("scene.json", "chair.obj"):
        shutil.copy(DEMO / name, tmp_path / name)
    return tmp_path


def test_render_splat_writes_the_scene_size(scene_dir):
    result = nvr("render", scene_dir / "scene.json", "-o", scene_dir / "out.png", "--size", "64", "--renderer", "splat")
    assert result.returncode == 0, result.stderr
    image = np.asarray(Image.open(scene_dir / "out.png"))
    assert image.shape == (64, 64, 3)
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 3  # floor, background and the chair's colors


def test_render_at_the_shaders_fast_quality_says_so_and_differs_from_full(scene_dir):
    images = {}
    for quality in ("full", "fast"):
        out = scene_dir / f"{quality}.png"
        result = nvr("render", scene_dir / "scene.json", "-o", out, "--size", "64", "--renderer", "shaded",
                     "--quality", quality)
        assert result.returncode == 0, result.stderr
        assert ("fast shading" in result.stdout) == (quality == "fast")
        images[quality] = np.asarray(Image.open(out)).astype(int)
    difference = np.abs(images["fast"] - images["full"])
    assert 0 < difference.max() and difference.mean() < 3.0  # another sampling of the same shading


def test_existing_output_is_kept_without_force(scene_dir):
    (scene_dir / "out.png").write_bytes(b"precious")
    assert_user_error(nvr("render", scene_dir / "scene.json", "-o", scene_dir / "out.png"), "--force")
    assert (scene_dir / "out.png").read_bytes() == b"precious"


def test_a_network_that_draws_the_image_at_another_size_says_which_size_to_ask_for(scene_dir):
    data = json.loads((scene_dir / "scene.json").read_text())
    data["image_size"] = 96
    (scene_dir / "scene.json").write_text(json.dumps(data))
    out = scene_dir / "out.png"
    assert_user_error(nvr("render", scene_dir / "scene.json", "-o", out, "--renderer", "nvr"),
                      "renders 256x256", "the scene's image_size 96", "--size 256")
    assert_user_error(nvr("render", scene_dir / "scene.json", "-o", out, "--renderer", "nvr+", "--model",
                          ROOT / "assets/models/nvrplus_compact.safetensors", "--size", "128"),
                      "--size 128 is not supported")
    assert not out.exists()


def test_the_shipped_nvr_plus_renders_any_size_from_the_shaded_image_at_that_size(scene_dir):
    """It corrects the voxel shader's image: at 96 px the shader's 96 px image, corrected at the network's 256 px."""
    out = scene_dir / "out.png"
    result = nvr("render", scene_dir / "scene.json", "-o", out, "--renderer", "nvr+", "--size", "96")
    assert result.returncode == 0, result.stderr
    assert "corrected at 256 px" in result.stdout
    shaded = scene_dir / "shaded.png"
    assert nvr("render", scene_dir / "scene.json", "-o", shaded, "--renderer", "shaded", "--size", "96").returncode == 0
    image, shader = (np.asarray(Image.open(path)).astype(float) for path in (out, shaded))
    assert image.shape == (96, 96, 3)
    assert 1.0 < np.mean((image - shader) ** 2) < 400.0  # corrected, and still the same picture


def test_voxelize_and_info(scene_dir):
    result = nvr("voxelize", scene_dir / "chair.obj", "-o", scene_dir / "chair.npz", "--res", "24")
    assert result.returncode == 0, result.stderr
    rgba = np.load(scene_dir / "chair.npz")["rgba"]
    assert rgba.shape == (24, 24, 24, 4) and rgba[..., 3].any()
    info = nvr("info", scene_dir / "scene.json")
    assert info.returncode == 0 and "all values inside the training ranges" in info.stdout
    data = json.loads((scene_dir / "scene.json").read_text())
    data["camera"]["elevation_deg"] = 70.0
    (scene_dir / "scene.json").write_text(json.dumps(data))
    info = nvr("info", scene_dir / "scene.json")
    assert "camera.elevation_deg = 70 is outside the training range [5, 50]" in info.stdout


@pytest.mark.parametrize(
    ("change", "fragments"),
    [
        (lambda d, folder: d["objects"][0].update(mesh="missing.obj"), ("missing.obj", "file not found")),
        (lambda d, folder: (folder / "bad.obj").write_text("v 1 2\nf 1 2 9\nrubbish"), ("bad.obj",)),
        (lambda d, folder: (folder / "empty.obj").write_text("# nothing\n"), ("empty.obj",)),
        (lambda d, folder: d["objects"][0].update(scale=[1, 0, 1]), ("objects[0].scale", "positive")),
        (lambda d, folder: d.update(image_size="big"), ("image_size", "integer")),
        (lambda d, folder: d["light"].update(position=[0, -1, 0]), ("above the floor",)),
        (lambda d, folder: d["objects"][0].update(paint=[{"target": "region", "seed": [0, 0, 0], "color": [1, 0, 0]}]),
         ("scene.json: paint seed [0, 0, 0] is on an empty voxel",)),
    ],
)
def test_bad_scenes_give_one_line_and_exit_2(scene_dir, change, fragments):
    data = json.loads((scene_dir / "scene.json").read_text())
    change(data, scene_dir)
    for name in ("bad.obj", "empty.obj"):
        if (scene_dir / name).exists():
            data["objects"][0]["mesh"] = name
    (scene_dir / "scene.json").write_text(json.dumps(data))
    assert_user_error(nvr("render", scene_dir / "scene.json", "-o", scene_dir / "out.png"), *fragments)
    assert not (scene_dir / "out.png").exists()


def test_broken_json_names_the_file(scene_dir):
    (scene_dir / "scene.json").write_text('{"version": 1, "object": {')
    assert_user_error(nvr("info", scene_dir / "scene.json"), "scene.json", "broken JSON")


def test_unreadable_mesh_for_voxelize(tmp_path):
    (tmp_path / "x.stl").write_bytes(b"\x00\x01garbage")
    assert_user_error(nvr("voxelize", tmp_path / "x.stl", "-o", tmp_path / "x.npz"), "x.stl")
    assert not (tmp_path / "x.npz").exists()


def test_under_a_sky_the_render_warns_only_when_its_network_does_not_read_the_environment(scene_dir):
    """The shipped NVR+ shows the shader's image for a sky-lit scene and says so; a network that reads the
    environment renders it without the warning, and its image is not the shader's."""
    import torch

    from models.networks.checkpoint import save_model
    from models.networks.config import EnvironmentRefinerConfig
    from models.networks.nvr import build_model

    data = json.loads((scene_dir / "scene.json").read_text())
    data["environment"] = {"sky": {"sun_elevation_deg": 30, "sun_azimuth_deg": 100}}
    data["light"]["enabled"] = False
    (scene_dir / "scene.json").write_text(json.dumps(data))
    torch.manual_seed(0)
    model = build_model("nvr_plus", EnvironmentRefinerConfig()).eval()
    for parameter in (*model.rerender.to_rgb.parameters(), *model.light_decoder.environment.mlp[-1].parameters()):
        parameter.data.normal_(0.0, 0.05)  # a network that has learned something
    save_model(scene_dir / "environment.safetensors", model, model.config)
    shipped, reading = scene_dir / "shipped.png", scene_dir / "reading.png"
    result = nvr("render", scene_dir / "scene.json", "-o", shipped, "--renderer", "nvr+", "--size", "64")
    assert result.returncode == 0, result.stderr
    assert "not trained for environment light" in result.stderr
    result = nvr("render", scene_dir / "scene.json", "-o", reading, "--renderer", "nvr+", "--size", "64",
                 "--model", scene_dir / "environment.safetensors")
    assert result.returncode == 0, result.stderr
    assert "trained" not in result.stderr
    assert np.abs(np.asarray(Image.open(reading)).astype(int) - np.asarray(Image.open(shipped)).astype(int)).max() > 3
