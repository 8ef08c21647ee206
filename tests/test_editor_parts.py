"""The editor's parts that need no window: history, document, edits, picking, viewport camera, faces, files."""

from __future__ import annotations

import math
import threading
import time
from dataclasses import replace

import numpy as np
import pytest

from app.editor import edits, state
from app.editor.document import Document
from app.editor.file_dialog import FileDialog, FileKind, dialog_command, dialog_program
from app.editor.frame_damage import FrameSummary, changed_boxes, merge
from app.editor.history import History
from app.editor.jobs import JobRunner
from app.editor.orbit_view import HOME, frustum_corners, orbit, pan, projection_matrix, viewport_camera, zoom
from app.editor.photo_capture import PhotoAlignment, object_shape, shape_key
from app.editor.picking import hits_light, pick_voxel, ray_at_height
from app.editor.side_by_side import compose, scale_for
from models.renderers import RendererOptions, ShaderRenderer
from renderer.camera import Camera
from renderer.errors import InputError
from renderer.paint import apply_paint
from renderer.scene import LightSpec, ObjectSpec, PaintOp, Scene, replaced
from renderer.shading import shade_scene
from renderer.voxel_cache import VoxelCache
from renderer.voxel_faces import exposed_faces, voxel_surface_mesh
from renderer.voxels import save_voxels


@pytest.fixture
def box_scene(tmp_path) -> Scene:
    """An 8^3 object: a red 4x4x4 cube with a blue top layer, standing in the middle of its grid."""
    rgba = np.zeros((8, 8, 8, 4), np.float32)
    rgba[2:6, 0:3, 2:6] = (0.8, 0.2, 0.2, 1.0)
    rgba[2:6, 3, 2:6] = (0.2, 0.2, 0.8, 1.0)
    save_voxels(tmp_path / "box.npz", rgba)
    return Scene.single(object=ObjectSpec(voxels="box.npz", resolution=8), base_dir=tmp_path)


# --- history and document -------------------------------------------------------------------------


def test_history_undo_redo_and_a_new_edit_drops_the_redo_stack(box_scene):
    a, b, c = box_scene, edits.set_elevation(box_scene, 20.0), edits.set_elevation(box_scene, 40.0)
    h = History(a)
    assert not h.commit(a)  # no change, no step
    assert h.commit(b) and h.commit(c)
    assert h.undo() and h.current == b
    assert h.undo() and h.current == a
    assert not h.undo()
    assert h.redo() and h.current == b
    h.commit(c)
    assert not h.can_redo and h.current == c


def test_document_preview_is_not_an_undo_step_and_dirty_follows_saves(box_scene, tmp_path):
    doc = Document(box_scene, tmp_path / "scene.json")
    assert not doc.dirty
    start = doc.revision
    for x in (0.5, 1.0, 1.5):  # a drag: three previews
        doc.preview(edits.move_light(box_scene, (x, 2.7, 0.0)))
    assert doc.previewing and doc.dirty and doc.revision == start + 3
    doc.commit()
    assert not doc.previewing and doc.scene.light.position == (1.5, 2.7, 0.0)
    assert doc.undo() and doc.scene == box_scene and not doc.dirty  # the three previews were one step
    doc.redo()
    doc.mark_saved(tmp_path / "other.json")
    assert not doc.dirty and doc.path == tmp_path / "other.json"
    doc.preview(edits.set_elevation(doc.scene, 10.0))
    doc.cancel_preview()
    assert doc.scene.camera.elevation_deg == box_scene.camera.elevation_deg


# --- edits ----------------------------------------------------------------------------------------


@pytest.mark.parametrize(("edit", "message"), [
    (lambda s: edits.move_light(s, (0.0, -3.0, 0.0)), "light height must be from 0.05 to 10, got -3"),
    (lambda s: edits.move_light(s, (-50.0, 2.75, -50.0)), "light x and z must be from -10 to 10, got -50, -50"),
    (lambda s: edits.set_elevation(s, 95.0), "camera elevation must be from 0 to 89, got 95"),
    (lambda s: edits.place_object(s, scale=(-1.0, 1.0, 1.0)), "scale must be from 0.05 to 20, got -1, 1, 1"),
    (lambda s: edits.place_object(s, translation=(float("nan"), 0.0)), "position must be from -10 to 10, got nan, 0"),
    (lambda s: edits.set_floor_color(s, (1.5, 0.5, -1.0)), "floor color must be from 0 to 1, got 1.5, 0.5, -1"),
])
def test_edits_refuse_values_outside_their_bounds_naming_them(box_scene, edit, message):
    with pytest.raises(InputError) as refused:
        edit(box_scene)
    assert str(refused.value) == message


