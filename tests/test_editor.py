"""The editor's real window under Xvfb: panels on screen, light drag, bucket fill, undo, export, recovery.

Each test runs `nvr-editor --frames ... --replay ...` in a subprocess on its own Xvfb display
and checks the pixels of its screenshots and the scene files it saves. The scene is a 16^3
box, red below and blue on top, rendered by a tiny random NVR+ network (so the light matters).
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from app.editor.layout import Rect, layout_for
from app.editor.orbit_view import HOME, viewport_camera
from app.editor.picking import ray_at_height
from app.editor.viewport_input import LIGHT_HEIGHT_PER_PIXEL
from models.networks.checkpoint import save_model
from models.networks.config import CompactConfig
from models.networks.nvr import build_model
from renderer.pipeline import object_voxels, painted_voxels
from renderer.scene import CameraSpec, FloorSpec, LightSpec, ObjectSpec, Scene, load_scene, replaced, save_scene
from renderer.surface import voxel_centers_at
from renderer.transform import apply_transform, object_to_world
from renderer.voxels import load_voxels, save_voxels

WINDOW = (1280, 800)
RED, BLUE, GREEN = (0.8, 0.3, 0.2), (0.2, 0.3, 0.8), (0.1, 0.8, 0.2)
TINY = CompactConfig(grid_size=64, output_size=64, voxel_channels=(4, 8, 8), latent_channels=16, light_channels=8,
                     decoder_channels=(8, 8), splat_channels=4, unet_channels=(4, 8))
EDITOR = [sys.executable, "-m", "app.editor.main"]
REPOSITORY = Path(__file__).resolve().parents[1]


# --- fixtures: a display, a scene, a model ------------------------------------------------------


@pytest.fixture(scope="module")
def model_file(tmp_path_factory) -> Path:
    import torch

    torch.manual_seed(0)
    model = build_model("nvr_plus", TINY).eval()
    # A fresh network renders a nearly flat image that hardly depends on the light. Random
    # BatchNorm statistics with gains of 1-3 spread its output, and a light MLP 100x stronger makes
    # a light move change the image by about 0.04 on average.
    for module in model.modules():
        if isinstance(module, (torch.nn.BatchNorm2d, torch.nn.BatchNorm3d)):
            module.running_mean.uniform_(-0.5, 0.5)
            module.running_var.uniform_(0.5, 2.0)
            module.weight.data.uniform_(1.0, 3.0)
            module.bias.data.uniform_(-0.5, 0.5)
    with torch.no_grad():
        for parameter in model.light_decoder.light_mlp.parameters():
            parameter.mul_(10.0)
    path = tmp_path_factory.mktemp("model") / "tiny.safetensors"
    save_model(path, model, TINY)
    return path


def box_voxels() -> np.ndarray:
    rgba = np.zeros((16, 16, 16, 4), np.float32)
    rgba[4:12, 0:10, 4:12] = (*RED, 1.0)
    rgba[4:12, 10:12, 4:12] = (*BLUE, 1.0)
    return rgba


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory) -> Path:
    """The box scene (tests save their edits elsewhere, so one file serves them all)."""
    tmp_path = tmp_path_factory.mktemp("scene")
    save_voxels(tmp_path / "box.npz", box_voxels())
    scene = Scene.single(object=ObjectSpec(voxels="box.npz", resolution=16, rotation_deg=20.0),
                  floor=FloorSpec((0.5, 0.6, 0.7)), light=LightSpec((1.0, 2.75, 0.5)), camera=CameraSpec(30.0),
                  image_size=64, base_dir=tmp_path)
    save_scene(scene, tmp_path / "scene.json")
    return tmp_path / "scene.json"


def run_editor(display: str, tmp_path: Path, scene: Path, actions: list | None = None, *args: str,
               state: Path | None = None, cwd: Path = REPOSITORY) -> subprocess.CompletedProcess:
    env = dict(os.environ, DISPLAY=display, XDG_STATE_HOME=str(state or tmp_path / "state"), NVR_EDITOR_TIMEOUT="120")
    if "--renderer" not in args and "--model" not in args:
        args = (*args, "--renderer", "shaded")  # the quick renderer, at the scene's small size, unless a test asks
    command = [*EDITOR, str(scene), "--frames", "3", *args]
    if actions is not None:
        replay = tmp_path / f"replay{time.monotonic_ns()}.json"
        replay.write_text(json.dumps(actions))
        command += ["--replay", str(replay)]
    result = subprocess.run(command, env=env, capture_output=True, text=True, timeout=240, cwd=cwd)
    assert result.returncode == 0, result.stderr
    return result


def pixels(path: Path, rect) -> np.ndarray:
    """The screenshot's pixels inside a layout rectangle, as floats in [0, 1]."""
    image = np.asarray(Image.open(path).convert("RGB"), dtype=np.float64) / 255.0
    assert image.shape == (WINDOW[1], WINDOW[0], 3)
    return image[rect.y:rect.y + rect.height, rect.x:rect.x + rect.width]


def share_of(region: np.ndarray, color: tuple[float, float, float]) -> float:
    """Share of pixels whose color is a shade of `color` (same channel ratios, any brightness)."""
    c = np.asarray(color)
    brightness = region.sum(axis=-1, keepdims=True) / c.sum()
    close = np.abs(region - brightness * c).max(axis=-1) < 0.05
    return float(np.mean(close & (brightness[..., 0] > 0.2)))


PANELS = layout_for(*WINDOW)


# --- tests ----------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def edit_run(display, tmp_path_factory, scene_file, model_file) -> Path:
    """One session on the box scene: drag the light, bucket-fill the red block green; screenshots between."""
    out = tmp_path_factory.mktemp("edits")
    run_editor(display, out, scene_file, [
        {"action": "screenshot", "path": str(out / "start.png")},
        {"action": "drag_light", "to": [-1.5, 2.5, -1.0], "steps": 4},
        {"action": "screenshot", "path": str(out / "lit.png")},
        {"action": "save", "path": str(out / "lit.json")},
        {"action": "paint", "voxel": [8, 5, 11], "color": list(GREEN), "tolerance": 0.05},
        {"action": "screenshot", "path": str(out / "painted.png")},
        {"action": "save", "path": str(out / "painted.json")},
    ], "--model", str(model_file), "--screenshot", str(out / "final.png"), "--export", str(out / "export.png"),
        "--export-side-by-side", str(out / "side.png"))
    return out


def test_window_shows_viewport_and_render_panel(edit_run):
    viewport = pixels(edit_run / "final.png", PANELS.viewport)
    assert share_of(viewport, GREEN) > 0.005  # the box's painted voxels, shaded
    assert share_of(viewport, FloorSpec((0.5, 0.6, 0.7)).color) > 0.2  # the ground
    shown = pixels(edit_run / "final.png", PANELS.render_image)
    export = Image.open(edit_run / "export.png").resize(shown.shape[1::-1], Image.Resampling.BILINEAR)  # as OpenGL magnifies
    assert np.abs(shown - np.asarray(export) / 255.0).mean() < 0.005  # the panel shows the network's image


def test_dragging_the_light_changes_the_render(edit_run):
    assert load_scene(edit_run / "lit.json").light.position == (-1.5, 2.5, -1.0)
    before, after = edit_run / "start.png", edit_run / "lit.png"
    change = np.abs(pixels(before, PANELS.render_image) - pixels(after, PANELS.render_image)).mean()
    assert change > 0.01
    viewport_change = np.abs(pixels(before, PANELS.viewport) - pixels(after, PANELS.viewport)).max(axis=-1)
    assert (viewport_change > 0.1).mean() > 0.002  # the light square moved


def test_bucket_fill_changes_viewport_and_scene_file(edit_run, scene_file):
    before, after = pixels(edit_run / "lit.png", PANELS.viewport), pixels(edit_run / "painted.png", PANELS.viewport)
    assert share_of(before, RED) > 0.005
    assert share_of(after, RED) < 0.0005
    assert share_of(after, GREEN) > 0.005
    scene = load_scene(edit_run / "painted.json")
    assert scene.paint[-1].similarity == "perceptual"  # the bucket's default
    rgba, _ = painted_voxels(scene, object_voxels(scene))
    expected = load_voxels(scene_file.parent / "box.npz")  # the box as stored (colors rounded to 8 bits)
    expected[4:12, 0:10, 4:12, :3] = GREEN  # the red block is one connected region of one color
    np.testing.assert_allclose(rgba, expected, atol=1e-6)


def test_undo_restores_the_scene_exactly_and_redo_repeats(display, tmp_path, scene_file, model_file):
    s = {name: str(tmp_path / f"{name}.json") for name in ("start", "undone", "redone", "edited")}
    run_editor(display, tmp_path, scene_file, [
        {"action": "save", "path": s["start"]},
        {"action": "move_object", "translation": [0.3, -0.2]},
        {"action": "set_elevation", "deg": 15.0},
        {"action": "paint", "voxel": [8, 11, 8], "color": list(GREEN), "tolerance": 0.05},
        {"action": "drag_light", "to": [0.0, 2.9, 1.0], "steps": 3},
        {"action": "fill_floor", "color": [0.9, 0.9, 0.2]},
        {"action": "save", "path": s["edited"]},
        {"action": "load_mesh", "path": str(tmp_path / "missing.obj")},  # an error: the scene survives
        {"action": "undo"}, {"action": "undo"}, {"action": "undo"},
        {"action": "key", "key": "z", "mods": ["ctrl"]},
        {"action": "key", "key": "z", "mods": ["ctrl"]},
        {"action": "save", "path": s["undone"]},
        {"action": "redo"}, {"action": "redo"},
        {"action": "key", "key": "z", "mods": ["ctrl", "shift"]},
        {"action": "redo"}, {"action": "redo"},
        {"action": "save", "path": s["redone"]},
    ], "--model", str(model_file))
    assert Path(s["undone"]).read_text() == Path(s["start"]).read_text()
    assert Path(s["redone"]).read_text() == Path(s["edited"]).read_text()
    edited = load_scene(s["edited"])
    assert edited.object.translation == (0.3, -0.2)
    assert edited.camera.elevation_deg == 15.0
    assert edited.light.position == (0.0, 2.9, 1.0)
    assert [op.target for op in edited.paint] == ["region"]  # the floor's fill set its color


