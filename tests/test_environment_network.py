"""NVR+ reading the environment (config.environment_input): the probe it reads, its light input, and that it starts
out rendering what the network it starts from renders."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from models.engine.light_merge import SplitLightMerge, split_light_merge
from models.engine.onednn import use_onednn_convolutions
from models.networks.checkpoint import save_model
from models.networks.config import LIGHT_DIMS, LIGHTING_SCALARS, PROBE_DIMS, PROBE_SIZE, NVRConfig
from models.networks.inference import prepare_for_inference
from models.networks.nvr import ENVIRONMENT_ENCODER, SHADING_CHANNELS, build_model, lighting_input
from models.training.data import permute_colors
from models.training.train import initialize_from
from renderer.environment import environment_light, environment_probe, texel_solid_angles, uniform_environment
from renderer.errors import InputError
from renderer.scene import AMBIENT_RADIANCE, EnvironmentSpec, MaterialSpec, Scene, SkySpec, replaced
from tests.test_engine import TINY_ENVIRONMENT_REFINER, TINY_HALF_REFINER, refiner
from tests.test_environment import write_map


def probe_power(probe: np.ndarray) -> np.ndarray:
    """(3,) the probe's radiance integrated over the sphere."""
    return (probe * texel_solid_angles(*probe.shape[:2])[..., None]).sum(axis=(0, 1))


def map_scene(two_color_box: Scene, path: Path, rotation: float = 0.0, strength: float = 1.0) -> Scene:
    env = EnvironmentSpec(image=str(path), rotation_deg=rotation, strength=strength)
    return replace(two_color_box, environment=env, light=replace(two_color_box.light, enabled=False))


def test_the_probe_keeps_the_maps_light_and_a_full_turn_changes_nothing(two_color_box, tmp_path):
    rng = np.random.default_rng(0)
    radiance = rng.uniform(0.0, 2.0, (64, 128, 3)).astype(np.float32)
    path = write_map(tmp_path / "map.hdr", radiance)
    env = environment_light(map_scene(two_color_box, path, strength=1.5))
    probe = environment_probe(env, PROBE_SIZE)
    assert probe.shape == (PROBE_SIZE, PROBE_SIZE, 3)
    expected = 1.5 * (radiance * texel_solid_angles(64, 128)[..., None]).sum(axis=(0, 1))
    np.testing.assert_allclose(probe_power(probe), expected, rtol=0.01)
    turned = environment_probe(environment_light(map_scene(two_color_box, path, 360.0, 1.5)), PROBE_SIZE)
    np.testing.assert_allclose(turned, probe, rtol=1e-4, atol=1e-5)


