"""Appearance capture: camera files, silhouettes against geometry, segmentation, the pose search
on rendered photos, symmetry detection, and the bad photos a user may give."""

from dataclasses import replace

import numpy as np
import pytest
import trimesh
from PIL import Image
from scipy.spatial import ConvexHull

from renderer.camera import Camera
from renderer.capture.align import (
    FINAL_STEPS,
    INITIAL_STEPS,
    _Problem,
    align_pose,
    disk_iou,
    rotation_error_deg,
    silhouette_iou,
)
from renderer.capture.capture import capture_appearance, find_pose
from renderer.capture.pose import PhotoPose, load_pose, photo_camera, pose_from_dict, save_pose
from renderer.capture.segment import object_mask
from renderer.capture.silhouette import SilhouetteRenderer
from renderer.errors import InputError
from renderer.io import load_image, photo_focal_35mm
from renderer.objects import generate_object
from renderer.pathtrace.path_tracer import render_pathtraced
from renderer.photo import is_mirror_symmetric
from renderer.scene import CameraSpec, LightSpec, Scene
from renderer.voxels import voxelize


@pytest.fixture(scope="module")
def chair():
    return generate_object("chair", 8).mesh  # a back and open arms: its rotation shows in its silhouette


def box_mesh(lo=(-0.3, 0.0, -0.2), hi=(0.3, 0.8, 0.2)) -> trimesh.Trimesh:
    lo, hi = np.array(lo), np.array(hi)
    box = trimesh.creation.box(extents=hi - lo)
    box.apply_translation((lo + hi) / 2)
    return box


# --- camera files --------------------------------------------------------------------------


def test_camera_file_round_trip(tmp_path):
    pose = PhotoPose(Camera(23.5, 320, 240, principal_offset=(4.0, -2.0)), rotation_deg=-71.0,
                     translation=(0.2, -0.1), scale=(1.1, 0.9, 1.0))
    save_pose(tmp_path / "cam.json", pose)
    assert load_pose(tmp_path / "cam.json") == pose


def test_camera_file_without_placement_takes_the_scene_placement():
    from renderer.scene import ObjectSpec

    spec = ObjectSpec(rotation_deg=12.0, translation=(0.1, 0.2), scale=(2.0, 2.0, 2.0))
    pose = pose_from_dict({"elevation_deg": 10, "width": 64, "height": 64}, spec)
    assert (pose.rotation_deg, pose.translation, pose.scale) == (12.0, (0.1, 0.2), (2.0, 2.0, 2.0))


@pytest.mark.parametrize("data, problem", [
    ({"width": 64, "height": 64}, "missing elevation_deg"),
    ({"elevation_deg": 95, "width": 64, "height": 64}, "elevation_deg must be in"),
    ({"elevation_deg": 10, "width": 64.5, "height": 64}, "whole numbers"),
    ({"elevation_deg": 10, "width": 64, "height": 64, "scale": [1, 0, 1]}, "scale must be positive"),
    ({"elevation_deg": 10, "width": 64, "height": 64, "focal_mm": float("nan")}, "finite"),
    ([1, 2], "JSON object"),
])
def test_broken_camera_files_name_the_problem(data, problem):
    with pytest.raises(InputError, match=problem) as info:
        pose_from_dict(data, path="cam.json")
    assert "cam.json" in str(info.value)


def test_resized_pose_projects_to_the_same_relative_place():
    pose = PhotoPose(Camera(30.0, 200, 100, principal_offset=(10.0, 6.0)), rotation_deg=40.0)
    point = np.array([0.3, 0.7, -0.2])
    u, v, _ = pose.camera.project(point)
    u2, v2, _ = pose.at_size(100, 50).camera.project(point)
    assert u2 == pytest.approx(u / 2) and v2 == pytest.approx(v / 2)


# --- silhouettes -------------------------------------------------------------------------------