def screen_position(point, scene_view=HOME) -> list[float]:
    """Window pixel where the viewport (at its starting view) shows a world point."""
    v = PANELS.viewport
    u, row, _ = viewport_camera(scene_view, v.width, v.height).project(np.asarray(point, dtype=np.float64))
    return [v.x + float(u), v.y + float(row)]


def test_mouse_drags_the_light_clicks_paint_and_g_grabs(display, tmp_path, scene_file, model_file):
    scene = load_scene(scene_file)
    light = screen_position(scene.light.position)
    target = [light[0] - 120, light[1] + 40]
    # Where the light will be: the floor point under it moves with the mouse (so the square itself moves less).
    v = PANELS.viewport
    under = np.add(screen_position((scene.light.position[0], 0.0, scene.light.position[2])), np.subtract(target, light))
    origin, direction = viewport_camera(HOME, v.width, v.height).pixel_rays(np.array(under[0] - v.x), np.array(under[1] - v.y))
    floor_point = ray_at_height(origin, np.asarray(direction), 0.0)
    light_after = screen_position((floor_point[0], scene.light.position[1], floor_point[2]))
    # The centre of the red block's front face (voxel (8, 5, 11), its +z side) as placed in the world.
    front = apply_transform(object_to_world(scene.object), voxel_centers_at(np.array([[8, 5, 11]]), 16) + [0, 0, 0.5 / 16])[0]
    middle = [PANELS.viewport.x + PANELS.viewport.width / 2, PANELS.viewport.y + PANELS.viewport.height / 2]
    run_editor(display, tmp_path, scene_file, [
        {"action": "mouse_move", "pos": light},
        {"action": "mouse_down", "button": 0},
        {"action": "mouse_move", "pos": [light[0] - 60, light[1] + 20]},
        {"action": "mouse_move", "pos": target},
        {"action": "mouse_up", "button": 0},
        {"action": "save", "path": str(tmp_path / "light.json")},
        {"action": "mouse_move", "pos": light_after},
        {"action": "mouse_down", "button": 0, "mods": ["shift"]},  # Shift + drag: height only
        {"action": "mouse_move", "pos": [light_after[0] + 30, light_after[1] - 20]},
        {"action": "mouse_up", "button": 0},
        {"action": "save", "path": str(tmp_path / "raised.json")},
        {"action": "tool", "name": "paint"},
        {"action": "mouse_move", "pos": screen_position(front)},
        {"action": "mouse_down", "button": 0},
        {"action": "mouse_up", "button": 0},
        {"action": "save", "path": str(tmp_path / "painted.json")},
        {"action": "mouse_move", "pos": middle},
        {"action": "key", "key": "g"},
        {"action": "key", "key": "x"},
        {"action": "mouse_move", "pos": [middle[0] + 80, middle[1] + 40]},
        {"action": "mouse_down", "button": 0},
        {"action": "mouse_up", "button": 0},
        {"action": "save", "path": str(tmp_path / "grabbed.json")},
    ], "--model", str(model_file))
    # The light moved by what the mouse covered on the floor: the floor point under it moved with the mouse.
    moved = load_scene(tmp_path / "light.json").light.position
    assert moved[1] == scene.light.position[1]
    under_before = screen_position((scene.light.position[0], 0.0, scene.light.position[2]))
    under_after = screen_position((moved[0], 0.0, moved[2]))
    np.testing.assert_allclose(np.subtract(under_after, under_before), np.subtract(target, light), atol=1.5)
    raised = load_scene(tmp_path / "raised.json").light.position
    assert raised[0] == moved[0] and raised[2] == moved[2]
    assert raised[1] == pytest.approx(moved[1] + 20 * LIGHT_HEIGHT_PER_PIXEL)  # 20 pixels up
    painted = load_scene(tmp_path / "painted.json").paint
    assert len(painted) == 1 and painted[0].target == "region"
    assert painted[0].seed[2] == 11 and 4 <= painted[0].seed[0] < 12 and painted[0].seed[1] < 10  # the red front face
    x, z = load_scene(tmp_path / "grabbed.json").object.translation
    assert abs(x) > 0.05 and z == 0.0  # X: along x only


def test_export_equals_nvr_render(edit_run, tmp_path, model_file):
    cli = tmp_path / "cli.png"
    subprocess.run([sys.executable, "-m", "app.cli", "render", str(edit_run / "painted.json"), "--renderer", "nvr+",
                    "--model", str(model_file), "-o", str(cli)], check=True, capture_output=True, timeout=120)
    np.testing.assert_array_equal(np.asarray(Image.open(edit_run / "export.png")), np.asarray(Image.open(cli)))


def test_the_panel_renders_with_the_chosen_renderer_and_exports_what_it_shows(display, tmp_path, scene_file, model_file):
    """With --renderer shaded the panel shows the voxel shader; switching to
    NVR+ in the window shows (and exports) the network's image; each export equals `nvr render` with that
    renderer."""
    out = tmp_path / "out"
    out.mkdir()
    run_editor(display, tmp_path, scene_file, [
        {"action": "export", "path": str(out / "shaded.png")},
        {"action": "screenshot", "path": str(out / "shaded_window.png")},
        {"action": "renderer", "name": "nvr+"},
        {"action": "wait", "frames": 5},
        {"action": "export", "path": str(out / "network.png")},
    ], "--model", str(model_file), "--renderer", "shaded")
    for name, renderer in (("shaded", "shaded"), ("network", "nvr+")):
        cli = tmp_path / f"cli_{name}.png"
        subprocess.run([sys.executable, "-m", "app.cli", "render", str(scene_file), "--renderer", renderer,
                        "--model", str(model_file), "-o", str(cli)], check=True, capture_output=True, timeout=120)
        np.testing.assert_array_equal(np.asarray(Image.open(out / f"{name}.png")), np.asarray(Image.open(cli)))
    assert not np.array_equal(np.asarray(Image.open(out / "shaded.png")), np.asarray(Image.open(out / "network.png")))
    # The panel shows the shader's image: the render panel's pixels match the export, magnified.
    shown = pixels(out / "shaded_window.png", PANELS.render_image)
    export = Image.open(out / "shaded.png").resize(shown.shape[1::-1], Image.Resampling.BILINEAR)
    assert np.abs(shown - np.asarray(export) / 255.0).mean() < 0.01


def test_the_editor_opens_on_the_shipped_nvr_plus(display, tmp_path, scene_file):
    """Without --renderer or --model the panel renders (and exports) the shipped NVR+'s image, as `nvr render --renderer
    nvr+` does, at the network's size and at another scene size (the shader's image at that size, corrected)."""
    scene = load_scene(scene_file)
    scene_256 = tmp_path / "scene256.json"
    save_scene(replace(scene, image_size=256), scene_256)  # the network's own size (save_scene keeps the voxel path)
    env = dict(os.environ, DISPLAY=display, XDG_STATE_HOME=str(tmp_path / "state"), NVR_EDITOR_TIMEOUT="120")
    for scene_path, export in ((scene_256, "editor256.png"), (scene_file, "editor64.png")):
        result = subprocess.run([*EDITOR, str(scene_path), "--frames", "3", "--export", str(tmp_path / export)],
                                env=env, capture_output=True, text=True, timeout=240, cwd=REPOSITORY)
        assert result.returncode == 0, result.stderr[-2000:]
        cli = tmp_path / f"cli_{export}"
        subprocess.run([sys.executable, "-m", "app.cli", "render", str(scene_path), "--renderer", "nvr+", "-o",
                        str(cli)], check=True, capture_output=True, timeout=120)
        np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / export)), np.asarray(Image.open(cli)))
    assert Image.open(tmp_path / "editor64.png").size == (64, 64)


def test_closing_asks_about_unsaved_changes_and_the_next_start_offers_them_back(display, tmp_path, scene_file,
                                                                                model_file):
    state = tmp_path / "state"
    recovery = state / "nvr-studio" / "recovery-headless" / "scene.json"  # a headless run's own autosave
    calm, asking = tmp_path / "calm.png", tmp_path / "asking.png"
    run_editor(display, tmp_path, scene_file, [
        {"action": "move_object", "translation": [0.4, 0.1]},
        {"action": "screenshot", "path": str(calm)},
        {"action": "close"},
        {"action": "wait", "frames": 3},
        {"action": "screenshot", "path": str(asking)},
        {"action": "answer", "choice": "Cancel"},  # stay; the run then ends with the changes unsaved
    ], "--model", str(model_file), state=state)
    tint = np.abs(pixels(asking, PANELS.viewport) - pixels(calm, PANELS.viewport)).mean()
    assert tint > 0.05  # the question's modal window tints everything behind it
    assert recovery.is_file()
    run_editor(display, tmp_path, scene_file, [
        {"action": "answer", "choice": "Restore"},
        {"action": "save", "path": str(tmp_path / "restored.json")},
        {"action": "set_elevation", "deg": 12.0},
        {"action": "close"},
        {"action": "answer", "choice": "Discard"},
    ], "--model", str(model_file), state=state)
    assert load_scene(tmp_path / "restored.json").object.translation == (0.4, 0.1)
    assert not recovery.exists()  # discarded on purpose: nothing to offer next time