def test_a_quarter_turn_moves_the_probe_by_a_quarter_of_its_columns(two_color_box, tmp_path):
    radiance = np.full((64, 128, 3), 0.1, dtype=np.float32)
    radiance[20:30, 8:16] = 5.0  # a bright patch at the map's azimuth 22.5-45 degrees
    path = write_map(tmp_path / "map.hdr", radiance)
    probe = environment_probe(environment_light(map_scene(two_color_box, path)), PROBE_SIZE)
    turned = environment_probe(environment_light(map_scene(two_color_box, path, 90.0)), PROBE_SIZE)
    column = int(np.argmax(probe[..., 0].sum(axis=0)))
    turned_column = int(np.argmax(turned[..., 0].sum(axis=0)))
    assert column in (2, 3)  # 22.5-45 degrees of 360, 32 columns
    # Turning the map by +90 degrees about +y carries the patch a quarter of the way round, to the decreasing azimuth
    # the maps count (renderer.environment.rotate_y and direction_angles).
    assert (turned_column - column) % PROBE_SIZE in (PROBE_SIZE * 3 // 4, PROBE_SIZE // 4)
    assert abs(turned[..., 0].max() - probe[..., 0].max()) < 0.2 * probe[..., 0].max()


def test_the_suns_light_lands_in_the_texel_of_its_direction(two_color_box):
    scene = replace(two_color_box, environment=EnvironmentSpec(sky=SkySpec(30.0, 90.0, 3.0)))
    env = environment_light(scene)
    probe = environment_probe(env, PROBE_SIZE)
    # By hand: polar angle 60 degrees -> row floor(60 / 180 * 32) = 10; azimuth: the sun's world direction
    # (sin 90 cos 30, sin 30, cos 90 cos 30) = (0.866, 0.5, 0) has atan2(x, -z) = 90 degrees -> column 8.
    row, col = np.unravel_index(np.argmax(probe.sum(axis=-1)), probe.shape[:2])
    assert (row, col) == (10, 8)
    sun_power = env.sun_irradiance
    sky_only = probe.copy()
    sky_only[10, 8] -= env.sun_irradiance / texel_solid_angles(PROBE_SIZE, PROBE_SIZE)[10, 0]
    assert np.all(sky_only[10, 8] > -1e-3)  # the sky's own light stays under it
    np.testing.assert_allclose(probe_power(probe) - probe_power(np.maximum(sky_only, 0.0)), sun_power, rtol=1e-3)


@pytest.mark.parametrize("case", ["black", "one hot pixel", "sun at the horizon", "sun at the zenith"])
def test_the_light_input_is_finite_for_hard_environments(two_color_box, tmp_path, case):
    if case in ("black", "one hot pixel"):
        radiance = np.zeros((64, 128, 3), dtype=np.float32)
        if case == "one hot pixel":
            radiance[5, 7] = 65000.0
        scene = map_scene(two_color_box, write_map(tmp_path / "map.hdr", radiance))
    else:
        scene = replace(two_color_box, environment=EnvironmentSpec(sky=SkySpec(0.0 if "horizon" in case else 90.0)))
    light = lighting_input(scene, True)
    assert light.shape == (LIGHT_DIMS + LIGHTING_SCALARS + PROBE_DIMS,) and np.isfinite(light).all()
    assert light.min() >= -10.0 and light[LIGHT_DIMS + LIGHTING_SCALARS:].max() < 25.0  # log(1 + radiance): bounded


def test_an_area_light_scene_reads_as_the_light_on_a_diffuse_object_under_the_uniform_ambient(two_color_box):
    light = lighting_input(two_color_box, True)
    np.testing.assert_array_equal(light[:LIGHT_DIMS], lighting_input(two_color_box, False))
    np.testing.assert_array_equal(light[LIGHT_DIMS:LIGHT_DIMS + LIGHTING_SCALARS], [1.0, 1.0, 0.0, 0.0])
    np.testing.assert_allclose(light[LIGHT_DIMS + LIGHTING_SCALARS:], math.log1p(AMBIENT_RADIANCE), rtol=1e-5)
    glossy = replaced(two_color_box, object=replace(two_color_box.object, material=MaterialSpec(0.3, 0.5, 0.25)),
                     light=replace(two_color_box.light, enabled=False))
    np.testing.assert_allclose(lighting_input(glossy, True)[LIGHT_DIMS:LIGHT_DIMS + LIGHTING_SCALARS],
                               [0.0, 0.3, 0.5, 0.25])
    uniform = environment_probe(uniform_environment(AMBIENT_RADIANCE), PROBE_SIZE)
    np.testing.assert_allclose(uniform, AMBIENT_RADIANCE, rtol=1e-5)


def inputs(config: NVRConfig, seed: int = 0) -> tuple[torch.Tensor, ...]:
    gen = torch.Generator().manual_seed(seed)
    g, s = config.grid_size, config.output_size
    voxels = (torch.rand(2, 4, g, g, g, generator=gen) > 0.8).float()
    light = torch.rand(2, config.light_dims, generator=gen) * 2.0
    return voxels, light, torch.rand(2, 3, s, s, generator=gen), torch.rand(2, SHADING_CHANNELS, s, s, generator=gen)


def test_an_untrained_environment_network_renders_the_shaded_image():
    model = build_model("nvr_plus", TINY_ENVIRONMENT_REFINER).eval()
    voxels, light, splat, shading = inputs(TINY_ENVIRONMENT_REFINER)
    with torch.no_grad():
        torch.testing.assert_close(model(voxels, light, splat, shading=shading), shading[:, :3], rtol=0, atol=1e-6)


def test_from_a_network_without_it_it_renders_what_that_network_renders_until_it_learns(tmp_path):
    source = refiner(config=TINY_HALF_REFINER)
    save_model(tmp_path / "source.safetensors", source, source.config)
    model = build_model("nvr_plus", TINY_ENVIRONMENT_REFINER).eval()
    initialize_from(model, tmp_path / "source.safetensors")
    voxels, light, splat, shading = inputs(TINY_ENVIRONMENT_REFINER)
    light[:, LIGHT_DIMS] = 1.0  # the area light on, as in every scene the source was trained on
    with torch.no_grad():
        expected = source(voxels, light[:, :LIGHT_DIMS], splat, shading=shading)
        torch.testing.assert_close(model(voxels, light, splat, shading=shading), expected, rtol=0, atol=1e-6)
        model.light_decoder.environment.mlp[-1].weight.data.normal_(0.0, 1.0)  # once it has learned, the probe matters
        other = light.clone()
        other[:, LIGHT_DIMS + LIGHTING_SCALARS:] *= 3.0
        assert (model(voxels, light, splat, shading=shading) - model(voxels, other, splat, shading=shading)).abs().max() > 1e-4
    assert any(key.startswith(ENVIRONMENT_ENCODER) for key in model.state_dict())
    narrow = build_model("nvr_plus", replace(TINY_ENVIRONMENT_REFINER, light_channels=4))
    with pytest.raises(InputError):
        initialize_from(narrow, tmp_path / "source.safetensors")


def test_the_split_light_merge_equals_the_plain_decoder_with_the_environment():
    model = refiner(config=TINY_ENVIRONMENT_REFINER)
    model.light_decoder.environment.mlp[-1].weight.data.normal_(0.0, 1.0)
    plain = use_onednn_convolutions(prepare_for_inference(model))
    split = split_light_merge(use_onednn_convolutions(prepare_for_inference(model)))
    assert isinstance(split.light_decoder, SplitLightMerge)
    gen = torch.Generator().manual_seed(3)
    latent = torch.randn(1, 16, 16, 16, generator=gen)
    features = torch.rand(1, 4, 32, 32, generator=gen)
    with torch.inference_mode():
        for seed in range(3):
            light = torch.rand(1, TINY_ENVIRONMENT_REFINER.light_dims, generator=torch.Generator().manual_seed(seed))
            expected = plain.correction_from_latent(latent, light, features)
            torch.testing.assert_close(split.correction_from_latent(latent, light, features), expected, rtol=0, atol=1e-5)


def test_a_color_permutation_reorders_the_probes_channels_with_the_images():
    gen = torch.Generator().manual_seed(0)
    light = torch.rand(2, LIGHT_DIMS + LIGHTING_SCALARS + PROBE_DIMS, generator=gen)
    batch = {"light": light, "target": torch.rand(2, 3, 4, 4, generator=gen)}
    orders = torch.tensor([[2, 0, 1], [0, 1, 2]])
    out = permute_colors(batch, orders)
    head = LIGHT_DIMS + LIGHTING_SCALARS
    torch.testing.assert_close(out["light"][:, :head], light[:, :head])  # position, switch, material stay
    probe, permuted = light[:, head:].reshape(2, 3, -1), out["light"][:, head:].reshape(2, 3, -1)
    torch.testing.assert_close(permuted[0], probe[0, [2, 0, 1]])
    torch.testing.assert_close(permuted[1], probe[1])
    torch.testing.assert_close(out["target"][0], batch["target"][0, [2, 0, 1]])