def test_box_silhouette_is_the_hull_of_its_projected_corners():
    box = box_mesh()
    pose = PhotoPose(Camera(35.0, 96, 96), rotation_deg=30.0, translation=(0.2, -0.1), scale=(1.2, 1.0, 0.8))
    mask = SilhouetteRenderer(box).mask(pose)
    corners = np.array(box.vertices)
    world = corners @ pose.object_to_world()[:3, :3].T + pose.object_to_world()[:3, 3]
    u, v, _ = pose.camera.project(world)
    hull = ConvexHull(np.stack([u, v], axis=1))
    vv, uu = np.mgrid[0:96, 0:96] + 0.5
    points = np.stack([uu.ravel(), vv.ravel(), np.ones(uu.size)], axis=1)
    expected = (points @ hull.equations.T <= 0).all(axis=1).reshape(96, 96)
    assert expected.sum() > 500
    assert silhouette_iou(mask, expected) > 0.99


@pytest.mark.parametrize("pose", [
    PhotoPose(Camera(35.0, 80, 64), rotation_deg=30.0, translation=(0.2, -0.1), scale=(1.2, 1.0, 0.8)),
    PhotoPose(Camera(10.0, 64, 64), rotation_deg=-70.0, translation=(1.6, 0.0)),  # cut by the frame's edge
    PhotoPose(Camera(20.0, 64, 64), translation=(9.0, 0.0)),  # out of the frame
    PhotoPose(Camera(80.0, 48, 48), scale=(4.0, 4.0, 4.0)),  # the camera inside the bounding box
])
@pytest.mark.parametrize("shape", ["chair", "box"])
def test_silhouettes_cast_only_where_the_object_can_be_and_miss_nothing(chair, pose, shape):
    """The mask and the surface cast rays only within the projected bounding box, and equal casting every pixel
    (a box fills its bounding box's projection to the edge)."""
    import open3d as o3d

    mesh = chair if shape == "chair" else box_mesh()
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(np.asarray(mesh.vertices, dtype=np.float32)),
                        o3d.core.Tensor(np.asarray(mesh.faces, dtype=np.uint32)))
    v, u = np.mgrid[0:pose.camera.height, 0:pose.camera.width] + 0.5
    origin, directions = pose.camera.pixel_rays(u.ravel(), v.ravel())
    to_object = pose.world_to_object()
    rays = np.concatenate([np.broadcast_to(origin @ to_object[:3, :3].T + to_object[:3, 3], directions.shape),
                           directions @ to_object[:3, :3].T], axis=1).astype(np.float32)
    expected = np.isfinite(scene.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()).reshape(u.shape)
    silhouettes = SilhouetteRenderer(mesh)
    mask = silhouettes.mask(pose)
    hit, points, normals = silhouettes.surface(pose)
    assert np.count_nonzero(mask != expected) <= 2 and np.array_equal(hit, mask)  # float32 rays: ties at edges
    assert len(points) == len(normals) == np.count_nonzero(hit)
    to_world = pose.object_to_world()
    pu, pv, _ = pose.camera.project(points @ to_world[:3, :3].T + to_world[:3, 3])
    rows, cols = np.nonzero(hit)  # each point lies on its own pixel's ray, in the mask's row-major order
    assert np.abs(pu - (cols + 0.5)).max(initial=0.0) < 1e-3 and np.abs(pv - (rows + 0.5)).max(initial=0.0) < 1e-3


# --- segmentation --------------------------------------------------------------------------


def disc_photo(h=120, w=160, centre=(60, 80), radius=30, object_color=(0.8, 0.2, 0.1)):
    y, x = np.mgrid[0:h, 0:w]
    vignette = 0.7 - 0.15 * (((x - w / 2) / w) ** 2 + ((y - h / 2) / h) ** 2)  # a darkening backdrop
    rgb = np.repeat(vignette[..., None], 3, axis=2)
    disc = (y - centre[0]) ** 2 + (x - centre[1]) ** 2 <= radius**2
    rgb[disc] = object_color
    return rgb, disc


def striped_object_filling_the_frame():
    rgb, _ = disc_photo(radius=200)
    for column in range(4):
        rgb[:, column::8] = (0.1, 0.5, 0.1)
    return rgb


