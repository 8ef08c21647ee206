"""Environment light and materials: the scene's new parts, reading maps, the sky, and the shader against known answers."""

import json
import math
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from renderer.camera import Camera
from renderer.environment import (
    environment_light,
    map_directions,
    read_environment_image,
    rotate_y,
    sample_map,
    sky_light,
    sun_direction,
    texel_solid_angles,
    uniform_environment,
)
from renderer.errors import InputError
from renderer.grid import pool_voxels, shader_pool_factors
from renderer.scene import (
    AMBIENT_RADIANCE,
    SHADER_GRID_SIZE,
    CameraSpec,
    EnvironmentSpec,
    LightSpec,
    MaterialSpec,
    ObjectSpec,
    Scene,
    SkySpec,
    load_scene,
    save_scene,
    scene_from_dict,
)
from renderer.shading.environment_shading import shade_environment
from renderer.shading.geometry import object_geometry, placed
from renderer.shading.lighting import shade
from renderer.shading.shader import shade_scene
from renderer.shading.surface import visible_surface
from tests.test_shading import ball, cube

ROOT = Path(__file__).resolve().parents[1]
SIZE = 96
WHITE = (1.0, 1.0, 1.0)


def write_map(path: Path, radiance: np.ndarray) -> Path:
    """An HDR map written by Mitsuba's own writer (the file format is the test's, not the code's)."""
    import mitsuba as mi

    from renderer.pathtrace.mitsuba_variant import active_variant

    active_variant()
    mi.Bitmap(np.ascontiguousarray(radiance, dtype=np.float32)).write(str(path))
    return path


def env_scene(environment: EnvironmentSpec | None, material: MaterialSpec | None = None, light_on: bool = False,
              base_dir: Path = Path("."), elevation: float = 30.0) -> Scene:
    return Scene.single(object=ObjectSpec(voxels="ball.npz", material=material or MaterialSpec()), environment=environment,
                 light=LightSpec(enabled=light_on), camera=CameraSpec(elevation), image_size=SIZE, base_dir=base_dir)


def pixel_of(point, elevation=30.0, size=SIZE) -> tuple[int, int]:
    u, v, _ = Camera(elevation, width=size, height=size).project(np.asarray(point, dtype=np.float64)[None])
    return int(v[0]), int(u[0])


# --- the scene ----------------------------------------------------------------------------------------


def test_a_scene_without_the_new_parts_saves_without_them(tmp_path):
    data = json.loads((ROOT / "assets" / "demo" / "scene.json").read_text())
    scene = scene_from_dict(data, tmp_path / "scene.json")
    written = scene.to_dict()
    assert "environment" not in written and "material" not in written["objects"][0] and written["light"] == {
        "position": data["light"]["position"]}


def test_new_parts_round_trip_through_a_file(tmp_path):
    (tmp_path / "maps").mkdir()
    scene = Scene.single(object=ObjectSpec(mesh="chair.obj", material=MaterialSpec(0.3, 0.5, 0.25)),
                  light=LightSpec((0.5, 2.6, 0.0), enabled=False),
                  environment=EnvironmentSpec(image="maps/studio.exr", rotation_deg=40.0, strength=1.5),
                  base_dir=tmp_path)
    save_scene(scene, tmp_path / "sub.json")
    again = load_scene(tmp_path / "sub.json")
    assert again == scene and again.environment_path() == tmp_path / "maps" / "studio.exr"
    sky = replace(scene, environment=EnvironmentSpec(sky=SkySpec(20.0, -45.0, 5.0)))
    save_scene(sky, tmp_path / "sky.json")
    assert load_scene(tmp_path / "sky.json") == sky