def test_edits_inside_their_bounds_are_taken_as_given(box_scene):
    assert edits.move_light(box_scene, (10.0, 0.05, -10.0)).light.position == (10.0, 0.05, -10.0)
    assert edits.set_elevation(box_scene, 89.0).camera.elevation_deg == 89.0
    assert edits.place_object(box_scene, rotation_deg=190.0).object.rotation_deg == pytest.approx(-170.0)
    assert edits.place_object(box_scene, scale=(0.05, 1.0, 20.0)).object.scale == (0.05, 1.0, 20.0)


def test_a_new_object_keeps_placement_and_the_floor_but_not_paint(box_scene, tmp_path):
    scene = edits.place_object(box_scene, translation=(0.3, 0.1), rotation_deg=45.0)
    scene = edits.paint(edits.paint(scene, PaintOp("object", (0.1, 0.1, 0.1))), PaintOp("floor", (0.9, 0.9, 0.9)))
    mesh = tmp_path / "chair.obj"
    changed = edits.replace_object_source(scene, mesh=mesh)
    assert changed.object.mesh == str(mesh.resolve()) and changed.object.voxels is None
    assert changed.object.translation == (0.3, 0.1) and changed.object.rotation_deg == 45.0
    assert changed.paint == () and changed.floor.color == (0.9, 0.9, 0.9)


# --- picking --------------------------------------------------------------------------------------


def test_pick_voxel_finds_the_first_occupied_voxel_along_the_ray():
    occupied = np.zeros((8, 8, 8), bool)
    occupied[2:6, 0:4, 2:6] = True
    spec = ObjectSpec(voxels="x.npz", resolution=8)
    # Straight down through the centre of voxel (3, *, 4): x = -0.5 + 3.5/8, z = -0.5 + 4.5/8; the top layer is j = 3.
    x, z = -0.5 + 3.5 / 8, -0.5 + 4.5 / 8
    assert pick_voxel(occupied, spec, np.array([x, 5.0, z]), np.array([0.0, -1.0, 0.0])) == (3, 3, 4)
    # From the +z side, level with j = 1: the first voxel is on the cube's front face k = 5.
    y = 1.5 / 8
    assert pick_voxel(occupied, spec, np.array([x, y, 4.0]), np.array([0.0, 0.0, -1.0])) == (3, 1, 5)
    # Beside the cube: a miss.
    assert pick_voxel(occupied, spec, np.array([0.45, 5.0, 0.0]), np.array([0.0, -1.0, 0.0])) is None


def test_pick_voxel_follows_the_placement():
    occupied = np.zeros((8, 8, 8), bool)
    occupied[7, 0, 4] = True  # the voxel at the object's +x end
    spec = ObjectSpec(voxels="x.npz", resolution=8, translation=(1.0, -2.0), rotation_deg=90.0, scale=(2.0, 1.0, 1.0))
    # Rotating +90 degrees about y takes +x to -z; scale 2 along x puts the voxel centre 2 * 7.5/8 - 1 from the axis.
    reach = 2.0 * (-0.5 + 7.5 / 8)
    z_offset = -0.5 + 4.5 / 8  # the voxel's own z becomes +x after the turn
    centre = np.array([1.0 + z_offset, 0.5 / 8, -2.0 - reach])
    assert pick_voxel(occupied, spec, centre + [0.0, 3.0, 0.0], np.array([0.0, -1.0, 0.0])) == (7, 0, 4)


def test_rays_meet_horizontal_planes_and_the_light_square():
    hit = ray_at_height(np.array([0.0, 2.0, 0.0]), np.array([1.0, -1.0, 0.0]) / math.sqrt(2), 0.0)
    np.testing.assert_allclose(hit, [2.0, 0.0, 0.0], atol=1e-12)
    assert ray_at_height(np.array([0.0, 2.0, 0.0]), np.array([0.0, 1.0, 0.0]), 0.0) is None  # plane behind
    up = np.array([0.0, 1.0, 0.0])
    assert hits_light(np.array([1.5, 0.0, 0.5]), up, (1.0, 2.75, 0.5), margin=0.0)  # 0.5 from the centre: the edge
    assert not hits_light(np.array([1.7, 0.0, 0.5]), up, (1.0, 2.75, 0.5), margin=0.0)


# --- the viewport camera --------------------------------------------------------------------------


