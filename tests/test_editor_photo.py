"""The Photo tab through the real window under Xvfb: load a photo, align the object to it (search or mouse),
take its view, color the object from it, undo; bad photos leave the scene alone.

The object is a generated chair (24^3 voxels, so voxelising is quick); the photo is its
silhouette, blue on a gray backdrop, at a known pose (rendering it takes milliseconds).
Each test runs `nvr-editor --frames ... --replay ...` and checks the scene files it saves.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from renderer.camera import Camera
from renderer.capture.align import rotation_error_deg
from renderer.capture.pose import PhotoPose, save_pose
from renderer.capture.silhouette import SilhouetteRenderer
from renderer.objects import generate_object
from renderer.pathtrace.path_tracer import render_pathtraced
from renderer.pipeline import object_voxels
from renderer.scene import CameraSpec, LightSpec, ObjectSpec, Scene, load_scene, replaced, save_scene
from tests import test_editor
from tests.test_editor import PANELS, _click, pixels, run_editor

model_file = test_editor.model_file  # the window tests' tiny NVR+ (the Xvfb display comes from conftest.py)

TRUTH = PhotoPose(Camera(25.0, 120, 100), rotation_deg=-35.0, translation=(0.1, -0.05))  # where the photo was taken
START = ObjectSpec(mesh="chair.obj", resolution=24, rotation_deg=20.0)  # the scene before: turned and seen otherwise
CHAIR_BLUE, BACKDROP = (0.2, 0.4, 0.9), 0.75
OUTLINE = (1.0, 0.2, 0.6)  # app/editor/photo_capture.py OUTLINE_COLOR
# Window pixels in the 1280x800 window (tests/test_editor.py WINDOW): the Photo tab's label, and the middle of the
# photo as it covers the viewport once loaded (the 120 x 100 photo fitted to the 840 x 752 viewport: 7 times larger).
PHOTO_TAB, PHOTO_MIDDLE = [1062, 539], [420, 398]
PHOTO_SCALE = 7.0
PHOTO_ORIGIN = (0.0, 398 - 50 * PHOTO_SCALE)  # window pixels of the photo's top left corner, fitted


@pytest.fixture(scope="module")
def chair_scene(tmp_path_factory):
    """The chair's scene, its photo (the silhouette at TRUTH) and the photo's camera file."""
    folder = tmp_path_factory.mktemp("chair")
    chair = generate_object("chair", 8).mesh
    chair.export(folder / "chair.obj")
    mask = SilhouetteRenderer(chair).mask(TRUTH)
    photo = np.where(mask[..., None], np.array(CHAIR_BLUE), BACKDROP)
    Image.fromarray((photo * 255).round().astype(np.uint8)).save(folder / "photo.png")
    save_pose(folder / "camera.json", TRUTH)
    scene = Scene.single(object=START, camera=CameraSpec(35.0), image_size=64, base_dir=folder)
    save_scene(scene, folder / "scene.json")
    return folder / "scene.json"


def test_a_photo_without_camera_is_aligned_from_scratch_and_the_scene_takes_its_view(display, tmp_path, chair_scene,
                                                                                    model_file):
    run_editor(display, tmp_path, chair_scene, [
        {"action": "load_photo", "photo": str(chair_scene.parent / "photo.png")},
        *aligned_and_saved(tmp_path / "aligned.json"),
        {"action": "undo"},
        {"action": "save", "path": str(tmp_path / "undone.json")},
    ], "--model", str(model_file))
    aligned = load_scene(tmp_path / "aligned.json")
    assert rotation_error_deg(aligned.object.rotation_deg, TRUTH.rotation_deg) < 3.0  # from 55 degrees away
    assert aligned.camera.elevation_deg == pytest.approx(TRUTH.camera.elevation_deg, abs=3.0)  # from 35
    np.testing.assert_allclose(aligned.object.translation, TRUTH.translation, atol=0.03)
    np.testing.assert_allclose(aligned.object.scale, (1.0, 1.0, 1.0), atol=0.05)
    assert aligned.light == load_scene(chair_scene).light and aligned.object.voxels is None  # the view only
    undone = load_scene(tmp_path / "undone.json")
    assert (undone.object.rotation_deg, undone.camera.elevation_deg) == (START.rotation_deg, 35.0)  # one undo step


def test_color_from_the_photo_changes_the_voxels_and_undo_restores_them_exactly(display, tmp_path, chair_scene,
                                                                              model_file):
    folder = chair_scene.parent
    run_editor(display, tmp_path, chair_scene, [  # the camera-file flow: the photo's pose is known, no search
        {"action": "load_photo", "photo": str(folder / "photo.png"), "camera": str(folder / "camera.json")},
        {"action": "color_from_photo"},
        {"action": "save", "path": str(tmp_path / "colored.json")},
        {"action": "undo"},
        {"action": "save", "path": str(tmp_path / "undone.json")},
    ], "--model", str(model_file))
    before = object_voxels(load_scene(chair_scene))
    colored_scene = load_scene(tmp_path / "colored.json")
    colored = object_voxels(colored_scene)
    occupied = before[..., 3] > 0.5
    assert np.array_equal(colored[..., 3], before[..., 3])  # the same shape
    assert np.all(before[occupied][:, :3] == 0.5)  # the mesh has no colors: gray
    blue = np.abs(colored[occupied][:, :3] - CHAIR_BLUE).max(axis=1) < 0.02
    assert blue.mean() > 0.5  # the photo shows (or the mirror copies) most of the chair, all of it blue
    assert colored_scene.mesh_path().resolve() == (folder / "chair.obj").resolve()  # the mesh stays: its shape, for aligning
    assert colored_scene.object.rotation_deg == START.rotation_deg  # coloring does not move the object
    undone = load_scene(tmp_path / "undone.json")
    assert undone.object.voxels is None
    np.testing.assert_array_equal(object_voxels(undone), before)


def test_a_bad_photo_is_a_message_and_the_scene_stays(display, tmp_path, chair_scene, model_file):
    folder = chair_scene.parent
    (tmp_path / "broken.png").write_bytes(b"not a png")
    result = run_editor(display, tmp_path, chair_scene, [
        {"action": "load_photo", "photo": str(tmp_path / "missing.png")},
        {"action": "load_photo", "photo": str(tmp_path / "broken.png")},
        {"action": "load_photo", "photo": str(folder / "photo.png"), "camera": "assets/demo/photo_camera.json"},
        {"action": "align_photo"},
        {"action": "color_from_photo"},
        {"action": "match_photo_view"},
        {"action": "save", "path": str(tmp_path / "unchanged.json")},
    ], "--model", str(model_file))
    errors = [line for line in result.stderr.splitlines() if line.startswith("nvr-editor: ")]
    assert errors == [
        f"nvr-editor: {tmp_path / 'missing.png'}: file not found",
        f"nvr-editor: {tmp_path / 'broken.png'}: not a readable image (cannot identify image file "
        f"'{tmp_path / 'broken.png'}')",
        f"nvr-editor: {folder / 'photo.png'}: the photo is 120x100 pixels but its camera is 256x256",
        *["nvr-editor: load a photo first (Photo tab)"] * 3,
    ]  # the first says the tiny model is used; no traceback
    assert "Traceback" not in result.stderr
    unchanged, original = load_scene(tmp_path / "unchanged.json"), load_scene(chair_scene)
    assert unchanged.mesh_path().resolve() == original.mesh_path().resolve()
    assert replaced(unchanged, base_dir=original.base_dir, object=original.object) == original
    assert replace(unchanged.object, mesh=original.object.mesh) == original.object


def test_dragging_on_the_photo_turns_shift_drag_moves_and_the_wheel_scales(display, tmp_path, chair_scene, model_file):
    folder = chair_scene.parent
    x, y = PHOTO_MIDDLE
    click = [{"action": "wait", "frames": 2}, {"action": "mouse_down", "button": 0},
             {"action": "wait", "frames": 2}, {"action": "mouse_up", "button": 0}]
    run_editor(display, tmp_path, chair_scene, [
        {"action": "mouse_move", "pos": PHOTO_TAB}, *click,
        {"action": "load_photo", "photo": str(folder / "photo.png"), "camera": str(folder / "camera.json")},
        {"action": "screenshot", "path": str(tmp_path / "tab.png")},
        {"action": "mouse_move", "pos": [x, y]}, {"action": "wait", "frames": 2},
        {"action": "mouse_down", "button": 0}, {"action": "wait", "frames": 2},
        {"action": "mouse_move", "pos": [x + 40, y - 10]}, {"action": "wait", "frames": 2},  # 0.5 degree a pixel
        {"action": "mouse_up", "button": 0},
        {"action": "mouse_down", "button": 0, "mods": ["shift"]}, {"action": "wait", "frames": 2},
        {"action": "mouse_move", "pos": [x + 15, y]}, {"action": "wait", "frames": 2},  # 0.004 object units a pixel
        {"action": "mouse_up", "button": 0},
        {"action": "scroll", "dy": 2}, {"action": "wait", "frames": 2},  # 5 % a step
        {"action": "screenshot", "path": str(tmp_path / "posed.png")},
        {"action": "match_photo_view"},
        {"action": "save", "path": str(tmp_path / "posed.json")},
    ], "--model", str(model_file))
    posed = load_scene(tmp_path / "posed.json")
    assert posed.object.rotation_deg == pytest.approx(TRUTH.rotation_deg + 20.0)
    assert posed.camera.elevation_deg == pytest.approx(TRUTH.camera.elevation_deg - 5.0)
    assert posed.object.translation == pytest.approx((TRUTH.translation[0] - 0.1, TRUTH.translation[1] + 0.04))
    assert posed.object.scale == pytest.approx((1.05**2,) * 3)
    shown = (pixels(tmp_path / name, PANELS.viewport) for name in ("tab.png", "posed.png"))
    outlines = [np.all(np.abs(t - OUTLINE) < 0.03, axis=-1) for t in shown]
    assert outlines[0].sum() > 300  # the viewport shows the photo with the chair's outline
    assert (outlines[0] != outlines[1]).sum() > 300  # which follows the pose



def aligned_and_saved(path: Path) -> list[dict]:
    """Replay actions: align from scratch, take the photo's view, save the scene to `path`."""
    return [{"action": "align_photo", "from_scratch": True}, {"action": "match_photo_view"},
            {"action": "save", "path": str(path)}]