@pytest.mark.parametrize(("change", "fragments"), [
    (lambda d: d.update(enviroment={"sky": {}}), ('enviroment: unknown key (did you mean "environment"?)',)),
    (lambda d: d["objects"][0].update(materal={}), ('objects[0].materal', '"material"')),
    (lambda d: d["objects"][0].update(material={"roughnes": 0.2}), ('objects[0].material.roughnes', '"roughness"')),
    (lambda d: d["objects"][0].update(material={"roughness": 7}), ("objects[0].material.roughness", "[0, 1]")),
    (lambda d: d["objects"][0].update(material={"metallic": "yes"}), ("objects[0].material.metallic", "number")),
    (lambda d: d.update(environment={"sky": {}, "image": "a.hdr"}), ("environment", "not both")),
    (lambda d: d.update(environment={"strength": 1.0}), ("environment", "neither")),
    (lambda d: d.update(environment={"sky": {"turbidity": 20}}), ("environment.sky.turbidity", "[1, 10]")),
    (lambda d: d.update(environment={"sky": {"sun_elevation_deg": -5}}), ("sun_elevation_deg", "[0, 90]")),
    (lambda d: d.update(environment={"sky": {}, "strength": -1}), ("environment.strength",)),
    (lambda d: d["light"].update(enabled=False), ("light.enabled", "environment")),
    (lambda d: d["light"].update(enabled="no"), ("light.enabled", "true or false")),
])
def test_bad_new_values_are_refused_naming_the_field(change, fragments):
    data = json.loads((ROOT / "assets" / "demo" / "scene.json").read_text())
    change(data)
    with pytest.raises(InputError) as caught:
        scene_from_dict(data, "scene.json")
    for fragment in fragments:
        assert fragment in str(caught.value)


# --- reading maps ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".exr", ".hdr"])
def test_hdr_maps_read_back_as_written(tmp_path, suffix):
    radiance = np.random.default_rng(0).random((16, 32, 3)).astype(np.float32) * 40.0
    read = read_environment_image(write_map(tmp_path / f"map{suffix}", radiance))
    # Radiance's RGBE shares one exponent per pixel: each channel is exact to 1/128 of the pixel's largest.
    tolerance = radiance.max(axis=2, keepdims=True) / (128 if suffix == ".hdr" else 1e6)
    assert np.all(np.abs(read - radiance) <= tolerance)


def test_ldr_maps_are_srgb(tmp_path):
    from PIL import Image

    Image.fromarray(np.full((8, 16, 3), 128, dtype=np.uint8)).save(tmp_path / "map.png")
    np.testing.assert_allclose(read_environment_image(tmp_path / "map.png"), ((128 / 255 + 0.055) / 1.055) ** 2.4,
                               rtol=1e-3)