def test_gl_projection_puts_points_where_the_camera_model_does():
    camera = viewport_camera(HOME, 640, 400)
    points = np.array([[0.0, 0.0, 0.0], [0.4, 1.0, -0.3], [-1.0, 0.2, 0.8]])
    clip = (projection_matrix(camera) @ camera.world_to_camera() @ np.c_[points, np.ones(3)].T).T
    ndc = clip[:, :3] / clip[:, 3:]
    u, v, _ = camera.project(points)
    np.testing.assert_allclose((ndc[:, 0] + 1) / 2 * 640, u, atol=1e-9)
    np.testing.assert_allclose((1 - ndc[:, 1]) / 2 * 400, v, atol=1e-9)
    assert np.all(np.abs(ndc[:, 2]) < 1)  # inside the depth range


def test_frustum_corners_project_to_the_image_corners():
    camera = Camera(elevation_deg=30.0, width=256, height=256)
    u, v, depth = camera.project(frustum_corners(camera, 1.5))
    np.testing.assert_allclose(u, [0, 256, 256, 0], atol=1e-9)
    np.testing.assert_allclose(v, [0, 0, 256, 256], atol=1e-9)
    np.testing.assert_allclose(depth, 1.5, atol=1e-12)


def test_orbit_pan_zoom():
    view = viewport_camera(HOME, 800, 600)
    turned = orbit(view, 100, 50)
    assert turned.distance == view.distance and turned.target == view.target
    assert turned.elevation_deg == pytest.approx(view.elevation_deg + 20.0)
    assert orbit(view, 0, 10_000).elevation_deg == 89.0
    moved = pan(view, 30, 0)
    assert moved.distance == view.distance
    # Panning moves the target along the view's left-right axis only, by distance / focal length per pixel.
    shift = np.asarray(moved.target) - np.asarray(view.target)
    assert np.linalg.norm(shift) == pytest.approx(30 * view.distance / view.focal_px)
    assert abs(shift @ view.camera_to_world()[:3, 2]) < 1e-12
    assert zoom(view, 1).distance == pytest.approx(view.distance * 0.88)
    assert zoom(view, -100).distance == 60.0


# --- faces ----------------------------------------------------------------------------------------


def test_exposed_faces_of_two_touching_voxels():
    rgba = np.zeros((4, 4, 4, 4), np.float32)
    rgba[1, 1, 1] = (1.0, 0.0, 0.0, 1.0)
    rgba[2, 1, 1] = (0.0, 1.0, 0.0, 1.0)
    cells, colors = exposed_faces(rgba)
    assert len(cells) == 10  # 12 faces, minus the two they share
    red = cells[colors[:, 0] == 1.0]
    assert sorted(red[:, 3].tolist()) == [1, 2, 3, 4, 5]  # every face but +x (id 0), which touches green
    assert np.all(red[:, :3] == [1, 1, 1])


# --- voxel cache ----------------------------------------------------------------------------------


def test_painted_voxels_from_the_cache_equal_a_fresh_replay(box_scene):
    cache = VoxelCache()
    one = edits.paint(box_scene, PaintOp("region", (0.1, 0.9, 0.1), seed=(3, 3, 3), tolerance=0.05))
    two = edits.paint(one, PaintOp("region", (0.9, 0.9, 0.1), seed=(3, 0, 3), tolerance=0.05))
    two = edits.paint(two, PaintOp("floor", (0.3, 0.3, 0.3)))
    first, _ = cache.painted(one)
    rgba, floor = cache.painted(two)  # painted from `one`'s result
    expected, _ = apply_paint(cache.object_rgba(box_scene), box_scene.floor.color, two.paint)
    np.testing.assert_array_equal(rgba, expected)
    assert floor == two.floor.color == (0.3, 0.3, 0.3)  # a floor fill sets the floor's color
    assert cache.painted(one)[0] is first  # undo back to `one`: no repaint


def test_the_cache_finds_an_objects_occupied_voxels_once_for_all_its_strokes(box_scene, monkeypatch):
    import renderer.paint as paint
    import renderer.voxel_cache as voxel_cache

    scans = []

    def counted(rgba):
        scans.append(rgba.shape)
        return np.flatnonzero(np.asarray(rgba)[..., 3] >= 0.5)

    monkeypatch.setattr(paint, "occupied_voxels", counted)
    monkeypatch.setattr(voxel_cache, "occupied_voxels", counted)
    cache = VoxelCache(run_later=lambda task: None)
    scene = box_scene
    for k in range(4):  # strokes that do not extend the last (each from the unpainted voxels) and that do
        stroke = PaintOp("region", (0.2 * k, 0.5, 0.1), seed=(3, 3, 3), tolerance=1.0)
        scene = edits.paint(scene if k % 2 else box_scene, stroke)
        expected, _ = apply_paint(cache.object_rgba(box_scene), box_scene.floor.color, scene.paint,
                                  occupied=np.flatnonzero(cache.object_rgba(box_scene)[..., 3] >= 0.5))
        np.testing.assert_array_equal(cache.painted(scene)[0], expected)
    assert len(scans) == 1