def test_alpha_channel_is_the_mask():
    rgb, disc = disc_photo()
    alpha = np.where(disc, 0.9, 0.1)
    assert np.array_equal(object_mask(rgb, alpha), disc)


def test_object_on_a_shaded_plain_backdrop_is_found():
    rgb, disc = disc_photo()
    assert silhouette_iou(object_mask(rgb, np.ones(disc.shape)), disc) > 0.98  # an all-opaque alpha says nothing


def test_object_touching_the_border_is_found():
    rgb, disc = disc_photo(centre=(60, 150), radius=35)
    assert silhouette_iou(object_mask(rgb), disc) > 0.97


@pytest.mark.parametrize("make, problem", [
    (lambda: disc_photo(radius=0)[0], "found no object"),
    (lambda: disc_photo(radius=200)[0], "found no object"),  # a frame of one color is a plain backdrop
    (lambda: striped_object_filling_the_frame(), "nothing in the photo separates from the background"),
    (lambda: np.random.default_rng(0).uniform(size=(80, 80, 3)), "nothing in the photo separates from the background"),
    (lambda: disc_photo()[0], None),
])
def test_photos_without_a_separable_object_say_so(make, problem):
    if problem is None:
        object_mask(make(), path="p.png")
        return
    with pytest.raises(InputError, match=problem) as info:
        object_mask(make(), path="p.png")
    assert "p.png" in str(info.value)


def test_transparent_photo_says_so():
    with pytest.raises(InputError, match="fully transparent"):
        object_mask(np.zeros((10, 10, 3)), np.zeros((10, 10)))


# --- the pose search ---------------------------------------------------------------------------


def test_search_finds_the_pose_of_a_silhouette_from_no_pose(chair):
    silhouettes = SilhouetteRenderer(chair)
    truth = PhotoPose(Camera(27.0, 128, 128), rotation_deg=-115.0, translation=(0.25, -0.3), scale=(1.15,) * 3)
    found = align_pose(silhouettes, silhouettes.mask(truth))
    assert rotation_error_deg(found.pose.rotation_deg, truth.rotation_deg) < 3.0
    assert abs(found.pose.camera.elevation_deg - truth.camera.elevation_deg) < 3.0
    assert found.iou > 0.9


def test_search_refines_a_perturbed_pose(chair):
    silhouettes = SilhouetteRenderer(chair)
    truth = PhotoPose(Camera(40.0, 128, 128), rotation_deg=60.0, translation=(-0.2, 0.1), scale=(0.9,) * 3)
    start = replace(truth, rotation_deg=85.0, camera=replace(truth.camera, elevation_deg=20.0),
                    translation=(-0.12, 0.18), scale=(0.99,) * 3)
    found = align_pose(silhouettes, silhouettes.mask(truth), initial=start)
    assert rotation_error_deg(found.pose.rotation_deg, truth.rotation_deg) < 3.0
    assert abs(found.pose.camera.elevation_deg - truth.camera.elevation_deg) < 3.0
    assert silhouette_iou(silhouettes.mask(found.pose), silhouettes.mask(truth)) > 0.9


def test_refinement_moves_elevation_together_with_the_placement(chair):
    # Seen from 10 degrees, a pose 4 degrees too high whose silhouette was placed on the mask: a step in elevation
    # alone moves the silhouette off the mask, and one number at a time the search stalled at 12 degrees.
    silhouettes = SilhouetteRenderer(chair)
    truth = PhotoPose(Camera(10.0, 160, 160), rotation_deg=-103.3, translation=(-0.35, 0.17), scale=(1.07,) * 3)
    mask = silhouettes.mask(truth)
    problem = _Problem(silhouettes, mask, truth)
    start = np.array([truth.rotation_deg, 14.0, -0.351, 0.115, 0.0])
    steps = INITIAL_STEPS / 4
    params, iou = problem.compass(start, steps, FINAL_STEPS, coupled=True)
    assert abs(params[1] - 10.0) < 0.75 and iou > 0.97


