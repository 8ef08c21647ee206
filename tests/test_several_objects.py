"""Scenes of several objects: the file format, the voxel shader's and the path tracer's shadows between objects, the
shader's per-object stages, and the renderers and commands that draw them."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from renderer.camera import Camera
from renderer.color import srgb_to_linear
from renderer.errors import InputError
from renderer.limits import MAX_OBJECTS
from renderer.scene import LightSpec, ObjectSpec, PaintOp, Scene, load_scene, save_scene, scene_from_dict
from renderer.shading.staged import ObjectVoxels, StagedShader
from renderer.voxels import save_voxels

N = 32  # voxels per side of the test cube
# The far cube (0.3 wide) and, between it and a low light on its right, a wall 0.9 high and 0.6 deep: geometry puts
# the centre of the far cube's top in the wall's shadow (every ray from it to the light's square meets the wall).
FAR = ObjectSpec(voxels="cube.npz", translation=(-0.3, 0.0), scale=(0.3, 0.3, 0.3), name="far")
WALL = ObjectSpec(voxels="cube.npz", translation=(0.35, 0.0), scale=(0.3, 0.9, 0.6), name="wall")
LOW_LIGHT = LightSpec((1.5, 1.2, 0.0))
SIZE = 64


@pytest.fixture
def cube_folder(tmp_path: Path) -> Path:
    rgba = np.zeros((N, N, N, 4), np.float32)
    rgba[...] = (0.8, 0.8, 0.8, 1.0)
    save_voxels(tmp_path / "cube.npz", rgba)
    return tmp_path


def _scene(folder: Path, *objects: ObjectSpec) -> Scene:
    return Scene(objects=objects, light=LOW_LIGHT, image_size=SIZE, base_dir=folder)


def _top_centre_pixel(scene: Scene) -> tuple[int, int]:
    """The pixel showing the centre of the far cube's top."""
    u, v, _ = Camera.from_scene(scene, SIZE).project(np.array([[FAR.translation[0], 0.3 * 0.999, FAR.translation[1]]]))
    return int(v[0]), int(u[0])


def _shaded(scene: Scene, shader: StagedShader | None = None) -> np.ndarray:
    from renderer.pipeline import painted_objects

    shader = shader or StagedShader()
    objects = [ObjectVoxels(o, ("voxels", o), rgba, ("shape", o.voxels)) for o, rgba in zip(scene.objects,
                                                                                           painted_objects(scene))]
    shader.cache.begin()
    return shader.run_objects(scene, objects, scene.floor.color, SIZE).image


# --- the file ---------------------------------------------------------------------------------------


def test_a_version_1_file_reads_as_one_object_and_saves_as_version_2(cube_folder):
    v1 = {"version": 1, "object": {"voxels": "cube.npz", "rotation_deg": 10.0},
          "paint": [{"target": "object", "color": [1, 0, 0]}, {"target": "floor", "color": [0.2, 0.3, 0.4]}]}
    scene = scene_from_dict(v1, cube_folder / "old.json")
    assert len(scene.objects) == 1 and scene.object.paint == (PaintOp("object", (1.0, 0.0, 0.0)),)
    assert scene.floor.color == (0.2, 0.3, 0.4)  # the floor's fill is its color
    save_scene(scene, cube_folder / "new.json")
    written = json.loads((cube_folder / "new.json").read_text())
    assert written["version"] == 2 and "object" not in written and "paint" not in written
    assert written["objects"][0]["paint"] == [{"target": "object", "color": [1.0, 0.0, 0.0]}]
    assert load_scene(cube_folder / "new.json") == scene


def test_several_objects_round_trip_with_their_names_and_paint(cube_folder):
    scene = _scene(cube_folder, replace(FAR, paint=(PaintOp("region", (0, 1, 0), (1, 1, 1)),)), WALL)
    save_scene(scene, cube_folder / "two.json")
    assert load_scene(cube_folder / "two.json") == scene


def _v2(**changes) -> dict:
    data = {"version": 2, "objects": [{"name": "a", "voxels": "cube.npz"}, {"name": "b", "voxels": "cube.npz"}]}
    data.update(changes)
    return data


