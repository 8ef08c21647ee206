"""The Mitsuba reference renderer against geometry and light transport computed by hand.

Tiny images and few samples keep this file fast; each test renders at most a few 64^2 images.
"""

import colorsys
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image
from scipy.spatial import ConvexHull

from renderer.camera import Camera
from renderer.color import srgb_to_linear
from renderer.errors import InputError
from renderer.pathtrace.mitsuba_object import condition_faces
from renderer.pathtrace.mitsuba_variant import LLVM_VARIANT, SCALAR_VARIANT, choose_variant, libllvm_version
from renderer.pathtrace.path_tracer import LIGHT_RADIANCE, PathTracer, render_pathtraced, sample_passes
from renderer.scene import AMBIENT_RADIANCE, CameraSpec, FloorSpec, LightSpec, ObjectSpec, Scene
from renderer.transform import apply_transform, object_to_world

REPO = Path(__file__).resolve().parents[1]


def make_scene(light=(0.0, 2.75, 0.0), floor=(0.6, 0.6, 0.6), elevation=30.0, **obj) -> Scene:
    return Scene.single(object=ObjectSpec(mesh="test.obj", **obj), floor=FloorSpec(floor), light=LightSpec(light),
                 camera=CameraSpec(elevation))


def column(width=0.3, height=0.8) -> trimesh.Trimesh:
    box = trimesh.creation.box([width, height, width])
    box.apply_translation([0.0, 0.5 * height, 0.0])
    return box


def marker(center, radius=0.07) -> trimesh.Trimesh:
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=radius)
    sphere.apply_translation(center)
    return sphere


def pixel_at(image: np.ndarray, camera: Camera, point) -> np.ndarray:
    u, v, _ = camera.project(np.asarray(point, dtype=float))
    return image[int(v), int(u)]


# --- the camera: Mitsuba must see exactly what renderer.camera predicts ----------------------


@pytest.mark.parametrize(
    "elevation, spec, object_point, world_point",
    [
        # identity placement: object coordinates are world coordinates
        (10.0, {}, (0.45, 0.7, 0.25), (0.45, 0.7, 0.25)),
        # rotate 90 degrees about y: (x, y, z) -> (z, y, -x), then translate by (0.3, 0, -0.2)
        (45.0, {"rotation_deg": 90.0, "translation": (0.3, -0.2)}, (0.2, 0.5, -0.1), (0.2, 0.5, -0.4)),
    ],
)
def test_marker_appears_at_the_pixel_the_camera_model_predicts(elevation, spec, object_point, world_point):
    # A pure red sphere (green and blue albedo 0) on a grey floor: its pixels are the red ones.
    scene = make_scene(elevation=elevation, color=(1.0, 0.0, 0.0), **spec)
    image = render_pathtraced(scene, marker(object_point), size=128, spp=16).image
    redness = image[..., 0] / np.maximum(image.sum(axis=2), 1e-6)
    rows, cols = np.nonzero(redness > 0.6)
    u_expected, v_expected, _ = Camera.from_scene(scene, 128).project(np.array(world_point))
    assert len(rows) > 20  # radius 0.07 at ~2.8 units is about 4 px: ~50 px of area
    assert abs(cols.mean() + 0.5 - u_expected) < 0.4  # tight enough to catch a half-pixel convention slip
    assert abs(rows.mean() + 0.5 - v_expected) < 0.4


# --- light transport ---------------------------------------------------------------------------


def shadow_centroid_u(light_x: float) -> tuple[float, float]:
    """Image column of the floor's shadow centroid, and the column of the object's foot."""
    scene = make_scene(light=(light_x, 2.75, 0.0), floor=(0.8, 0.8, 0.8), elevation=40.0, color=(0.1, 0.2, 0.9))
    image = render_pathtraced(scene, column(), size=64, spp=16).image
    blueness = image[..., 2] / np.maximum(image.sum(axis=2), 1e-6)
    luminance = image.mean(axis=2)
    floor = blueness < 0.4
    shadow = floor & (luminance < 0.75 * np.median(luminance[floor]))
    _, cols = np.nonzero(shadow)
    foot_u, _, _ = Camera.from_scene(scene, 64).project(np.zeros(3))
    return cols.mean() + 0.5, foot_u


