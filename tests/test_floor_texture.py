"""The textured and the round floor: the scene's fields, bad input, where the path tracer and the shader put the
image and the disk's edge, and the shader's texture against a plain floor of the same color."""

from __future__ import annotations

import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image

from renderer.camera import Camera
from renderer.errors import InputError
from renderer.floor_texture import floor_texture
from renderer.scene import (
    CameraSpec,
    FloorSpec,
    LightSpec,
    ObjectSpec,
    Scene,
    load_scene,
    replaced,
    save_scene,
    scene_from_dict,
)
from renderer.shading.shader import shade_scene
from tests.test_shading import cube

ROOT = Path(__file__).resolve().parents[1]
QUADRANTS = {(0, 0): (255, 0, 0), (0, 1): (0, 255, 0), (1, 0): (0, 0, 255), (1, 1): (255, 255, 255)}


def quadrant_texture(path: Path) -> Path:
    """A 64-pixel square: red top left, green top right, blue bottom left, white bottom right."""
    image = np.zeros((64, 64, 3), dtype=np.uint8)
    for (row, col), color in QUADRANTS.items():
        image[row * 32:(row + 1) * 32, col * 32:(col + 1) * 32] = color
    Image.fromarray(image).save(path)
    return path


def scene_on(folder: Path, texture: str | None, scale: float = 3.0, color=(0.5, 0.5, 0.5)) -> Scene:
    return Scene.single(object=ObjectSpec(voxels="cube.npz", scale=(0.3, 0.3, 0.3), translation=(2.0, -2.0)),
                 floor=FloorSpec(color, texture, scale), light=LightSpec((0.0, 2.75, 0.0)), camera=CameraSpec(60.0),
                 image_size=96, base_dir=folder)


def test_the_floors_texture_round_trips_relative_to_the_scene_and_old_floors_save_as_before(tmp_path):
    quadrant_texture(tmp_path / "tiles.png")
    scene = scene_on(tmp_path, "tiles.png", 0.75)
    (tmp_path / "sub").mkdir()
    save_scene(scene, tmp_path / "sub" / "scene.json")
    data = json.loads((tmp_path / "sub" / "scene.json").read_text())
    assert data["floor"] == {"color": [0.5, 0.5, 0.5], "texture": "../tiles.png", "texture_scale": 0.75}
    loaded = load_scene(tmp_path / "sub" / "scene.json")
    assert loaded.floor_texture_path().resolve() == (tmp_path / "tiles.png").resolve()
    assert loaded.floor.texture_scale == 0.75
    save_scene(scene_on(tmp_path, None), tmp_path / "plain.json")
    assert json.loads((tmp_path / "plain.json").read_text())["floor"] == {"color": [0.5, 0.5, 0.5]}
    disk = scene_on(tmp_path, None)
    save_scene(replace(disk, floor=replace(disk.floor, shape="disk")), tmp_path / "disk.json")
    assert load_scene(tmp_path / "disk.json").floor.shape == "disk"


@pytest.mark.parametrize(("floor", "fragment"), [
    ({"color": [0.5, 0.5, 0.5], "texture_scale": 0.0}, "floor.texture_scale: must be in (0, 100]"),
    ({"color": [0.5, 0.5, 0.5], "texture_scale": -2}, "floor.texture_scale: must be in (0, 100]"),
    ({"color": [0.5, 0.5, 0.5], "texture_scale": "big"}, "floor.texture_scale: must be a number"),
    ({"color": [0.5, 0.5, 0.5], "texture": 3}, "floor.texture: must be a string"),
    ({"color": [0.5, 0.5, 0.5], "textur": "a.png"}, 'floor.textur: unknown key (did you mean "texture"?)'),
    ({"color": [0.5, 0.5, 0.5], "shape": "round"}, 'floor.shape: must be "square" or "disk"'),
])
def test_bad_floor_values_are_refused_naming_the_field(floor, fragment):
    data = json.loads((ROOT / "assets" / "demo" / "scene.json").read_text())
    data["floor"] = floor
    with pytest.raises(InputError, match=None) as caught:
        scene_from_dict(data, ROOT / "assets" / "demo" / "scene.json")
    assert fragment in str(caught.value)


@pytest.mark.parametrize(("name", "content", "fragment"), [
    ("tiles.png", b"this is not an image", "not a readable image"),
    ("tiles.hdr", b"#?RADIANCE\n", "a floor texture must be a .png or .jpg image"),
    ("missing.png", None, "floor texture not found"),
])
def test_a_texture_that_is_not_an_image_is_refused_in_one_line_with_exit_2_and_nothing_written(
        tmp_path, name, content, fragment):
    if content is not None:
        (tmp_path / name).write_bytes(content)
    data = json.loads((ROOT / "assets" / "demo" / "scene.json").read_text())
    data["objects"][0]["mesh"] = str(ROOT / "assets" / "demo" / "chair.obj")
    data["floor"] = {"color": [0.5, 0.5, 0.5], "texture": name}
    (tmp_path / "scene.json").write_text(json.dumps(data))
    out = tmp_path / "render.png"
    result = subprocess.run([sys.executable, "-m", "app.cli", "render", str(tmp_path / "scene.json"), "-o", str(out),
                             "--renderer", "shaded"], capture_output=True, text=True, cwd=ROOT)
    assert result.returncode == 2, result.stderr
    lines = [line for line in result.stderr.splitlines() if not line.startswith("warning:")]
    assert len(lines) == 1 and fragment in lines[0] and "Traceback" not in result.stderr
    assert not out.exists()