def circle_on_the_floor(pose: PhotoPose, radius: float) -> np.ndarray:
    """The pixels inside the projection of a circle of `radius` (object units) on the floor under the posed object:
    the convex hull of 360 projected points of its rim."""
    angles = np.radians(np.arange(360.0))
    rim = np.stack([radius * np.cos(angles), np.zeros(360), radius * np.sin(angles)], axis=1)
    world = rim @ pose.object_to_world()[:3, :3].T + pose.object_to_world()[:3, 3]
    u, v, _ = pose.camera.project(world)
    hull = ConvexHull(np.stack([u, v], axis=1))
    h, w = pose.camera.height, pose.camera.width
    vv, uu = np.mgrid[0:h, 0:w] + 0.5
    points = np.stack([uu.ravel(), vv.ravel(), np.ones(uu.size)], axis=1)
    return (points @ hull.equations.T <= 0).all(axis=1).reshape(h, w)


def test_floor_radii_draw_a_circle_on_the_floor_as_the_camera_sees_it(chair):
    pose = PhotoPose(Camera(30.0, 120, 100), rotation_deg=40.0, translation=(0.2, -0.3), scale=(1.1,) * 3)
    radii = SilhouetteRenderer(chair).floor_radii(pose)
    expected = circle_on_the_floor(pose, 0.6)
    assert expected.sum() > 500
    assert silhouette_iou(radii <= 0.6, expected) > 0.98
    low = SilhouetteRenderer(chair).floor_radii(replace(pose, camera=Camera(3.0, 120, 100)))
    assert np.isinf(low[0]).all() and np.isfinite(low[-1]).all()  # above the horizon the floor is never met


@pytest.mark.parametrize("elevation, rotation, reach", [(30.0, 0.0, 0.6), (30.0, 40.0, 0.6), (3.0, 0.0, 0.9),
                                                     (60.0, 40.0, 5.0)])
def test_floor_radii_within_a_reach_are_the_full_radii_cut_there(chair, elevation, rotation, reach):
    pose = PhotoPose(Camera(elevation, 120, 100), rotation_deg=rotation, translation=(0.2, -0.3), scale=(1.1,) * 3)
    silhouettes = SilhouetteRenderer(chair)
    full, cut = silhouettes.floor_radii(pose), silhouettes.floor_radii(pose, reach)
    assert (full <= reach).sum() > 50
    np.testing.assert_array_equal(cut, np.where(full <= reach, full, np.inf))


def test_disk_iou_is_the_best_disk_of_every_radius():
    rng = np.random.default_rng(3)
    mask, target = rng.random((30, 40)) < 0.2, rng.random((30, 40)) < 0.4
    radii = np.where(rng.random((30, 40)) < 0.9, rng.uniform(0.0, 3.0, (30, 40)), np.inf)
    best, radius = disk_iou(mask, target, radii, 1.0, 2.0)
    tried = [(silhouette_iou(mask, target), 0.0)] + [(silhouette_iou(mask | (radii <= r), target), r)
                                                    for r in np.unique(radii[np.isfinite(radii)]) if 1.0 <= r <= 2.0]
    assert best == pytest.approx(max(tried)[0])
    assert 1.0 <= radius <= 2.0 and silhouette_iou(mask | (radii <= radius), target) == pytest.approx(best)
    assert disk_iou(mask, target, np.full((30, 40), np.inf), 1.0, 2.0) == (silhouette_iou(mask, target), 0.0)


def test_search_with_a_disk_finds_an_object_standing_on_a_saucer(chair):
    silhouettes = SilhouetteRenderer(chair)
    truth = PhotoPose(Camera(25.0, 128, 128), rotation_deg=70.0, translation=(0.1, -0.2), scale=(1.0,) * 3)
    saucer = 1.4 * silhouettes.footprint_radius
    mask = silhouettes.mask(truth) | circle_on_the_floor(truth, saucer)
    plain = align_pose(silhouettes, mask)
    assert silhouette_iou(silhouettes.mask(plain.pose), silhouettes.mask(truth)) < 0.85 and plain.floor_disk == 0.0
    found = align_pose(silhouettes, mask, disk=True)
    assert rotation_error_deg(found.pose.rotation_deg, truth.rotation_deg) < 3.0
    assert abs(found.pose.camera.elevation_deg - truth.camera.elevation_deg) < 3.0
    assert silhouette_iou(silhouettes.mask(found.pose), silhouettes.mask(truth)) > 0.9
    assert found.floor_disk == pytest.approx(saucer, rel=0.1)


