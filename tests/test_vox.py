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


def _node(chunk_id: bytes, *ints_and_dicts) -> bytes:
    """A scene graph chunk: ints as they are, dicts ({key: value}) as .vox DICTs."""
    out = b""
    for item in ints_and_dicts:
        if isinstance(item, dict):
            out += struct.pack("<i", len(item))
            for key, value in item.items():
                for text in (key, value):
                    out += struct.pack("<i", len(text)) + text.encode()
        else:
            out += struct.pack("<i", item)
    return chunk(chunk_id, out)


def test_a_files_models_become_objects_where_its_scene_graph_puts_them(tmp_path):
    from renderer.vox import placed_objects, read_vox_scene

    palette = np.full((256, 4), 255, np.uint8)
    cube = [(x, y, z, 1) for x in range(4) for y in range(4) for z in range(4)]  # 4^3, centre at 2
    tall = [(x, y, z, 2) for x in range(2) for y in range(2) for z in range(8)]  # 2 x 2 x 8
    body = b""
    for size, voxels in (((4, 4, 4), cube), ((2, 2, 8), tall), ((4, 4, 4), cube)):
        body += chunk(b"SIZE", struct.pack("<3i", *size))
        body += chunk(b"XYZI", struct.pack("<i", len(voxels)) + bytes(np.asarray(voxels, np.uint8).ravel()))
    # root transform 0 -> group 1 -> (transform 2 -> shape 3: the cube at x -10 on the ground,
    #                                  transform 4 -> shape 5: the pillar at x +10, y 6, turned a quarter about z,
    #                                  standing 3 voxels up; transform 6 hidden -> shape 7)
    body += _node(b"nTRN", 0, {}, 1, -1, -1, 1, {})
    body += _node(b"nGRP", 1, {}, 3, 2, 4, 6)
    body += _node(b"nTRN", 2, {"_name": "box"}, 3, -1, 0, 1, {"_t": "-10 0 2"})
    body += _node(b"nSHP", 3, {}, 1, 0, {})
    body += _node(b"nTRN", 4, {"_name": "pillar"}, 5, -1, 0, 1, {"_t": "10 6 7", "_r": str(1 | 0 << 2 | 1 << 4)})
    body += _node(b"nSHP", 5, {}, 1, 1, {})
    body += _node(b"nTRN", 6, {"_hidden": "1"}, 7, -1, 0, 1, {})
    body += _node(b"nSHP", 7, {}, 1, 2, {})
    body += chunk(b"RGBA", bytes(palette.ravel()))
    path = tmp_path / "scene.vox"
    path.write_bytes(b"VOX " + struct.pack("<i", 200) + chunk(b"MAIN", b"", body))
    box, pillar = read_vox_scene(path)
    assert (box.name, pillar.name) == ("box", "pillar")
    assert box.rgba.shape[0] == 4 and (box.rgba[..., 3] > 0).sum() == 64
    # The pillar's lowest voxel is 3 above the box's (z 7 - 4); the grid keeps that gap below it.
    lowest = np.nonzero((pillar.rgba[..., 3] > 0).any(axis=(0, 2)))[0].min()
    assert lowest == 3 and pillar.rgba.shape[0] == 11  # 3 + 8 voxels high
    # The quarter turn (x' = -y) puts the pillar's voxels at x 10 and 11, the box's at -12 to -9: centres 21 apart (the
    # pillar's grid, wider than its footprint, is centred within half a voxel). MagicaVoxel's y (6 against 0) points
    # away from the viewer: -6 in z.
    assert pillar.centre[0] - box.centre[0] == pytest.approx(21.0, abs=0.6)
    assert pillar.centre[1] - box.centre[1] == pytest.approx(-6.0, abs=0.6)
    box_spec, pillar_spec = placed_objects([box, pillar], ["a.npz", "b.npz"])
    unit = pillar_spec.scale[0] / 11
    assert box_spec.scale[0] == pytest.approx(4 * unit)  # one file voxel is as wide in both
    assert (pillar_spec.translation[0] - box_spec.translation[0]) == pytest.approx(21.0 * unit, abs=unit)