def test_a_headless_run_neither_offers_nor_replaces_the_interactive_autosave(display, tmp_path, scene_file,
                                                                            monkeypatch):
    from app.editor import state as editor_state

    state = tmp_path / "state"
    interactive = state / "nvr-studio" / "recovery" / "scene.json"
    monkeypatch.setenv("XDG_STATE_HOME", str(state))
    moved = load_scene(scene_file)
    editor_state.write_recovery(replaced(moved, object=replace(moved.object, translation=(0.3, -0.2))), scene_file)
    before = interactive.read_bytes()  # unsaved changes the interactive editor left
    result = run_editor(display, tmp_path, scene_file, [
        {"action": "answer", "choice": "Restore"},  # nothing is offered: refused with a message
        {"action": "move_object", "translation": [-0.4, 0.2]},  # ends unsaved: autosaved in its own place
    ], state=state)
    assert "no question to answer" in result.stderr
    assert interactive.read_bytes() == before
    headless = load_scene(state / "nvr-studio" / "recovery-headless" / "scene.json")
    assert headless.object.translation == (-0.4, 0.2)


def test_meshes_and_photos_load_and_bad_files_leave_the_scene_alone(display, tmp_path, scene_file, model_file):
    import trimesh

    trimesh.creation.box(extents=(1.0, 2.0, 1.0)).export(tmp_path / "tall.obj")
    (tmp_path / "broken.obj").write_text("not a mesh\n")
    result = run_editor(display, tmp_path, scene_file, [
        {"action": "load_mesh", "path": str(tmp_path / "broken.obj")},
        {"action": "load_photo", "photo": "assets/demo/photo.png", "camera": str(scene_file)},
        {"action": "save", "path": str(tmp_path / "unchanged.json")},
        {"action": "load_mesh", "path": str(tmp_path / "tall.obj")},
        {"action": "save", "path": str(tmp_path / "tall.json")},
        {"action": "load_photo", "photo": "assets/demo/photo.png", "camera": "assets/demo/photo_camera.json"},
        {"action": "color_from_photo"},  # at the camera file's pose
        {"action": "save", "path": str(tmp_path / "photo.json")},
    ], "--model", str(model_file))
    assert "broken.obj" in result.stderr and "scene.json: missing" in result.stderr  # shown, and echoed on stderr
    unchanged, original = load_scene(tmp_path / "unchanged.json"), load_scene(scene_file)
    assert unchanged.voxels_path().resolve() == original.voxels_path().resolve()  # saved elsewhere: relative path differs
    assert replaced(unchanged, object=original.object) == original
    tall = load_scene(tmp_path / "tall.json")
    assert tall.mesh_path().resolve() == (tmp_path / "tall.obj").resolve() and tall.object.voxels is None
    occupied = object_voxels(tall)[..., 3] > 0.5
    assert occupied[:, -1].any() and not occupied[:, :, 0].all()  # 1 x 2 x 1 box: the full height, half the depth
    photo = load_scene(tmp_path / "photo.json")
    assert photo.voxels_path() == (tmp_path / "photo.voxels.npz").resolve()  # copied beside the saved scene
    colored = object_voxels(photo)
    assert np.array_equal(colored[..., 3], object_voxels(tall)[..., 3])  # same shape, new colors
    assert np.abs(colored[occupied][:, :3] - object_voxels(tall)[occupied][:, :3]).max() > 0.1


# --- drawing only what changed ---------------------------------------------------------------------


