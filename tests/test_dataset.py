"""The data generator at CI size: files, manifest, determinism, resume after a kill, shards and merge."""

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from renderer.dataset import (
    DataConfig,
    generate_dataset,
    merge_datasets,
    recolor_dataset,
    sample_test_sequence,
    sample_train_views,
)
from renderer.errors import InputError
from renderer.scene import ELEVATION_RANGE, LIGHT_Y_RANGE

TINY = DataConfig(setting="default", split="train", objects=2, views=2, size=32, spp=2, denoise=False, resolution=32)


class Killed(Exception):
    pass


def files_of(folder: Path) -> dict[str, bytes]:
    """Every data file (not the config or records) by relative path, with its bytes."""
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.parent.name in ("objects", "images", "splats")
    }


def manifest_of(folder: Path) -> dict:
    return json.loads((folder / "manifest.json").read_text())


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("ref") / "set"
    generate_dataset(out, TINY, progress=False)
    return out


def test_files_and_manifest(reference):
    manifest = manifest_of(reference)
    assert manifest["complete"] is True
    assert manifest["renderer"]["name"] == "mitsuba" and manifest["renderer"]["spp"] == 2
    assert manifest["config"]["seed"] == 0
    assert len(manifest["objects"]) == 2 and len(manifest["samples"]) == 4
    for sample in manifest["samples"]:
        for key in ("target", "splat"):
            assert (reference / sample[key]).is_file()
        scene = sample["scene"]
        assert (reference / scene["objects"][0]["voxels"]).is_file()
        assert ELEVATION_RANGE[0] <= scene["camera"]["elevation_deg"] <= ELEVATION_RANGE[1]
        assert LIGHT_Y_RANGE[0] <= scene["light"]["position"][1] <= LIGHT_Y_RANGE[1]
    rgba = np.load(reference / manifest["objects"][0]["voxels"])["rgba"]
    assert rgba.shape == (32, 32, 32, 4) and (rgba[..., 3] > 0).sum() > 100
    # no temporary files left behind
    assert not [p for p in reference.rglob("*") if ".tmp" in p.name]


def test_same_arguments_give_the_same_set(reference, tmp_path):
    generate_dataset(tmp_path / "again", TINY, progress=False)
    assert manifest_of(tmp_path / "again") == manifest_of(reference)
    assert files_of(tmp_path / "again") == files_of(reference)


def test_resume_after_a_kill_gives_the_same_set(reference, tmp_path):
    def kill(index: int) -> None:
        raise Killed

    with pytest.raises(Killed):
        generate_dataset(tmp_path / "set", TINY, progress=False, on_object_done=kill)
    assert len(list((tmp_path / "set" / "records").glob("*.json"))) == 1
    # What a kill -9 in the middle of an atomic write leaves: a temporary beside the real name.
    stale = [tmp_path / "set" / "objects" / ".o00001.npz.k3x9q2ab.tmp.npz", tmp_path / "set" / ".manifest.json.a1b2c3d4.tmp.json"]
    for path in stale:
        path.write_bytes(b"half a file")
    generate_dataset(tmp_path / "set", TINY, progress=False)
    assert not any(path.exists() for path in stale)
    assert manifest_of(tmp_path / "set") == manifest_of(reference)
    assert files_of(tmp_path / "set") == files_of(reference)


def test_shards_merge_into_the_same_set(reference, tmp_path):
    for i in range(2):
        generate_dataset(tmp_path / f"shard{i}", TINY, shard=(i, 2), progress=False)
        assert not manifest_of(tmp_path / f"shard{i}")["complete"]
    merge_datasets(tmp_path / "merged", [tmp_path / "shard0", tmp_path / "shard1"])
    assert manifest_of(tmp_path / "merged") == manifest_of(reference)
    assert files_of(tmp_path / "merged") == files_of(reference)


def test_a_folder_of_another_config_is_refused(reference):
    other = DataConfig(**{**TINY.to_dict(), "categories": ("chair",), "seed": 1})
    with pytest.raises(InputError, match="other arguments"):
        generate_dataset(reference, other, progress=False)


