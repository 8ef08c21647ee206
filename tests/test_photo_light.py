"""Dividing a photo's light out (renderer.photo.photo_albedo, unmixed_albedo): photos whose albedo is known, drawn by
the voxel shader and by the path tracer, give it back; dark, empty and odd inputs stay finite."""

from dataclasses import replace

import numpy as np
import pytest
import trimesh

from renderer.capture.capture import capture_appearance
from renderer.capture.pose import pose_from_dict
from renderer.color import srgb_to_linear
from renderer.errors import InputError
from renderer.pathtrace.path_tracer import render_pathtraced
from renderer.photo import photo_albedo, unmixed_albedo
from renderer.scene import CameraSpec, FloorSpec, LightSpec, ObjectSpec, Scene
from renderer.shading.shader import shade_scene
from renderer.voxels import voxelize

FLOOR = (0.55, 0.5, 0.45)
SIZE = 64
RED, BLUE = (0.8, 0.25, 0.2), (0.15, 0.3, 0.7)


def photo_scene(light=(0.6, 2.6, 0.4), elevation=30.0, rotation=25.0, size=SIZE, **obj) -> Scene:
    spec = ObjectSpec(rotation_deg=rotation, **({"voxels": "v.npz"} | obj))
    return Scene.single(object=spec, floor=FloorSpec(FLOOR), light=LightSpec(light), camera=CameraSpec(elevation),
                 image_size=size)


