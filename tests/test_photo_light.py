"""Dividing a photo's light out (renderer.photo.photo_albedo): photos whose albedo is known, drawn by the voxel
shader and by the path tracer, give it back; dark, empty and odd inputs stay finite."""

import numpy as np
import pytest
import trimesh

from renderer.color import srgb_to_linear
from renderer.errors import InputError
from renderer.pathtrace.path_tracer import render_pathtraced
from renderer.photo import photo_albedo
from renderer.scene import CameraSpec, FloorSpec, LightSpec, ObjectSpec, Scene
from renderer.shading.shader import shade_scene
from renderer.voxels import voxelize

FLOOR = (0.55, 0.5, 0.45)
SIZE = 64
RED, BLUE = (0.8, 0.25, 0.2), (0.15, 0.3, 0.7)


def photo_scene(light=(0.6, 2.6, 0.4), elevation=30.0, rotation=25.0, size=SIZE, **obj) -> Scene:
    spec = ObjectSpec(rotation_deg=rotation, **({"voxels": "v.npz"} | obj))
    return Scene(object=spec, floor=FloorSpec(FLOOR), light=LightSpec(light), camera=CameraSpec(elevation),
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
    # Every pixel whose light is known is one of the two colors, and both halves are seen.
    distance = np.stack([np.abs(albedo[known] - np.float32(c)).max(axis=1) for c in (RED, BLUE)])
    assert distance.min(axis=0).max() < 2e-3
    assert (distance[0] < 2e-3).sum() > 20 and (distance[1] < 2e-3).sum() > 20
    assert np.all(albedo[~known] == 0.0)


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
