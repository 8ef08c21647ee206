"""MagicaVoxel .vox: files laid out as MagicaVoxel writes them import with the right colors and orientation;
export and import give back the same voxels; broken files are refused in one line."""

import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from renderer.errors import InputError
from renderer.vox import default_palette, read_vox, write_vox

REPO = Path(__file__).resolve().parents[1]


def chunk(chunk_id: bytes, content: bytes, children: bytes = b"") -> bytes:
    return struct.pack("<4sii", chunk_id, len(content), len(children)) + content + children


def vox_file(models, palette=None, version=200, scene_graph=True) -> bytes:
    """A file in MagicaVoxel's own chunk order: SIZE/XYZI per model, the scene graph, layers, then RGBA."""
    body = b""
    for size, voxels in models:
        body += chunk(b"SIZE", struct.pack("<3i", *size))
        body += chunk(b"XYZI", struct.pack("<i", len(voxels)) + bytes(np.asarray(voxels, np.uint8).ravel()))
    if scene_graph:  # nodes this reader skips (their content is a dictionary, here empty)
        body += chunk(b"nTRN", struct.pack("<iiiiii", 0, 0, 1, -1, -1, 1) + struct.pack("<i", 0))
        body += chunk(b"nGRP", struct.pack("<iii", 1, 0, 0))
        body += chunk(b"LAYR", struct.pack("<iii", 0, 0, -1))
    if palette is not None:
        body += chunk(b"RGBA", bytes(np.asarray(palette, np.uint8).ravel()))
    return b"VOX " + struct.pack("<i", version) + chunk(b"MAIN", b"", body)


def test_a_magicavoxel_layout_imports_with_its_palette_and_z_up_turned_to_y_up(tmp_path):
    palette = np.zeros((256, 4), np.uint8)
    palette[0] = (200, 10, 10, 255)  # the file's first entry is color index 1
    palette[4] = (10, 10, 200, 255)  # color index 5
    # A 2 x 3 x 4 model (z up): a red voxel on the ground at the front left, a blue one at the top back right.
    voxels = [(0, 0, 0, 1), (1, 2, 3, 5)]
    path = tmp_path / "model.vox"
    path.write_bytes(vox_file([((2, 3, 4), voxels)], palette))
    rgba = read_vox(path)
    assert rgba.shape == (4, 4, 4, 4) and rgba[..., 3].sum() == 2
    # (x, y, z) -> (x + (4 - 2) // 2, z, (3 - 1 - y) + (4 - 3) // 2): z becomes height, y turns to -z
    assert np.allclose(rgba[1, 0, 2], [200 / 255, 10 / 255, 10 / 255, 1.0])
    assert np.allclose(rgba[2, 3, 0], [10 / 255, 10 / 255, 200 / 255, 1.0])


def test_without_a_palette_the_default_one_colors_the_voxels(tmp_path):
    palette = default_palette()
    assert len(palette) == 256 and tuple(palette[1]) == (255, 255, 255) and tuple(palette[2]) == (255, 255, 204)
    assert tuple(palette[216]) == (0xEE, 0, 0) and tuple(palette[255]) == (0x11, 0x11, 0x11)
    path = tmp_path / "plain.vox"
    path.write_bytes(vox_file([((4, 4, 4), [(1, 1, 1, 216)])], palette=None, version=150, scene_graph=False))
    assert np.allclose(read_vox(path)[1, 1, 2, :3], np.array([0xEE, 0, 0]) / 255)


def test_the_largest_model_is_taken_unless_one_is_chosen(tmp_path):
    path = tmp_path / "two.vox"
    small, large = ((4, 4, 4), [(0, 0, 0, 1)]), ((8, 8, 8), [(0, 0, 0, 1), (1, 0, 0, 1), (2, 0, 0, 1)])
    path.write_bytes(vox_file([small, large], np.full((256, 4), 255, np.uint8)))
    assert read_vox(path).shape[0] == 8 and read_vox(path, model=0).shape[0] == 4
    with pytest.raises(InputError, match="has 2 models"):
        read_vox(path, model=2)


def test_export_then_import_gives_back_the_voxels(tmp_path):
    rng = np.random.default_rng(0)
    rgba = np.zeros((12, 12, 12, 4), np.float32)
    occupied = rng.random((12, 12, 12)) < 0.3
    colors = rng.integers(0, 256, (40, 3)) / 255.0  # 40 colors: exact
    rgba[occupied, :3] = colors[rng.integers(0, 40, int(occupied.sum()))]
    rgba[occupied, 3] = 1.0
    assert write_vox(tmp_path / "out.vox", rgba) <= 40
    back = read_vox(tmp_path / "out.vox")
    np.testing.assert_allclose(back, rgba, atol=0.5 / 255)


def test_more_than_255_colors_are_reduced_to_255_close_ones(tmp_path):
    rng = np.random.default_rng(1)
    rgba = np.ones((16, 16, 16, 4), np.float32)
    rgba[..., :3] = rng.random((16, 16, 16, 3))  # 4096 colors
    assert write_vox(tmp_path / "many.vox", rgba) == 255
    back = read_vox(tmp_path / "many.vox")
    assert (back[..., 3] == 1).all()
    assert np.abs(back[..., :3] - rgba[..., :3]).mean() < 0.06  # median cut of random colors: about 0.04


@pytest.mark.parametrize(("data", "message"), [
    (b"not a vox file at all", "not a MagicaVoxel file"),
    (b"VOX " + struct.pack("<i", 999) + b"\0" * 12, "unknown .vox version 999"),
    (vox_file([((4, 4, 4), [(0, 0, 0, 1)])], None)[:-3], "file is cut"),
    (b"VOX " + struct.pack("<i", 150) + chunk(b"MAIN", b"", chunk(b"SIZE", struct.pack("<3i", 4, 4, 4))
                                                 + chunk(b"XYZI", struct.pack("<i", 10**6))), "claims 1000000 voxels"),
    (b"VOX " + struct.pack("<i", 150) + chunk(b"MAIN", b"", chunk(b"SIZE", struct.pack("<3i", 4000, 4, 4))), "not 1 to 256"),
    (b"VOX " + struct.pack("<i", 150) + struct.pack("<4sii", b"MAIN", -5, 0), "negative size"),
    (vox_file([], None), "holds no model"),
])
def test_broken_files_are_refused_in_one_line(tmp_path, data, message):
    path = tmp_path / "bad.vox"
    path.write_bytes(data)
    with pytest.raises(InputError, match=message) as refused:
        read_vox(path)
    assert "\n" not in str(refused.value) and str(path) in str(refused.value)


def test_import_vox_and_export_vox_commands(tmp_path):
    palette = np.full((256, 4), 255, np.uint8)
    palette[0] = (40, 160, 60, 255)
    (tmp_path / "m.vox").write_bytes(vox_file([((6, 6, 6), [(x, y, 0, 1) for x in range(6) for y in range(6)])], palette))
    run = [sys.executable, "-m", "app.cli"]
    made = subprocess.run([*run, "import-vox", "m.vox", "-o", "scene.json"], cwd=tmp_path, capture_output=True, text=True)
    assert made.returncode == 0, made.stderr
    out = subprocess.run([*run, "export-vox", "scene.json", "-o", "again.vox"], cwd=tmp_path, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    np.testing.assert_allclose(read_vox(tmp_path / "again.vox"), read_vox(tmp_path / "m.vox"), atol=0.5 / 255)
    again = subprocess.run([*run, "export-vox", "scene.json", "-o", "again.vox"], cwd=tmp_path, capture_output=True, text=True)
    assert again.returncode == 2 and "exists" in again.stderr  # never overwritten without --force