@pytest.mark.parametrize(("data", "fragments"), [
    (_v2(objects=[{"voxels": "cube.npz"}] * (MAX_OBJECTS + 1)), ("objects", f"17 objects; a scene holds 1 to {MAX_OBJECTS}")),
    (_v2(objects=[]), ("objects", "0 objects")),
    (_v2(objects={"voxels": "cube.npz"}), ("objects", "must be a list")),
    (_v2(objects=[{"name": "a", "voxels": "cube.npz"}, {"name": "a", "voxels": "cube.npz"}]),
     ("objects[1].name", "'a' is the name of objects[0] too")),
    (_v2(objects=[{"voxels": "cube.npz"}, {"voxels": "cube.npz", "scael": [1, 1, 1]}]),
     ('objects[1].scael', 'did you mean "scale"')),
    (_v2(objects=[{"voxels": "cube.npz", "paint": [{"target": "floor", "color": [0, 0, 0]}]}]),
     ("objects[0].paint", "floor.color")),
    (_v2(objects=[{"voxels": "cube.npz"}, {"voxels": "cube.npz", "scale": [1, -1, 1]}]),
     ("objects[1].scale", "positive")),
    (_v2(object={"voxels": "cube.npz"}), ('object', 'did you mean "objects"')),
    ({"version": 1, "objects": [{"voxels": "cube.npz"}]}, ('objects', 'did you mean "object"')),
])
def test_a_bad_object_list_is_refused_in_one_line_naming_the_field(data, fragments):
    with pytest.raises(InputError) as err:
        scene_from_dict(data, "s.json")
    message = str(err.value)
    assert message.startswith("s.json: ") and "\n" not in message
    for fragment in fragments:
        assert fragment in message


def test_the_only_object_is_refused_for_a_scene_of_several(cube_folder):
    with pytest.raises(InputError, match="holds 2"):
        _ = _scene(cube_folder, FAR, WALL).object


# --- shadows between objects ------------------------------------------------------------------------------------


def _linear_at(image: np.ndarray, pixel: tuple[int, int]) -> float:
    """Mean linear radiance over the 3 x 3 pixels around `pixel` (a few samples' noise averaged)."""
    row, col = pixel
    return float(srgb_to_linear(image[row - 1:row + 2, col - 1:col + 2].astype(np.float64)).mean())


def _render_all(render, folder: Path) -> dict[str, float]:
    alone = _scene(folder, FAR)
    pixel = _top_centre_pixel(alone)
    scenes = {"alone": alone, "wall": _scene(folder, FAR, WALL),
              "moved": _scene(folder, FAR, replace(WALL, translation=(0.35, -1.5)))}
    return {name: _linear_at(render(scene), pixel) for name, scene in scenes.items()}


def test_the_wall_shadows_the_far_cube_as_geometry_says_in_the_shader_and_the_path_tracer(cube_folder):
    """Geometry: every ray from the top's centre to the light's square passes through the wall, so the top keeps the
    sky's and the floor's light alone (the path tracer: 43 % of its light). Both renderers agree within 15 %; moving
    the wall out of the light's way gives the light back."""
    from models.renderers import RendererOptions, make_renderer

    tracer = make_renderer("pathtrace", RendererOptions(spp=64, denoise=True))
    path = _render_all(tracer.render, cube_folder)
    shader = _render_all(_shaded, cube_folder)
    for got in (path, shader):
        assert got["wall"] < 0.55 * got["alone"]
        assert got["moved"] == pytest.approx(got["alone"], rel=0.05)
    assert shader["wall"] == pytest.approx(path["wall"], rel=0.15)
    assert shader["alone"] == pytest.approx(path["alone"], rel=0.15)


def test_the_mask_of_the_others_shadows_holds_the_far_cubes_top_as_geometry_says(cube_folder):
    """What `nvr eval` scores apart: the far cube's top lies in the wall's shadow, nothing of the wall lies in the
    cube's (the light is beyond the wall), and with the wall moved away or alone nothing does."""
    from renderer.pipeline import painted_objects
    from renderer.shading import shadows_of_others

    scene = _scene(cube_folder, FAR, WALL)
    mask = shadows_of_others(scene, painted_objects(scene), SIZE)
    row, col = _top_centre_pixel(scene)
    assert mask[row, col]
    wall_alone = _scene(cube_folder, WALL)
    wall_pixels = StagedShader().run_objects(wall_alone, [ObjectVoxels(WALL, "w", painted_objects(wall_alone)[0], "w")],
                                              wall_alone.floor.color, SIZE).coverage > 0.5
    assert not (mask & wall_pixels).any()
    moved = _scene(cube_folder, FAR, replace(WALL, translation=(0.35, -1.5)))
    assert not shadows_of_others(moved, painted_objects(moved), SIZE).any()
    alone = _scene(cube_folder, FAR)
    assert not shadows_of_others(alone, painted_objects(alone), SIZE).any()