def test_moving_the_light_moves_the_shadow_the_other_way():
    # A column lit from x = +1.2 casts its shadow towards -x (left in the image), and vice versa.
    right_lit, foot = shadow_centroid_u(1.2)
    left_lit, _ = shadow_centroid_u(-1.2)
    assert right_lit < foot - 2.0
    assert left_lit > foot + 2.0


def box_mask(scene: Scene, box: trimesh.Trimesh, size: int) -> np.ndarray:
    """Pixels at least 1 px inside the box's silhouette: the convex hull of its 8 projected corners."""
    corners = apply_transform(object_to_world(scene.object), trimesh.bounds.corners(box.bounds))
    u, v, _ = Camera.from_scene(scene, size).project(corners)
    hull = ConvexHull(np.stack([u, v], axis=1))
    jj, ii = np.meshgrid(np.arange(size) + 0.5, np.arange(size) + 0.5)
    centres = np.stack([jj.ravel(), ii.ravel()], axis=1)
    inside = np.all(centres @ hull.equations[:, :2].T + hull.equations[:, 2] < -1.0, axis=1)
    return inside.reshape(size, size)


def colored_box(kind: str, rgb255) -> trimesh.Trimesh:
    box = column(0.6, 0.6)
    if kind == "vertex":
        box.visual.vertex_colors = [*rgb255, 255]
    elif kind == "face":
        box.visual.face_colors = [*rgb255, 255]
    return box


@pytest.mark.parametrize("kind", ["scene", "vertex", "face"])
def test_a_uniform_color_object_renders_with_that_hue(kind):
    # White lights and a grey floor scale and whiten the object's linear color, neither changes its hue.
    rgb255 = (217, 115, 38)
    srgb = tuple(c / 255 for c in rgb255)
    scene = make_scene(color=srgb if kind == "scene" else None, rotation_deg=30.0)
    mesh = colored_box(kind, rgb255)
    image = render_pathtraced(scene, mesh, size=64, spp=16).image
    mask = box_mask(scene, mesh, 64)
    assert mask.sum() > 50
    mean_linear = srgb_to_linear(image[mask]).mean(axis=0)
    hue = colorsys.rgb_to_hsv(*mean_linear)[0]
    expected = colorsys.rgb_to_hsv(*srgb_to_linear(srgb))[0]
    assert abs(hue - expected) < 0.02


def test_face_colors_stay_on_their_faces():
    # Averaged into shared corner vertices, each face would blend with its neighbours' colors.
    box = column(0.6, 0.6)
    normals = box.face_normals
    colors = np.tile([30, 30, 200, 255], (len(box.faces), 1))  # blue sides and bottom
    colors[normals[:, 2] > 0.9] = (200, 30, 30, 255)  # front (+z) red
    colors[normals[:, 1] > 0.9] = (30, 200, 30, 255)  # top green
    box.visual.face_colors = colors
    # Turned -30 degrees about y, (x, y, z) -> (x c - z s, y, x s + z c) with c = cos 30, s = sin 30.
    scene = make_scene(light=(0.0, 2.75, 1.5), elevation=30.0, rotation_deg=-30.0)
    image = render_pathtraced(scene, box, size=64, spp=16).image
    camera = Camera.from_scene(scene, 64)
    c, s = np.cos(np.radians(30.0)), 0.5
    assert np.argmax(pixel_at(image, camera, (-0.3 * s, 0.3, 0.3 * c))) == 0  # front face centre
    assert np.argmax(pixel_at(image, camera, (0.0, 0.6, 0.0))) == 1  # top face centre
    assert np.argmax(pixel_at(image, camera, (0.3 * c, 0.3, 0.3 * s))) == 2  # right face centre, now in view