def test_the_voxel_shader_panel_keeps_the_shape_through_paint_and_draws_the_new_colors(box_scene):
    # A stroke changes colors, never occupancy: the shaded renderer reruns only the colors and what they light, and its
    # image is the one the shader draws from scratch.
    engine = ShaderRenderer(RendererOptions(voxels=VoxelCache()))
    box_scene = replace(box_scene, image_size=48)
    engine.render(box_scene)
    stroke = edits.paint(box_scene, PaintOp("region", (0.1, 0.9, 0.1), seed=(3, 3, 3), tolerance=0.05))
    image = engine.render(stroke)
    assert set(engine.last_report.stage_ms) == {"pool", "colors", "reflection", "lighting"}
    rgba, floor = apply_paint(VoxelCache().object_rgba(stroke), stroke.floor.color, stroke.paint)
    np.testing.assert_array_equal(image, shade_scene(stroke, rgba, floor).image)
    before = shade_scene(box_scene, *apply_paint(VoxelCache().object_rgba(box_scene), box_scene.floor.color, ())).image
    assert np.abs(image - before).max() > 0.1  # the top turned green

@pytest.mark.parametrize("prepared", [False, True])
def test_the_cache_keeps_painted_states_within_its_budget_and_paints_into_spares_nothing_holds(box_scene, monkeypatch,
                                                                                               prepared):
    """Past PAINTED_BYTES_KEPT the oldest states go; a stroke paints into a spare array: a forgotten one only if nothing
    else holds it (an array a caller still reads never changes), or one prepared after the object loaded and after
    each stroke (here at once, in the editor on another thread); every state equals a replay from scratch."""
    import renderer.voxel_cache as voxel_cache

    state_bytes = 8**3 * 4 * 4
    monkeypatch.setattr(voxel_cache, "PAINTED_BYTES_KEPT", 2 * state_bytes)  # two states of the 8^3 box
    painted_into = []  # per fill: whether it wrote into a forgotten array

    def recording(rgba, floor, ops, occupied=None, out=None):
        if any(op.target != "floor" for op in ops):  # (the floor's strokes are replayed apart)
            painted_into.append(out is not None)
        return apply_paint(rgba, floor, ops, occupied, out)

    monkeypatch.setattr(voxel_cache, "apply_paint", recording)
    cache = VoxelCache(run_later=(lambda task: task()) if prepared else (lambda task: None))
    base = cache.object_rgba(box_scene)
    colors = [(0.1 * k, 0.9 - 0.1 * k, 0.5) for k in range(8)]
    scenes = [box_scene]
    for color in colors:  # each stroke recolors the whole red cube (seed in it, tolerance wide)
        scenes.append(edits.paint(scenes[-1], PaintOp("region", color, seed=(3, 1, 3), tolerance=1.0)))

    def replayed(scene: Scene) -> np.ndarray:
        return apply_paint(base, scene.floor.color, scene.paint)[0]

    held = cache.painted(scenes[1])[0]  # a caller keeps reading the first state
    held_copy = held.copy()
    for scene in scenes[2:]:
        rgba = cache.painted(scene)[0]
        np.testing.assert_array_equal(rgba, replayed(scene))
        assert len(cache._painted) <= 2
        del rgba
    np.testing.assert_array_equal(held, held_copy)  # never painted into: it was still held
    if prepared:  # every fill, the first too, into a prepared spare
        assert painted_into == [True] * 8
    else:  # the third fill forgets the held first state, the fourth the second: from the fifth on, into those
        assert painted_into == [False] * 4 + [True] * 4
    np.testing.assert_array_equal(cache.painted(scenes[3])[0], replayed(scenes[3]))  # forgotten: painted again

# --- photo camera ---------------------------------------------------------------------------------


def test_a_photo_of_the_wrong_size_is_a_clear_error(box_scene, tmp_path):
    from renderer.io import save_png

    save_png(tmp_path / "small.png", np.zeros((32, 48, 3)))
    with pytest.raises(InputError, match="small.png.*48x32 pixels but its camera is 256x256"):
        PhotoAlignment(tmp_path / "small.png", box_scene, "assets/demo/photo_camera.json")
    save_png(tmp_path / "half.png", np.zeros((128, 128, 3)))  # the same photo, smaller: the pose scales with it
    assert PhotoAlignment(tmp_path / "half.png", box_scene, "assets/demo/photo_camera.json").pose.camera.width == 128