def test_a_set_made_by_older_color_rules_is_copied_as_generation_makes_it_now(reference, tmp_path):
    """`nvr data recolor`: the copy's voxels and splats are the ones generation makes now, with the light divided
    out and hidden voxels blended (up to the source photo's 8-bit rounding, which generation does not go through);
    its targets are links."""
    old = tmp_path / "old"
    generate_dataset(old, replace(TINY, delight=False, hidden_rule="ray"), progress=False)
    stored = json.loads((old / "config.json").read_text())
    for key in ("delight", "hidden_rule", "delight_shader"):  # as data sets made before the options hold it
        del stored["config"][key]
    (old / "config.json").write_text(json.dumps(stored))
    recolor_dataset(old, tmp_path / "new", progress=False)
    new = tmp_path / "new"
    assert manifest_of(new)["config"] == TINY.to_dict()
    assert manifest_of(new)["samples"] == manifest_of(reference)["samples"]
    largest = 0
    for obj in manifest_of(reference)["objects"]:
        before, after, made = (np.load(f / obj["voxels"])["rgba"].astype(int) for f in (old, new, reference))
        occupied = made[..., 3] > 0
        assert np.array_equal(after[..., 3], made[..., 3])
        # 8-bit steps of the photo, more where the light divided out is faint (a twentieth of white's, at least)
        difference = np.abs(after - made)[occupied]
        assert np.quantile(difference, 0.99) <= 3 and difference.mean() < 0.5
        largest = max(largest, int(difference.max()))
        assert np.abs(after - before)[occupied].mean() > 5  # the light was divided out: colors changed
    for sample in manifest_of(reference)["samples"]:
        assert (new / sample["target"]).stat().st_ino == (old / sample["target"]).stat().st_ino
        splat_new, splat_made = (np.asarray(Image.open(f / sample["splat"]), dtype=int) for f in (new, reference))
        assert np.abs(splat_new - splat_made).max() <= largest + 1  # drawn from those voxels
    with pytest.raises(InputError, match="already made by these rules"):
        recolor_dataset(new, tmp_path / "again", progress=False)
    # A set whose light an older shader divided out (its colors follow that shader's light) is recolored too.
    stored = json.loads((new / "config.json").read_text())
    stored["config"]["delight_shader"] = "camera grid"
    (new / "config.json").write_text(json.dumps(stored))
    assert manifest_of(recolor_dataset(new, tmp_path / "today", progress=False).parent)["config"] == TINY.to_dict()
    ray = recolor_dataset(new, tmp_path / "ray", progress=False, hidden_rule="ray").parent  # back to the paper's rule
    assert manifest_of(ray)["config"]["hidden_rule"] == "ray"
    # The voxel shader's light, which the shipped models' sets divided out, can still be chosen; it gives other colors.
    shader = recolor_dataset(new, tmp_path / "shader", progress=False, delight_shader="object voxels").parent
    assert manifest_of(shader)["config"]["delight_shader"] == "object voxels"
    for obj in manifest_of(reference)["objects"]:
        by_shader, unmixed = (np.load(f / obj["voxels"])["rgba"].astype(int) for f in (shader, new))
        assert np.abs(by_shader - unmixed)[unmixed[..., 3] > 0].mean() > 2


def test_a_retired_delight_shader_is_refused_before_anything_is_written(tmp_path):
    with pytest.raises(InputError, match="'camera grid' is unknown or no longer made"):
        generate_dataset(tmp_path / "d", replace(TINY, delight_shader="camera grid"), progress=False)
    assert not (tmp_path / "d").exists()


@pytest.mark.parametrize("setting", ["default", "single"])
def test_a_set_moved_to_finer_voxels_equals_one_generated_at_them(setting, tmp_path):
    """`nvr data recolor --res`: every object voxelised anew from its remade mesh and colored from its stored source
    photo, as generation at that resolution makes it (up to the photo's 8-bit rounding), with no path tracing: the
    targets are the coarse set's, linked."""
    coarse, fine = replace(TINY, setting=setting), replace(TINY, setting=setting, resolution=48)
    generate_dataset(tmp_path / "coarse", coarse, progress=False)
    generate_dataset(tmp_path / "fine", fine, progress=False)
    moved = recolor_dataset(tmp_path / "coarse", tmp_path / "moved", progress=False, resolution=48).parent
    assert manifest_of(moved)["config"] == fine.to_dict()
    largest = 0
    for obj in manifest_of(moved)["objects"]:
        after, made = (np.load(f / obj["voxels"])["rgba"].astype(int) for f in (moved, tmp_path / "fine"))
        assert after.shape == made.shape == (48, 48, 48, 4)
        assert np.array_equal(after[..., 3], made[..., 3])
        difference = np.abs(after - made)[made[..., 3] > 0]
        assert np.quantile(difference, 0.99) <= 3 and difference.mean() < 0.5  # 8-bit steps, as above
        largest = max(largest, int(difference.max()))
    for sample in manifest_of(moved)["samples"]:
        assert (moved / sample["target"]).stat().st_ino == (tmp_path / "coarse" / sample["target"]).stat().st_ino
        splat_moved, splat_made = (np.asarray(Image.open(f / sample["splat"]), dtype=int) for f in (moved, tmp_path / "fine"))
        assert np.abs(splat_moved - splat_made).max() <= largest + 1
    with pytest.raises(InputError, match="already made by these rules"):
        recolor_dataset(moved, tmp_path / "again", progress=False, resolution=48)


