"""Data sets of scenes that hold several objects (`nvr data generate --scene-objects N`): the layout, the files,
the loader's grid, shards and the refusals."""

import json
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from models.training.data import VoxelRenderSet, network_inputs
from renderer.dataset import (
    GROUP_SCALE_RANGE,
    GROUP_VIEW_X,
    GROUP_VIEW_Z,
    DataConfig,
    generate_dataset,
    merge_datasets,
    recolor_dataset,
    sample_layout,
)
from renderer.grid import ground_mask
from renderer.scene import ObjectSpec, scene_from_dict

SEVERAL = DataConfig(setting="default", split="train", objects=3, views=2, size=32, spp=2, denoise=False, resolution=32,
                     categories=("chair", "table", "stool"), scene_objects=3)


def manifest_of(folder: Path) -> dict:
    return json.loads((folder / "manifest.json").read_text())


def floor_points(spec: dict, folder: Path) -> tuple[np.ndarray, float]:
    """World (x, z) of the centres of the floor cells under an object's voxels, and the cell's half diagonal."""
    rgba = np.load(folder / spec["voxels"])["rgba"]
    n = rgba.shape[0]
    i, k = np.nonzero((rgba[..., 3] > 0.5).any(axis=1))
    x, z = (-0.5 + (i + 0.5) / n) * spec["scale"][0], (-0.5 + (k + 0.5) / n) * spec["scale"][2]
    a = math.radians(spec["rotation_deg"])  # counter-clockwise seen from above: x' = c x + s z, z' = -s x + c z
    world = np.column_stack([math.cos(a) * x + math.sin(a) * z + spec["translation"][0],
                             -math.sin(a) * x + math.cos(a) * z + spec["translation"][1]])
    return world, 0.5 * math.hypot(spec["scale"][0], spec["scale"][2]) / n