def cluttered_photo(chair_scene: Path, folder: Path) -> Path:
    """The chair's photo with a second blue thing at its left edge, written into `folder`."""
    photo = np.asarray(Image.open(chair_scene.parent / "photo.png").convert("RGB")).copy()
    photo[5:40, 2:22] = (np.array(CHAIR_BLUE) * 255).round()
    Image.fromarray(photo).save(folder / "cluttered.png")
    return folder / "cluttered.png"


def test_a_box_drawn_on_the_photo_keeps_a_distractor_out_of_the_alignment(display, tmp_path, chair_scene, model_file):
    cluttered = cluttered_photo(chair_scene, tmp_path)
    mask = SilhouetteRenderer(generate_object("chair", 8).mesh).mask(TRUTH)
    ys, xs = np.nonzero(mask)
    box = [int(xs.min()) - 4, int(ys.min()) - 4, int(xs.max()) + 5, int(ys.max()) + 5]
    run_editor(display, tmp_path, chair_scene, [
        {"action": "load_photo", "photo": str(cluttered)},
        {"action": "photo_box", "box": box},
        *aligned_and_saved(tmp_path / "boxed.json"),
    ], "--model", str(model_file))
    aligned = load_scene(tmp_path / "boxed.json")
    assert rotation_error_deg(aligned.object.rotation_deg, TRUTH.rotation_deg) < 3.0
    np.testing.assert_allclose(aligned.object.translation, TRUTH.translation, atol=0.03)


