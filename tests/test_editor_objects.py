"""The editor with several objects, in the real window under Xvfb: selecting by click and in the list, duplicate,
rename, move, delete and add, each one undo step; hiding from the viewport; a scene whose one object cannot be loaded
shows the others; a .vox file's models as objects."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest
import trimesh

from app.editor import edits
from app.editor.orbit_view import HOME, viewport_camera
from renderer.errors import InputError
from renderer.scene import LightSpec, ObjectSpec, Scene, load_scene, save_scene
from renderer.transform import footprint_radius
from renderer.voxels import save_voxels
from tests.test_editor import PANELS, RED, box_voxels, pixels, run_editor, share_of

LEFT = ObjectSpec(voxels="box.npz", resolution=16, translation=(-0.6, 0.0), scale=(0.6, 0.6, 0.6), name="left")
RIGHT = ObjectSpec(voxels="box.npz", resolution=16, translation=(0.6, 0.0), scale=(0.6, 0.6, 0.6), name="right")


@pytest.fixture(scope="module")
def two_boxes(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("two")
    save_voxels(folder / "box.npz", box_voxels())
    trimesh.creation.box([0.5, 1.0, 0.5]).export(folder / "pillar.obj")
    scene = Scene(objects=(LEFT, RIGHT), light=LightSpec((1.0, 2.75, 0.5)), image_size=64, base_dir=folder)
    save_scene(scene, folder / "two.json")
    return folder / "two.json"


def _viewport_pixel(world: tuple[float, float, float]) -> list[float]:
    """Window pixel where the viewport (at its home view) shows the world point."""
    camera = viewport_camera(HOME, PANELS.viewport.width, PANELS.viewport.height)
    u, v, _ = camera.project(np.array([world]))
    return [float(u[0]) + PANELS.viewport.x, float(v[0]) + PANELS.viewport.y]


def test_object_list_edits_are_undo_steps_and_a_click_selects(display, tmp_path, two_boxes):
    out = tmp_path
    click = _viewport_pixel((RIGHT.translation[0], 0.2, RIGHT.translation[1]))

    def save(name: str) -> dict:
        return {"action": "save", "path": str(out / f"{name}.json")}

    run_editor(display, out, two_boxes, [
        save("start"),
        {"action": "mouse_move", "pos": click}, {"action": "mouse_down", "button": 0},
        {"action": "mouse_up", "button": 0}, {"action": "wait", "frames": 2},
        {"action": "key", "key": "d", "mods": ["shift"]},  # the clicked (right) box, copied and selected
        {"action": "rename", "name": "copy"},
        {"action": "move_object", "translation": [0.6, -1.0]},
        save("edited"),
        {"action": "select", "index": 0}, {"action": "key", "key": "x"},  # the left box deleted
        save("deleted"),
        {"action": "screenshot", "path": str(out / "deleted.png")},
        {"action": "hide", "index": 0}, {"action": "wait", "frames": 2},  # the right box, hidden from the viewport
        {"action": "screenshot", "path": str(out / "hidden.png")},
        {"action": "hide", "index": 0},  # shown again (not an undo step)
        {"action": "undo"}, save("undeleted"),
        *[{"action": "undo"}] * 4, save("undone"),  # select, move, rename, duplicate
        *[{"action": "redo"}] * 5, save("redone"),
        {"action": "add_object", "path": str(two_boxes.parent / "pillar.obj")},
        save("added"),
    ])
    edited = load_scene(out / "edited.json")
    assert [o.name for o in edited.objects] == ["left", "right", "copy"]  # the click selected the right box
    assert edited.objects[2].translation == (0.6, -1.0) and edited.objects[1].translation == RIGHT.translation
    assert [o.name for o in load_scene(out / "deleted.json").objects] == ["right", "copy"]
    assert (out / "undeleted.json").read_text() == (out / "edited.json").read_text()
    assert (out / "undone.json").read_text() == (out / "start.json").read_text()
    assert (out / "redone.json").read_text() == (out / "deleted.json").read_text()
    added = load_scene(out / "added.json")
    assert [o.name for o in added.objects] == ["right", "copy", "pillar"]
    pillar = added.objects[2]
    for other in added.objects[:2]:  # placed where the floor has room
        gap = np.linalg.norm(np.subtract(pillar.translation, other.translation))
        assert gap >= footprint_radius(pillar) + footprint_radius(other)
    # The deleted box is gone from the viewport: red shows where the right box and its copy stand, not the left.
    shot = pixels(out / "deleted.png", PANELS.viewport)
    left_at = np.subtract(_viewport_pixel((LEFT.translation[0], 0.2, LEFT.translation[1])),
                          (PANELS.viewport.x, PANELS.viewport.y)).astype(int)
    right_at = np.subtract(click, (PANELS.viewport.x, PANELS.viewport.y)).astype(int)
    around = (slice(-6, 7), slice(-6, 7))

    def patch(at):
        return shot[at[1] + around[0].start:at[1] + around[0].stop, at[0] + around[1].start:at[0] + around[1].stop]

    assert share_of(patch(right_at), RED) > 0.3 and share_of(patch(left_at), RED) < 0.05
    shot = pixels(out / "hidden.png", PANELS.viewport)
    assert share_of(patch(right_at), RED) < 0.05  # hidden: the viewport draws the right box no more


def test_a_scene_whose_object_cannot_be_loaded_shows_the_others_and_names_it(display, tmp_path, two_boxes):
    data = json.loads(two_boxes.read_text())
    data["objects"][0]["voxels"] = "gone.npz"
    (two_boxes.parent / "broken.json").write_text(json.dumps(data))
    result = run_editor(display, tmp_path, two_boxes.parent / "broken.json", [
        {"action": "screenshot", "path": str(tmp_path / "shown.png")}])
    assert "gone.npz" in result.stderr and "Traceback" not in result.stderr
    assert share_of(pixels(tmp_path / "shown.png", PANELS.viewport), RED) > 0.002  # the right box


def test_object_list_edits_refuse_what_a_scene_cannot_hold(two_boxes):
    scene = load_scene(two_boxes)
    with pytest.raises(InputError, match="another object is named 'right'"):
        edits.rename_object(scene, 0, "right")
    one = edits.delete_object(scene, 0)
    with pytest.raises(InputError, match="at least one object"):
        edits.delete_object(one, 0)
    full = Scene(objects=tuple(ObjectSpec(voxels="box.npz", name=f"b{i}", scale=(0.2, 0.2, 0.2)) for i in range(16)),
                 base_dir=scene.base_dir)
    with pytest.raises(InputError, match="at most 16"):
        edits.duplicate_object(full, 0)
    named = edits.duplicate_object(edits.duplicate_object(scene, 1), 1)
    assert [o.name for o in named.objects] == ["left", "right", "right.001", "right.002"]


def test_a_vox_file_of_several_models_imports_them_as_objects_in_their_places(display, tmp_path, two_boxes):
    from tests.test_vox import _node, chunk

    body = b""
    for _ in range(2):
        voxels = [(x, y, z, 1) for x in range(4) for y in range(4) for z in range(4)]
        body += chunk(b"SIZE", struct.pack("<3i", 4, 4, 4))
        body += chunk(b"XYZI", struct.pack("<i", len(voxels)) + bytes(np.asarray(voxels, np.uint8).ravel()))
    body += _node(b"nTRN", 0, {}, 1, -1, -1, 1, {})
    body += _node(b"nGRP", 1, {}, 2, 2, 4)
    body += _node(b"nTRN", 2, {"_name": "near"}, 3, -1, 0, 1, {"_t": "-6 0 2"})
    body += _node(b"nSHP", 3, {}, 1, 0, {})
    body += _node(b"nTRN", 4, {"_name": "far"}, 5, -1, 0, 1, {"_t": "6 0 2"})
    body += _node(b"nSHP", 5, {}, 1, 1, {})
    (tmp_path / "pair.vox").write_bytes(b"VOX " + struct.pack("<i", 200) + chunk(b"MAIN", b"", body))
    run_editor(display, tmp_path, two_boxes, [
        {"action": "import_vox", "path": str(tmp_path / "pair.vox")},
        {"action": "answer", "choice": "All models"},
        {"action": "save", "path": str(tmp_path / "imported.json")},
    ])
    near, far = load_scene(tmp_path / "imported.json").objects
    assert (near.name, far.name) == ("near", "far")
    assert far.translation[0] - near.translation[0] == pytest.approx(12 * near.scale[0] / 4)  # 12 file voxels apart