def test_frame_summaries_read_whole_vertex_and_index_buffers(display, monkeypatch):
    """The byte sizes the digest assumes: every index read points at one of the list's vertices, the last at the last."""
    import ctypes

    from imgui_bundle import imgui

    from app.editor.frame_damage import INDEX_BYTES, VERTEX_BYTES, summarize
    from app.editor.window import Window

    monkeypatch.setenv("DISPLAY", display)
    window = Window("summaries", 320, 200)
    try:
        digests = []
        for text in ("one", "one", "one", "two", "two"):  # a new ImGui window settles in its first frames
            window.begin_frame()
            imgui.set_next_window_pos(imgui.ImVec2(10, 10))
            imgui.set_next_window_size(imgui.ImVec2(200, 100))
            imgui.begin("panel")
            imgui.text(text)
            imgui.end()
            window.end_frame()  # uploads the font on the first frame
            draw_data = imgui.get_draw_data()
            for draw_list in draw_data.cmd_lists:
                v, i = draw_list.vtx_buffer, draw_list.idx_buffer
                indices = np.frombuffer(ctypes.string_at(i.data_address(), i.size() * INDEX_BYTES), f"u{INDEX_BYTES}")
                assert indices.min() == 0 and indices.max() == v.size() - 1
                xy = np.frombuffer(ctypes.string_at(v.data_address(), v.size() * VERTEX_BYTES), np.float32)
                xy = xy.reshape(-1, VERTEX_BYTES // 4)[:, :2]
                assert (xy >= 0).all() and (xy <= (320, 200)).all()  # positions in the window
            digests.append(summarize(draw_data, window.size, ()).lists)
            window.present()
        assert digests[1] == digests[2] != digests[3] == digests[4]
        assert [box for _, box in digests[-1]] == [(10, 10, 211, 111)]  # the panel's rectangle, rounded outwards
    finally:
        window.close()


def test_the_screen_shows_the_full_frame_after_partial_updates(display, tmp_path, scene_file, model_file):
    """What the X server shows after frames drawn in parts (light drag, object move) equals the whole frame drawn at once."""
    from PIL import ImageGrab, features

    if not features.check("xcb"):
        pytest.skip("Pillow was built without XCB: cannot read the screen")
    marker = tmp_path / "ba.json"
    replay = tmp_path / "replay.json"
    replay.write_text(json.dumps([
        # Saving shows a message, and a message with letters not seen before makes ImGui add them to its font
        # texture, which redraws the whole frame. The same letters now mean the frame after the last save
        # (the marker) is drawn only where it changed.
        {"action": "save", "path": str(tmp_path / "ab.json")},
        {"action": "drag_light", "to": [-1.5, 2.5, -1.0], "steps": 12},
        {"action": "move_object", "translation": [0.3, -0.2]},
        {"action": "drag_light", "to": [1.5, 3.0, 0.0], "steps": 12},
        {"action": "save", "path": str(marker)},
        {"action": "wait", "frames": 600},
    ]))
    env = dict(os.environ, DISPLAY=display, XDG_STATE_HOME=str(tmp_path / "state"), NVR_EDITOR_TIMEOUT="120")
    editor = subprocess.Popen([*EDITOR, str(scene_file), "--frames", "3", "--replay", str(replay), "--model", str(model_file),
                               "--screenshot", str(tmp_path / "whole.png")], env=env, cwd=Path(__file__).resolve().parents[1],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 200
    while not marker.exists() and editor.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.5)  # the editor is idle since the marker: nothing but the frame rate in the status bar changes
    screen = np.asarray(ImageGrab.grab(xdisplay=display), dtype=np.float64)[:WINDOW[1], :WINDOW[0]] / 255.0
    out, err = editor.communicate(timeout=200)
    assert editor.returncode == 0, err
    drawn = [int(n) for n in re.findall(r"(\d+) drawn", out)]
    frames = int(re.search(r"(\d+) frames;", out).group(1))
    assert sum(drawn) < frames - 300  # the waiting frames looked the same and were not drawn again
    whole = np.asarray(Image.open(tmp_path / "whole.png"), dtype=np.float64) / 255.0
    above_status = PANELS.status.y
    np.testing.assert_array_equal(screen[:above_status], whole[:above_status])


# --- side-by-side export -----------------------------------------------------------------------------


def test_side_by_side_export_puts_the_viewport_beside_the_exact_render(edit_run):
    side = np.asarray(Image.open(edit_run / "side.png").convert("RGB"))
    render = np.asarray(Image.open(edit_run / "export.png").convert("RGB"))
    scale = -(-512 // TINY.output_size)  # the 64^2 render, each pixel repeated to reach 512 rows
    assert side.shape == (64 * scale, 2 * 64 * scale, 3)
    right = side[:, 64 * scale:]
    np.testing.assert_array_equal(right[::scale, ::scale], render)  # the render's own pixels
    np.testing.assert_array_equal(right, np.repeat(np.repeat(render, scale, axis=0), scale, axis=1))
    left = side[:, :64 * scale] / 255.0
    assert share_of(left, GREEN) > 0.005  # the painted block, shaded
    assert share_of(left, BLUE) > 0.002  # the blue top
    assert share_of(left, RED) < 0.0005  # nothing red is left after the fill
    assert share_of(left, FloorSpec((0.5, 0.6, 0.7)).color) > 0.2  # the ground


def test_headless_exports_refuse_to_overwrite_without_force(display, tmp_path, scene_file, model_file):
    env = dict(os.environ, DISPLAY=display, XDG_STATE_HOME=str(tmp_path / "state"))
    for flag in ("--export-side-by-side", "--export", "--screenshot"):
        existing = tmp_path / f"existing{flag}.png"
        existing.write_bytes(b"keep me")
        command = [*EDITOR, str(scene_file), "--frames", "2", "--model", str(model_file), flag, str(existing)]
        refused = subprocess.run(command, env=env, capture_output=True, text=True, timeout=240)
        assert refused.returncode == 2 and "file exists (pass --force to overwrite)" in refused.stderr
        assert existing.read_bytes() == b"keep me"
    forced = subprocess.run([*command, "--force"], env=env, capture_output=True, text=True, timeout=240)
    assert forced.returncode == 0, forced.stderr
    assert Image.open(existing).size == WINDOW  # the screenshot replaced the file


def test_the_window_asks_before_replacing_a_file_and_the_file_menu_exports_side_by_side(display, tmp_path, scene_file,
                                                                                          model_file):
    target, other_scene = tmp_path / "side.png", tmp_path / "other.json"
    target.write_bytes(b"keep me")
    other_scene.write_text("keep me too")
    run_editor(display, tmp_path, scene_file, [
        {"action": "export_side_by_side", "path": str(target)},
        {"action": "answer", "choice": "Cancel"},
        {"action": "save", "path": str(other_scene)},  # "Save as" onto another scene's file asks too
        {"action": "answer", "choice": "Cancel"},
    ], "--model", str(model_file))
    assert target.read_bytes() == b"keep me" and other_scene.read_text() == "keep me too"
    run_editor(display, tmp_path, scene_file, [
        {"action": "export_side_by_side", "path": str(target)},
        {"action": "answer", "choice": "Replace"},
    ], "--model", str(model_file))
    assert Image.open(target).size == (1024, 512)
    # The File menu's item, clicked with the mouse, writes to the File tab's default path (beside the scene file).
    # The menu: New, Open, Open recent, Save, Save as | Export render, Export viewport and render (at y = 155), ...
    item = [60, 155]
    run_editor(display, tmp_path, scene_file, [
        {"action": "mouse_move", "pos": [18, 11]}, {"action": "wait", "frames": 2},
        {"action": "mouse_down", "button": 0}, {"action": "wait", "frames": 2}, {"action": "mouse_up", "button": 0},
        {"action": "mouse_move", "pos": item}, {"action": "wait", "frames": 2},
        {"action": "mouse_down", "button": 0}, {"action": "wait", "frames": 2}, {"action": "mouse_up", "button": 0},
    ], "--model", str(model_file), cwd=tmp_path)
    assert Image.open(scene_file.parent / "viewport_and_render.png").size == (1024, 512)
    assert not (tmp_path / "viewport_and_render.png").exists()  # not into the working folder


# --- file dialog and the path fields without one ------------------------------------------------------

# Where the Object tab (shown first) puts its mesh row, in window pixels: the path field, its Browse button
# (only when a dialog program exists) and the "Load and voxelise" button below.
MESH_FIELD, MESH_BROWSE, MESH_LOAD = [990, 645], [1225, 645], [904, 694]


def _click(pos) -> list[dict]:
    return [{"action": "mouse_move", "pos": pos}, {"action": "wait", "frames": 2}, {"action": "mouse_down", "button": 0},
            {"action": "wait", "frames": 2}, {"action": "mouse_up", "button": 0}]


def test_browse_fills_the_mesh_field_from_zenity_and_from_the_editors_own_browser_without_it(
        display, tmp_path, scene_file, model_file, monkeypatch):
    import trimesh

    from app.editor.file_dialog import dialog_command
    from app.editor.panels import MESH_FILES

    mesh = tmp_path / "tall.obj"
    trimesh.creation.box(extents=(1.0, 2.0, 1.0)).export(mesh)
    with_dialog, without = tmp_path / "with_dialog", tmp_path / "without"
    with_dialog.mkdir()
    without.mkdir()  # PATH holds no dialog program (the editor itself needs nothing from PATH)
    zenity = with_dialog / "zenity"
    zenity.write_text(f'#!/bin/sh\nprintf "%s\\n" "$@" > "{with_dialog}/args.txt"\necho "{mesh}"\n')
    zenity.chmod(0o755)
    own_browser = [{"action": "wait", "frames": 3}, {"action": "type", "text": str(mesh)},
                   {"action": "key", "key": "enter"}, {"action": "wait", "frames": 3}]  # its name field has the keys
    for path_dir, pick in ((with_dialog, _click(MESH_BROWSE) + [{"action": "wait", "frames": 60}]),
                           (without, _click(MESH_BROWSE) + own_browser)):
        monkeypatch.setenv("PATH", str(path_dir))  # run_editor passes the environment on
        run_editor(display, path_dir, scene_file, [
            {"action": "screenshot", "path": str(path_dir / "tools.png")},
            *pick, *_click(MESH_LOAD),
            {"action": "save", "path": str(path_dir / "loaded.json")},
        ], "--model", str(model_file))
        assert load_scene(path_dir / "loaded.json").mesh_path().resolve() == mesh.resolve()
    assert (with_dialog / "args.txt").read_text().splitlines() == dialog_command("zenity", MESH_FILES)[1:]
    browse = [MESH_BROWSE[0] - 15, MESH_BROWSE[1] - 6, MESH_BROWSE[0] + 15, MESH_BROWSE[1] + 6]
    shown, absent = (np.asarray(Image.open(d / "tools.png").crop(browse), dtype=np.float64) / 255.0 for d in (with_dialog, without))
    assert np.abs(shown - absent).mean() < 0.02  # the Browse button is there either way


# --- rotate and scale with R and S ------------------------------------------------------------------


def test_r_turns_the_object_by_the_angle_the_mouse_sweeps_and_s_x_scales_x_only(display, tmp_path, scene_file, model_file):
    scene = load_scene(scene_file)  # the box at the origin, turned 20 degrees, scale 1
    cx, cy = screen_position([0.0, 0.5 * scene.object.scale[1], 0.0])  # the tools turn and scale about this point
    moves = [
        # R, then a quarter turn counterclockwise on screen: from right of the centre to above it.
        {"action": "mouse_move", "pos": [cx + 120, cy]}, {"action": "wait", "frames": 2},
        {"action": "key", "key": "r"},
        {"action": "mouse_move", "pos": [cx + 85, cy - 85]}, {"action": "mouse_move", "pos": [cx, cy - 120]},
        {"action": "mouse_down", "button": 0}, {"action": "mouse_up", "button": 0},
        {"action": "save", "path": str(tmp_path / "turned.json")},
        # S then X, from 60 to 150 pixels right of the centre: x grows by 150 / 60.
        {"action": "mouse_move", "pos": [cx + 60, cy]}, {"action": "wait", "frames": 2},
        {"action": "key", "key": "s"}, {"action": "key", "key": "x"},
        {"action": "mouse_move", "pos": [cx + 150, cy]},
        {"action": "mouse_down", "button": 0}, {"action": "mouse_up", "button": 0},
        {"action": "save", "path": str(tmp_path / "wide.json")},
        # S alone, from 100 pixels right to 50 pixels below: every axis shrinks by 50 / 100.
        {"action": "mouse_move", "pos": [cx + 100, cy]}, {"action": "wait", "frames": 2},
        {"action": "key", "key": "s"},
        {"action": "mouse_move", "pos": [cx, cy + 50]},
        {"action": "key", "key": "enter"},
        {"action": "save", "path": str(tmp_path / "small.json")},
        # R, then Esc: nothing changes, and a click afterwards confirms nothing (saving alone would drop a preview).
        {"action": "key", "key": "r"}, {"action": "mouse_move", "pos": [cx - 100, cy]},
        {"action": "key", "key": "escape"},
        {"action": "mouse_move", "pos": [cx - 100, cy + 40]},
        {"action": "mouse_down", "button": 0}, {"action": "mouse_up", "button": 0},
        {"action": "save", "path": str(tmp_path / "cancelled.json")},
    ]
    run_editor(display, tmp_path, scene_file, moves, "--model", str(model_file))
    turned = load_scene(tmp_path / "turned.json").object
    assert turned.rotation_deg == pytest.approx(20.0 + 90.0, abs=1e-6)
    assert turned.scale == scene.object.scale and turned.translation == scene.object.translation
    # Counterclockwise on screen is counterclockwise seen from above: the object's own +x axis, as drawn,
    # turned counterclockwise too (y grows downwards on screen, hence the minus signs).
    def screen_angle(obj) -> float:
        centre, tip = (apply_transform(object_to_world(obj), p) for p in ([0.0, 0.5, 0.0], [0.5, 0.5, 0.0]))
        (x0, y0), (x1, y1) = screen_position(centre), screen_position(tip)
        return math.degrees(math.atan2(-(y1 - y0), x1 - x0))
    assert 0.0 < (screen_angle(turned) - screen_angle(scene.object)) % 360.0 < 180.0
    wide = load_scene(tmp_path / "wide.json").object
    assert wide.scale == pytest.approx((150 / 60, 1.0, 1.0), abs=1e-6) and wide.rotation_deg == turned.rotation_deg
    small = load_scene(tmp_path / "small.json").object
    assert small.scale == pytest.approx((150 / 60 * 0.5, 0.5, 0.5), abs=1e-6)
    assert load_scene(tmp_path / "cancelled.json").object == small


def test_resizing_the_window_keeps_the_editor_alive_and_the_layout_follows(display, tmp_path, scene_file, model_file):
    """Enlarge, shrink, enlarge again and restore the real window (Mesa's software OpenGL under Xvfb): the
    editor lives on, and each screenshot has the new size with the menu bar once at the top, the viewport's
    floor right under it, the render where the layout puts it and the status bar at the bottom."""
    sizes = [(1400, 900), (1000, 700), (1500, 950), (900, 600), (1280, 800)]
    actions = []
    for i, size in enumerate(sizes):
        actions += [{"action": "resize", "size": list(size)}, {"action": "wait", "frames": 3},
                    {"action": "screenshot", "path": str(tmp_path / f"size{i}.png")}]
    result = run_editor(display, tmp_path, scene_file, actions, "--model", str(model_file), "--renderer", "nvr+")
    assert result.returncode == 0, result.stderr[-2000:]
    for i, (width, height) in enumerate(sizes):
        image = np.asarray(Image.open(tmp_path / f"size{i}.png").convert("RGB"), dtype=np.float64) / 255.0
        assert image.shape == (height, width, 3)
        panels = layout_for(width, height)
        menu_color = image[2, width // 2]
        rows_like_menu = np.all(np.abs(image[:, width // 3] - menu_color) < 0.02, axis=-1)
        assert rows_like_menu[1: panels.viewport.y - 2].all()  # the menu bar at the top ...
        assert not rows_like_menu[panels.viewport.y + 4: panels.viewport.y + 120].any()  # ... and only there
        floor = FloorSpec((0.5, 0.6, 0.7)).color
        bottom = image[panels.viewport.y + panels.viewport.height - 60: panels.viewport.y + panels.viewport.height - 40,
                       panels.viewport.x + 10: panels.viewport.x + panels.viewport.width - 10]
        assert share_of(bottom, floor) > 0.5  # the viewport's near floor reaches its bottom edge
        render = image[panels.render_image.y: panels.render_image.y + panels.render_image.height,
                       panels.render_image.x: panels.render_image.x + panels.render_image.width]
        assert render.std() > 0.02  # the network's image fills its place, not the panel background
        status = image[panels.status.y + 2: panels.status.y + panels.status.height - 2, :]
        assert np.abs(status - status[0, 0]).max(axis=-1).mean() < 0.2  # the status bar's own band, text aside


def _tools_point(dx: float, dy: float) -> list[float]:
    """A window pixel in the tools panel, from its top-left corner (its tabs at dy 39; fields from dy 64, 25 apart)."""
    return [PANELS.tools.x + dx, PANELS.tools.y + dy]


OBJECT_TAB, PAINT_TAB, SCALE_X_FIELD = _tools_point(30, 39), _tools_point(177, 39), _tools_point(52, 114)


def test_what_a_user_meets_first_dragging_far_leaving_paint_typing_a_bad_value(display, tmp_path, scene_file, model_file):
    """Drag the light square far upwards: it moves over the floor, stays inside the floor's square and says it
    left the training range. Leave the Paint tab and click the object: nothing is painted. Type -1 into scale:
    refused with a message under the field, the scale stays."""
    scene = load_scene(scene_file)
    light = screen_position(scene.light.position)
    front = apply_transform(object_to_world(scene.object), voxel_centers_at(np.array([[8, 5, 11]]), 16) + [0, 0, 0.5 / 16])[0]
    result = run_editor(display, tmp_path, scene_file, [
        {"action": "mouse_move", "pos": light},
        {"action": "mouse_down", "button": 0},
        {"action": "mouse_move", "pos": [light[0], light[1] - 100]},
        {"action": "mouse_move", "pos": [light[0], light[1] - 300]},
        {"action": "mouse_up", "button": 0},
        {"action": "screenshot", "path": str(tmp_path / "far.png")},
        {"action": "save", "path": str(tmp_path / "far.json")},
        {"action": "undo"},
        {"action": "tool", "name": "paint"},  # opens the Paint tab with the bucket
        {"action": "mouse_move", "pos": OBJECT_TAB},
        {"action": "mouse_down", "button": 0},
        {"action": "mouse_up", "button": 0},
        {"action": "mouse_move", "pos": screen_position(front)},
        {"action": "mouse_down", "button": 0},
        {"action": "mouse_up", "button": 0},
        {"action": "save", "path": str(tmp_path / "clicked.json")},
        {"action": "mouse_move", "pos": SCALE_X_FIELD},
        {"action": "mouse_down", "button": 0, "mods": ["ctrl"]},  # Ctrl+click: type into the field
        {"action": "mouse_up", "button": 0},
        {"action": "key", "key": "a", "mods": ["ctrl"]},
        {"action": "type", "text": "-1"},
        {"action": "key", "key": "enter"},
        {"action": "wait", "frames": 3},
        {"action": "screenshot", "path": str(tmp_path / "typed.png")},
        {"action": "save", "path": str(tmp_path / "typed.json")},
        {"action": "key", "key": "n", "mods": ["ctrl"]},  # a new scene: the old field's message goes with it
        {"action": "mouse_move", "pos": OBJECT_TAB},
        {"action": "mouse_down", "button": 0},
        {"action": "mouse_up", "button": 0},
        {"action": "wait", "frames": 3},
        {"action": "screenshot", "path": str(tmp_path / "new.png")},
    ], "--model", str(model_file))
    assert result.returncode == 0, result.stderr[-2000:]
    far = load_scene(tmp_path / "far.json").light.position
    assert far[1] == scene.light.position[1] and all(math.isfinite(c) for c in far)
    assert max(abs(far[0]), abs(far[2])) <= 10.0 and far != scene.light.position  # moved, but stayed over the floor
    amber = share_of(pixels(tmp_path / "far.png", replace(PANELS.viewport, y=PANELS.viewport.y + PANELS.viewport.height - 40,
                                                                 height=30)), (1.0, 0.75, 0.3))
    assert amber > 0.002  # "Outside the training range: light.position..." at the bottom of the viewport
    assert load_scene(tmp_path / "clicked.json").paint == ()  # the bucket is off outside the Paint tab
    assert load_scene(tmp_path / "typed.json").object.scale == scene.object.scale
    assert "scale must be from 0.05 to 20, got -1" in result.stderr
    below_field = pixels(tmp_path / "typed.png", replace(PANELS.tools, y=int(SCALE_X_FIELD[1]) + 10, height=22))
    assert share_of(below_field, (1.0, 0.42, 0.38)) > 0.01  # the message in red under the field
    below_field = pixels(tmp_path / "new.png", replace(PANELS.tools, y=int(SCALE_X_FIELD[1]) + 10, height=22))
    assert share_of(below_field, (1.0, 0.42, 0.38)) < 0.001  # gone with its scene


def test_ctrl_s_saves_a_new_scene_under_the_name_the_file_tab_shows(display, tmp_path, scene_file):
    """Ctrl+S on a new scene asks for a name (here in the editor's own browser: no dialog program is installed),
    offering the File tab's Save-as name; Enter takes it."""
    result = run_editor(display, tmp_path, scene_file, [
        {"action": "key", "key": "n", "mods": ["ctrl"]},
        {"action": "set_elevation", "deg": 22},
        {"action": "key", "key": "s", "mods": ["ctrl"]},  # Save as: the editor's browser, the File tab's name filled in
        {"action": "wait", "frames": 3},
        {"action": "key", "key": "enter"},
        {"action": "wait", "frames": 3},
    ], cwd=tmp_path)
    assert result.returncode == 0, result.stderr[-2000:]
    saved = load_scene(tmp_path / "scene.json")
    assert saved.camera.elevation_deg == 22 and saved.mesh_path().name == "chair.obj"


def test_ctrl_s_on_the_shipped_demo_scene_leaves_it_alone_and_asks_for_a_name(display, tmp_path):
    demo = REPOSITORY / "assets" / "demo" / "scene.json"
    before = demo.read_bytes(), demo.stat().st_mtime_ns
    result = run_editor(display, tmp_path, demo, [
        {"action": "set_elevation", "deg": 20},
        {"action": "key", "key": "s", "mods": ["ctrl"]},
        {"action": "wait", "frames": 3},
        {"action": "screenshot", "path": str(tmp_path / "after.png")},
    ])
    assert result.returncode == 0, result.stderr[-2000:]
    assert (demo.read_bytes(), demo.stat().st_mtime_ns) == before
    assert "ships with NVR Studio and is not saved over" in result.stderr


def test_import_vox_makes_the_object_and_export_vox_writes_it_back(display, tmp_path, scene_file):
    from renderer.vox import read_vox, write_vox

    rgba = np.zeros((8, 8, 8, 4), np.float32)
    rgba[2:6, 0:5, 2:6] = (*GREEN, 1.0)
    rgba[2:6, 5:7, 2:6] = (*BLUE, 1.0)
    write_vox(tmp_path / "model.vox", rgba)
    result = run_editor(display, tmp_path, scene_file, [
        {"action": "import_vox", "path": str(tmp_path / "model.vox")},
        {"action": "save", "path": str(tmp_path / "imported.json")},
        {"action": "export_vox", "path": str(tmp_path / "back.vox")},
        {"action": "screenshot", "path": str(tmp_path / "imported.png")},
    ])
    assert result.returncode == 0, result.stderr[-2000:]
    scene = load_scene(tmp_path / "imported.json")
    assert scene.object.mesh is None and scene.object.resolution == 8
    assert Path(scene.voxels_path()).resolve().parent == tmp_path.resolve()  # copied beside the scene on save
    np.testing.assert_allclose(read_vox(tmp_path / "back.vox"), read_vox(tmp_path / "model.vox"), atol=0.5 / 255)
    assert share_of(pixels(tmp_path / "imported.png", PANELS.viewport), GREEN) > 0.005


def test_export_turntable_renders_in_the_background_with_the_panels_renderer(display, tmp_path, scene_file):
    from PIL import ImageSequence

    result = run_editor(display, tmp_path, scene_file, [
        {"action": "export_turntable", "path": str(tmp_path / "turn.gif"), "frames": 6, "sweep": "light"},
    ])
    assert result.returncode == 0, result.stderr[-2000:]
    with Image.open(tmp_path / "turn.gif") as gif:
        frames = [np.asarray(f.convert("RGB"), dtype=float) for f in ImageSequence.Iterator(gif)]
    assert len(frames) == 6 and frames[0].shape[:2] == (64, 64)  # the scene's image size, voxel shader
    assert np.abs(frames[0] - frames[3]).mean() > 1.0  # the light went round


def test_the_reference_button_path_traces_the_edited_scene_beside_the_render(display, tmp_path, scene_file):
    """The reference window shows the edited scene inside the viewport; Escape closes it, and so does another scene."""
    result = run_editor(display, tmp_path, scene_file, [
        {"action": "fill_object", "color": list(GREEN)},
        {"action": "screenshot", "path": str(tmp_path / "before.png")},
        {"action": "reference_render", "spp": 4},
        {"action": "wait", "frames": 3},
        {"action": "screenshot", "path": str(tmp_path / "after.png")},
        {"action": "key", "key": "escape"},
        {"action": "wait", "frames": 3},
        {"action": "screenshot", "path": str(tmp_path / "closed.png")},
        {"action": "reference_render", "spp": 4},
        {"action": "open", "path": str(scene_file)},
        {"action": "answer", "choice": "Discard"},
        {"action": "wait", "frames": 3},
        {"action": "screenshot", "path": str(tmp_path / "reopened.png")},
    ])
    assert result.returncode == 0, result.stderr[-2000:]
    v = PANELS.viewport
    corner = replace(v, x=v.x + v.width - 290, y=v.y + 8, width=270, height=270)  # where the reference window sits
    before, after = pixels(tmp_path / "before.png", corner), pixels(tmp_path / "after.png", corner)
    assert np.abs(after - before).max(axis=-1).mean() > 0.1  # the window appeared
    assert share_of(after, GREEN) > 0.003  # the path tracer shows the painted object, not the mesh's own colors
    closed, reopened = pixels(tmp_path / "closed.png", corner), pixels(tmp_path / "reopened.png", corner)
    assert np.abs(closed - before).max(axis=-1).mean() < 0.01  # Escape closed it
    assert share_of(reopened, GREEN) == 0.0  # the old scene's reference went with it
    right = Image.open(tmp_path / "after.png").convert("RGB").crop((v.x + v.width, v.y + 8, v.x + v.width + 40, v.y + 40))
    assert np.array_equal(np.asarray(right), np.asarray(Image.open(tmp_path / "before.png").convert("RGB").crop(
        (v.x + v.width, v.y + 8, v.x + v.width + 40, v.y + 40))))  # the window stays inside the viewport


def test_exports_at_a_chosen_size_render_the_shader_there_and_upscale_the_network(display, tmp_path, scene_file, model_file):
    result = run_editor(display, tmp_path, scene_file, [
        {"action": "export", "path": str(tmp_path / "shaded128.png"), "size": 128},
        {"action": "renderer", "name": "nvr+"},
        {"action": "export", "path": str(tmp_path / "network128.png"), "size": 128},
    ], "--model", str(model_file), "--renderer", "shaded")
    assert result.returncode == 0, result.stderr[-2000:]
    cli = tmp_path / "cli128.png"
    subprocess.run([sys.executable, "-m", "app.cli", "render", str(scene_file), "--renderer", "shaded", "--size", "128",
                    "-o", str(cli)], check=True, capture_output=True, timeout=120, cwd=REPOSITORY)
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "shaded128.png")), np.asarray(Image.open(cli)))
    assert Image.open(tmp_path / "network128.png").size == (128, 128)  # the 64 px network image, upscaled


def test_the_bucket_previews_the_region_it_would_fill_before_the_click(display, tmp_path, scene_file, model_file):
    scene = load_scene(scene_file)
    front = apply_transform(object_to_world(scene.object), voxel_centers_at(np.array([[8, 5, 11]]), 16) + [0, 0, 0.5 / 16])[0]
    result = run_editor(display, tmp_path, scene_file, [
        {"action": "tool", "name": "paint"},
        {"action": "paint_color", "color": list(GREEN)},
        {"action": "mouse_move", "pos": screen_position(front)},
        {"action": "wait", "frames": 25},
        {"action": "screenshot", "path": str(tmp_path / "hover.png")},
        {"action": "mouse_move", "pos": [PANELS.viewport.x + 20, PANELS.viewport.y + PANELS.viewport.height - 20]},
        {"action": "wait", "frames": 25},
        {"action": "screenshot", "path": str(tmp_path / "away.png")},
        {"action": "save", "path": str(tmp_path / "after.json")},
    ], "--model", str(model_file))
    assert result.returncode == 0, result.stderr[-2000:]
    hover, away = pixels(tmp_path / "hover.png", PANELS.viewport), pixels(tmp_path / "away.png", PANELS.viewport)
    tinted = np.asarray(RED) * 0.4 + np.asarray(GREEN) * 0.6
    assert share_of(hover, tuple(tinted)) > 0.003 and share_of(hover, RED) < share_of(away, RED)  # the red block, tinted
    assert share_of(away, RED) > 0.005  # back to red once the cursor leaves
    assert load_scene(tmp_path / "after.json").paint == ()  # a preview, not an edit


def test_ctrl_n_starts_an_untitled_scene_after_asking_and_open_recent_remembers_files(display, tmp_path, scene_file):
    state = tmp_path / "state"
    result = run_editor(display, tmp_path, scene_file, [
        {"action": "set_elevation", "deg": 20},
        {"action": "key", "key": "n", "mods": ["ctrl"]},
        {"action": "answer", "choice": "Discard"},
        {"action": "save", "path": str(tmp_path / "new.json")},
    ], state=state)
    assert result.returncode == 0, result.stderr[-2000:]
    new = load_scene(tmp_path / "new.json")
    assert Path(new.mesh_path()).resolve() == (REPOSITORY / "assets" / "demo" / "chair.obj").resolve()
    assert new.camera.elevation_deg == 30.0  # the new scene, not the edited one
    recent = json.loads((state / "nvr-studio" / "recent.json").read_text())
    assert recent[0] == str((tmp_path / "new.json").resolve())


def test_a_paint_stroke_recolors_the_viewport_faces_as_if_they_were_made_again(display, monkeypatch):
    """recolor (a paint stroke, the bucket's tint) draws what set_voxels of the painted voxels draws, without finding the
    faces again; the blocks drawn in motion take the new colors too."""
    import moderngl

    from app.editor.viewport import ViewportRenderer
    from renderer.paint import fill_region_voxels

    monkeypatch.setenv("DISPLAY", display)
    ctx = moderngl.create_standalone_context()
    n = 120  # finer than MOTION_RESOLUTION: the viewport also has blocks for drags
    rgba = np.zeros((n, n, n, 4), dtype=np.float32)
    i, j, k = np.ogrid[:n, :n, :n]
    rgba[(i - 60) ** 2 + (j - 40) ** 2 + (k - 60) ** 2 < 30**2] = (0.8, 0.3, 0.2, 1.0)
    rgba[40:80, 20:40, 40:80] = (0.2, 0.6, 0.3, 1.0)  # a green slab through the ball's lower half
    scene = Scene.single(object=ObjectSpec(voxels="unused.npz", resolution=n))
    view = viewport_camera(replace(HOME, distance=2.0), 320, 240)
    region = fill_region_voxels(rgba, (60, 30, 60), 0.05)  # the slab
    painted = rgba.copy()
    painted.reshape(-1, 4)[region, :3] = (0.1, 0.2, 0.9)

    def pixels(viewport: ViewportRenderer, moving: bool = False) -> np.ndarray:
        fbo = viewport.draw(320, 240, view, scene, (0.5, 0.5, 0.5), moving=moving)
        return np.frombuffer(fbo.read(components=3), dtype=np.uint8).reshape(240, 320, 3).astype(int)

    def made_from(voxels: np.ndarray) -> ViewportRenderer:
        viewport = ViewportRenderer(ctx)
        viewport.set_voxels(voxels)
        return viewport

    viewport = made_from(rgba)
    before, before_moving = pixels(viewport), pixels(viewport, moving=True)
    viewport.recolor(painted)
    assert np.array_equal(pixels(viewport), pixels(made_from(painted)))
    assert np.abs(pixels(viewport) - before).max() > 50  # the stroke shows
    assert np.array_equal(pixels(viewport, moving=True), pixels(made_from(painted), moving=True))
    assert not np.array_equal(pixels(viewport, moving=True), before_moving)
    tint = painted.reshape(-1, 4)[region[::2], :3] * 0.5  # every other slab voxel darker
    tinted = painted.copy()
    tinted.reshape(-1, 4)[region[::2], :3] = tint
    viewport.recolor(painted, (region[::2], tint))
    assert np.array_equal(pixels(viewport), pixels(made_from(tinted)))
    viewport.recolor(rgba)
    assert np.array_equal(pixels(viewport), before)


def test_a_fine_object_is_drawn_in_merged_blocks_while_the_user_drags(display, monkeypatch):
    """In motion the viewport draws a 200^3 object's 2^3 blocks (a block occupied if any voxel is): the same image as
    at rest with every voxel set to its block's merged value, with about a quarter of the faces."""
    import moderngl

    from app.editor.viewport import ViewportRenderer
    from renderer.grid import pool_voxels

    monkeypatch.setenv("DISPLAY", display)
    ctx = moderngl.create_standalone_context()
    n = 200
    rgba = np.zeros((n, n, n, 4), dtype=np.float32)
    i, j, k = np.ogrid[:n, :n, :n]
    ball = (i - 100) ** 2 + (j - 60) ** 2 + (k - 100) ** 2 < 50**2
    rgba[ball] = (0.8, 0.3, 0.2, 1.0)
    rgba[101, 110:190, 99] = (0.2, 0.3, 0.9, 1.0)  # a rod one voxel thick on top: a block holding it stays occupied
    blocks = pool_voxels(rgba, (2, 2, 2))
    as_blocks = blocks.repeat(2, axis=0).repeat(2, axis=1).repeat(2, axis=2)  # every voxel its block's value
    scene = Scene.single(object=ObjectSpec(voxels="unused.npz", resolution=n))
    view = viewport_camera(replace(HOME, distance=2.0), 320, 240)  # the object fills much of the view

    def pixels(voxels: np.ndarray, moving: bool) -> np.ndarray:
        viewport = ViewportRenderer(ctx)
        viewport.set_voxels(voxels)
        fbo = viewport.draw(320, 240, view, scene, (0.5, 0.5, 0.5), moving=moving)
        return np.frombuffer(fbo.read(components=3), dtype=np.uint8).reshape(240, 320, 3).astype(float)

    at_rest, moving, expected = pixels(rgba, False), pixels(rgba, True), pixels(as_blocks, False)
    assert np.abs(moving - expected).mean() < 0.05  # the same surface, up to a few edge pixels
    assert np.abs(moving - at_rest).max(axis=2).astype(bool).any()  # the blocks, not the voxels, in motion

    def rod(image: np.ndarray) -> int:  # pixels where the blue rod shows
        return int(np.count_nonzero((image[..., 2] > image[..., 0] + 30) & (image[..., 2] > image[..., 1] + 20)))

    assert rod(moving) >= max(0.5 * rod(at_rest), 10)  # the one-voxel rod is still there in motion
    viewport = ViewportRenderer(ctx)
    assert viewport.quads_in_motion == 0
    quads_at_rest = viewport.set_voxels(rgba)
    assert viewport.quads_in_motion <= quads_at_rest / 3.5
    one = viewport.quads_in_motion
    for index in range(1, 4):  # four objects: each drawn coarser in motion, about one object's faces in all
        viewport.set_voxels(rgba, index)
    assert viewport.quads_in_motion <= 1.5 * one


def test_save_as_and_exports_follow_the_open_scene(display, tmp_path, scene_file):
    """After Save as into another folder, Ctrl+E exports beside the new scene file, not where the editor started."""
    moved = tmp_path / "elsewhere" / "scene.json"
    moved.parent.mkdir()
    started_in = tmp_path / "started here"
    started_in.mkdir()
    run_editor(display, tmp_path, scene_file, [
        {"action": "save", "path": str(moved)},
        {"action": "wait", "frames": 2},
        {"action": "key", "key": "e", "mods": ["ctrl"]},
        {"action": "wait", "frames": 2},
    ], cwd=started_in)
    assert (moved.parent / "render.png").is_file()
    assert not (started_in / "render.png").exists() and not (scene_file.parent / "render.png").exists()


def test_sky_environment_image_and_material_edits_render_save_and_undo(display, tmp_path, scene_file):
    """The Light tab's sun and sky, an environment image, the area light switch and the Object tab's material: each
    one undo step, saved in the scene, and seen in the render panel."""
    import mitsuba as mi

    from renderer.pathtrace.mitsuba_variant import active_variant

    active_variant()
    studio = np.full((32, 64, 3), 0.3, dtype=np.float32)
    studio[4:10, 20:30] = 40.0  # a soft box high on one side
    mi.Bitmap(studio).write(str(tmp_path / "studio.exr"))
    (tmp_path / "not_a_map.hdr").write_text("hello")
    shots = {name: str(tmp_path / f"{name}.png") for name in ("start", "sky", "metal")}
    saved = {name: str(tmp_path / f"{name}.json") for name in ("start", "edited", "undone", "image")}
    run_editor(display, tmp_path, scene_file, [
        {"action": "save", "path": saved["start"]},
        {"action": "screenshot", "path": shots["start"]},
        {"action": "area_light", "on": False},  # refused: nothing else lights the scene
        {"action": "use_sky"},
        {"action": "set_sky", "elevation": 25, "azimuth": -70, "turbidity": 4},
        {"action": "area_light", "on": False},
        {"action": "turn_environment", "deg": 30, "strength": 1.5},
        {"action": "screenshot", "path": shots["sky"]},
        {"action": "material", "preset": "metal", "roughness": 0.2},
        {"action": "screenshot", "path": shots["metal"]},
        {"action": "save", "path": saved["edited"]},
        {"action": "undo"}, {"action": "undo"}, {"action": "undo"}, {"action": "undo"}, {"action": "undo"},
        {"action": "save", "path": saved["undone"]},
        {"action": "load_environment", "path": str(tmp_path / "not_a_map.hdr")},  # refused, the scene stays
        {"action": "load_environment", "path": str(tmp_path / "studio.exr")},
        {"action": "save", "path": saved["image"]},
    ])
    edited = load_scene(saved["edited"])
    assert edited.environment.sky.sun_azimuth_deg == -70.0 and edited.environment.sky.turbidity == 4.0
    assert edited.environment.rotation_deg == 30.0 and edited.environment.strength == 1.5
    assert not edited.light.enabled and edited.object.material.metallic == 1.0
    assert edited.object.material.roughness == 0.2
    assert Path(saved["undone"]).read_text() == Path(saved["start"]).read_text()
    image = load_scene(saved["image"])
    assert image.environment_path().resolve() == (tmp_path / "studio.exr").resolve() and image.environment.sky is None
    render = PANELS.render_image
    start, sky, metal = (pixels(Path(shots[n]), render) for n in ("start", "sky", "metal"))
    assert np.abs(sky - start).mean() > 0.02 and np.abs(metal - sky).mean() > 0.005


def test_a_floor_texture_loads_scales_renders_saves_and_undoes(display, tmp_path, scene_file):
    """The Light tab's floor texture: a file that is not an image is refused and the scene stays; an image textures
    the floor in the render panel (its mean becomes the floor color); its repeat scales; the floor becomes a disk whose
    edge shows the sky's grey above it; each is one undo step."""
    from PIL import Image

    tiles = np.zeros((64, 64, 3), dtype=np.uint8)
    tiles[:32, :32] = tiles[32:, 32:] = (230, 200, 150)
    tiles[:32, 32:] = tiles[32:, :32] = (60, 40, 30)
    Image.fromarray(tiles).save(tmp_path / "tiles.png")
    (tmp_path / "not_an_image.png").write_text("hello")
    shots = {name: str(tmp_path / f"{name}.png") for name in ("plain", "tiled", "finer", "disk")}
    saved = {name: str(tmp_path / f"{name}.json") for name in ("start", "tiled", "undone")}
    result = run_editor(display, tmp_path, scene_file, [
        {"action": "save", "path": saved["start"]},
        {"action": "screenshot", "path": shots["plain"]},
        {"action": "load_floor_texture", "path": str(tmp_path / "not_an_image.png")},
        {"action": "load_floor_texture", "path": str(tmp_path / "tiles.png")},
        {"action": "wait", "frames": 3},
        {"action": "screenshot", "path": shots["tiled"]},
        {"action": "floor_texture_scale", "scale": 0.25},
        {"action": "wait", "frames": 3},
        {"action": "screenshot", "path": shots["finer"]},
        {"action": "floor_shape", "shape": "disk"},
        {"action": "wait", "frames": 3},
        {"action": "screenshot", "path": shots["disk"]},
        {"action": "save", "path": saved["tiled"]},
        {"action": "undo"}, {"action": "undo"}, {"action": "undo"},
        {"action": "save", "path": saved["undone"]},
    ])
    assert "not a readable image" in result.stderr
    tiled = load_scene(saved["tiled"])
    assert tiled.floor_texture_path().resolve() == (tmp_path / "tiles.png").resolve()
    assert tiled.floor.texture_scale == 0.25 and tiled.floor.shape == "disk"
    mean = ((np.array([230, 200, 150]) / 255.0) ** 2.2 + (np.array([60, 40, 30]) / 255.0) ** 2.2) / 2.0
    np.testing.assert_allclose(tiled.floor.color, mean ** (1 / 2.2), atol=0.02)  # the tiles' mean, in sRGB
    assert Path(saved["undone"]).read_text() == Path(saved["start"]).read_text()
    plain, with_tiles, finer = (pixels(Path(shots[n]), PANELS.render_image) for n in ("plain", "tiled", "finer"))
    assert np.abs(with_tiles - plain).mean() > 0.03 and np.abs(finer - with_tiles).mean() > 0.01
    # Tiles of two colors make the floor's pixels far more varied than the plain floor's.
    assert with_tiles[-40:].std() > 2.0 * plain[-40:].std()
    # The viewport's floor shows the tiles too (its lower part is floor in both shots).
    plain_floor, tiled_floor = (pixels(Path(shots[n]), PANELS.viewport)[-150:] for n in ("plain", "tiled"))
    assert tiled_floor.std() > 2.0 * plain_floor.std()
    disk = pixels(Path(shots["disk"]), PANELS.render_image)
    assert np.abs(disk - finer).mean() > 0.005 and np.abs(disk[-40:] - finer[-40:]).mean() < 0.01  # the near floor stays


LIGHT_TAB, SUN_WIDGET_CENTRE = _tools_point(105, 39), _tools_point(83, 204)  # under a sky, the area light on


def test_the_sun_is_dragged_on_its_hemisphere_in_one_undo_step(display, tmp_path, scene_file):
    """The Light tab's hemisphere (the sky from above, the camera's side down): dragging the sun from behind on the
    right to the front on the left brings it to the camera's left and lower, and one undo puts it back."""
    saved = {name: str(tmp_path / f"{name}.json") for name in ("before", "after", "undone")}
    cx, cy = SUN_WIDGET_CENTRE
    start = [cx + 35.0, cy - 21.0]  # where the sun at 35 degrees up, azimuth 120 shows (radius 67)
    run_editor(display, tmp_path, scene_file, [
        {"action": "use_sky"},
        {"action": "set_sky", "elevation": 35, "azimuth": 120, "turbidity": 3},
        {"action": "mouse_move", "pos": LIGHT_TAB}, {"action": "mouse_down", "button": 0},
        {"action": "wait", "frames": 2}, {"action": "mouse_up", "button": 0}, {"action": "wait", "frames": 3},
        {"action": "save", "path": saved["before"]},
        {"action": "mouse_move", "pos": start}, {"action": "wait", "frames": 2},
        {"action": "mouse_down", "button": 0}, {"action": "wait", "frames": 2},
        {"action": "mouse_move", "pos": [cx - 10.0, cy + 10.0]}, {"action": "wait", "frames": 2},
        {"action": "mouse_move", "pos": [cx - 38.0, cy + 31.0]}, {"action": "wait", "frames": 2},
        {"action": "mouse_up", "button": 0}, {"action": "wait", "frames": 3},
        {"action": "save", "path": saved["after"]},
        {"action": "undo"},
        {"action": "save", "path": saved["undone"]},
    ])
    before, after = (load_scene(saved[n]).environment.sky for n in ("before", "after"))
    assert (before.sun_elevation_deg, before.sun_azimuth_deg) == (35.0, 120.0)
    # 49 px from the centre of a 67 px horizon, down and to the left: about 24 degrees up, azimuth about -51.
    assert abs(after.sun_elevation_deg - 24.1) < 4.0 and abs(after.sun_azimuth_deg + 50.8) < 5.0
    assert Path(saved["undone"]).read_text() == Path(saved["before"]).read_text()


def test_numpad_views_f_frames_the_object_f1_lists_every_key_and_delete_says_why(display, tmp_path, scene_file):
    shots = {name: str(tmp_path / f"{name}.png") for name in ("start", "top", "framed", "help", "closed")}
    result = run_editor(display, tmp_path, scene_file, [
        {"action": "mouse_move", "pos": [PANELS.viewport.x + 300, PANELS.viewport.y + 300]},
        {"action": "screenshot", "path": shots["start"]},
        {"action": "key", "key": "kp_7"},
        {"action": "screenshot", "path": shots["top"]},
        {"action": "key", "key": "f"},
        {"action": "screenshot", "path": shots["framed"]},
        {"action": "key", "key": "delete"},
        {"action": "key", "key": "f1"},
        {"action": "wait", "frames": 2},
        {"action": "screenshot", "path": shots["help"]},
        {"action": "key", "key": "escape"},
        {"action": "wait", "frames": 2},
        {"action": "screenshot", "path": shots["closed"]},
        {"action": "save", "path": str(tmp_path / "after.json")},
    ])
    start, top, framed, help_, closed = (pixels(Path(shots[n]), PANELS.viewport) for n in shots)
    assert np.abs(top - start).mean() > 0.03 and np.abs(framed - top).mean() > 0.01
    assert np.abs(help_ - framed).mean() > 0.01 and np.abs(closed - framed).mean() < 0.002
    assert "a scene holds at least one object" in result.stderr  # Delete on the only object
    after, before = load_scene(tmp_path / "after.json"), load_scene(scene_file)  # the keys changed the view alone
    assert (after.object.translation, after.object.rotation_deg, after.light, after.camera, after.paint) == (
        before.object.translation, before.object.rotation_deg, before.light, before.camera, before.paint)


def test_open_takes_a_mesh_as_a_new_scene_and_names_what_it_cannot_open(display, tmp_path, scene_file):
    shutil.copy(REPOSITORY / "assets" / "demo" / "chair.obj", tmp_path / "stool.obj")
    (tmp_path / "notes.txt").write_text("not a scene")
    result = run_editor(display, tmp_path, scene_file, [
        {"action": "open", "path": str(tmp_path / "notes.txt")},
        {"action": "open", "path": str(tmp_path / "stool.obj")},
        {"action": "save", "path": str(tmp_path / "from_mesh.json")},
    ])
    assert "Open takes scenes (.json), meshes" in result.stderr and "not .txt" in result.stderr
    opened = load_scene(tmp_path / "from_mesh.json")
    assert opened.mesh_path().resolve() == (tmp_path / "stool.obj").resolve() and opened.paint == ()


def test_alt_click_picks_the_voxels_color_for_the_bucket(display, tmp_path, scene_file):
    """The eyedropper: with the bucket, Alt+click on the red block takes its color; a plain click on the blue top
    then fills it with that red."""
    scene = load_scene(scene_file)
    place = object_to_world(scene.object)
    red_front = apply_transform(place, voxel_centers_at(np.array([[8, 5, 11]]), 16) + [0, 0, 0.5 / 16])[0]
    blue_top = apply_transform(place, voxel_centers_at(np.array([[8, 11, 8]]), 16) + [0, 0.5 / 16, 0])[0]
    result = run_editor(display, tmp_path, scene_file, [
        {"action": "tool", "name": "paint"},
        {"action": "paint_color", "color": list(GREEN)},
        {"action": "mouse_move", "pos": screen_position(red_front)},
        {"action": "mouse_down", "button": 0, "mods": ["alt"]},
        {"action": "mouse_up", "button": 0},
        {"action": "save", "path": str(tmp_path / "picked.json")},
        {"action": "mouse_move", "pos": screen_position(blue_top)},
        {"action": "mouse_down", "button": 0},
        {"action": "mouse_up", "button": 0},
        {"action": "save", "path": str(tmp_path / "filled.json")},
    ])
    assert result.returncode == 0, result.stderr[-2000:]
    assert load_scene(tmp_path / "picked.json").paint == ()  # picking paints nothing
    (stroke,) = load_scene(tmp_path / "filled.json").paint
    assert stroke.color == pytest.approx(RED, abs=1 / 255) and stroke.seed[1] >= 10  # the top, in the red (8-bit voxels)


def test_dragging_the_column_border_widens_the_render_panel_and_its_image(display, tmp_path, scene_file):
    border = [PANELS.render.x, PANELS.render.y + 300]
    wide = layout_for(*WINDOW, right_width=WINDOW[0] - 540)
    run_editor(display, tmp_path, scene_file, [
        {"action": "screenshot", "path": str(tmp_path / "before.png")},
        {"action": "mouse_move", "pos": border},
        {"action": "mouse_down", "button": 0},
        {"action": "mouse_move", "pos": [border[0] - 150, border[1]]},
        {"action": "mouse_move", "pos": [540, border[1]]},
        {"action": "mouse_up", "button": 0},
        {"action": "wait", "frames": 30},
        {"action": "screenshot", "path": str(tmp_path / "after.png")},
    ])
    assert wide.render.x == 540 and wide.render_image.width > PANELS.render_image.width + 20  # as high as it may be
    # Where the viewport was, the wide render panel now shows: its image, and above it its title bar.
    strip = replace(wide.render_image, x=wide.render_image.x + 20, width=60, y=wide.render_image.y + 100, height=60)
    before, after = pixels(tmp_path / "before.png", strip), pixels(tmp_path / "after.png", strip)
    assert np.abs(after - before).mean() > 0.05
    title = pixels(tmp_path / "after.png", Rect(560, wide.render.y + 2, 40, 14))  # the render panel's title bar
    assert np.abs(title - pixels(tmp_path / "before.png", Rect(560, wide.render.y + 2, 40, 14))).mean() > 0.05


def test_an_export_can_voxelise_the_mesh_finer_and_the_scene_keeps_its_voxels(display, tmp_path, scene_file):
    shutil.copy(REPOSITORY / "assets" / "demo" / "chair.obj", tmp_path / "chair.obj")
    coarse = replace(load_scene(REPOSITORY / "assets" / "demo" / "scene.json"), base_dir=tmp_path)
    coarse = replaced(coarse, object=replace(coarse.object, resolution=64), image_size=64)
    save_scene(coarse, tmp_path / "chair.json")
    result = run_editor(display, tmp_path, tmp_path / "chair.json", [
        {"action": "export", "path": str(tmp_path / "own.png"), "size": 256},
        {"action": "export", "path": str(tmp_path / "fine.png"), "size": 256, "voxels": 256},
        {"action": "save", "path": str(tmp_path / "after.json")},
        {"action": "open", "path": str(scene_file)},  # an object of voxels, no mesh: refused in one line
        {"action": "export", "path": str(tmp_path / "refused.png"), "size": 256, "voxels": 256},
    ])
    own, fine = (np.asarray(Image.open(tmp_path / f"{n}.png"), dtype=np.float64) for n in ("own", "fine"))
    assert own.shape == fine.shape == (256, 256, 3) and np.abs(own - fine).mean() > 0.5
    assert load_scene(tmp_path / "after.json").object.resolution == 64
    assert "no mesh to voxelise more finely" in result.stderr and not (tmp_path / "refused.png").exists()