def test_an_object_without_a_mesh_aligns_with_the_surface_of_its_voxels(box_scene):
    import trimesh

    from renderer.capture.align import silhouette_iou
    from renderer.capture.pose import PhotoPose
    from renderer.capture.silhouette import SilhouetteRenderer

    shape = object_shape(box_scene, VoxelCache())  # the red and blue 4^3 cube of the 8^3 grid, in object units
    np.testing.assert_allclose(shape.bounds, [[-0.25, 0.0, -0.25], [0.25, 0.5, 0.25]])
    assert shape.area == pytest.approx(6 * 0.5**2)  # only the outer faces: 96 voxel faces of 1/8 x 1/8
    cube = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    cube.apply_translation((0.0, 0.25, 0.0))
    pose = PhotoPose(Camera(35.0, 96, 96), rotation_deg=30.0)
    assert silhouette_iou(SilhouetteRenderer(shape).mask(pose), SilhouetteRenderer(cube).mask(pose)) > 0.99
    assert shape_key(box_scene) == ("voxels", str((box_scene.base_dir / "box.npz").resolve()), 8)
    assert len(voxel_surface_mesh(np.zeros((4, 4, 4, 4), np.float32)).faces) == 0


# --- recovery and captures ------------------------------------------------------------------------


def test_recovery_round_trip(box_scene, tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    assert state.read_recovery() is None
    moved = replace(box_scene, light=LightSpec((0.1, 2.9, 0.2)))
    state.write_recovery(moved, tmp_path / "scene.json")
    recovery = state.read_recovery()
    assert recovery.origin == (tmp_path / "scene.json").resolve()
    assert recovery.scene.voxels_path().resolve() == moved.voxels_path().resolve()  # written relative to the recovery folder
    assert replaced(recovery.scene, object=moved.object) == moved
    state.clear_recovery()
    assert state.read_recovery() is None


def test_captures_are_named_by_content_and_copied_beside_a_saved_scene(box_scene, tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path / "state"))
    rgba = VoxelCache().object_rgba(box_scene)
    path = state.save_capture(rgba)
    assert state.save_capture(rgba.copy()) == path
    scene = replaced(box_scene, object=replace(box_scene.object, voxels=str(path)))
    (tmp_path / "out").mkdir()
    adopted = state.adopt_capture(scene, tmp_path / "out" / "mine.json")
    assert adopted.voxels_path() == (tmp_path / "out" / "mine.voxels.npz").resolve()
    np.testing.assert_array_equal(VoxelCache().object_rgba(adopted), rgba)
    assert state.adopt_capture(box_scene, tmp_path / "out" / "mine.json") is box_scene


# --- the command line -----------------------------------------------------------------------------


def test_bad_scene_or_replay_file_exits_2_with_one_line(tmp_path, capsys):
    from app.editor.main import run

    assert run([str(tmp_path / "missing.json"), "--frames", "1"]) == 2
    assert capsys.readouterr().err.strip().endswith("missing.json: file not found")
    replay = tmp_path / "replay.json"
    replay.write_text('[{"action": "fly"}]')
    assert run(["assets/demo/scene.json", "--frames", "1", "--replay", str(replay)]) == 2
    err = capsys.readouterr().err.strip()
    assert "unknown action 'fly'" in err and len(err.splitlines()) == 1


# --- which parts of the window a frame changes ------------------------------------------------------


def _frame(lists=((b"menu", (0, 0, 100, 20)), (b"tools", (60, 20, 100, 80))), viewport=1, render=1, size=(100, 80)):
    return FrameSummary(size, tuple(lists), (((0, 20, 60, 80), viewport), ((70, 30, 90, 50), render)))


def test_a_frame_that_looks_the_same_changes_nothing_and_an_unknown_screen_changes_everything():
    assert changed_boxes(_frame(), _frame()) == []
    assert changed_boxes(None, _frame()) is None
    assert changed_boxes(_frame(size=(100, 90)), _frame(size=(100, 80))) is None  # resized
    assert changed_boxes(_frame(), _frame(lists=[(b"menu", (0, 0, 100, 20))])) is None  # a window closed