def test_kept_shaders_draw_the_next_view_as_fresh_ones_without_building_the_geometry_again(cube_folder):
    """`nvr eval` keeps its shaders from view to view (SceneShaders): a turned view of the same objects gives the
    mask and the image a fresh shader gives, to the bit, and builds no object's geometry again."""
    from renderer.pipeline import painted_objects
    from renderer.shading import shade_objects, shadows_of_others
    from renderer.shading.staged import SceneShaders

    first = _scene(cube_folder, FAR, WALL)
    turned = first.with_changes(objects=tuple(replace(o, rotation_deg=20.0) for o in first.objects))
    painted = painted_objects(first)
    kept, keys = SceneShaders(), ["far", "wall"]
    shadows_of_others(first, painted, SIZE, shaders=kept, keys=keys)
    kept.shade(first, painted, keys, SIZE)
    caches = kept.caches
    assert len(caches) == 4  # together, with and without the reflection, and each object alone
    for cache in caches:
        cache.begin()
    mask = shadows_of_others(turned, painted, SIZE, shaders=kept, keys=keys)
    image = kept.shade(turned, painted, keys, SIZE).image
    np.testing.assert_array_equal(mask, shadows_of_others(turned, painted, SIZE))
    np.testing.assert_array_equal(image, shade_objects(turned, painted, turned.floor.color, SIZE).image)
    ran = {name for cache in caches for name in cache.stage_ms}
    assert any(name.startswith("placement") for name in ran)
    assert not any(name.startswith(("geometry", "pool")) for name in ran)


def test_an_object_hides_what_stands_behind_it(cube_folder):
    """From the camera (+z), a wall in front of the far cube hides its top: the pixel shows the wall's face."""
    front = replace(WALL, translation=(-0.3, 0.6), scale=(0.6, 0.9, 0.2))
    scene = _scene(cube_folder, FAR, front)
    pixel = _top_centre_pixel(scene)
    image = StagedShader()
    shaded = _shaded(scene, image)
    alone = _shaded(_scene(cube_folder, front))
    np.testing.assert_allclose(shaded[pixel], alone[pixel], atol=0.03)


# --- per-object stages ------------------------------------------------------------------------------------------


def test_moving_one_object_reruns_its_own_stages_and_equals_a_fresh_render(cube_folder):
    scene = _scene(cube_folder, FAR, WALL)
    shader = StagedShader()
    _shaded(scene, shader)
    moved = _scene(cube_folder, FAR, replace(WALL, translation=(0.5, 0.2)))
    image = _shaded(moved, shader)
    ran = set(shader.stage_ms)
    assert {"placement[1]", "surface[1]", "join", "lighting"} <= ran
    assert not any(name.endswith("[0]") for name in ran)  # the far cube's stages were kept
    np.testing.assert_array_equal(image, _shaded(moved))


def test_painting_one_object_recolors_it_alone(cube_folder):
    scene = _scene(cube_folder, FAR, WALL)
    shader = StagedShader()
    _shaded(scene, shader)
    painted = _scene(cube_folder, replace(FAR, paint=(PaintOp("object", (0.9, 0.1, 0.1)),)), WALL)
    image = _shaded(painted, shader)
    assert "colors[0]" in shader.stage_ms and not any(name.endswith("[1]") for name in shader.stage_ms)
    assert "geometry[0]" not in shader.stage_ms  # paint keeps the shape
    np.testing.assert_array_equal(image, _shaded(painted))


def test_a_one_object_scene_renders_the_same_through_both_paths(cube_folder, tmp_path):
    """A version 1 file and its version 2 form render the same image, bit for bit."""
    v1 = {"version": 1, "object": {"voxels": "cube.npz", "scale": [0.5, 0.5, 0.5]},
          "light": {"position": [1.0, 2.75, 0.5]}, "image_size": SIZE,
          "paint": [{"target": "floor", "color": [0.3, 0.5, 0.2]}]}
    old = scene_from_dict(v1, cube_folder / "old.json")
    save_scene(old, cube_folder / "new.json")
    new = load_scene(cube_folder / "new.json")
    np.testing.assert_array_equal(_shaded(old), _shaded(new))


# --- renderers and commands -------------------------------------------------------------------------------------


def _network_image(model, scene: Scene) -> np.ndarray:
    """NVR+'s image of a scene from its inputs as training makes them (models/training/data.py), the plain model."""
    import torch

    from models.training.data import network_inputs, shading_tensor
    from renderer.pipeline import painted_objects
    from renderer.shading import quality_named, shade_objects
    from renderer.splat import splat_objects

    painted = painted_objects(scene)
    size = model.config.output_size
    voxels, light = network_inputs(scene, painted, scene.floor.color, model.config.grid_size)
    splat = torch.from_numpy(np.ascontiguousarray(splat_objects(scene, painted, scene.floor.color, size).transpose(2, 0, 1)))
    shaded = shade_objects(scene, painted, scene.floor.color, size, model.config.shading_grid_size, reflection=False,
                           quality=quality_named("full"))
    with torch.no_grad():
        image = model(voxels[None], light[None], splat=splat[None], shading=shading_tensor(shaded)[None])
    return image.clamp(0.0, 1.0)[0].permute(1, 2, 0).numpy()


