"""Property test: random valid scenes, hard corners included, render to finite images in [0, 1].

Hypothesis draws several hundred scenes (tiny objects, empty and full grids, extreme placements, a
light just above the floor or far away, grazing and steep cameras, paint) and sends each through the
splat, the voxel shader (on a 32^3 scene grid: the small size keeps 300 scenes within a minute) and the
live NVR+ engine (a small random network that reads the shader's buffers, one engine for all scenes,
so its caches see a random sequence of edits, as in the editor).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from models.engine.render_engine import RenderEngine
from models.networks.config import ShaderRefinerConfig
from renderer.limits import MIN_IMAGE_SIZE
from renderer.pipeline import painted_voxels
from renderer.scene import MAX_ABS_POSITION, CameraSpec, FloorSpec, LightSpec, ObjectSpec, PaintOp, Scene, validate
from renderer.shading import shade_scene
from renderer.splat import splat_scene
from renderer.voxels import save_voxels
from tests.test_engine import random_model

SMALL_NETWORK = ShaderRefinerConfig(grid_size=32, output_size=32, voxel_channels=(4, 8, 8), latent_channels=8,
                                    light_channels=8, decoder_channels=(8, 8), splat_channels=4, unet_channels=(4, 8))
unit = st.floats(0.0, 1.0)
color = st.tuples(unit, unit, unit)
position = st.one_of(st.floats(-1.5, 1.5), st.floats(-MAX_ABS_POSITION, MAX_ABS_POSITION))  # mostly in view
scale = st.one_of(st.floats(0.5, 1.5), st.floats(1e-3, 50.0))


@st.composite
def object_voxels(draw) -> np.ndarray:
    """A random object grid: from empty to full, in random colors (extremes included)."""
    n = draw(st.integers(4, 12))
    density = draw(st.sampled_from([0.0, 0.02, 0.3, 1.0]))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    rgba = np.zeros((n, n, n, 4), np.float32)
    occupied = rng.random((n, n, n)) < density
    rgba[occupied, :3] = rng.choice([0.0, 1.0, 0.5], size=(int(occupied.sum()), 3)) if draw(st.booleans()) else \
        rng.random((int(occupied.sum()), 3))
    rgba[occupied, 3] = 1.0
    return rgba


@st.composite
def scenes(draw) -> tuple[Scene, np.ndarray]:
    rgba = draw(object_voxels())
    occupied = [tuple(int(i) for i in index) for index in np.argwhere(rgba[..., 3] > 0.5)[:50]]
    strokes = [st.builds(lambda c: PaintOp("object", c), color)]
    if occupied:  # a region fill starts on a voxel of the object (else the scene is refused, as it should be)
        strokes.append(st.builds(lambda c, s, t: PaintOp("region", c, s, t), color, st.sampled_from(occupied), unit))
    paint = draw(st.lists(st.one_of(*strokes), max_size=3))
    scene = Scene.single(
        object=ObjectSpec(voxels="object.npz", color=draw(st.none() | color),
                          translation=(draw(position), draw(position)), rotation_deg=draw(st.floats(-1e6, 1e6)),
                          scale=(draw(scale), draw(scale), draw(scale))),
        floor=FloorSpec(draw(color)),
        light=LightSpec((draw(position), draw(st.one_of(st.floats(2.0, 3.5), st.floats(1e-4, MAX_ABS_POSITION))), draw(position))),
        camera=CameraSpec(draw(st.floats(0.0, 89.999))),
        image_size=draw(st.integers(MIN_IMAGE_SIZE, 40)),
        paint=tuple(paint),
    )
    validate(scene)
    return scene, rgba


@pytest.fixture(scope="module")
def engine():
    return RenderEngine(random_model(SMALL_NETWORK), threads=1, precision="fp32", device="cpu")


@pytest.mark.filterwarnings("error::RuntimeWarning")  # an overflow or a 0/0 on the way is a failure too
@settings(max_examples=300, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                                     HealthCheck.too_slow])
@given(drawn=scenes())
def test_random_valid_scenes_render_finite_images_in_the_unit_range(drawn, engine, tmp_path):
    scene, rgba = drawn
    save_voxels(tmp_path / "object.npz", rgba)
    scene = Scene(**{**scene.__dict__, "base_dir": tmp_path})
    painted, floor_color = painted_voxels(scene, rgba if scene.object.color is None else _colored(rgba, scene))
    images = {
        "splat": splat_scene(scene, painted, floor_color),
        "shaded": shade_scene(scene, painted, floor_color, grid_size=32).image,
        "nvr+": engine.render(scene),
    }
    for name, image in images.items():
        assert np.isfinite(image).all(), name
        assert image.min() >= 0.0 and image.max() <= 1.0, (name, float(image.min()), float(image.max()))


def _colored(rgba: np.ndarray, scene: Scene) -> np.ndarray:
    out = rgba.copy()
    out[out[..., 3] > 0.5, :3] = scene.object.color
    return out