def test_capture_finds_an_object_on_a_saucer_and_leaves_the_saucer_out(chair):
    """A dark chair on a light saucer on a blue floor: the mask holds both, the search models the saucer."""
    silhouettes = SilhouetteRenderer(chair)
    truth = PhotoPose(Camera(30.0, 160, 160), rotation_deg=-30.0, translation=(0.0, 0.0), scale=(1.0,) * 3)
    chair_mask = silhouettes.mask(truth)
    saucer = circle_on_the_floor(truth, 1.35 * silhouettes.footprint_radius)
    photo = np.where(chair_mask[..., None], np.array([0.35, 0.2, 0.1]),
                     np.where(saucer[..., None], np.array([0.9, 0.85, 0.8]), np.array([0.2, 0.3, 0.6])))
    found = find_pose(chair, photo)
    assert found.floor_disk > 0.0
    assert silhouette_iou(silhouettes.mask(found.pose.at_size(160, 160)), chair_mask) > 0.9


def test_a_segmentation_round_that_breaks_the_mask_is_not_followed(chair, monkeypatch):
    """The later segmentation rounds return the chair's bounding box filled: no pose fits it as well as the first
    mask was fitted, so the first pose stays; followed, the box turns the chair."""
    import renderer.capture.capture as capture_module

    silhouettes = SilhouetteRenderer(chair)
    truth = PhotoPose(Camera(20.0, 160, 160), rotation_deg=-110.0)
    true_mask = silhouettes.mask(truth)
    rows, cols = np.nonzero(true_mask)
    box = np.zeros_like(true_mask)
    box[rows.min():rows.max() + 1, cols.min():cols.max() + 1] = True
    masks = iter([true_mask, box, box])
    monkeypatch.setattr(capture_module, "object_mask", lambda *args, **kwargs: next(masks))
    photo = np.full((160, 160, 3), 0.5)

    def found_iou() -> float:
        found = find_pose(chair, photo, silhouettes=silhouettes)
        return silhouette_iou(silhouettes.mask(found.pose.at_size(160, 160)), true_mask)

    assert found_iou() > 0.9
    masks = iter([true_mask, box, box])
    monkeypatch.setattr(capture_module, "ROUND_FIT_DROP", 1.0)
    assert found_iou() < 0.85


def test_capture_of_a_path_traced_photo_recovers_pose_and_colors(chair):
    colored = chair.copy()
    colored.visual.vertex_colors = np.tile([200, 40, 30, 255], (len(chair.vertices), 1)).astype(np.uint8)
    truth = PhotoPose(Camera(22.0, 96, 96), rotation_deg=35.0)
    scene = Scene.single(object=truth.placed(Scene().object), light=LightSpec((0.5, 3.0, 1.5)),
                  camera=CameraSpec(truth.camera.elevation_deg), image_size=96)
    photo = render_pathtraced(scene, colored, spp=4, seed=1, denoise=True, floor=False).image
    rgba = voxelize(colored, 24)
    captured = capture_appearance(rgba, colored, photo, None, None, search=True)
    assert rotation_error_deg(captured.pose.rotation_deg, truth.rotation_deg) < 5.0
    assert abs(captured.pose.camera.elevation_deg - truth.camera.elevation_deg) < 5.0
    # The mask the pose was fitted to comes back at the photo's size (the colors use it: no second segmentation).
    assert silhouette_iou(captured.alignment.mask, SilhouetteRenderer(chair).mask(truth)) > 0.9
    seen = captured.rgba[captured.visible, :3]
    assert len(seen) > 100
    assert np.median(seen[:, 0]) > np.median(seen[:, 1]) + 0.2  # red object, red colors (with its shading)