def test_in_box_mode_a_drag_on_the_photo_draws_the_box(display, tmp_path, chair_scene, model_file):
    box_mode = [922, 688]  # the "box" drag mode radio button, under the "Photo over the viewport" row
    run_editor(display, tmp_path, chair_scene, [
        {"action": "load_photo", "photo": str(chair_scene.parent / "photo.png")},
        *_click(PHOTO_TAB),
        *_click(box_mode),
        {"action": "mouse_move", "pos": [300, 300]}, {"action": "mouse_down", "button": 0}, {"action": "wait", "frames": 2},
        {"action": "mouse_move", "pos": [500, 500]}, {"action": "wait", "frames": 2}, {"action": "mouse_up", "button": 0},
        {"action": "wait", "frames": 3},
        {"action": "screenshot", "path": str(tmp_path / "box.png")},
        {"action": "save", "path": str(tmp_path / "after.json")},
    ], "--model", str(model_file))
    image = np.asarray(Image.open(tmp_path / "box.png").convert("RGB"), dtype=float) / 255.0
    yellow = (image[..., 0] > 0.9) & (image[..., 1] > 0.75) & (image[..., 2] < 0.35)
    assert yellow[295:505, 295:505].sum() > 400  # the box's outline where the mouse went
    assert load_scene(tmp_path / "after.json").object.rotation_deg == START.rotation_deg  # the drag posed nothing