def _bad_maps(folder: Path) -> dict[str, tuple[Path, str]]:
    good = write_map(folder / "good.exr", np.ones((16, 32, 3)))
    data = good.read_bytes()
    (folder / "truncated.exr").write_bytes(data[: len(data) // 2])
    (folder / "empty.hdr").write_bytes(b"")
    (folder / "huge.hdr").write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 50000 +X 100000\n" + b"\0" * 64)
    (folder / "notes.png").write_text("not an image")
    (folder / "png_named.hdr").write_bytes((ROOT / "assets" / "demo" / "photo.png").read_bytes())
    return {
        "truncated": (folder / "truncated.exr", "not a readable HDR image"),
        "empty": (folder / "empty.hdr", "not an HDR image"),
        "huge": (folder / "huge.hdr", "100000 x 50000"),
        "not an image": (folder / "notes.png", "not a readable image"),
        "mislabelled": (folder / "png_named.hdr", "not an HDR image"),
        "nan": (write_map(folder / "nan.exr", np.full((16, 32, 3), np.nan)), "NaN"),
        "negative": (write_map(folder / "negative.exr", -np.ones((16, 32, 3))), "negative"),
        "square": (write_map(folder / "square.exr", np.ones((16, 16, 3))), "twice as wide"),
        "format": (folder / "map.tga", ".tga"),
    }


def test_bad_maps_are_refused_in_one_line(tmp_path):
    for name, (path, fragment) in _bad_maps(tmp_path).items():
        with pytest.raises(InputError) as caught:
            read_environment_image(path)
        message = str(caught.value)
        assert fragment in message and "\n" not in message, (name, message)


def test_the_cli_refuses_a_bad_map_with_exit_2_and_writes_nothing(tmp_path):
    shutil.copy(ROOT / "assets" / "demo" / "chair.obj", tmp_path / "chair.obj")
    write_map(tmp_path / "nan.exr", np.full((16, 32, 3), np.nan))
    data = json.loads((ROOT / "assets" / "demo" / "scene.json").read_text())
    data["environment"] = {"image": "nan.exr"}
    (tmp_path / "scene.json").write_text(json.dumps(data))
    result = subprocess.run([sys.executable, "-m", "app.cli", "render", str(tmp_path / "scene.json"), "-o",
                             str(tmp_path / "out.png"), "--renderer", "shaded"], capture_output=True, text=True,
                            cwd=ROOT)
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and "nan.exr" in result.stderr, result.stderr
    assert not (tmp_path / "out.png").exists()


# --- directions, rotation and the sky ---------------------------------------------------------------------


def test_map_directions_follow_mitsubas_envmap():
    """A bright texel of the map is what Mitsuba's envmap emitter shows along our direction of that texel."""
    import drjit as dr
    import mitsuba as mi

    from renderer.pathtrace.mitsuba_variant import active_variant

    active_variant()
    radiance = np.full((16, 32, 3), 0.01, dtype=np.float32)
    radiance[5, 9] = 50.0
    emitter = mi.load_dict({"type": "envmap", "bitmap": mi.Bitmap(radiance)})
    d = map_directions(16, 32)[5, 9]
    probe = np.stack([d, -d])
    if mi.variant().startswith("scalar"):
        values = []
        for v in probe:
            si = mi.SurfaceInteraction3f()
            si.wi = mi.Vector3f(-v)
            values.append(np.array(emitter.eval(si))[0])
    else:
        si = dr.zeros(mi.SurfaceInteraction3f, 2)
        si.wi = mi.Vector3f(np.ascontiguousarray(-probe.T, dtype=np.float32))
        values = np.array(emitter.eval(si))[0]
    assert values[0] > 10.0 > 1.0 > values[1]
    np.testing.assert_allclose(sample_map(radiance, d[None])[0], 50.0, rtol=1e-4)


def test_texel_solid_angles_cover_the_sphere():
    assert math.isclose(float(np.sum(texel_solid_angles(64, 128)) * 128), 4.0 * math.pi, rel_tol=1e-9)


def test_turning_by_a_full_turn_changes_nothing_and_a_quarter_turn_moves_plus_z_to_plus_x():
    d = np.random.default_rng(1).normal(size=(20, 3))
    np.testing.assert_allclose(rotate_y(d, 360.0), d, atol=1e-12)
    np.testing.assert_allclose(rotate_y(np.array([0.0, 0.0, 1.0]), 90.0), [1.0, 0.0, 0.0], atol=1e-12)


def test_the_sun_points_where_its_angles_say():
    np.testing.assert_allclose(sun_direction(SkySpec(90.0, 0.0)), [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(sun_direction(SkySpec(0.0, 90.0)), [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(sun_direction(SkySpec(30.0, 0.0)), [0, 0.5, math.sqrt(3) / 2], atol=1e-12)


def test_the_sky_is_brightest_around_its_sun_and_a_higher_sun_gives_more_light():
    sky = SkySpec(40.0, 60.0, 3.0)
    sky_map, sun = sky_light(sky)
    directions = map_directions(*sky_map.shape[:2])
    upper = directions[..., 1] > 0.05
    brightest = directions[upper][np.argmax(sky_map[upper].sum(axis=1))]
    azimuth = math.degrees(math.atan2(brightest[0], brightest[2]))  # the glow around the sun and the horizon below it
    assert abs(azimuth - sky.sun_azimuth_deg) < 15.0
    low, high = (sky_light(SkySpec(e, 60.0, 3.0))[1].sum() * math.sin(math.radians(e)) for e in (10.0, 60.0))
    assert high > 2.0 * low > 0.0 and np.all(sun > 0.0)


def test_a_scenes_sky_is_the_model_baked_at_its_suns_azimuth():
    """The scene's sky is baked with the sun at azimuth 0 and turned (so that a dragged sun reuses the bake): it
    must show what Mitsuba's model gives baked at the sun's own azimuth, the sun where its angles say."""
    spec = EnvironmentSpec(sky=SkySpec(25.0, 130.0, 4.0), rotation_deg=-20.0)
    light = environment_light(Scene(environment=spec))
    baked, sun = sky_light(spec.sky)
    directions = map_directions(16, 32).reshape(-1, 3)
    directions = directions[directions[:, 1] > 0.05]
    expected = sample_map(baked, rotate_y(directions, 20.0))  # the world direction in the map turned by -20
    np.testing.assert_allclose(light.radiance(directions, sharp=True), expected, rtol=0.05, atol=1e-3)
    np.testing.assert_allclose(light.sun_direction, rotate_y(sun_direction(spec.sky), -20.0), atol=1e-9)
    np.testing.assert_allclose(light.sun_irradiance, sun, rtol=0.01)  # its disc sampled turned


# --- the shader against known answers -----------------------------------------------------------------


@pytest.fixture()
def ball_dir(tmp_path) -> Path:
    from renderer.voxels import save_voxels

    save_voxels(tmp_path / "ball.npz", ball(40, WHITE))
    return tmp_path


def render(scene: Scene, rgba: np.ndarray | None = None, floor=WHITE, reflection=False):
    from renderer.voxels import load_voxels

    rgba = load_voxels(scene.voxels_path()) if rgba is None else rgba
    return shade_scene(scene, rgba, floor, SIZE, reflection=reflection)


def test_white_furnace_a_white_ball_under_a_constant_sky_shows_the_sky(ball_dir):
    """Constant radiance L all around, a white floor: the top of a white diffuse ball receives pi L from the sky
    above and reflects L (the floor below it adds nothing to a point facing up)."""
    level = 0.5
    write_map(ball_dir / "flat.exr", np.full((32, 64, 3), level))
    shaded = render(env_scene(EnvironmentSpec(image="flat.exr"), base_dir=ball_dir))
    top = pixel_of((0.0, 1.0, 0.0))
    linear = ((shaded.image[top[0] + 1, top[1]] + 0.055) / 1.055) ** 2.4
    np.testing.assert_allclose(linear, level, rtol=0.12)
    assert np.all(np.isfinite(shaded.image))


def test_the_ambient_light_as_an_environment_shades_as_the_plain_shader(ball_dir):
    """The environment path given today's uniform ambient light and the area light draws today's image."""
    from renderer.voxels import load_voxels

    rgba = load_voxels(ball_dir / "ball.npz")
    spec = ObjectSpec(voxels="ball.npz")
    factors = shader_pool_factors(rgba.shape[0], spec.scale, SHADER_GRID_SIZE)
    geometry = placed(object_geometry(pool_voxels(rgba, factors), rgba.shape[0], factors), spec, 30.0)
    surface = visible_surface(geometry, SIZE)
    light = (1.0, 2.75, 0.5)
    plain = shade(geometry, surface, light, (0.6, 0.6, 0.6)).image
    as_environment = shade_environment(geometry, surface, light, (0.6, 0.6, 0.6),
                                       uniform_environment(AMBIENT_RADIANCE)).image
    assert np.abs(plain - as_environment).mean() < 1.5 / 255 and np.abs(plain - as_environment).max() < 0.1


@pytest.mark.parametrize("azimuth", [90.0, 270.0])
def test_a_sun_puts_the_cubes_shadow_where_geometry_puts_it(tmp_path, azimuth):
    from renderer.voxels import save_voxels

    save_voxels(tmp_path / "ball.npz", cube())
    scene = env_scene(EnvironmentSpec(sky=SkySpec(45.0, azimuth)), base_dir=tmp_path)
    image = render(scene).image.mean(axis=2)
    away = 1.0 if azimuth == 270.0 else -1.0  # the shadow falls away from the sun, along x
    # The unit cube's top edge at x = -away * 0.5 casts to 1.0 beyond the cube's far side at 45 degrees.
    in_shadow = image[pixel_of((away * 1.0, 0.0, 0.0))]
    lit = image[pixel_of((-away * 1.0, 0.0, 0.0))]
    beyond = image[pixel_of((away * 1.0, 0.0, 0.85))]
    assert in_shadow < 0.75 * lit and in_shadow < 0.75 * beyond


def test_turning_the_environment_a_full_turn_changes_nothing_and_a_half_turn_moves_the_shadow(ball_dir):
    sky = SkySpec(40.0, 90.0)
    images = [render(env_scene(EnvironmentSpec(sky=sky, rotation_deg=r), base_dir=ball_dir)).image
              for r in (0.0, 360.0, 180.0)]
    np.testing.assert_allclose(images[0], images[1], atol=2e-3)
    assert np.abs(images[0] - images[2]).max() > 0.2


def test_a_mirror_ball_shows_the_bright_spot_where_the_reflection_law_puts_it(ball_dir):
    radiance = np.full((64, 128, 3), 0.05, dtype=np.float32)
    directions = map_directions(64, 128)
    toward = np.array([0.6, 0.5, 0.62])
    toward /= np.linalg.norm(toward)
    radiance[directions @ toward > math.cos(math.radians(4.0))] = 60.0
    write_map(ball_dir / "spot.exr", radiance)
    scene = env_scene(EnvironmentSpec(image="spot.exr"), MaterialSpec(0.05, 0.5, 1.0), base_dir=ball_dir)
    shaded = render(scene)
    camera = Camera(30.0, width=SIZE, height=SIZE)
    centre = np.array([0.0, 0.5, 0.0])
    view = camera.position - centre
    normal = view / np.linalg.norm(view) + toward
    normal /= np.linalg.norm(normal)
    expected = np.array(pixel_of(centre + 0.5 * normal))
    brightness = np.where(shaded.coverage > 0.99, shaded.image.sum(axis=2), 0.0)
    found = np.array(np.unravel_index(np.argmax(brightness), brightness.shape))
    assert np.abs(found - expected).max() <= 3, (found, expected)


def test_a_metal_ball_is_tinted_by_its_albedo_and_a_glossy_one_keeps_the_lights_color(tmp_path):
    from renderer.voxels import save_voxels

    save_voxels(tmp_path / "ball.npz", ball(40, (0.9, 0.5, 0.2)))
    sky = EnvironmentSpec(sky=SkySpec(50.0, 20.0))
    metal = render(env_scene(sky, MaterialSpec(0.3, 0.5, 1.0), base_dir=tmp_path))
    plastic = render(env_scene(sky, MaterialSpec(0.1, 0.5, 0.0), base_dir=tmp_path))
    on_ball = metal.coverage > 0.99
    red_to_blue = metal.image[on_ball][:, 0].mean() / metal.image[on_ball][:, 2].mean()
    assert red_to_blue > 1.5
    brightest = plastic.image[plastic.coverage > 0.99].max(axis=0)
    assert brightest.min() > 0.8 * brightest.max()  # the sun's highlight on the plastic is near white


GREY = (0.4, 0.4, 0.4)


def table(n: int = 40) -> np.ndarray:
    """A grey table: a top 4 voxels thick over the whole square, on four 3 x 3 legs at its corners."""
    rgba = np.zeros((n, n, n, 4), dtype=np.float32)
    rgba[:, n - 4:, :] = (*GREY, 1.0)
    for i in (slice(0, 3), slice(n - 3, n)):
        for k in (slice(0, 3), slice(n - 3, n)):
            rgba[i, :, k] = (*GREY, 1.0)
    return rgba


def linear_at(image: np.ndarray, point) -> float:
    """The mean linear value of the 3 x 3 pixels around where world `point` shows."""
    row, col = pixel_of(point)
    srgb = image[row - 1:row + 2, col - 1:col + 2].mean()
    return ((srgb + 0.055) / 1.055) ** 2.4


def test_a_tables_top_shades_the_ground_under_it_from_a_constant_sky(tmp_path):
    """Grey table 0.9 high on a grey floor under a constant sky: the path tracer (256 spp, a mesh of the same
    boxes) shows the ground under the table's centre at 0.77 of the open ground beside it at the same depth. The top
    is 35 voxels and more above it, past the 20 that the floor's straight-up probe reads."""
    from renderer.voxels import save_voxels

    save_voxels(tmp_path / "ball.npz", table())
    write_map(tmp_path / "flat.exr", np.full((32, 64, 3), 0.5))
    image = render(env_scene(EnvironmentSpec(image="flat.exr"), base_dir=tmp_path), floor=GREY).image
    assert 0.7 < linear_at(image, (0.0, 0.0, 0.0)) / linear_at(image, (1.3, 0.0, 0.0)) < 0.92


def test_a_sky_brighter_on_one_side_shades_the_ground_on_the_other_side_of_the_table(tmp_path):
    """A smooth sky (no part bright enough to be a light of its own) twice as bright towards -x. Against the same
    table without its top, the top darkens the ground beside the table on +x (which sees the bright side through it)
    more than its mirror image on -x: the path tracer (as above) to 0.87 and 0.93 of the legs' image."""
    from renderer.voxels import save_voxels

    directions = map_directions(32, 64)
    write_map(tmp_path / "side.exr", np.repeat((0.3 + 0.3 * np.maximum(-directions[..., :1], 0.0)), 3, axis=2))
    legs = table()
    legs[3:-3, 36:] = 0.0
    legs[:, 36:, 3:-3] = 0.0
    legs[:, 36:] = legs[:, :4]  # the legs' full height, so that the object's box (and its placement) stays the same
    shown = {}
    for name, rgba in (("table", table()), ("legs", legs)):
        save_voxels(tmp_path / "ball.npz", rgba)
        image = render(env_scene(EnvironmentSpec(image="side.exr"), base_dir=tmp_path), floor=GREY).image
        shown[name] = np.array([linear_at(image, (0.75, 0.0, 0.2)), linear_at(image, (-0.75, 0.0, 0.2))])
    east, west = shown["table"] / shown["legs"]
    assert east < 0.97 and east < 0.99 * west


def test_small_lights_leave_the_coats_map_and_a_soft_box_stays_in_it():
    """The floor's coat draws a small light (a sun) as a highlight the object's shadow hides, so its excess leaves
    the map the coat mirrors; a wide soft box keeps its shape in that map."""
    from renderer.shading.environment_shading import SMALL_LIGHT_SPREAD, prepare_environment

    h, w = 64, 128
    radiance = np.full((h, w, 3), 0.2)
    radiance[10, 20] = 500.0  # one texel: about 0.05 rad across
    radiance[20:30, 70:90] = 5.0  # about 0.5 x 1 rad
    ready = prepare_environment(radiance)
    assert sorted(ready.light_small.tolist()) == [False, True]
    assert ready.light_spread[ready.light_small][0] <= SMALL_LIGHT_SPREAD < ready.light_spread[~ready.light_small][0]
    assert ready.blurred[10, 20].max() < 5.0  # the sun's excess is gone (what is left: the sky's level, blurred)
    assert ready.blurred[25, 80].min() > 4.0  # the soft box is still there


@pytest.mark.parametrize("case", ["black", "one hot pixel", "sun at the horizon", "sun at the zenith", "strength 0"])
def test_hard_environments_give_finite_images(ball_dir, case):
    black = np.zeros((32, 64, 3))
    hot = black.copy()
    hot[3, 7] = 65000.0
    environments = {
        "black": EnvironmentSpec(image=str(write_map(ball_dir / "black.exr", black))),
        "one hot pixel": EnvironmentSpec(image=str(write_map(ball_dir / "hot.exr", hot))),
        "sun at the horizon": EnvironmentSpec(sky=SkySpec(0.0, 30.0, 10.0)),
        "sun at the zenith": EnvironmentSpec(sky=SkySpec(90.0, 0.0, 1.0)),
        "strength 0": EnvironmentSpec(sky=SkySpec(), strength=0.0),
    }
    for material in (MaterialSpec(), MaterialSpec(0.0, 1.0, 1.0)):
        shaded = render(env_scene(environments[case], material, base_dir=ball_dir), reflection=True)
        for image in (shaded.image, shaded.visibility, shaded.coverage):
            assert np.all(np.isfinite(image))
        assert 0.0 <= shaded.image.min() and shaded.image.max() <= 1.0


def test_the_environment_is_read_once_per_file_and_reread_when_it_changes(ball_dir):
    path = write_map(ball_dir / "map.exr", np.ones((16, 32, 3)))
    scene = env_scene(EnvironmentSpec(image="map.exr"), base_dir=ball_dir)
    first = environment_light(scene)
    assert environment_light(scene).background is first.background
    import os

    write_map(path, np.full((16, 32, 3), 2.0))
    os.utime(path, ns=(first.source_key[2] + 10**9, first.source_key[2] + 10**9))
    assert environment_light(scene).background.max() == pytest.approx(2.0)


# --- made maps and data sets lit by them ---------------------------------------------------------------


@pytest.mark.parametrize("kind", ["studio", "indoor", "outdoor"])
def test_made_maps_are_repeatable_finite_and_light_the_floor_as_said(kind):
    from renderer.environment_maps import IRRADIANCE_RANGE, make_map

    first = make_map(kind, 7)
    np.testing.assert_array_equal(first, make_map(kind, 7))
    assert np.all(np.isfinite(first)) and first.min() >= 0.0 and not np.array_equal(first, make_map(kind, 8))
    # The floor's irradiance by Monte Carlo over the upper hemisphere (cosine-weighted: E = pi * mean L).
    rng = np.random.default_rng(3)
    u, v = rng.random(200_000), rng.random(200_000)
    r, phi = np.sqrt(u), 2.0 * np.pi * v
    directions = np.stack([r * np.cos(phi), np.sqrt(1.0 - u), r * np.sin(phi)], axis=1)
    seen = sample_map(first, directions)
    irradiance = math.pi * float(np.mean(seen @ np.array([0.2126, 0.7152, 0.0722])))
    assert IRRADIANCE_RANGE[0] * 0.9 <= irradiance <= IRRADIANCE_RANGE[1] * 1.1


def test_training_and_test_maps_never_share_a_seed():
    from renderer.dataset import MAPS_PER_SPLIT
    from renderer.environment_maps import map_seed

    train = {map_seed("train", i) for i in range(MAPS_PER_SPLIT["train"])}
    test = {map_seed("test", i) for i in range(MAPS_PER_SPLIT["test"])}
    assert len(train) == MAPS_PER_SPLIT["train"] and len(test) == MAPS_PER_SPLIT["test"] and not train & test


def test_mixed_lighting_draws_the_area_light_an_environment_and_both():
    from renderer.dataset import sample_lighting

    rng = np.random.default_rng(0)
    draws = [sample_lighting(rng, "mixed", "train")[0] for _ in range(90)]
    kinds = {(d.area_light, d.environment is not None) for d in draws}
    assert kinds == {(True, False), (False, True), (True, True)}
    alone = [sample_lighting(rng, "environment", "test")[0] for _ in range(20)]
    assert all(d.environment is not None and not d.area_light for d in alone)
    assert sample_lighting(rng, "area", "train") == (sample_lighting(rng, "area", "test")[0], None)


def test_a_data_set_lit_by_environments_writes_its_maps_and_scenes_that_load(tmp_path):
    from renderer.dataset import DataConfig, generate_dataset

    config = DataConfig(setting="single", split="test", objects=1, views=4, size=32, spp=2, denoise=False,
                        resolution=32, lighting="environment", materials=True, seed=5)
    generate_dataset(tmp_path / "set", config, progress=False)
    manifest = json.loads((tmp_path / "set" / "manifest.json").read_text())
    for sample in manifest["samples"]:
        scene = scene_from_dict(sample["scene"], tmp_path / "set" / "manifest.json")
        assert scene.environment is not None and not scene.light.enabled
        if scene.environment.image is not None:
            assert scene.environment_path().is_file()
            assert environment_light(scene).lighting.shape == (64, 128, 3)
    assert manifest["config"]["lighting"] == "environment" and manifest["config"]["materials"] is True
    from models.training.data import VoxelRenderSet

    with pytest.raises(InputError, match="which this network does not read"):
        VoxelRenderSet([tmp_path / "set"]).check_samples(32)
    environment_set = VoxelRenderSet([tmp_path / "set"], grid_size=16, environment=True)
    environment_set.check_samples(32)  # a network that reads the environment trains on it
    light = environment_set[0]["light"]
    assert light.shape == (3 + 4 + 3 * 32 * 32,) and torch.isfinite(light).all()


def test_info_and_range_warnings_say_what_lights_the_scene_and_that_no_network_is_trained_for_it(tmp_path):
    from renderer.scene import range_warnings

    shutil.copy(ROOT / "assets" / "demo" / "chair.obj", tmp_path / "chair.obj")
    data = json.loads((ROOT / "assets" / "demo" / "scene.json").read_text())
    assert not any("no network" in w for w in range_warnings(scene_from_dict(data, tmp_path / "scene.json")))
    data["environment"] = {"sky": {"sun_elevation_deg": 20}, "strength": 2}
    data["objects"][0]["material"] = {"roughness": 0.2, "specular": 0.5}
    (tmp_path / "scene.json").write_text(json.dumps(data))
    assert not any("trained" in w for w in range_warnings(load_scene(tmp_path / "scene.json")))  # the renderer says
    info = subprocess.run([sys.executable, "-m", "app.cli", "info", str(tmp_path / "scene.json")], capture_output=True,
                          text=True, cwd=ROOT)
    assert info.returncode == 0, info.stderr
    assert "the shipped NVR+ is not trained for environments" in info.stdout
    assert "sun at 20 deg elevation" in info.stdout and "strength 2" in info.stdout
    assert "roughness 0.2, specular 0.5, metallic 0" in info.stdout


def test_the_light_tabs_picture_shows_the_environment_turned_scaled_and_its_sun_where_it_lights_from():
    from renderer.environment import environment_thumbnail

    radiance = np.full((32, 64, 3), 0.2, dtype=np.float32)
    radiance[8, 16] = 50.0  # one bright texel, up and to one side in the map's own frame
    turned = (0.0, 90.0)
    spots = []
    for rotation in turned:
        light = replace(uniform_environment(0.0), background=radiance, rotation_deg=rotation, strength=2.0)
        picture = environment_thumbnail(light, 64)
        assert picture.shape == (32, 64, 3) and 0.0 <= picture.min() and picture.max() <= 1.0
        spots.append(np.unravel_index(np.argmax(picture.sum(axis=2)), picture.shape[:2]))
    # A quarter turn moves the bright texel a quarter of the picture's width, in the map's own row.
    assert spots[0] == (8, 16) and spots[1][0] == 8 and (spots[1][1] - spots[0][1]) % 64 in (15, 16, 17, 47, 48, 49)
    sky = environment_light(Scene(environment=EnvironmentSpec(sky=SkySpec(30.0, 60.0, 3.0))))
    picture = environment_thumbnail(sky, 64)
    dot = np.all(np.isclose(picture, (1.0, 0.85, 0.2)), axis=2)
    assert dot.any()
    row, col = np.unravel_index(np.argmax(dot), picture.shape[:2])
    up = map_directions(32, 64)[row, col]
    assert np.degrees(np.arccos(np.clip(up @ sky.sun_direction, -1, 1))) < 8.0  # the dot where the sun is


@pytest.mark.parametrize("elevation, spread", [(12.0, 0.25), (30.0, 0.1), (60.0, 0.25)])
def test_the_floors_shadow_of_a_wide_low_light_equals_the_shadow_maps_read_everywhere(tmp_path, elevation, spread):
    """The floor reads the shadow maps only inside the box the object's shadow can reach: that box must hold the
    whole soft shadow of a wide light (a window low in the sky), so the floor equals the maps read at every point."""
    from renderer.shading.environment_shading import _ShadowMaps
    from renderer.shading.lighting import FLOOR_SHADOW_BIAS

    rgba = cube(16)
    spec = ObjectSpec(voxels="cube.npz")
    factors = shader_pool_factors(rgba.shape[0], spec.scale, SHADER_GRID_SIZE)
    geometry = placed(object_geometry(pool_voxels(rgba, factors), rgba.shape[0], factors), spec, 30.0)
    surface = visible_surface(geometry, SIZE)
    e = math.radians(elevation)
    direction = np.array([-math.cos(e), math.sin(e), 0.0])  # the shadow falls along +x, across the image
    block = 1.0 / 16
    maps = _ShadowMaps.directional(geometry, direction, spread, block)
    boxed = maps.floor_visibility(surface, block)
    everywhere = np.ones(len(surface.floor_points))
    maps.shadows.visibility(surface.floor_points, FLOOR_SHADOW_BIAS * block, maps.spacing, everywhere)
    assert everywhere.min() < 0.5  # the cube shadows the floor
    # Outside the box the floor sees all the light: no point of the shadow (beyond the unit cube's far side, along
    # +x) may be left there.
    cut_off = (boxed == 1.0) & (everywhere < 0.95) & (surface.floor_points[:, 0] > 0.55)
    assert cut_off.sum() == 0, f"{cut_off.sum()} floor points of the shadow are outside the box"
    # Inside, the box's grid interpolates the maps (FLOOR_SHADOW_STEP apart): equal but for the shadow's sharp edges.
    assert np.abs(boxed - everywhere).mean() < 0.01


def test_an_indoor_maps_empty_floor_is_as_bright_as_the_path_tracers(tmp_path):
    """A room lit through windows near the horizon: most of its light glances off the floor's coat. The shader's
    empty floor (the object far off and tiny) within 5 % of the path tracer's (256 spp); it was 15 % brighter when
    every direction's light reached the base alike."""
    import trimesh

    from renderer.color import srgb_to_linear
    from renderer.environment_maps import make_map
    from renderer.pathtrace.path_tracer import render_pathtraced
    from renderer.scene import FloorSpec
    from renderer.voxels import save_voxels

    floor = (0.95, 0.8, 0.65)
    save_voxels(tmp_path / "ball.npz", ball(40, WHITE))
    write_map(tmp_path / "room.exr", make_map("indoor", 2))
    scene = env_scene(EnvironmentSpec(image="room.exr"), base_dir=tmp_path, elevation=25.0)
    scene = replace(scene, floor=FloorSpec(floor),
                    objects=(replace(scene.objects[0], scale=(1e-3,) * 3, translation=(0.0, -8.0)),))
    traced = render_pathtraced(scene, trimesh.creation.box((1.0, 1.0, 1.0)), SIZE, spp=256, seed=1).image
    shaded = render(scene, floor=floor).image
    near = slice(SIZE * 5 // 8, SIZE)  # rows of floor in front of the camera
    ratio = srgb_to_linear(shaded[near]).mean() / srgb_to_linear(traced[near]).mean()
    assert 0.95 < ratio < 1.05