def two_colored_block(n: int = 24) -> np.ndarray:
    """A block in the middle of the object box, its left half RED and its right half BLUE."""
    rgba = np.zeros((n, n, n, 4), dtype=np.float32)
    a, b = n // 4, 3 * n // 4
    rgba[a:b, 0:n // 2, a:b] = (*RED, 1.0)
    rgba[n // 2:b, 0:n // 2, a:b, :3] = BLUE
    return rgba


@pytest.mark.parametrize("light", [(0.6, 2.6, 0.4), (-1.0, 2.2, -0.8)])
def test_a_photo_drawn_by_the_shader_gives_back_the_voxel_colors(light):
    rgba = two_colored_block()
    scene = photo_scene(light)
    photo = shade_scene(scene, rgba, FLOOR, grid_size=256).image
    albedo, known = photo_albedo(photo, scene, rgba)
    assert known.sum() > 100
    # Every pixel's albedo is one of the two colors or, where the shader's supersampled grid blends them at their
    # border, a mix of the two; both halves are seen; pixels whose light is unknown take a known one's.
    red, blue = np.float32(RED), np.float32(BLUE)
    share = np.clip(((albedo - red) @ (blue - red)) / float((blue - red) @ (blue - red)), 0.0, 1.0)
    assert np.abs(albedo - (red + share[..., None] * (blue - red))).max() < 2e-3
    distance = np.stack([np.abs(albedo - c).max(axis=2) for c in (red, blue)])
    assert (distance[0][known] < 2e-3).sum() > 20 and (distance[1][known] < 2e-3).sum() > 20


def test_a_path_traced_photo_of_a_grey_box_gives_back_its_albedo():
    """The path tracer is independent of the shader: its photo, divided by the shader's light, gives the box's
    albedo within the shader's error (the median pixel within 10 % in linear light)."""
    grey = (0.6, 0.6, 0.6)
    box = trimesh.creation.box([0.5, 0.6, 0.5])
    box.apply_translation([0.0, 0.3, 0.0])
    box.visual.vertex_colors = [*(round(255 * c) for c in grey), 255]
    rgba = voxelize(box, resolution=50)
    scene = photo_scene(mesh="box.obj")
    photo = render_pathtraced(scene, box, size=SIZE, spp=64, seed=3).image
    albedo, known = photo_albedo(photo, scene, rgba)
    assert known.sum() > 200
    found = np.median(srgb_to_linear(albedo[known].astype(np.float64)), axis=0)
    np.testing.assert_allclose(found, srgb_to_linear(np.float64(grey)), rtol=0.1)


def two_colored_boxes() -> trimesh.Trimesh:
    """Two boxes side by side on the floor, RED and BLUE, the blue one taller (it shadows the red one's side)."""
    red = trimesh.creation.box([0.3, 0.4, 0.5])
    red.apply_translation([-0.16, 0.2, 0.0])
    red.visual.vertex_colors = [*(round(255 * c) for c in RED), 255]
    blue = trimesh.creation.box([0.3, 0.7, 0.5])
    blue.apply_translation([0.16, 0.35, 0.0])
    blue.visual.vertex_colors = [*(round(255 * c) for c in BLUE), 255]
    return trimesh.util.concatenate([red, blue])


def off_the_two_colors(albedo: np.ndarray) -> np.ndarray:
    """Each sRGB albedo's linear distance to the segment from RED to BLUE (a pixel may hold both)."""
    red, blue = srgb_to_linear(np.array([RED, BLUE], dtype=np.float64))
    found = srgb_to_linear(albedo.astype(np.float64))
    share = np.clip(((found - red) @ (blue - red)) / ((blue - red) @ (blue - red)), 0.0, 1.0)
    return np.abs(found - (red + share[:, None] * (blue - red))).max(axis=1)


def test_unmixing_a_path_traced_photo_gives_back_each_albedo():
    """The photo is the path tracer's, of the mesh in its own colors; the unmixing sees only black and grey renders.
    Every known pixel's albedo is one of the two colors, or a mix of them where a pixel holds both, in shadow and at
    the silhouette too, within the noise of 64 samples per pixel, denoised (largest where the light is faint): closer
    than the voxel shader's light gets, on more pixels."""
    mesh = two_colored_boxes()
    scene = photo_scene(mesh="boxes.obj")
    photo = render_pathtraced(scene, mesh, spp=64, seed=5, denoise=True).image
    red, blue = srgb_to_linear(np.array([RED, BLUE], dtype=np.float64))
    albedo, known = unmixed_albedo(photo, scene, mesh, spp=64, seed=5)
    error = off_the_two_colors(albedo[known])
    assert known.sum() > 300
    assert np.median(error) < 0.015 and np.quantile(error, 0.9) < 0.08
    found = srgb_to_linear(albedo[known].astype(np.float64))
    assert (np.abs(found - red).max(axis=1) < 0.02).sum() > 50 and (np.abs(found - blue).max(axis=1) < 0.02).sum() > 50
    shader_albedo, shader_known = photo_albedo(photo, scene, voxelize(mesh, resolution=50))
    assert known.sum() > 1.2 * shader_known.sum()
    assert np.median(off_the_two_colors(shader_albedo[shader_known])) > 2 * np.median(error)
    # A channel that clipped (a bright color under a strong light) keeps its pixels known, the clipped channel no
    # darker than before; the other channels are unchanged.
    clipped = photo.copy()
    clipped[..., 0] = 1.0
    albedo_clipped, known_clipped = unmixed_albedo(clipped, scene, mesh, spp=64, seed=5)
    np.testing.assert_array_equal(known_clipped, known)
    assert np.all(albedo_clipped[known, 0] >= albedo[known, 0])
    np.testing.assert_array_equal(albedo_clipped[known, 1:], albedo[known, 1:])


def test_a_photo_larger_than_the_unmixing_side_is_unmixed_at_that_side(monkeypatch):
    """A photo of twice the side is area averaged to it for the two renders (their cost grows with the pixels); its
    albedo comes back at the photo's size, about as close to the two colors as the smaller photo's (median 0.011
    against 0.008 linear; 90 % within 0.09 against 0.06: the scaling up blurs the borders between colors)."""
    from renderer.pathtrace import path_tracer

    sides = []

    class CountedPathTracer(path_tracer.PathTracer):
        def __init__(self, scene, mesh, *args, **kwargs):
            super().__init__(scene, mesh, *args, **kwargs)
            sides.append(self.camera.width)

    monkeypatch.setattr(path_tracer, "PathTracer", CountedPathTracer)
    mesh = two_colored_boxes()
    scene = photo_scene(mesh="boxes.obj", size=2 * SIZE)
    photo = render_pathtraced(scene, mesh, spp=64, seed=5, denoise=True).image
    sides.clear()
    albedo, known = unmixed_albedo(photo, scene, mesh, spp=64, seed=5, max_side=SIZE)
    assert sides == [SIZE, SIZE]
    assert albedo.shape == (2 * SIZE, 2 * SIZE, 3) and known.shape == (2 * SIZE, 2 * SIZE)
    error = off_the_two_colors(albedo[known])
    assert known.sum() > 4 * 300
    assert np.median(error) < 0.015 and np.quantile(error, 0.9) < 0.1


@pytest.mark.parametrize("case", ["black photo", "white photo", "light outside its box", "grazing camera"])
def test_unmixing_hard_cases_give_finite_albedo(case):
    mesh = two_colored_boxes()
    scene = photo_scene(mesh="boxes.obj", light=(9.0, 0.3, -9.0) if case == "light outside its box" else (0.6, 2.6, 0.4),
                        elevation=0.0 if case == "grazing camera" else 30.0, size=32)
    photo = np.full((32, 32, 3), 1.0 if case == "white photo" else 0.0, dtype=np.float32)
    albedo, known = unmixed_albedo(photo, scene, mesh, spp=4)
    assert np.all(np.isfinite(albedo)) and albedo.min() >= 0.0 and albedo.max() <= 1.0
    if case == "black photo":
        assert np.all(albedo == 0.0)
    if case == "white photo":
        assert not known.any()  # clipped everywhere: no pixel says how bright the object is


@pytest.mark.parametrize("case", ["empty", "black photo", "light outside its box", "grazing camera"])
def test_hard_cases_give_finite_albedo(case):
    rgba = two_colored_block()
    scene = photo_scene()
    photo = shade_scene(scene, rgba, FLOOR, grid_size=256).image
    if case == "empty":
        rgba = np.zeros_like(rgba)
    elif case == "black photo":
        photo = np.zeros_like(photo)
    elif case == "light outside its box":
        scene = photo_scene(light=(9.0, 0.3, -9.0))
    else:
        scene = photo_scene(elevation=0.0)
    albedo, known = photo_albedo(photo, scene, rgba)
    assert np.all(np.isfinite(albedo)) and albedo.min() >= 0.0 and albedo.max() <= 1.0
    if case == "empty":
        assert not known.any()
    if case == "black photo":
        assert np.all(albedo == 0.0)


def test_a_photo_of_another_size_is_refused():
    rgba = two_colored_block()
    with pytest.raises(InputError, match="32x32 pixels but its camera is 64x64"):
        photo_albedo(np.zeros((32, 32, 3), dtype=np.float32), photo_scene(), rgba)


def captured_colors(photo, pose, rgba, light=None):
    capture = capture_appearance(rgba, None, photo, None, pose, search=False, light=light)
    return capture.rgba, capture.light_note


def test_capture_divides_out_the_light_its_camera_file_names():
    rgba = two_colored_block()
    rgba[..., :3] = np.where(rgba[..., 3:] > 0.5, np.float32(RED), np.float32(0.0))
    light = (0.6, 2.6, 0.4)
    scene = replace(photo_scene(light), floor=FloorSpec())  # capture knows no floor color: the scene's default
    photo = shade_scene(scene, rgba, scene.floor.color, grid_size=256).image
    pose = pose_from_dict({"elevation_deg": 30.0, "width": SIZE, "height": SIZE, "rotation_deg": 25.0,
                           "light": list(light)})
    assert pose.light == light and pose_from_dict(pose.to_dict()) == pose
    occupied = rgba[..., 3] > 0.5
    delit, note = captured_colors(photo, pose, rgba)
    assert "divided out" in note
    # Every voxel, seen or copied from a seen one, gets the block's color back: the shading is gone.
    assert np.abs(delit[occupied, :3] - np.float32(RED)).max() < 0.01
    kept, note = captured_colors(photo, replace(pose, light=None), rgba)
    assert "unknown" in note
    assert np.median(np.abs(kept[occupied, :3] - np.float32(RED)).max(axis=1)) > 0.2
    # The --light option gives the same as the camera file's light.
    given, _ = captured_colors(photo, replace(pose, light=None), rgba, light=light)
    np.testing.assert_array_equal(given, delit)
    # Off the scene camera (another lens) the shader cannot draw the photo's view: the shading is kept, and said so.
    zoomed = replace(pose, camera=replace(pose.camera, focal_mm=50.0))
    off, note = captured_colors(photo, zoomed, rgba)
    assert "not the scene camera" in note
    np.testing.assert_array_equal(off, captured_colors(photo, replace(zoomed, light=None), rgba)[0])


def test_capture_with_the_mesh_unmixes_the_light_from_a_path_traced_photo():
    """With the object's mesh, capture divides the path tracer's light out: the voxels the photo shows get their own
    box's color back (the mesh's colors, voxelised), closer than with the voxel shader's light (no mesh given)."""
    mesh = two_colored_boxes()
    rgba = voxelize(mesh, resolution=50)
    light = (0.6, 2.6, 0.4)
    pose = pose_from_dict({"elevation_deg": 30.0, "width": SIZE, "height": SIZE, "rotation_deg": 25.0,
                           "light": list(light)})
    scene = replace(photo_scene(light, mesh="boxes.obj"), floor=FloorSpec())  # capture knows no floor color
    photo = render_pathtraced(scene, mesh, spp=64, seed=2, denoise=True).image
    errors = []
    for given in (mesh, None):
        capture = capture_appearance(rgba, given, photo, None, pose, search=False)
        seen = capture.visible & (rgba[..., 3] > 0.5)
        errors.append(np.median(np.abs(capture.rgba[seen, :3] - rgba[seen, :3]).max(axis=1)))
    assert errors[0] < 0.025 and errors[0] < 0.6 * errors[1]  # measured: 0.017 against 0.036


@pytest.mark.parametrize("light", [[1.0, 2.0], [1.0, "up", 0.0], [1.0, float("nan"), 0.0]])
def test_a_camera_file_with_a_bad_light_is_refused(light):
    with pytest.raises(InputError, match="light must be"):
        pose_from_dict({"elevation_deg": 30.0, "width": SIZE, "height": SIZE, "light": light}, path="cam.json")


def test_the_editors_photo_keeps_its_light_whatever_pose_it_takes(tmp_path):
    """The light is the photo's: a search's or a drag's pose, which knows none, does not drop it."""
    from PIL import Image

    from app.editor.photo_capture import PhotoAlignment

    Image.new("RGB", (SIZE, SIZE), (120, 120, 120)).save(tmp_path / "photo.png")
    (tmp_path / "camera.json").write_text('{"elevation_deg": 30, "width": 64, "height": 64, "light": [0.5, 2.5, 0.2]}')
    photo = PhotoAlignment(tmp_path / "photo.png", photo_scene(), tmp_path / "camera.json")
    assert photo.pose.light == (0.5, 2.5, 0.2)
    photo.set_pose(replace(photo.pose, rotation_deg=40.0, light=None))
    photo.turn(10.0, 0.0)
    assert photo.pose.light == (0.5, 2.5, 0.2) and photo.pose.rotation_deg == pytest.approx(45.0)