@pytest.fixture(scope="module")
def several(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("several") / "set"
    generate_dataset(out, SEVERAL, progress=False)
    return out


def test_layouts_keep_objects_apart_and_in_view():
    rng = np.random.default_rng(3)
    blank = [ObjectSpec(voxels=f"o{k}.npz", name=f"o{k}") for k in range(4)]
    for _ in range(200):
        layout = sample_layout(rng, blank)
        assert [o.name for o in layout] == ["o0", "o1", "o2", "o3"]  # the objects' own fields kept
        for i, a in enumerate(layout):
            x, z = a.translation
            assert abs(x) <= GROUP_VIEW_X and GROUP_VIEW_Z[0] <= z <= GROUP_VIEW_Z[1]
            assert max(a.scale) <= GROUP_SCALE_RANGE[1] * 1.1 + 1e-9
            for b in layout[i + 1:]:
                gap = math.dist(a.translation, b.translation)
                assert gap > 0.5 * math.hypot(a.scale[0], a.scale[2]) + 0.5 * math.hypot(b.scale[0], b.scale[2])


def test_scenes_hold_their_objects_apart(several):
    manifest = manifest_of(several)
    assert manifest["complete"] and len(manifest["samples"]) == 6
    counts = [len(s["scene"]["objects"]) for s in manifest["samples"]]
    assert max(counts) > 1  # seed 0 draws scenes of several objects
    assert len(manifest["objects"]) == sum(counts[::2])  # every object of every scene, once
    for sample in manifest["samples"]:
        objects = sample["scene"]["objects"]
        assert len({o["name"] for o in objects}) == len(objects)
        for o in objects:
            assert (several / o["voxels"]).is_file()
        for i, a in enumerate(objects):
            for b in objects[i + 1:]:  # apart, never touching: no floor cell of one meets one of the other
                (pa, ra), (pb, rb) = floor_points(a, several), floor_points(b, several)
                nearest = np.sqrt(((pa[:, None, :] - pb[None, :, :]) ** 2).sum(-1)).min()
                assert nearest > ra + rb
    for obj in manifest["objects"]:
        for key in ("voxels", "source_image", "source_camera"):
            assert (several / obj[key]).is_file()


def test_the_loaders_grid_holds_every_object(several):
    """Objects apart fill disjoint grid cells: the scene's grid holds as many object cells as its objects alone."""
    data = VoxelRenderSet([several], grid_size=64)
    index = next(i for i in range(len(data)) if len(data.scene(i).objects) > 1)
    scene = data.scene(index)
    floor = ground_mask(scene.camera.elevation_deg, 64)

    def object_cells(voxels) -> int:
        return int(((voxels[3].numpy() > 0.5) & ~floor).sum())

    together = object_cells(data[index]["voxels"])
    alone = []
    for k, rgba in enumerate(data.object_voxels(index)):
        one = replace(scene, objects=(scene.objects[k],))
        alone.append(object_cells(network_inputs(one, [rgba], scene.floor.color, 64)[0]))
    assert min(alone) > 0 and together == sum(alone)


def test_a_test_split_turns_each_object_in_place(tmp_path):
    config = replace(SEVERAL, split="test", objects=2, views=3, categories=("novel",))
    out = generate_dataset(tmp_path / "test", config, progress=False).parent
    samples = [s for s in manifest_of(out)["samples"] if len(s["scene"]["objects"]) > 1]
    assert samples
    first = [s for s in samples if s["object"] == samples[0]["object"]]
    assert len(first) == 3
    for a, b in zip(first, first[1:]):
        for oa, ob in zip(a["scene"]["objects"], b["scene"]["objects"]):
            assert oa["translation"] == ob["translation"] and oa["scale"] == ob["scale"]
            turn = (ob["rotation_deg"] - oa["rotation_deg"] + 180.0) % 360.0 - 180.0
            assert abs(abs(turn) - 10.0) < 1e-6
    lights = np.array([s["scene"]["light"]["position"] for s in first])
    assert np.allclose(np.diff(lights, 2, axis=0), 0.0, atol=1e-12)
    assert {s["scene"]["camera"]["elevation_deg"] for s in first} == {first[0]["scene"]["camera"]["elevation_deg"]}


def test_shards_of_several_objects_merge_into_the_same_set(several, tmp_path):
    for i in range(2):
        generate_dataset(tmp_path / f"shard{i}", SEVERAL, shard=(i, 2), progress=False)
    merged = merge_datasets(tmp_path / "merged", [tmp_path / "shard0", tmp_path / "shard1"]).parent
    assert manifest_of(merged) == manifest_of(several)
    for obj in manifest_of(several)["objects"]:
        assert (merged / obj["voxels"]).read_bytes() == (several / obj["voxels"]).read_bytes()


def test_recoloring_a_set_of_several_objects_recolors_every_object(several, tmp_path):
    """`nvr data recolor` on scenes of several objects: every object's voxels are those generation makes by the new
    rule (up to the 8-bit rounding of the stored source photos), and each splat shows all of them."""
    made = tmp_path / "made"
    generate_dataset(made, replace(SEVERAL, hidden_rule="ray"), progress=False)
    recolored = recolor_dataset(several, tmp_path / "recolored", progress=False, hidden_rule="ray").parent
    assert manifest_of(recolored)["config"] == manifest_of(made)["config"]
    objects = manifest_of(made)["objects"]
    assert any(obj.get("part") for obj in objects)  # companions among them
    for obj in objects:
        after, expected, before = (np.load(f / obj["voxels"])["rgba"].astype(int) for f in (recolored, made, several))
        occupied = expected[..., 3] > 0
        assert np.array_equal(after[..., 3], expected[..., 3])
        assert np.quantile(np.abs(after - expected)[occupied], 0.99) <= 3
        assert np.abs(after - before)[occupied].mean() > 1  # the rule changed the colors
    for sample in manifest_of(made)["samples"]:
        assert (recolored / sample["target"]).stat().st_ino == (several / sample["target"]).stat().st_ino
        splat_after, splat_expected = (np.asarray(Image.open(f / sample["splat"]), dtype=int)
                                       for f in (recolored, made))
        assert np.abs(splat_after - splat_expected).mean() < 2


def test_every_scene_reads_back(several):
    for sample in manifest_of(several)["samples"]:
        scene = scene_from_dict(sample["scene"])
        assert 1 <= len(scene.objects) <= SEVERAL.scene_objects


@pytest.mark.parametrize("value", ["0", "5"])
def test_too_many_objects_a_scene_is_one_line_and_exit_2(tmp_path, value):
    command = [sys.executable, "-m", "app.cli", "data", "generate", "--out", str(tmp_path / "x"), "--objects", "1",
               "--scene-objects", value]
    result = subprocess.run(command, capture_output=True, text=True, cwd=Path(__file__).resolve().parents[1])
    assert result.returncode == 2
    assert result.stderr.strip() == f"nvr: error: --scene-objects must be a whole number from 1 to 4, got {value}"
    assert not (tmp_path / "x").exists()


def test_eval_reports_the_error_by_object_count_and_in_the_others_shadows(several, tmp_path):
    from models.evaluation.evaluate import evaluate

    report = evaluate([str(several)], None, "shaded", tmp_path / "report.md", shading_grid=128).read_text()
    header = "| objects in the scene | samples | MSE (0-255) | DSSIM | perceptual | MSE in the others' shadows (pixels) |"
    assert header in report
    lines = report.splitlines()
    start = lines.index(header) + 2
    rows = [line.strip("|").split("|") for line in lines[start:] if line.startswith("| ")]
    rows = rows[:next((k for k, r in enumerate(rows) if not r[0].strip().isdigit()), len(rows))]
    counts = [len(s["scene"]["objects"]) for s in manifest_of(several)["samples"]]
    assert {int(r[0]): int(r[1]) for r in rows} == {c: counts.count(c) for c in set(counts)}
    for row in rows:
        assert float(row[2]) > 0.0
        assert row[5].strip() == "-" if int(row[0]) == 1 else row[5].strip()
