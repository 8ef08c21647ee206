"""The editor's photo alignment model: starting pose, mouse gestures, the outline overlay, the photo's view."""

import numpy as np
import pytest

from app.editor.photo_capture import PhotoAlignment, scene_with_photo_view
from renderer.capture.align import rotation_error_deg
from renderer.capture.capture import find_pose
from renderer.io import save_png
from renderer.pipeline import object_mesh
from renderer.scene import load_scene

DEMO = "assets/demo/scene.json"


@pytest.fixture(scope="module")
def demo():
    scene = load_scene(DEMO)
    return scene, object_mesh(scene)


def test_the_overlay_outlines_a_saucer_the_search_found_beside_the_object_only(demo):
    scene, mesh = demo
    a = PhotoAlignment("assets/demo/photo.png", scene, "assets/demo/photo_camera.json")
    a.set_mesh(mesh, key=DEMO)
    rim = np.all(np.isclose(a.overlay(), [0.2, 0.8, 1.0]), axis=2)
    assert not rim.any()
    a.floor_disk = 1.5 * a.silhouettes.footprint_radius
    shown_pose = a.pose.at_size(*rim.shape[::-1])
    rim = np.all(np.isclose(a.overlay(), [0.2, 0.8, 1.0]), axis=2)
    disk = a.silhouettes.floor_radii(shown_pose) <= a.floor_disk
    assert rim.sum() > 50 and not (rim & a.silhouettes.mask(shown_pose)).any() and (rim <= disk).all()
    rows, _ = np.nonzero(rim)
    assert rows.max() > np.nonzero(a.silhouettes.mask(shown_pose))[0].max()  # the saucer's front below the chair
    a.set_mesh(mesh, key="another shape")
    assert a.floor_disk == 0.0


def test_camera_file_gives_the_pose_and_without_it_the_scene_does(demo, tmp_path):
    scene, _ = demo
    with_file = PhotoAlignment("assets/demo/photo.png", scene, "assets/demo/photo_camera.json")
    assert (with_file.pose.rotation_deg, with_file.pose.camera.elevation_deg) == (-40.0, 20.0)
    without = PhotoAlignment("assets/demo/photo.png", scene)
    assert without.pose.rotation_deg == scene.object.rotation_deg
    assert without.pose.camera.elevation_deg == scene.camera.elevation_deg


def test_gestures_move_the_pose_and_keep_elevation_valid(demo):
    scene, _ = demo
    a = PhotoAlignment("assets/demo/photo.png", scene)
    r, e = a.pose.rotation_deg, a.pose.camera.elevation_deg
    a.turn(20, -10)  # half a degree per pixel
    assert a.pose.rotation_deg == pytest.approx(r + 10) and a.pose.camera.elevation_deg == pytest.approx(e - 5)
    a.turn(0, 10_000)
    assert a.pose.camera.elevation_deg == 89.0
    x, z = a.pose.translation
    a.shift(25, -50)
    assert a.pose.translation == pytest.approx((x + 0.1, z - 0.2))
    s = a.pose.scale[0]
    a.zoom(2)
    assert a.pose.scale[0] == pytest.approx(s * 1.05**2)


def test_overlay_outlines_the_silhouette_where_the_object_is(demo):
    scene, mesh = demo
    a = PhotoAlignment("assets/demo/photo.png", scene, "assets/demo/photo_camera.json")
    plain = a.overlay()
    a.set_mesh(mesh, key=DEMO)
    shown = a.overlay()
    marked = np.any(shown != plain, axis=2)
    outline = np.all(np.isclose(shown, [1.0, 0.2, 0.6]), axis=2)
    assert 0.03 < marked.mean() < 0.4  # the chair covers part of the photo
    assert 0 < outline.sum() < marked.sum()
    rows, cols = np.nonzero(marked)
    assert 100 < rows.mean() < 220 and 90 < cols.mean() < 170  # the chair stands in the lower middle


def test_search_from_a_hand_pose_and_the_photo_view(demo, tmp_path):
    scene, mesh = demo
    a = PhotoAlignment("assets/demo/photo.png", scene)
    a.set_pose(a.pose.__class__(a.pose.camera, rotation_deg=-20.0))  # a rough hand alignment
    found = find_pose(mesh, a.rgb, a.alpha, initial=a.pose)
    assert rotation_error_deg(found.pose.rotation_deg, -40.0) < 4.0
    placed = scene_with_photo_view(scene, found.pose)
    assert placed.object.rotation_deg == found.pose.rotation_deg
    assert placed.camera.elevation_deg == pytest.approx(found.pose.camera.elevation_deg)
    assert placed.light == scene.light


def test_a_broken_photo_is_a_one_line_error(demo, tmp_path):
    from renderer.errors import InputError

    scene, _ = demo
    (tmp_path / "broken.png").write_bytes(b"not a png")
    with pytest.raises(InputError, match="broken.png"):
        PhotoAlignment(tmp_path / "broken.png", scene)
    save_png(tmp_path / "ok.png", np.zeros((20, 20, 3)))
    assert PhotoAlignment(tmp_path / "ok.png", scene).overlay().shape == (20, 20, 3)


def test_the_overlay_shows_the_masks_rim_whose_colors_are_not_taken(demo, tmp_path):
    """A mask of a 400 x 400 disc: the background darkened, the rim 4 pixels wide (TRUST_MARGIN of the shorter side)
    amber, the rest of the disc the photo's own color."""
    from app.editor.photo_capture import UNTRUSTED_COLOR

    photo = np.full((400, 400, 3), 0.5, dtype=np.float32)
    save_png(tmp_path / "gray.png", photo)
    a = PhotoAlignment(tmp_path / "gray.png", demo[0])
    yy, xx = np.mgrid[:400, :400]
    depth = 150.0 - np.hypot(yy - 200.0, xx - 200.0)
    a.set_mask(depth > 0.0)
    a._silhouettes = None  # the photo and the mask alone
    shown = a.overlay(400)
    amber = 0.5 * 0.5 + 0.5 * UNTRUSTED_COLOR
    np.testing.assert_allclose(shown[200, 200], 0.5, atol=0.01)  # inside: trusted
    np.testing.assert_allclose(shown[200, 52], amber, atol=0.01)  # 2 pixels inside the edge: the rim
    np.testing.assert_allclose(shown[200, 10], 0.5 * 0.45, atol=0.01)  # background
    is_amber = np.all(np.abs(shown - amber) < 0.01, axis=-1)
    assert np.all(depth[is_amber] <= 4.5) and np.all(is_amber[(depth > 1.0) & (depth < 3.5)])