def test_a_capture_reports_its_progress_in_order(chair):
    truth = PhotoPose(Camera(25.0, 96, 96), rotation_deg=-35.0)
    mask = SilhouetteRenderer(chair).mask(truth)
    photo = np.where(mask[..., None], np.array([0.2, 0.4, 0.9]), 0.75)  # no alpha: segmented, then searched in rounds
    shares = []
    capture_appearance(voxelize(chair, 16), chair, photo, None, None, search=True, progress=shares.append)
    assert shares == sorted(shares) and shares[-1] == 1.0 and 0.0 < shares[0] < 0.2
    assert len(set(shares)) >= 5  # the segmentation, the search, its two rounds, the light fit: not one jump at the end


def test_capture_needs_a_pose_or_the_search(chair):
    with pytest.raises(InputError, match="camera file"):
        capture_appearance(voxelize(chair, 8), chair, np.zeros((8, 8, 3)), None, None, search=False)


# --- symmetry ------------------------------------------------------------------------------


def test_symmetry_is_detected_for_a_symmetric_chair_and_not_for_a_lopsided_one(chair):
    assert is_mirror_symmetric(voxelize(chair, 48)[..., 3] > 0.5)
    lopsided = trimesh.util.concatenate([chair, box_mesh((0.3, 0.0, -0.45), (0.5, 0.9, 0.45))])
    assert not is_mirror_symmetric(voxelize(lopsided, 48)[..., 3] > 0.5)


# --- bad photos ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def studio_photo(chair):
    truth = PhotoPose(Camera(30.0, 120, 100), rotation_deg=20.0)
    mask = SilhouetteRenderer(chair).mask(truth)
    rgb = np.where(mask[..., None], np.array([0.2, 0.4, 0.9]), 0.75)
    return rgb, mask


def save_variant(path, rgb, variant):
    pixels = (rgb * 255).round().astype(np.uint8)
    if variant == "gray":
        Image.fromarray(pixels.mean(axis=2).astype(np.uint8)).save(path)
    elif variant == "gray16":
        Image.fromarray((pixels.mean(axis=2) * 257).astype(np.uint16)).save(path)
    elif variant == "palette":
        Image.fromarray(pixels).convert("P", palette=Image.Palette.ADAPTIVE, colors=16).save(path)
    elif variant == "rgba":
        Image.fromarray(np.dstack([pixels, np.full(pixels.shape[:2], 255, np.uint8)])).save(path)
    elif variant == "exif":
        image = Image.fromarray(np.ascontiguousarray(np.rot90(pixels, 1)))  # stored turned; EXIF 6 turns it back
        exif = Image.Exif()
        exif[0x0112] = 6
        image.save(path, exif=exif)
    elif variant == "huge":
        Image.fromarray(pixels).resize((120 * 36, 100 * 36), Image.Resampling.NEAREST).save(path)  # over 4096
    return path


@pytest.mark.parametrize("variant", ["gray", "gray16", "palette", "rgba", "exif"])
def test_every_kind_of_photo_segments_like_the_plain_one(tmp_path, studio_photo, variant):
    rgb, truth = studio_photo
    photo, alpha = load_image(save_variant(tmp_path / "photo.png", rgb, variant))
    assert silhouette_iou(object_mask(photo, alpha), truth) > 0.95


def test_huge_photo_is_captured_within_bounded_memory(tmp_path, studio_photo, chair):
    path = save_variant(tmp_path / "photo.png", studio_photo[0], "huge")
    photo, alpha = load_image(path)
    assert max(photo.shape) <= 4096
    found = find_pose(chair, photo, alpha, initial=PhotoPose(Camera(35.0, 120, 100), rotation_deg=10.0))
    assert found.pose.camera.width == photo.shape[1]
    assert rotation_error_deg(found.pose.rotation_deg, 20.0) < 5.0