def test_uv_texture_keeps_its_orientation():
    # A quad facing the camera with uv (0, 0) at its bottom left; its texture's top row is the image's row 0.
    quad = trimesh.Trimesh(
        vertices=[[-0.4, 0.1, 0.0], [0.4, 0.1, 0.0], [0.4, 0.9, 0.0], [-0.4, 0.9, 0.0]], faces=[[0, 1, 2], [0, 2, 3]],
        process=False,
    )
    texture = np.zeros((8, 8, 3), dtype=np.uint8)
    texture[:4, :4] = (255, 0, 0)  # top left red
    texture[:4, 4:] = (0, 255, 0)  # top right green
    texture[4:] = (0, 0, 255)  # bottom blue
    quad.visual = trimesh.visual.TextureVisuals(uv=[[0, 0], [1, 0], [1, 1], [0, 1]], image=Image.fromarray(texture))
    scene = make_scene(light=(0.0, 2.75, 1.5), elevation=0.0)
    image = render_pathtraced(scene, quad, size=64, spp=8).image
    camera = Camera.from_scene(scene, 64)
    assert np.argmax(pixel_at(image, camera, (-0.2, 0.7, 0.0))) == 0
    assert np.argmax(pixel_at(image, camera, (0.2, 0.7, 0.0))) == 1
    assert np.argmax(pixel_at(image, camera, (0.0, 0.3, 0.0))) == 2


def sliver_comb(count=100, height=1e-4) -> trimesh.Trimesh:
    """Flat slivers facing the camera, 0.9 wide and `height` tall at their apex, corners red, green and blue."""
    vertices, faces, colors = [], [], []
    for k in range(count):
        y = 0.1 + 0.8 * k / count
        vertices += [[-0.45, y, 0.0], [0.45, y, 0.0], [0.0, y + height, 0.0]]
        faces.append([3 * k, 3 * k + 1, 3 * k + 2])
        colors += [[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255]]
    return trimesh.Trimesh(vertices, faces, vertex_colors=colors, process=False)


def test_vertex_colors_on_slivers_stay_within_their_corner_colors():
    # Mitsuba's float32 barycentrics on these slivers gave albedos below 0 before they got flat colors.
    tracer = PathTracer(make_scene(light=(0.0, 2.75, 1.5), elevation=0.0), sliver_comb(), size=64)
    albedo = tracer.render_layers(4, seed=0).albedo
    assert np.all(np.isfinite(albedo)) and albedo.min() >= 0.0 and albedo.max() <= 1.0


def test_faces_start_at_their_best_corner_and_slivers_are_set_apart():
    vertices = np.array([
        [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0],  # right angle at corner 0
        [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1e-3, 0.0],  # needle: the angle at corner 1 is 90 degrees
        [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 1e-6, 0.0],  # sliver: angles 0, 0 and 180 degrees
        [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0],  # no area at all
    ])
    faces = np.arange(12).reshape(4, 3)
    good, slivers = condition_faces(vertices, faces)
    assert good.tolist() == [[0, 1, 2], [4, 5, 3]]  # cyclic rotation keeps the winding
    assert len(slivers) == 1 and sorted(slivers[0]) == [6, 7, 8]


def test_white_floor_below_the_light_is_bright_but_not_clipped():
    # Irradiance below a unit square at height h, per unit radiance: the integral of h^2 / r^4 over the
    # square (midpoint rule); the light also hides that much of the ambient sky. An ideal white
    # Lambertian floor reflects E / pi; the glossy coat keeps a few percent of it for itself.
    h, n = 2.75, 400
    x = (np.arange(n) + 0.5) / n - 0.5
    form = np.mean(h**2 / (x[:, None] ** 2 + x[None, :] ** 2 + h**2) ** 2)
    ideal = (LIGHT_RADIANCE * form + AMBIENT_RADIANCE * (np.pi - form)) / np.pi
    scene = make_scene(floor=(1.0, 1.0, 1.0), translation=(0.0, -8.0), scale=(0.01, 0.01, 0.01))
    image = render_pathtraced(scene, column(), size=32, spp=64).image
    value = pixel_at(image, Camera.from_scene(scene, 32), (0.0, 0.0, 0.0))
    assert np.all((0.85 * ideal < srgb_to_linear(value)) & (srgb_to_linear(value) < ideal))
    assert np.all((0.75 < value) & (value < 0.95))  # sRGB: well exposed, with headroom below clipping