def test_the_shader_puts_the_texture_where_the_path_tracer_does(tmp_path):
    """Seen from above, the floor under each quadrant's centre shows that quadrant's color in the path tracer
    (Mitsuba's rectangle and bitmap, the reference) and in the shader alike."""
    from renderer.pathtrace.path_tracer import render_pathtraced
    from renderer.voxels import save_voxels

    quadrant_texture(tmp_path / "tiles.png")
    save_voxels(tmp_path / "cube.npz", cube())
    scene = scene_on(tmp_path, "tiles.png")
    far = trimesh.creation.box(extents=(0.01, 0.01, 0.01))
    far.apply_translation((0.0, 50.0, 0.0))  # no object in the path tracer's view
    traced = render_pathtraced(scene, far, 96, spp=16).image
    shaded = shade_scene(scene, cube(), scene.floor.color, 96).image
    camera = Camera(60.0, width=96, height=96)
    # Quadrant centres: a repeat of 3 units starts at x = -10 and z = +10 (rows run towards -z).
    for (row, col), color in QUADRANTS.items():
        point = np.array([[-10.0 + 3.0 * (3 + 0.25 + 0.5 * col), 0.0, 10.0 - 3.0 * (3 + 0.25 + 0.5 * row)]])
        u, v, _ = camera.project(point)
        expected = np.asarray(color, dtype=float) / 255.0
        for image in (traced, shaded):
            seen = image[int(v[0]), int(u[0])]
            assert np.abs(seen / max(seen.max(), 1e-6) - expected).max() < 0.4, (row, col, seen)


def test_a_texture_of_one_color_shades_as_a_plain_floor_of_that_color(tmp_path):
    from renderer.voxels import save_voxels

    save_voxels(tmp_path / "cube.npz", cube())
    Image.fromarray(np.full((8, 8, 3), (150, 90, 60), dtype=np.uint8)).save(tmp_path / "flat.png")
    textured = scene_on(tmp_path, "flat.png")
    plain = replace(textured, floor=FloorSpec((150 / 255, 90 / 255, 60 / 255)), light=replace(textured.light))
    # The plain floor takes the same (environment) path: the textured floor's only difference is the texture.
    plain = replaced(plain, object=replace(plain.object, material=replace(plain.object.material, specular=1e-6)))
    a = shade_scene(textured, cube(), textured.floor.color, 96).image
    b = shade_scene(plain, cube(), plain.floor.color, 96).image
    assert np.abs(a - b).max() < 2.0 / 255
    assert floor_texture(textured).mean_srgb == pytest.approx((150 / 255, 90 / 255, 60 / 255), abs=1e-3)


def test_a_disk_floor_ends_where_its_radius_says_in_both_renderers_and_keeps_the_squares_texture(tmp_path):
    """Points a little inside the disk's rim show the floor; a little outside, the ambient light behind it (the
    scene's background); inside, the textured disk shows what the textured square shows there."""
    from renderer.pathtrace.path_tracer import render_pathtraced
    from renderer.scene import AMBIENT_RADIANCE, FLOOR_DISK_RADIUS
    from renderer.voxels import save_voxels

    quadrant_texture(tmp_path / "tiles.png")
    save_voxels(tmp_path / "cube.npz", cube())
    square = replace(scene_on(tmp_path, "tiles.png"), camera=CameraSpec(30.0))
    disk = replace(square, floor=replace(square.floor, shape="disk"))
    far = trimesh.creation.box(extents=(0.01, 0.01, 0.01))
    far.apply_translation((0.0, 50.0, 0.0))
    traced = render_pathtraced(disk, far, 96, spp=16).image
    shaded = shade_scene(disk, cube(), disk.floor.color, 96).image
    on_square = shade_scene(square, cube(), square.floor.color, 96).image
    camera = Camera(30.0, width=96, height=96)
    background = ((AMBIENT_RADIANCE ** (1 / 2.4)) * 1.055 - 0.055)  # the ambient radiance in sRGB
    for angle in (-0.6, 0.0, 0.6):  # along the far rim, which the camera sees
        direction = np.array([np.sin(angle), 0.0, -np.cos(angle)])
        for radius, inside in ((FLOOR_DISK_RADIUS * 0.93, True), (FLOOR_DISK_RADIUS * 1.07, False)):
            u, v, _ = camera.project((radius * direction)[None])
            pixel = int(v[0]), int(u[0])
            for image in (traced, shaded):
                off_background = np.abs(image[pixel] - background).max()
                assert (off_background > 0.05) == inside, (angle, radius, image[pixel])
            if inside:
                np.testing.assert_allclose(shaded[pixel], on_square[pixel], atol=0.02)