def test_changed_images_and_draw_lists_mark_their_boxes():
    assert changed_boxes(_frame(), _frame(viewport=2)) == [(0, 20, 60, 80)]
    assert changed_boxes(_frame(), _frame(render=2)) == [(70, 30, 90, 50)]
    # The viewport and the render both changed: two separate boxes (the render lies inside the tools).
    assert sorted(changed_boxes(_frame(), _frame(viewport=2, render=2))) == [(0, 20, 60, 80), (70, 30, 90, 50)]
    # The menu's text changed and its drop-down grew from 20 to 50 pixels: the old and the new box, merged.
    grown = [(b"menu 2", (0, 0, 40, 50)), (b"tools", (60, 20, 100, 80))]
    assert changed_boxes(_frame(), _frame(lists=grown)) == [(0, 0, 100, 50)]
    # A changed list whose box reaches outside the window counts only inside it.
    wide = [(b"menu", (0, 0, 100, 20)), (b"tools 2", (60, 20, 8192, 8192))]
    assert changed_boxes(_frame(), _frame(lists=wide)) == [(60, 20, 100, 80)]


def test_overlapping_boxes_merge_into_the_box_around_them_and_too_many_mean_everything():
    assert merge([(0, 0, 10, 10), (5, 5, 20, 20), (30, 30, 40, 40)]) == [(0, 0, 20, 20), (30, 30, 40, 40)]
    # (0..10) and (20..30) do not touch until (8..22) joins them.
    assert merge([(0, 0, 10, 10), (20, 0, 30, 10), (8, 0, 22, 10)]) == [(0, 0, 30, 10)]
    assert merge([(0, 0, 10, 10), (10, 0, 20, 10)]) == [(0, 0, 10, 10), (10, 0, 20, 10)]  # touching edges do not overlap
    many = [(bytes([i]), (10 * i, 0, 10 * i + 5, 5)) for i in range(6)]
    changed = [(bytes([i + 100]), box) for i, (_, box) in enumerate(many)]
    assert changed_boxes(_frame(lists=many), _frame(lists=changed)) is None


# --- side-by-side export ------------------------------------------------------------------------------


def test_side_by_side_enlarges_the_render_by_a_whole_factor_beside_the_viewport():
    assert [scale_for(n) for n in (64, 100, 256, 512, 600)] == [8, 6, 2, 1, 1]  # ceil(512 / n), at least 1
    render = np.arange(2 * 2 * 3, dtype=np.uint8).reshape(2, 2, 3)
    viewport = np.full((6, 5, 3), 200, np.uint8)
    image = compose(viewport, render)
    assert image.shape == (6, 11, 3)
    assert (image[:, :5] == 200).all()
    assert (image[0:3, 5:8] == render[0, 0]).all() and (image[3:6, 8:11] == render[1, 1]).all()
    with pytest.raises(ValueError):
        compose(np.zeros((7, 5, 3), np.uint8), render)  # 7 rows are not a whole number of render rows


# --- the system's file dialog ------------------------------------------------------------------------

MESHES = FileKind("Open a mesh", "Meshes", ("*.obj", "*.ply"))


def _fake_program(folder, name: str, body: str):
    """An executable shell script `name` in `folder` that records its arguments, one a line, then runs `body`."""
    script = folder / name
    script.write_text(f'#!/bin/sh\nprintf "%s\\n" "$@" > "{folder}/{name}.args"\n{body}\n')
    script.chmod(0o755)
    return folder / f"{name}.args"


def test_dialog_commands_for_zenity_and_kdialog():
    assert dialog_command("zenity", MESHES) == [
        "zenity", "--file-selection", "--title=Open a mesh", "--file-filter=Meshes | *.obj *.ply", "--file-filter=All files | *"]
    png = FileKind("Export as", "PNG images", ("*.png",), save=True)
    assert dialog_command("zenity", png, "out/render.png") == [
        "zenity", "--file-selection", "--title=Export as", "--save", "--filename=out/render.png",
        "--file-filter=PNG images | *.png", "--file-filter=All files | *"]
    assert dialog_command("kdialog", MESHES) == ["kdialog", "--title", "Open a mesh", "--getopenfilename", ".",
                                                 "*.obj *.ply|Meshes"]
    assert dialog_command("kdialog", png, "render.png") == ["kdialog", "--title", "Export as", "--getsavefilename",
                                                            "render.png", "*.png|PNG images"]
    with pytest.raises(ValueError):
        dialog_command("yad", MESHES)


def test_the_dialog_program_is_found_on_path_zenity_first(tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path))
    assert dialog_program() is None  # no dialog: the editor shows no Browse buttons
    _fake_program(tmp_path, "kdialog", "exit 1")
    assert dialog_program() == "kdialog"
    _fake_program(tmp_path, "zenity", "exit 1")
    assert dialog_program() == "zenity"


def _finish(dialog: FileDialog) -> FileDialog:
    deadline = time.monotonic() + 30
    while not dialog.poll():
        assert time.monotonic() < deadline
        time.sleep(0.01)
    return dialog