def test_a_background_stroke_keeps_a_distractor_out_and_the_mask_shows_over_the_photo(display, tmp_path, chair_scene,
                                                                                     model_file):
    cluttered = cluttered_photo(chair_scene, tmp_path)
    run_editor(display, tmp_path, chair_scene, [
        *_click(PHOTO_TAB),
        {"action": "load_photo", "photo": str(cluttered)},
        *[{"action": "photo_stroke", "at": [12, y], "radius": 9, "kind": "background"} for y in (12, 22, 32)],
        {"action": "show_photo_mask"},
        {"action": "wait", "frames": 3},
        {"action": "screenshot", "path": str(tmp_path / "mask.png")},
        *aligned_and_saved(tmp_path / "stroked.json"),
    ], "--model", str(model_file))
    aligned = load_scene(tmp_path / "stroked.json")
    assert rotation_error_deg(aligned.object.rotation_deg, TRUTH.rotation_deg) < 3.0
    image = pixels(tmp_path / "mask.png", PANELS.viewport)
    red = np.all(np.abs(image - np.array([0.95, 0.3, 0.2])) < 0.05, axis=-1)
    assert red.sum() > 1000  # the stroke over the distractor
    darkened = np.all(np.abs(image - BACKDROP * 0.45) < 0.03, axis=-1)
    assert darkened.sum() > 50_000  # the segmented background, darkened


def test_the_photo_over_the_viewport_zooms_about_the_mouse_pans_and_goes_back_into_the_tab(display, tmp_path, chair_scene,
                                                                                      model_file):
    """Ctrl+wheel zooms about the mouse (the photo's pixel under it stays there) and leaves the object's scale alone;
    middle-drag pans; unticking "Photo over the viewport" gives the viewport back and shows the photo in the tab."""
    folder = chair_scene.parent
    corner = [200, 200]  # a point of the fitted photo: photo pixel ((200 - 0) / 7, (200 - 48) / 7)
    run_editor(display, tmp_path, chair_scene, [
        *_click(PHOTO_TAB),
        {"action": "load_photo", "photo": str(folder / "photo.png"), "camera": str(folder / "camera.json")},
        {"action": "show_photo_mask"},
        {"action": "wait", "frames": 10},
        {"action": "screenshot", "path": str(tmp_path / "fitted.png")},
        {"action": "mouse_move", "pos": corner}, {"action": "wait", "frames": 2},
        {"action": "scroll", "dy": 2, "mods": ["ctrl"]}, {"action": "wait", "frames": 3},
        {"action": "screenshot", "path": str(tmp_path / "zoomed.png")},
        {"action": "mouse_down", "button": 2}, {"action": "wait", "frames": 2},
        {"action": "mouse_move", "pos": [corner[0] + 60, corner[1] + 30]}, {"action": "wait", "frames": 2},
        {"action": "mouse_up", "button": 2}, {"action": "wait", "frames": 3},
        {"action": "screenshot", "path": str(tmp_path / "panned.png")},
        *_click([858, 664]),  # the "Photo over the viewport" box
        {"action": "wait", "frames": 3},
        {"action": "screenshot", "path": str(tmp_path / "in_tab.png")},
        {"action": "save", "path": str(tmp_path / "after.json")},
    ], "--model", str(model_file))
    assert load_scene(tmp_path / "after.json").object.scale == (1.0, 1.0, 1.0)  # the wheel zoomed the view only
    shots = {name: np.asarray(Image.open(tmp_path / f"{name}.png").convert("RGB"), dtype=float) / 255.0
             for name in ("fitted", "zoomed", "panned", "in_tab")}
    zoom = 1.25**2

    def fitted_at(x: float, y: float) -> np.ndarray:
        """The fitted photo's pixel that the zoomed view shows at window pixel (x, y), zoomed about `corner`."""
        return shots["fitted"][round(corner[1] + (y - corner[1]) / zoom), round(corner[0] + (x - corner[0]) / zoom)]

    def outline(image: np.ndarray) -> np.ndarray:
        return np.all(np.abs(image - OUTLINE) < 0.03, axis=-1)

    # The mask over the photo, the background darkened (its rim lies under the outline at this photo's size).
    shown = pixels(tmp_path / "fitted.png", PANELS.viewport)
    assert np.all(np.abs(shown - BACKDROP * 0.45) < 0.03, axis=-1).sum() > 100_000

    # The zoomed view is the fitted one scaled about the mouse: compare where the chair's outline lies.
    ys, xs = np.nonzero(outline(shots["zoomed"][30:770, :840]))
    ys += 30
    agree = np.mean([np.all(np.abs(fitted_at(x, y) - OUTLINE) < 0.05) for x, y in zip(xs[::7], ys[::7])])
    assert len(xs) > 500 and agree > 0.7
    # Panned by (60, 30) window pixels: the zoomed outline moved by as much.
    moved = outline(shots["panned"][30 + 30:770, 60:840])
    assert np.mean(moved[: 740 - 30, : 780] == outline(shots["zoomed"][30:770 - 30, :780])) > 0.99
    viewport, tools = (pixels(tmp_path / "in_tab.png", rect) for rect in (PANELS.viewport, PANELS.tools))
    assert outline(viewport).sum() < 50 and outline(tools).sum() > 30  # the photo back in the tab