def test_the_floor_reflects_the_object():
    # A red object over a black floor: only the floor's coat shows, and its mirror image of the object is red.
    scene = make_scene(light=(0.0, 2.75, 1.5), floor=(0.0, 0.0, 0.0), elevation=10.0, color=(1.0, 0.0, 0.0))
    image = srgb_to_linear(render_pathtraced(scene, column(0.6, 0.8), size=64, spp=16).image)
    camera = Camera.from_scene(scene, 64)
    mirrored = pixel_at(image, camera, (0.0, -0.2, 0.3))  # mirror image of the front face point (0, 0.2, 0.3)
    beside = pixel_at(image, camera, (0.8, -0.2, 0.3))  # mirror image of the sky
    assert mirrored[0] > 2.0 * mirrored[1]
    assert beside[0] < 1.2 * beside[1]


def test_a_red_object_bleeds_red_onto_a_white_floor():
    scene = make_scene(floor=(1.0, 1.0, 1.0), elevation=40.0, color=(1.0, 0.0, 0.0))
    image = srgb_to_linear(render_pathtraced(scene, column(0.6, 0.8), size=64, spp=64).image)
    camera = Camera.from_scene(scene, 64)
    near = pixel_at(image, camera, (-0.4, 0.0, 0.1))  # beside the left face, out of its mirror image
    far = pixel_at(image, camera, (-1.4, 0.0, 0.1))
    assert near[0] / near[1] > 1.1 * far[0] / far[1]


# --- sampling, denoising, robustness -----------------------------------------------------------


def test_a_seed_fixes_the_image_and_different_seeds_differ():
    tracer = PathTracer(make_scene(light=(1.0, 2.75, 0.5)), column(), size=32)
    first = tracer.render(spp=4, seed=3).image
    assert np.array_equal(first, tracer.render(spp=4, seed=3).image)
    assert np.abs(first - tracer.render(spp=4, seed=4).image).mean() > 1e-3


def test_denoised_one_sample_is_closer_to_the_converged_image_than_the_raw_one():
    tracer = PathTracer(make_scene(light=(1.0, 2.75, 0.5), color=(0.8, 0.3, 0.2)), column(0.5, 0.7), size=64)
    reference = tracer.render(spp=256, seed=1).image
    raw = tracer.render(spp=1, seed=2).image
    denoised = tracer.render(spp=1, seed=2, denoise=True).image
    assert np.all(np.isfinite(denoised)) and denoised.min() >= 0.0 and denoised.max() <= 1.0
    assert np.mean((denoised - reference) ** 2) < 0.5 * np.mean((raw - reference) ** 2)


LIGHTS_AT_CORNERS = [(x, y, z) for x in (-1.5, 1.5) for y in (2.5, 3.0) for z in (-1.5, 1.5)]


@pytest.mark.parametrize(
    "light, elevation",
    [(light, 30.0) for light in LIGHTS_AT_CORNERS]
    + [((1.0, 2.75, 0.5), 0.0), ((1.0, 2.75, 0.5), 89.0), ((0.0, 0.05, 0.0), 30.0), ((5.0, 0.01, 5.0), 30.0)],
)
def test_no_nan_or_inf_anywhere_in_the_light_box_and_at_extreme_elevations(light, elevation):
    result = render_pathtraced(make_scene(light=light, elevation=elevation), column(), size=32, spp=4, denoise=True)
    assert result.image.shape == (32, 32, 3) and result.image.dtype == np.float32
    assert np.all(np.isfinite(result.image)) and result.image.min() >= 0.0 and result.image.max() <= 1.0


