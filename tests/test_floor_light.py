"""The lit empty floor: hand-computed irradiance, the path tracer's empty floor, geometry, hard cases."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy import ndimage

from renderer.camera import Camera
from renderer.color import srgb_to_linear
from renderer.errors import InputError
from renderer.floor_light import COARSE_STEP, _coarse_geometry, lit_floor_image
from renderer.pathtrace.path_tracer import render_pathtraced
from renderer.resample import upsampled
from renderer.scene import AMBIENT_RADIANCE, CameraSpec, FloorSpec, LightSpec, ObjectSpec, Scene
from renderer.splat import background_color, floor_mask


def floor_pixel(camera: Camera, point) -> tuple[int, int]:
    u, v, _ = camera.project(np.asarray(point, dtype=np.float64))
    return int(v), int(u)


def test_diffuse_floor_below_the_light_matches_the_hand_integral():
    # A black floor shows only its coat; subtracting it from a white floor leaves the diffuse base.
    # Straight below a unit square light at height h the irradiance factor is the integral of
    # h^2 / r^4 over the square (midpoint rule, fine), and the light hides as much of the ambient sky.
    h, n = 2.75, 400
    x = (np.arange(n) + 0.5) / n - 0.5
    form = np.mean(h**2 / (x[:, None] ** 2 + x[None, :] ** 2 + h**2) ** 2)
    irradiance = 14.0 * form + AMBIENT_RADIANCE * (np.pi - form)
    camera = Camera(elevation_deg=30.0, width=128, height=128)
    white = srgb_to_linear(lit_floor_image(camera, (0.0, h, 0.0), (1.0, 1.0, 1.0)))
    black = srgb_to_linear(lit_floor_image(camera, (0.0, h, 0.0), (0.0, 0.0, 0.0)))
    row, col = floor_pixel(camera, (0.0, 0.0, 0.0))
    diffuse = white[row, col] - black[row, col]
    # The coat lets through 0.94 - 0.859 F(view) of an ideal Lambertian floor's irradiance / pi (fitted
    # to the path tracer; the next test checks the whole image against it), F by Schlick at ior 1.5.
    cos_view = camera.position[1] / np.linalg.norm(camera.position)  # seen from the camera, at the origin
    fresnel = 0.04 + 0.96 * (1.0 - cos_view) ** 5
    expected = irradiance / np.pi * (0.94 - 0.859 * fresnel)
    np.testing.assert_allclose(diffuse, expected, rtol=0.02)


def test_matches_the_path_traced_empty_floor():
    # The object shrunk to nothing far away: the path tracer shows the empty floor, the independent reference.
    scene = Scene.single(object=ObjectSpec(scale=(1e-3, 1e-3, 1e-3), translation=(0.0, -8.0)),
                  floor=FloorSpec((0.7, 0.35, 0.2)), light=LightSpec((0.8, 2.6, -0.6)), camera=CameraSpec(20.0))
    box = trimesh.creation.box((1.0, 1.0, 1.0))
    traced = render_pathtraced(scene, box, size=64, spp=256).image
    analytic = lit_floor_image(Camera.from_scene(scene, 64), scene.light.position, scene.floor.color)
    mse = np.mean(((traced - analytic) * 255.0) ** 2)
    assert mse < 30.0  # 8 on average at 256^2 against 256 spp + OIDN; this adds 256 spp noise
    # ... and it is the light that makes it: the same floor unlit is far off.
    unlit = lit_floor_image(Camera.from_scene(scene, 64), (30.0, 2.6, 30.0), scene.floor.color)
    assert np.mean(((traced - unlit) * 255.0) ** 2) > 4 * mse


def test_the_bright_spot_follows_the_light_and_the_sky_is_the_background():
    camera = Camera(elevation_deg=35.0, width=96, height=96)
    spots = []
    for x in (-1.0, 0.0, 1.0):
        image = lit_floor_image(camera, (x, 2.75, 0.0), (0.5, 0.5, 0.5))
        luminance = image.mean(-1)
        spots.append(np.unravel_index(np.argmax(luminance), luminance.shape)[1])
    assert spots[0] < spots[1] < spots[2]  # the light moves right, so does its brightest floor pixel
    sky = ~floor_mask(Camera(elevation_deg=5.0, width=64, height=64))
    image = lit_floor_image(Camera(elevation_deg=5.0, width=64, height=64), (0.0, 2.75, 0.0), (0.5, 0.5, 0.5))
    assert sky.any() and np.array_equal(image[sky], np.broadcast_to(background_color(), image[sky].shape))


def test_a_darker_floor_is_darker_everywhere_and_colors_keep_their_order():
    camera = Camera(elevation_deg=25.0, width=64, height=64)
    bright = lit_floor_image(camera, (0.3, 2.8, 0.4), (0.8, 0.8, 0.8))
    dark = lit_floor_image(camera, (0.3, 2.8, 0.4), (0.2, 0.2, 0.2))
    red = lit_floor_image(camera, (0.3, 2.8, 0.4), (0.9, 0.1, 0.1))
    floor = floor_mask(camera)
    assert np.all(bright[floor] > dark[floor])
    assert np.all(red[floor][:, 0] > red[floor][:, 1])


@pytest.mark.parametrize("elevation", [0.0, 5.0, 50.0, 89.9])
@pytest.mark.parametrize("light", [(0.0, 2.75, 0.0), (1e3, 2.75, -1e3), (1.5, 1e-4, 1.5), (0.0, 1e4, 0.0)])
def test_finite_and_in_range_for_extreme_lights_and_elevations(elevation, light):
    image = lit_floor_image(Camera(elevation_deg=elevation, width=32, height=32), light, (1.0, 1.0, 1.0))
    assert image.shape == (32, 32, 3) and image.dtype == np.float32
    assert np.all(np.isfinite(image)) and image.min() >= 0.0 and image.max() <= 1.0


def test_odd_sizes_interpolate_to_every_pixel():
    camera = Camera(elevation_deg=30.0, width=37, height=21)
    image = lit_floor_image(camera, (0.0, 2.75, 0.0), (0.5, 0.5, 0.5))
    assert image.shape == (21, 37, 3) and np.all(np.isfinite(image))


@pytest.mark.parametrize("width, height", [(256, 256), (37, 21)])
def test_the_coarse_shading_is_interpolated_bilinearly(width, height):
    """Against scipy's linear interpolation at the pixel centres, in the coarse samples' coordinates."""
    geometry = _coarse_geometry(Camera(elevation_deg=30.0, width=width, height=height))
    coarse = np.random.default_rng(0).random((geometry.points.shape[0],
                                              geometry.points.shape[1], 4)).astype(np.float32)
    rows = np.append(np.arange(0.5, height, COARSE_STEP), height - 0.5)[: coarse.shape[0]]
    cols = np.append(np.arange(0.5, width, COARSE_STEP), width - 0.5)[: coarse.shape[1]]
    at_r = np.interp(np.arange(height) + 0.5, rows, np.arange(len(rows)))
    at_c = np.interp(np.arange(width) + 0.5, cols, np.arange(len(cols)))
    rr, cc = np.meshgrid(at_r, at_c, indexing="ij")
    expected = np.stack([ndimage.map_coordinates(coarse[..., k], [rr, cc], order=1) for k in range(4)], axis=-1)
    np.testing.assert_allclose(upsampled(coarse, geometry.row_weights, geometry.col_weights), expected, atol=1e-5)


@pytest.mark.parametrize("light,color,match", [
    ((0.0, 0.0, 0.0), (0.5, 0.5, 0.5), "above the floor"),
    ((0.0, float("nan"), 0.0), (0.5, 0.5, 0.5), "above the floor"),
    ((0.0, 2.0), (0.5, 0.5, 0.5), "light position"),
    ((0.0, 2.0, 0.0), (0.5, float("inf"), 0.5), "floor color"),
])
def test_impossible_values_are_clear_errors(light, color, match):
    with pytest.raises(InputError, match=match):
        lit_floor_image(Camera(elevation_deg=30.0, width=16, height=16), light, color)


def test_the_coats_entry_table_is_the_path_tracers_floor_material():
    """COAT_ENTRY against Mitsuba's own floor material: its value for light at each incidence, seen at 45 degrees
    and from the side (away from the gloss), over its value for light head on."""
    from renderer.floor_light import COAT_ENTRY
    from renderer.pathtrace.mitsuba_variant import active_variant
    from renderer.pathtrace.path_tracer import floor_bsdf

    active_variant()
    import mitsuba as mi

    bsdf = mi.load_dict(floor_bsdf({"type": "rgb", "value": [0.3, 0.3, 0.3]}))
    interaction = mi.SurfaceInteraction3f()
    interaction.wi = mi.Vector3f(float(np.sin(np.pi / 4)), 0.0, float(np.cos(np.pi / 4)))
    values = []
    for cosine in np.linspace(0.0, 1.0, len(COAT_ENTRY)):
        cosine = max(float(cosine), 0.01)
        toward = mi.Vector3f(0.0, float(np.sqrt(1.0 - cosine**2)), cosine)
        values.append(float(np.array(bsdf.eval(mi.BSDFContext(), interaction, toward)).ravel()[0]) / cosine)
    np.testing.assert_allclose(COAT_ENTRY, np.array(values) / values[-1], atol=0.005)


@pytest.mark.parametrize("zenith_deg", [20.0, 50.0, 75.0])
def test_the_coats_reflection_of_a_uniform_sky_is_the_path_tracers_floor_materials(zenith_deg):
    """The share of a uniform sky the coat reflects towards a view (the environment's coat samples' weights, averaged)
    against Mitsuba's own floor material with no base, integrated over the hemisphere by Monte Carlo."""
    from renderer.floor_light import _coat_samples
    from renderer.pathtrace.mitsuba_variant import active_variant
    from renderer.pathtrace.path_tracer import floor_bsdf

    active_variant()
    import mitsuba as mi

    bsdf = mi.load_dict(floor_bsdf({"type": "rgb", "value": [0.0, 0.0, 0.0]}))
    count = 200_000
    rng = np.random.default_rng(5)
    up, turn = rng.random(count), 2.0 * np.pi * rng.random(count)  # uniform over the hemisphere
    side = np.sqrt(1.0 - up**2)
    zenith = np.radians(zenith_deg)
    interaction = mi.SurfaceInteraction3f()
    interaction.wi = mi.Vector3f(mi.Float(np.full(count, np.sin(zenith))), mi.Float(np.zeros(count)),
                                 mi.Float(np.full(count, np.cos(zenith))))
    toward = mi.Vector3f(mi.Float(side * np.cos(turn)), mi.Float(side * np.sin(turn)), mi.Float(up))
    values = np.array(bsdf.eval(mi.BSDFContext(), interaction, toward))  # the cosine included
    expected = float(np.mean(values[0] if values.shape[0] == 3 else values.reshape(-1, 3)[:, 0])) * 2.0 * np.pi
    _, _, weights = _coat_samples(np.array([[[np.sin(zenith), np.cos(zenith), 0.0]]]))
    assert abs(float(weights.mean()) / expected - 1.0) < 0.04