def test_capture_command_writes_a_scene_that_reproduces_the_pose(tmp_path, chair, studio_photo):
    import json

    from app.cli import run

    chair.export(tmp_path / "chair.obj")
    Image.fromarray((studio_photo[0] * 255).astype(np.uint8)).save(tmp_path / "photo.png")
    save_pose(tmp_path / "rough.json", PhotoPose(Camera(40.0, 120, 100), rotation_deg=0.0))
    out = tmp_path / "scene.json"
    code = run(["capture", str(tmp_path / "chair.obj"), str(tmp_path / "photo.png"), "--camera",
                str(tmp_path / "rough.json"), "--auto", "--res", "24", "-o", str(out)])
    assert code == 0
    scene = json.loads(out.read_text())
    assert rotation_error_deg(scene["objects"][0]["rotation_deg"], 20.0) < 3.0
    assert abs(scene["camera"]["elevation_deg"] - 30.0) < 3.0
    assert (tmp_path / "scene_colors.npz").exists() and (tmp_path / "scene_camera.json").exists()
    assert run(["capture", str(tmp_path / "chair.obj"), str(tmp_path / "photo.png"), "-o", str(out)]) == 2  # exists


def test_free_focal_length_is_recovered_for_a_longer_lens(chair):
    silhouettes = SilhouetteRenderer(chair)
    truth = PhotoPose(Camera(25.0, 128, 128, focal_mm=55.0), rotation_deg=-30.0)
    start = replace(truth, camera=replace(truth.camera, focal_mm=40.0), rotation_deg=-20.0)
    fixed = align_pose(silhouettes, silhouettes.mask(truth), initial=start)
    free = align_pose(silhouettes, silhouettes.mask(truth), initial=start, free_focal=True)
    assert fixed.pose.camera.focal_mm == 40.0
    assert free.pose.camera.focal_mm == pytest.approx(55.0, rel=0.15)
    assert free.iou >= fixed.iou


def test_the_lens_a_photos_exif_states_is_the_searchs_lens(chair, tmp_path):
    """A JPEG taken with a 24 mm lens (35 mm equivalent, in its EXIF) of the chair on a backdrop: the search reads the
    lens and finds the pose through it (silhouette IoU over 0.95, the rotation within 3 degrees); assuming the
    scene camera's 40 mm instead fits worse. A photo without EXIF, or with an impossible lens, states none."""
    truth = PhotoPose(photo_camera(160, 120, 24.0, 30.0), rotation_deg=20.0)
    true_mask = SilhouetteRenderer(chair).mask(truth)
    rgb = np.where(true_mask[..., None], np.array([0.2, 0.4, 0.9]), 0.75)
    exif = Image.Exif()
    exif.get_ifd(0x8769)[0xA405] = 24
    image = Image.fromarray((rgb * 255).round().astype(np.uint8))
    image.save(tmp_path / "phone.jpg", quality=95, exif=exif)
    focal = photo_focal_35mm(tmp_path / "phone.jpg")
    assert focal == 24.0
    photo, _ = load_image(tmp_path / "phone.jpg")
    through_lens = find_pose(chair, photo, focal_35mm=focal)
    assumed = find_pose(chair, photo)
    ious = [silhouette_iou(SilhouetteRenderer(chair).mask(a.pose), true_mask) for a in (through_lens, assumed)]
    assert through_lens.pose.camera.focal_mm == pytest.approx(truth.camera.focal_mm)
    assert ious[0] > 0.95 and ious[0] > ious[1]
    assert rotation_error_deg(through_lens.pose.rotation_deg, 20.0) < 3.0
    image.save(tmp_path / "plain.jpg")
    exif.get_ifd(0x8769)[0xA405] = 0
    image.save(tmp_path / "zero.jpg", exif=exif)
    assert photo_focal_35mm(tmp_path / "plain.jpg") is None and photo_focal_35mm(tmp_path / "zero.jpg") is None
    assert photo_focal_35mm(tmp_path / "missing.jpg") is None