def test_a_dialog_runs_the_program_and_returns_its_choice(tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path))
    arguments = _fake_program(tmp_path, "zenity", "echo /data/chair.obj")
    command = dialog_command("zenity", MESHES, "old.obj")
    assert _finish(FileDialog(command)).path == "/data/chair.obj"
    assert arguments.read_text().splitlines() == command[1:]  # the program got exactly these arguments
    _fake_program(tmp_path, "zenity", "exit 1")  # the user pressed Cancel
    cancelled = _finish(FileDialog(command))
    assert cancelled.path is None and cancelled.error is None
    missing = _finish(FileDialog(["no-such-dialog-program", "--file-selection"]))
    assert missing.path is None and "cannot start the file dialog no-such-dialog-program" in missing.error


def test_an_nvr_plus_that_corrects_the_shader_exports_other_sizes_drawn_at_that_size(box_scene, tmp_path,
                                                                                     refiner_file):
    """The File tab's export at another size than the network's: for a network that corrects the shader's image, the
    engine's image at that size (the shaded image at that size, corrected), not the network's image resized."""
    from PIL import Image

    from app.editor.render_panel import export_render
    from models.engine.render_engine import RenderEngine
    from renderer.color import to_uint8

    used = export_render(box_scene, tmp_path / "out.png", str(refiner_file), "nvr+", VoxelCache(), size=96)
    assert "corrected at 64 px" in used and "upscaled" not in used
    engine = RenderEngine.load(refiner_file)  # as the editor loads it
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "out.png")),
                                  to_uint8(engine.render_sized(box_scene, 96)))


def _next_frame(live, timeout: float = 30.0):
    """The next frame LiveRender hands out (refining when one is due), or a failure after `timeout` seconds."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        live.refine()
        frame = live.poll()
        if frame is not None:
            return frame
        time.sleep(0.005)
    raise AssertionError("no frame")


def test_a_settled_nvr_plus_image_is_drawn_again_at_the_panels_size(box_scene, refiner_file):
    """The render panel shows the network's 64 px image stretched to its size; once that image has stood, the scene
    is drawn again at the panel's size (the shaded image there, corrected), unless an edit came first; likewise the
    voxel shader's."""
    from app.editor.render_panel import LiveRender
    from models.engine.render_engine import RenderEngine

    live = LiveRender(VoxelCache(), str(refiner_file), "nvr+", detail_delay=0.0)
    try:
        live.panel_size = 96
        live.submit(box_scene)
        frame = _next_frame(live)
        assert not frame.detail and frame.image.shape == (64, 64, 3)
        assert not live.idle  # the larger image is due
        detail = _next_frame(live)
        assert detail.detail and detail.scene == box_scene and live.idle
        np.testing.assert_array_equal(detail.image, RenderEngine.load(refiner_file).render_sized(box_scene, 96))
        # An edit before the settled image is refined: only the edit is rendered, then refined in turn.
        lit = box_scene.with_changes(light=LightSpec((-1.0, 2.5, 0.3)))
        live.submit(box_scene.with_changes(light=LightSpec((1.0, 2.5, 0.3))))
        assert not _next_frame(live).detail
        live.submit(lit)
        frames = [_next_frame(live), _next_frame(live)]
        assert [(f.detail, f.scene == lit, f.image.shape[0]) for f in frames] == [(False, True, 64), (True, True, 96)]
        # The voxel shader's is redrawn too: its image at the panel's size (the live size's stages kept).
        live.select("shaded")
        small = replace(box_scene, image_size=64)  # the shader renders the scene's size
        live.submit(small)
        assert not _next_frame(live).detail
        detail = _next_frame(live)
        assert detail.detail and live.idle
        np.testing.assert_array_equal(detail.image, shade_scene(small, *VoxelCache().painted(small), 96).image)
    finally:
        live.close()


def test_a_new_scene_is_not_unsaved_until_edited_and_a_restored_one_is(box_scene):
    from app.editor.document import Document

    fresh = Document(box_scene, None)
    assert not fresh.dirty
    fresh.commit(replace(box_scene, image_size=128))
    assert fresh.dirty
    assert Document(box_scene, None, changed=True).dirty


def test_voxelising_the_same_mesh_again_keeps_the_scenes_color_and_another_mesh_shows_its_own(tmp_path):
    from app.editor import edits
    from renderer.scene import ObjectSpec, Scene

    for name in ("a.obj", "b.obj"):
        (tmp_path / name).write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    scene = Scene.single(object=ObjectSpec(mesh="a.obj", color=(0.9, 0.1, 0.1)), base_dir=tmp_path)
    again = edits.replace_object_source(scene, mesh=tmp_path / "a.obj", up="z")
    assert again.object.color == (0.9, 0.1, 0.1) and again.object.up == "z"
    other = edits.replace_object_source(scene, mesh=tmp_path / "b.obj")
    assert other.object.color is None