def test_a_fine_texture_far_away_shades_as_its_mean_color_not_moire(tmp_path):
    """One-texel checks a hundredth of a unit wide: every pixel's footprint covers many, so the shader's floor (mip
    levels by footprint) must look like a plain floor of the checks' mean, as the path tracer's samples average it."""
    from renderer.voxels import save_voxels

    save_voxels(tmp_path / "cube.npz", cube())
    checks = (np.indices((64, 64)).sum(axis=0) % 2 * 255).astype(np.uint8)
    Image.fromarray(np.repeat(checks[..., None], 3, axis=2)).save(tmp_path / "checks.png")
    textured = replace(scene_on(tmp_path, "checks.png", 0.64), camera=CameraSpec(30.0))
    mean = floor_texture(textured).mean_srgb
    plain = replaced(textured, floor=FloorSpec(mean, shape="square"),
                     object=replace(textured.object, material=replace(textured.object.material, specular=1e-6)))
    a = shade_scene(textured, cube(), textured.floor.color, 96)
    b = shade_scene(plain, cube(), plain.floor.color, 96)
    floor = b.coverage == 0.0
    assert np.abs(a.image - b.image)[floor].mean() < 0.01 and np.abs(a.image - b.image)[floor].max() < 0.08


def test_textured_grounds_in_a_data_set_repeat_without_seams_and_come_from_the_splits_families(tmp_path):
    from renderer.dataset import DataConfig, generate_dataset, sample_ground
    from renderer.objects.textures import FAMILIES

    tiles = [sample_ground(np.random.default_rng(seed), "test") for seed in range(6)]
    for tile, scale, shape, family in tiles:
        assert tile.shape == (512, 512, 3) and shape in ("square", "disk") and 1.0 <= scale <= 3.0
        assert family in FAMILIES["test"] and family not in FAMILIES["train"]
        # Mirrored: the tile's last row and column meet its first where it repeats.
        assert np.array_equal(tile[0], tile[-1]) and np.array_equal(tile[:, 0], tile[:, -1])
    assert {shape for _, _, shape, _ in tiles} == {"square", "disk"}
    config = DataConfig(setting="single", split="test", objects=1, views=3, size=32, spp=2, denoise=False,
                        resolution=32, lighting="environment", grounds="textured", seed=2)
    generate_dataset(tmp_path / "set", config, progress=False)
    manifest = json.loads((tmp_path / "set" / "manifest.json").read_text())
    for sample in manifest["samples"]:
        scene = scene_from_dict(sample["scene"], tmp_path / "set" / "manifest.json")
        assert scene.floor_texture_path().is_file() and floor_texture(scene).albedo.shape == (512, 512, 3)
    assert manifest["config"]["grounds"] == "textured"


def test_mixed_grounds_put_some_views_on_a_plain_floor_and_some_on_a_texture(tmp_path):
    from renderer.dataset import DataConfig, generate_dataset

    config = DataConfig(setting="single", split="train", objects=1, views=8, size=32, spp=2, denoise=False,
                        resolution=32, lighting="mixed", grounds="mixed", seed=3)
    generate_dataset(tmp_path / "set", config, progress=False)
    manifest = json.loads((tmp_path / "set" / "manifest.json").read_text())
    textured = [scene_from_dict(s["scene"], tmp_path / "set" / "manifest.json").floor.texture is not None
                for s in manifest["samples"]]
    assert 0 < sum(textured) < len(textured)


def test_info_says_what_the_floor_is_and_that_no_network_corrects_a_textured_one(tmp_path):
    quadrant_texture(tmp_path / "tiles.png")
    data = json.loads((ROOT / "assets" / "demo" / "scene.json").read_text())
    data["objects"][0]["mesh"] = str(ROOT / "assets" / "demo" / "chair.obj")
    data["floor"] = {"color": [0.5, 0.5, 0.5], "texture": "tiles.png", "texture_scale": 0.5, "shape": "disk"}
    (tmp_path / "scene.json").write_text(json.dumps(data))
    info = subprocess.run([sys.executable, "-m", "app.cli", "info", str(tmp_path / "scene.json")], capture_output=True,
                          text=True, cwd=ROOT)
    assert info.returncode == 0, info.stderr
    floor = next(line for line in info.stdout.splitlines() if line.startswith("floor"))
    assert "tiles.png repeated every 0.5 units; disk" in floor
    assert "not trained for environments, gloss or floor textures" in info.stdout