def test_a_rod_in_front_of_the_object_gives_it_no_colors(monkeypatch):
    """A blue box on a grey backdrop with a red rod before it, running on below it (as a spoon before a cup): the
    rod's pixels inside the box's silhouette are told apart by the color of its part beside the box, and no voxel
    takes its red. Without that (a rod too short to show beside the box), a good share of the seen voxels does."""
    import renderer.capture.capture as capture_module

    box = box_mesh()
    pose = PhotoPose(Camera(20.0, 120, 100), rotation_deg=30.0)
    silhouette = SilhouetteRenderer(box).mask(pose)
    rows, cols = np.nonzero(silhouette)
    middle = int(cols.mean())
    photo = np.where(silhouette[..., None], np.array([0.2, 0.35, 0.85]), 0.7)
    photo[rows.min() + 10:rows.max() + 15, middle - 4:middle + 4] = (0.85, 0.15, 0.1)
    rgba = voxelize(box, resolution=24)

    def red_share() -> float:
        capture = capture_appearance(rgba, box, photo, None, pose, search=False)
        seen = capture.rgba[capture.visible][:, :3]
        return float(np.mean((seen[:, 0] > 0.5) & (seen[:, 2] < 0.5)))

    assert red_share() < 0.01
    monkeypatch.setattr(capture_module, "MIN_FOREIGN_PIXELS", 10**9)
    assert red_share() > 0.05


def test_coloring_near_the_silhouette_never_takes_the_background_even_from_a_pose_a_little_off():
    """A red box on a blue backdrop; colored from a pose shifted by 2 pixels, the voxels along the edge would
    land on the backdrop: with the mask's trusted inside they take the nearest sure voxel's red instead."""
    box = box_mesh()
    truth = PhotoPose(Camera(25.0, 200, 160), rotation_deg=30.0)
    silhouette = SilhouetteRenderer(box).mask(truth)
    photo = np.where(silhouette[..., None], np.array([0.85, 0.1, 0.1]), np.array([0.2, 0.3, 0.8]))
    off = replace(truth, translation=(0.02, 0.0))  # about 2 pixels to the side
    rgba = voxelize(box, 32)
    colored = capture_appearance(rgba, box, photo, None, off, search=False)
    occupied = colored.rgba[..., 3] > 0.5
    colors = colored.rgba[occupied, :3]
    assert (colors[:, 2] < 0.3).all() and (colors[:, 0] > 0.7).all()  # every voxel red, none blue
    from renderer.photo import color_voxels_from_photo

    untrusted = color_voxels_from_photo(rgba, off.object_to_world(), photo, off.camera)
    assert (untrusted.rgba[occupied, 2] > 0.5).any()  # without it, the edge takes the backdrop's blue


def test_a_loose_fit_advises_a_box_or_strokes():
    from renderer.capture.align import Alignment
    from renderer.capture.capture import fit_advice

    pose = PhotoPose(Camera(30.0, 64, 64))
    assert fit_advice(Alignment(pose, 0.95, 0, 0.0), hinted=False) is None
    assert "--box" in fit_advice(Alignment(pose, 0.84, 0, 0.0), hinted=False)
    assert "strokes" in fit_advice(Alignment(pose, 0.84, 0, 0.0), hinted=True)


def test_trusted_pixels_keep_the_middle_of_thin_parts_and_never_their_edge():
    """A 300 x 300 mask (margin 3 px) holding a thick square, a bar 5 px wide and a bar 2 px wide, far apart:
    the square is trusted only more than 3 px in, the wide bar along its middle 3 columns (2-3 px deep) but not
    its edge columns, the narrow bar (all of it 1 px deep: all of it its middle) whole, nothing else."""
    from renderer.capture.capture import trusted_pixels

    mask = np.zeros((300, 300), dtype=bool)
    mask[20:120, 20:120] = True  # thick
    mask[150:280, 40:45] = True  # 5 px wide: depths 1, 2, 3, 2, 1 across
    mask[150:280, 200:202] = True  # 2 px wide: depths 1, 1
    trusted = trusted_pixels(mask)
    assert trusted[70, 70] and not trusted[20:23, 20:120].any() and trusted[24, 70]
    middle_rows = slice(160, 270)
    assert trusted[middle_rows, 41:44].all() and not trusted[middle_rows, [40, 44]].any()
    assert trusted[150:280, 200:202].all()
    assert not (trusted & ~mask).any()