def test_a_render_that_reuses_every_stage_shows_the_time_of_the_one_that_made_its_image(box_scene):
    """After a light drag the final render reuses the drag's last frame: the panel names that frame's time, not 0 ms."""
    from app.editor.render_panel import LiveRender

    live = LiveRender(VoxelCache(), None, "shaded", detail_delay=60.0)
    try:
        live.submit(box_scene, preview=True)
        made = _next_frame(live)
        live.submit(box_scene)  # the same scene, final: every stage is kept
        again = _next_frame(live)
        assert live.engine.last_report.stages_run == ()
        assert made.seconds > 0.0 and again.seconds == made.seconds
    finally:
        live.close()


def test_panning_moves_the_target_by_the_viewports_own_pixels_and_views_and_framing_aim_right():
    from app.editor.orbit_view import framed, looking_from, pan_in_viewport

    view = HOME  # the view as the app keeps it: its own 256 px size, not the viewport's
    moved = pan_in_viewport(view, 40, 0, 800, 600)
    shift = np.linalg.norm(np.asarray(moved.target) - np.asarray(view.target))
    # The point under the mouse follows it: 40 viewport pixels at the target's depth.
    assert shift == pytest.approx(40 * view.distance / viewport_camera(view, 800, 600).focal_px)
    assert moved.width == view.width
    front = looking_from(view, "front")
    assert front.position[2] > 0 and abs(front.position[0]) < 1e-9  # on the render camera's side
    assert looking_from(view, "right").position[0] > 0 and looking_from(view, "top").position[1] > 4.0
    aimed = framed(view, (0.3, 0.5, -0.2), 0.8)
    camera = viewport_camera(aimed, 400, 400)
    assert aimed.target == (0.3, 0.5, -0.2)
    # The sphere fits: its silhouette's half width, seen from the camera, stays inside the half field of view.
    half_fov = np.arctan(0.5 * camera.sensor_mm / camera.focal_mm)
    assert np.arcsin(0.8 / aimed.distance) < half_fov


def test_the_file_browser_lists_folders_first_then_the_kinds_files_without_hidden_ones(tmp_path):
    from app.editor.file_browser import entries

    for name in ("b.obj", "A.OBJ", "notes.txt", ".hidden.obj", "c.ply"):
        (tmp_path / name).write_text("x")
    for name in ("zeta", "Alpha", ".git"):
        (tmp_path / name).mkdir()
    assert entries(tmp_path, ("*.obj", "*.ply")) == (["Alpha", "zeta"], ["A.OBJ", "b.obj", "c.ply"])
    with pytest.raises(OSError):
        entries(tmp_path / "missing", ("*.obj",))


def test_the_suns_hemisphere_maps_elevation_to_radius_and_azimuth_to_the_compass_with_the_camera_down():
    from app.editor.light_panel import sun_from_widget, sun_on_widget

    assert sun_on_widget(90.0, 37.0, 60.0) == pytest.approx((0.0, 0.0))  # overhead: the centre
    assert sun_on_widget(0.0, 0.0, 60.0) == pytest.approx((0.0, 60.0))  # on the horizon towards the camera: bottom
    assert sun_on_widget(45.0, 90.0, 60.0) == pytest.approx((30.0, 0.0))  # towards +x: right, half way out
    assert sun_from_widget(0.0, -60.0, 60.0) == pytest.approx((0.0, 180.0))  # the top of the rim: behind the object
    assert sun_from_widget(500.0, 0.0, 60.0)[0] == 0.0  # past the rim: the horizon
    for elevation, azimuth in ((10.0, -170.0), (33.0, 20.0), (80.0, 95.0)):
        assert sun_from_widget(*sun_on_widget(elevation, azimuth, 75.0), 75.0) == pytest.approx((elevation, azimuth))


def test_a_job_started_while_another_runs_is_refused_and_the_tab_gets_none():
    said = []
    runner = JobRunner(lambda text, error=False: said.append((text, error)))
    gate = threading.Event()
    first = runner.start("Aligning", lambda progress: (progress(0.4), gate.wait(5)), lambda result: None)
    second = runner.start("Coloring", lambda progress: None, lambda result: None)
    assert first is runner.current and second is None and said == [("busy: Aligning", True)]
    deadline = time.monotonic() + 5.0
    while first.progress == 0.0 and time.monotonic() < deadline:
        time.sleep(0.01)
    assert first.progress == 0.4  # what the Photo tab's bar shows while the job waits
    gate.set()