def test_bad_input_is_a_one_line_input_error():
    empty = trimesh.Trimesh(vertices=np.zeros((0, 3)), faces=np.zeros((0, 3), dtype=int))
    with pytest.raises(InputError, match="no faces"):
        render_pathtraced(make_scene(), empty, size=16, spp=1)
    with pytest.raises(InputError, match="image size"):
        PathTracer(make_scene(), column(), size=8)
    tracer = PathTracer(make_scene(), column(), size=16)
    with pytest.raises(InputError, match="at least 1"):
        tracer.render(spp=0)
    with pytest.raises(InputError, match="non-negative"):
        tracer.render(spp=1, seed=-1)


def test_sample_passes_split_evenly_and_sum_to_spp():
    assert sample_passes(1024, 256 * 256, max_samples=1 << 22) == [64] * 16
    assert sample_passes(5, 10, max_samples=20) == [2, 2, 1]
    assert sample_passes(3, 10_000, max_samples=100) == [1, 1, 1]  # one sample per pass at least


# --- variant choice ------------------------------------------------------------------------------


def test_libllvm_versions_are_read_from_names_and_folders():
    assert libllvm_version("/usr/lib/x86_64-linux-gnu/libLLVM-19.so") == 19
    assert libllvm_version("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1") == 19
    assert libllvm_version("/usr/lib/llvm-14/lib/libLLVM-14.0.6.so.1") == 14
    assert libllvm_version("/usr/lib/llvm-17/lib/libLLVM.so") == 17
    assert libllvm_version("/opt/lib/libLLVM.so") is None


def test_variant_choice_needs_llvm_16_or_newer():
    assert choose_variant([]) == (SCALAR_VARIANT, None)
    assert choose_variant(["/fake/libLLVM-14.so", "/fake/libLLVM-15.so.1"]) == (SCALAR_VARIANT, None)
    assert choose_variant(["/fake/libLLVM.so"]) == (SCALAR_VARIANT, None)  # unknown version: not trusted
    assert choose_variant(["/fake/libLLVM-15.so", "/fake/libLLVM.so.19.1", "/fake/libLLVM-16.so"]) == (
        LLVM_VARIANT,
        "/fake/libLLVM.so.19.1",
    )


def test_scalar_fallback_renders_the_same_scene_when_llvm_does_not_load():
    # A libLLVM that claims version 19 but does not exist: LLVM is chosen, fails to load, scalar takes over.
    program = (
        "import json, numpy as np\n"
        "from tests.test_pathtrace import make_scene, column\n"
        "from renderer.pathtrace.path_tracer import render_pathtraced\n"
        "r = render_pathtraced(make_scene(light=(1.0, 2.75, 0.5)), column(), size=32, spp=64)\n"
        "d = render_pathtraced(make_scene(light=(1.0, 2.75, 0.5)), column(), size=32, spp=4, denoise=True)\n"
        "print(json.dumps({'variant': r.variant, 'mean': float(r.image.mean()), 'denoised': float(d.image.mean())}))\n"
    )
    env = dict(os.environ, DRJIT_LIBLLVM_PATH="/nonexistent/libLLVM-19.so", PYTHONPATH=str(REPO))
    done = subprocess.run([sys.executable, "-c", program], env=env, cwd=REPO, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    scalar = json.loads(done.stdout.strip().splitlines()[-1])
    assert scalar["variant"] == SCALAR_VARIANT
    here = render_pathtraced(make_scene(light=(1.0, 2.75, 0.5)), column(), size=32, spp=64)
    assert abs(scalar["mean"] - float(here.image.mean())) < 0.01
    assert abs(scalar["denoised"] - float(here.image.mean())) < 0.02