def test_nvr_plus_renders_several_objects_as_from_its_training_inputs_and_follows_each_edit(cube_folder):
    """The engine's image of two objects is the network's on the inputs training makes (grid, splat, shader buffers of
    both); moving one object reruns its own stages alone and equals a fresh engine's image; back to one object the
    others' stages are let go."""
    from models.networks.checkpoint import load_model
    from models.networks.shipped import shipped_weights
    from models.renderers import RendererOptions, make_renderer

    exact = RendererOptions(precision="fp32")  # bf16 (auto on CPUs that have it) rounds a cached and a fresh image apart
    engine = make_renderer("nvr+", exact)
    model = load_model(shipped_weights("nvr_plus"))[0].eval()
    scene = _scene(cube_folder, FAR, WALL)
    image = engine.render(scene)
    assert engine.last_report.note == ""
    assert np.abs(image - _network_image(model, scene)).max() < 1.0 / 255.0
    moved = _scene(cube_folder, FAR, replace(WALL, translation=(0.5, 0.2)))
    image = engine.render(moved)
    ran = engine.last_report.stages_run
    assert "object_grid[1]" in ran and "splat_layout[1]" in ran
    assert not any(name.endswith("[0]") for name in ran)  # the first object's own stages are kept
    assert np.abs(image - make_renderer("nvr+", exact).render(moved)).max() < 1e-5
    assert np.abs(image - _network_image(model, moved)).max() < 1.0 / 255.0
    larger = engine.render_sized(moved, 384)  # the editor's panel: the correction applied to the shader's image
    assert larger.shape == (384, 384, 3) and np.isfinite(larger).all() and "light" not in engine.last_report.stages_run
    assert np.abs(larger[::3, ::3].mean((0, 1)) - image[::2, ::2].mean((0, 1))).max() < 0.02
    engine.render(_scene(cube_folder, FAR))  # down to one object: the others' voxels let go
    assert engine.last_report.note == "" and engine._cache.last("paint[1]") is None
    assert engine._cache.last("object_grid[1]") is None and engine._cache.last("shade_surface[1]") is None


def test_nvr_plus_follows_an_object_out_of_the_grid_and_into_another(cube_folder):
    """Hard cases of the joined grid: an object moved out of the grid (no cell), then onto the other (overlapping:
    the later object's voxels win), then back; each image equals a fresh engine's and is finite."""
    from models.renderers import make_renderer

    engine = make_renderer("nvr+")
    engine.render(_scene(cube_folder, FAR, WALL))
    for place in ((9.0, 9.0), FAR.translation, (0.35, 0.0)):
        scene = _scene(cube_folder, FAR, replace(WALL, translation=place))
        image = engine.render(scene)
        assert np.isfinite(image).all()
        assert np.abs(image - make_renderer("nvr+").render(scene)).max() < 1e-5


def test_the_cli_renders_several_objects(cube_folder):
    from tests.test_cli import nvr as run_cli

    save_scene(_scene(cube_folder, FAR, WALL), cube_folder / "two.json")
    for renderer in ("shaded", "splat"):
        done = run_cli("render", str(cube_folder / "two.json"), "-o", str(cube_folder / f"{renderer}.png"),
                       "--renderer", renderer)
        assert done.returncode == 0 and (cube_folder / f"{renderer}.png").is_file(), done.stderr
    info = run_cli("info", str(cube_folder / "two.json"))
    assert info.returncode == 0 and "object 1 (wall)" in info.stdout
    assert "the shipped NVR+ corrects the voxel shader's image" in info.stdout  # it trained on several objects


def test_the_splat_shows_the_nearest_objects_voxel(cube_folder):
    """A wall in front of the far cube (from the camera, +z) hides its top in the splat; alone, each object splats
    as splat_scene splats it."""
    from renderer.pipeline import painted_objects
    from renderer.splat import splat_objects, splat_scene

    front = replace(WALL, translation=(-0.3, 0.6), scale=(0.6, 0.9, 0.2), color=(0.1, 0.2, 0.9))
    scene = _scene(cube_folder, FAR, front)
    painted = painted_objects(scene)
    both = splat_objects(scene, painted, scene.floor.color)
    row, col = _top_centre_pixel(scene)
    np.testing.assert_allclose(both[row, col], (0.1, 0.2, 0.9), atol=1e-6)  # the wall's color, not the cube's grey
    for k in range(2):
        one = replace(scene, objects=(scene.objects[k],))
        np.testing.assert_array_equal(splat_objects(one, [painted[k]], scene.floor.color),
                                      splat_scene(one, painted[k], scene.floor.color))