def test_a_set_with_larger_source_photos_equals_one_generated_with_them(tmp_path):
    """`nvr data recolor --photo-size`: every source photo path traced again at that side, as generation with
    --photo-size renders it, so the voxels, splats, photos and their cameras are generation's, byte for byte (no 8-bit
    photo between them); the targets are linked."""
    larger = replace(TINY, photo_size=48)
    generate_dataset(tmp_path / "larger", larger, progress=False)
    generate_dataset(tmp_path / "small", TINY, progress=False)
    moved = recolor_dataset(tmp_path / "small", tmp_path / "moved", progress=False, photo_size=48).parent
    assert manifest_of(moved)["config"] == larger.to_dict()
    assert files_of(moved) == files_of(tmp_path / "larger")  # camera files included
    for obj in manifest_of(moved)["objects"]:
        assert Image.open(moved / obj["source_image"]).size == (48, 48)
    for sample in manifest_of(moved)["samples"]:
        assert (moved / sample["target"]).stat().st_ino == (tmp_path / "small" / sample["target"]).stat().st_ino
    with pytest.raises(InputError, match="photos 48\\^2"):
        recolor_dataset(moved, tmp_path / "again", progress=False, photo_size=48)
    # The images' size again: the photos of the set generated without --photo-size.
    back = recolor_dataset(moved, tmp_path / "back", progress=False, photo_size=0).parent
    assert files_of(back) == files_of(tmp_path / "small")
    with pytest.raises(InputError, match="already made by these rules"):  # the images' size, said as a number
        recolor_dataset(back, tmp_path / "same", progress=False, photo_size=TINY.size)


def test_sampling_protocol_ranges():
    rng = np.random.default_rng(0)
    views = sample_train_views(rng, 500)
    elevations = [v.elevation_deg for v in views]
    assert min(elevations) >= 5 and max(elevations) <= 50 and max(elevations) - min(elevations) > 40
    assert all(-90 <= v.rotation_deg <= 90 for v in views)
    assert all(abs(t) <= 0.5 for v in views for t in v.translation)
    sequence = sample_test_sequence(rng, 8)
    assert len({v.elevation_deg for v in sequence}) == 1 and 15 <= sequence[0].elevation_deg <= 45
    steps = np.diff([v.rotation_deg for v in sequence])
    assert np.allclose(np.abs(steps), 10.0) and all(-90 <= v.rotation_deg <= 90 for v in sequence)
    lights = np.array([v.light for v in sequence])
    assert np.allclose(np.diff(lights, 2, axis=0), 0.0, atol=1e-12)  # linear interpolation


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["--setting", "fancy"], "invalid choice"),
        (["--objects", "0"], "--objects must be a whole number from 1 to 1000000, got 0"),
        (["--seed", "-1"], "--seed must be a whole number from 0 to 4294967295, got -1"),
        (["--size", "100000"], "--size must be a whole number from 16 to 2048, got 100000"),
        (["--photo-size", "8"], "--photo-size must be 0 (the images' size) or a whole number from 16 to 2048, got 8"),
        (["--workers", "0"], "--workers must be a whole number from 1 to 256, got 0"),
        (["--workers", "-2"], "--workers must be a whole number from 1 to 256, got -2"),
        (["--out", "/proc/nvr-cannot-write-here"], "cannot create the output folder"),
    ],
)
def test_bad_arguments_give_one_line_and_exit_code_2(tmp_path, arguments, message):
    base = ["--out", str(tmp_path / "x"), "--objects", "1", "--views", "1", "--size", "16", "--spp", "1"]
    command = [sys.executable, "-m", "app.cli", "data", "generate", *base, *arguments]
    result = subprocess.run(command, capture_output=True, text=True, cwd=Path(__file__).resolve().parents[1])
    assert result.returncode == 2
    assert message in result.stderr
    assert len(result.stderr.splitlines()) == 1
    assert not (tmp_path / "x").exists()  # refused before anything is written