def test_coloring_divides_out_the_photos_fitted_light_and_the_scene_can_take_it(display, tmp_path, chair_scene,
                                                                                 model_file):
    """A path-traced photo of the grey chair under a known light: colored with the light divided out, the chair's
    voxels are more even than with the shading kept; "use" moves the scene's light to the fitted one, which stands
    where the photo's was (within 25 degrees seen from the chair), in one undo step."""
    light, pose = (-1.2, 2.8, 1.0), PhotoPose(Camera(25.0, 96, 96), rotation_deg=-35.0)
    chair = generate_object("chair", 8).mesh
    scene = Scene.single(object=pose.placed(ObjectSpec()), light=LightSpec(light), camera=CameraSpec(25.0), image_size=96)
    Image.fromarray((render_pathtraced(scene, chair, spp=16, seed=0, denoise=True).image * 255).round()
                    .astype(np.uint8)).save(tmp_path / "shaded.png")
    save_pose(tmp_path / "shaded.json", pose)
    load = {"action": "load_photo", "photo": str(tmp_path / "shaded.png"), "camera": str(tmp_path / "shaded.json")}
    run_editor(display, tmp_path, chair_scene, [
        load, {"action": "photo_light", "divide": False}, {"action": "color_from_photo"},
        {"action": "save", "path": str(tmp_path / "kept.json")}, {"action": "undo"},
        {"action": "photo_light", "divide": True}, {"action": "color_from_photo"},
        {"action": "save", "path": str(tmp_path / "divided.json")},
        {"action": "use_photo_light"}, {"action": "save", "path": str(tmp_path / "lit.json")},
        {"action": "undo"}, {"action": "save", "path": str(tmp_path / "unlit.json")},
    ], "--model", str(model_file))
    spread = []
    for name in ("kept", "divided"):
        rgba = object_voxels(load_scene(tmp_path / f"{name}.json"))
        brightness = rgba[rgba[..., 3] > 0.5][:, :3].mean(axis=1)
        spread.append(np.std(brightness) / np.mean(brightness))
    assert spread[1] < 0.7 * spread[0]
    lit = load_scene(tmp_path / "lit.json").light.position
    middle = np.array([0.0, 0.5, 0.0])
    a, b = np.subtract(lit, middle), np.subtract(light, middle)
    assert np.degrees(np.arccos(a @ b / np.linalg.norm(a) / np.linalg.norm(b))) < 25.0
    assert load_scene(tmp_path / "unlit.json").light == load_scene(chair_scene).light
