"""NVR / NVR+ networks at tiny sizes: shapes, cacheable stages, robustness, determinism, learning."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from models.networks.config import (
    CompactConfig,
    EnvironmentRefinerConfig,
    HalfResolutionRefinerConfig,
    NVRConfig,
    PaperConfig,
    ShaderRefinerConfig,
)
from models.networks.inference import prepare_for_inference
from models.networks.layers import cat_channels
from models.networks.nvr import LIGHT_SCALE, NVR, SHADING_CHANNELS, NVRPlus, build_model, light_to_network
from models.training.loss import RenderLoss
from renderer.scene import CAMERA_DISTANCE, LOOK_AT

# The paper's structure (block counts, kernels, U-Net depth) at a tiny size and width.
TINY_PAPER = PaperConfig(grid_size=16, output_size=32, voxel_channels=(4, 4, 4, 8, 8), latent_channels=32,
                         light_channels=8, decoder_channels=(16, 8, 8), splat_channels=8, unet_channels=(8, 16, 32))
TINY_COMPACT = CompactConfig(grid_size=16, output_size=32)
CONFIGS = {"paper": TINY_PAPER, "compact": TINY_COMPACT}
CASES = [(name, arch) for name in CONFIGS for arch in ("nvr", "nvr_plus")]


pytestmark = pytest.mark.usefixtures("single_thread")  # see tests/conftest.py


def make_inputs(config: NVRConfig, batch: int = 2, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    g, s = config.grid_size, config.output_size
    gen = torch.Generator().manual_seed(seed)
    voxels = torch.rand(batch, 4, g, g, g, generator=gen)
    voxels[:, 3] = (voxels[:, 3] > 0.7).float()
    light = torch.randn(batch, 3, generator=gen)
    splat = torch.rand(batch, 3, s, s, generator=gen)
    return voxels, light, splat


def eval_model(name: str, arch: str, seed: int = 0) -> NVR | NVRPlus:
    torch.manual_seed(seed)
    return build_model(arch, CONFIGS[name]).eval()


def image_inputs(model: NVR | NVRPlus, splat: torch.Tensor) -> tuple[torch.Tensor | None, ...]:
    """The image arguments a network takes: none (NVR), the splat, or the splat and a lit floor
    (a stand-in made from the splat, mirrored, for configs with floor_light_input)."""
    if not isinstance(model, NVRPlus):
        return (None,)
    return (splat, splat.flip(-1)) if model.config.floor_light_input else (splat,)


def run(model: NVR | NVRPlus, voxels: torch.Tensor, light: torch.Tensor, splat: torch.Tensor) -> torch.Tensor:
    with torch.no_grad():
        return model(voxels, light, *image_inputs(model, splat))


@pytest.mark.parametrize("name,arch", CASES)
def test_forward_shape_and_range(name: str, arch: str) -> None:
    model = eval_model(name, arch)
    out = run(model, *make_inputs(CONFIGS[name]))
    assert out.shape == (2, 3, 32, 32)
    assert torch.isfinite(out).all() and out.min() > 0.0 and out.max() < 1.0


@pytest.mark.parametrize("name,arch", CASES)
def test_stages_compose_to_forward_exactly(name: str, arch: str) -> None:
    model = eval_model(name, arch)
    voxels, light, splat = make_inputs(CONFIGS[name])
    with torch.no_grad():
        latent = model.encode_voxels(voxels)
        features = model.encode_splat(*image_inputs(model, splat)) if arch == "nvr_plus" else None
        staged = model.render_from_latent(latent, light, features)
    assert latent.shape == (2, CONFIGS[name].latent_channels, 4, 4)
    assert torch.equal(staged, run(model, voxels, light, splat))


def test_light_changes_output_but_not_latent() -> None:
    model = eval_model("compact", "nvr")
    voxels, light, _ = make_inputs(TINY_COMPACT)
    with torch.no_grad():
        latent = model.encode_voxels(voxels)
        a = model.render_from_latent(latent, light)
        b = model.render_from_latent(latent, light + 1.0)
    assert not torch.equal(a, b)


@pytest.mark.parametrize("name,arch", CASES)
def test_finite_for_extreme_scenes_and_lights(name: str, arch: str) -> None:
    model = eval_model(name, arch)
    g, s = CONFIGS[name].grid_size, CONFIGS[name].output_size
    corners = torch.tensor([[x, y, z] for x in (-1.5, 1.5) for y in (0.0, 2.0) for z in (-2.0, 0.0)])
    lights = torch.cat([corners, corners * 100.0, torch.zeros(1, 3)])
    n = lights.shape[0]
    for value in (0.0, 1.0):  # an empty scene (and black splat), a full grid (and white splat)
        out = run(model, torch.full((n, 4, g, g, g), value), lights, torch.full((n, 3, s, s), value))
        assert torch.isfinite(out).all()


@pytest.mark.parametrize("name,arch", CASES)
def test_inference_is_deterministic(name: str, arch: str) -> None:
    inputs = make_inputs(CONFIGS[name])
    assert torch.equal(run(eval_model(name, arch), *inputs), run(eval_model(name, arch), *inputs))


@pytest.mark.parametrize("arch", ["nvr", "nvr_plus"])
def test_inference_copy_matches_eval_model(arch: str) -> None:
    model = eval_model("compact", arch)
    # Non-trivial BatchNorm statistics, so folding them has something to do.
    for module in model.modules():
        if isinstance(module, torch.nn.modules.batchnorm._BatchNorm):
            module.running_mean.uniform_(-0.5, 0.5)
            module.running_var.uniform_(0.5, 2.0)
            module.weight.data.uniform_(0.5, 1.5)
    inputs = make_inputs(TINY_COMPACT)
    fast = prepare_for_inference(model)
    assert not any(isinstance(m, torch.nn.modules.batchnorm._BatchNorm) for m in fast.modules())
    assert torch.allclose(run(fast, *inputs), run(model, *inputs), atol=1e-5)


def test_a_few_optimisation_steps_lower_the_loss() -> None:
    torch.manual_seed(0)
    model = build_model("nvr_plus", TINY_COMPACT).train()
    voxels, light, splat = make_inputs(TINY_COMPACT)
    target = torch.linspace(0.1, 0.9, 32).view(1, 1, 1, 32).expand(2, 3, 32, 32).contiguous()
    loss_fn = RenderLoss(TINY_COMPACT.perceptual_weight)
    optimiser = torch.optim.Adam(model.parameters(), lr=2e-3)
    losses = []
    for _ in range(12):
        optimiser.zero_grad()
        loss, _ = loss_fn(model(voxels, light, *image_inputs(model, splat)), target)
        loss.backward()
        optimiser.step()
        losses.append(loss.item())
    assert all(math.isfinite(v) for v in losses)
    assert losses[-1] < 0.7 * losses[0]


def test_paper_config_has_the_published_widths() -> None:
    with torch.device("meta"):
        model = build_model("nvr_plus", PaperConfig())
    shapes = {k: tuple(v.shape) for k, v in model.state_dict().items()}
    # 3D stages 16, 16, 16, 32, 32 (kernel 4, strides 2, 1, 2, 1, 1), five 3D residual blocks of 32.
    stages = [next(m for m in stage if isinstance(m, torch.nn.Conv3d)) for stage in model.voxel_encoder.stages]
    assert [tuple(c.weight.shape) for c in stages] == [
        (16, 4, 4, 4, 4), (16, 16, 4, 4, 4), (16, 16, 4, 4, 4), (32, 16, 4, 4, 4), (32, 32, 4, 4, 4)]
    assert [c.stride[0] for c in stages] == [2, 1, 2, 1, 1]
    assert len(model.voxel_encoder.residual.blocks) == 5
    # Projection: 32 depth x 32 channels = 1024 -> 512.
    assert shapes["voxel_encoder.projection.0.weight"] == (512, 1024, 1, 1)
    assert len(model.voxel_encoder.blocks.blocks) == 5 and len(model.light_decoder.blocks.blocks) == 5
    assert shapes["light_decoder.light_mlp.2.weight"] == (64, 64)
    assert shapes["light_decoder.merge.1.weight"] == (512, 576, 4, 4)  # after its explicit zero pad
    assert [shapes[f"light_decoder.decoder.{i}.0.weight"] for i in (0, 2, 4)] == [(512, 128, 4, 4), (128, 64, 4, 4), (64, 32, 4, 4)]
    assert shapes["splat_encoder.layers.1.1.weight"] == (32, 32, 4, 4)
    assert [shapes[f"rerender.down.{i}.body.0.weight"][0] for i in range(3)] == [128, 256, 512]
    assert len(model.rerender.middle.blocks) == 3


def test_light_to_network_matches_hand_geometry() -> None:
    elevation = 30.0
    e = math.radians(elevation)
    look_at = np.array(LOOK_AT)
    assert np.allclose(light_to_network(look_at, elevation), [0.0, 0.0, -CAMERA_DISTANCE / LIGHT_SCALE], atol=1e-6)
    # A point h above the look-at point: camera y = h cos(e), z = h sin(e) - distance.
    h = 2.0
    expected = np.array([0.0, h * math.cos(e), h * math.sin(e) - CAMERA_DISTANCE]) / LIGHT_SCALE
    assert np.allclose(light_to_network(look_at + [0.0, h, 0.0], elevation), expected, atol=1e-6)
    # One unit to the world's +x is one unit to the camera's right at azimuth 0; batches work.
    batch = light_to_network(np.stack([look_at, look_at + [1.0, 0.0, 0.0]]), elevation)
    assert batch.shape == (2, 3) and batch.dtype == np.float32
    assert np.allclose(batch[1] - batch[0], [1.0 / LIGHT_SCALE, 0.0, 0.0], atol=1e-6)


def test_bad_inputs_raise_clear_errors() -> None:
    nvr, plus = eval_model("compact", "nvr"), eval_model("compact", "nvr_plus")
    voxels, light, splat = make_inputs(TINY_COMPACT)
    with pytest.raises(ValueError, match="voxels must have shape"):
        nvr.encode_voxels(voxels[:, :, :8])
    with pytest.raises(ValueError, match="light must have shape"):
        nvr(voxels, light[:, :2])
    with pytest.raises(ValueError, match="takes no splat"):
        nvr(voxels, light, splat)
    with pytest.raises(ValueError, match="needs a splat"):
        plus(voxels, light)
    with pytest.raises(ValueError, match="splat must have shape"):
        plus.encode_splat(splat[:, :, :16], splat)
    with pytest.raises(ValueError, match="pass floor_light"):
        plus.encode_splat(splat)
    with pytest.raises(ValueError, match="floor_light must have shape"):
        plus.encode_splat(splat, splat[:, :2])
    paper_plus = eval_model("paper", "nvr_plus")
    with pytest.raises(ValueError, match="reads no lit floor"):
        paper_plus.encode_splat(torch.rand(2, 3, 32, 32), torch.rand(2, 3, 32, 32))


def test_lit_floor_input_changes_the_output() -> None:
    model = eval_model("compact", "nvr_plus")
    voxels, light, splat = make_inputs(TINY_COMPACT)
    with torch.no_grad():
        a = model(voxels, light, splat, splat.flip(-1))
        b = model(voxels, light, splat, splat.flip(-2))
    assert not torch.allclose(a, b, atol=1e-4)


def test_config_round_trip_and_validation() -> None:
    for config in (PaperConfig(), CompactConfig(), TINY_PAPER, ShaderRefinerConfig(), HalfResolutionRefinerConfig(),
                   EnvironmentRefinerConfig()):
        data = config.to_dict()
        again = NVRConfig.from_dict(data)
        assert again == config and type(again) is type(config)
    assert PaperConfig().latent_size == 32 and CompactConfig().latent_size == 32
    with pytest.raises(ValueError, match="output_size"):
        CompactConfig(output_size=128)
    with pytest.raises(ValueError, match="unknown configuration"):
        NVRConfig.from_dict({**CompactConfig().to_dict(), "name": "huge"})
    with pytest.raises(ValueError, match="missing"):
        NVRConfig.from_dict({k: v for k, v in CompactConfig().to_dict().items() if k != "latent_channels"})
    with pytest.raises(ValueError, match="non-negative integer"):
        CompactConfig(latent_channels=-1)
    assert HalfResolutionRefinerConfig().network_size == 128 and HalfResolutionRefinerConfig().output_size == 256
    with pytest.raises(ValueError, match="needs shading_input"):
        CompactConfig(decoder_channels=(32, 16), correction_downsampling=2)
    with pytest.raises(ValueError, match="correction_downsampling must be"):
        ShaderRefinerConfig(correction_downsampling=3)
    with pytest.raises(ValueError, match="output_size"):
        ShaderRefinerConfig(correction_downsampling=2)  # the decoder would reach 256, the network works at 128


def test_cat_channels_keeps_channels_last_and_the_values() -> None:
    gen = torch.Generator().manual_seed(0)
    # As the engine passes images: (H, W, C) arrays seen as (1, C, H, W), i.e. channels-last.
    a = torch.rand(1, 5, 7, 3, generator=gen).permute(0, 3, 1, 2)
    b = torch.rand(1, 5, 7, 13, generator=gen).permute(0, 3, 1, 2)
    joined = cat_channels([a, b])
    assert joined.shape == (1, 16, 5, 7) and joined.is_contiguous(memory_format=torch.channels_last)
    assert torch.equal(joined[:, :3], a) and torch.equal(joined[:, 3:], b)
    mixed = cat_channels([a, b.contiguous()])  # one channels-first input: torch.cat's layout
    assert torch.equal(mixed, joined) and mixed.is_contiguous()


def test_shader_refiner_corrects_the_shaded_image_the_same_in_either_layout() -> None:
    config = ShaderRefinerConfig(grid_size=16, output_size=32)
    torch.manual_seed(0)
    model = build_model("nvr_plus", config).eval()
    for parameter in model.rerender.to_rgb.parameters():  # a trained correction, not the zero one it starts as
        torch.nn.init.normal_(parameter, std=0.05)
    voxels, light, splat = make_inputs(config, batch=1)
    shading = torch.rand(1, SHADING_CHANNELS, 32, 32, generator=torch.Generator().manual_seed(1))
    with torch.no_grad():
        image = model(voxels, light, splat, shading=shading)
        last = model.rerender(model.to_features(model._features(model.encode_voxels(voxels), light))
                              + model.encode_splat(splat, shading=shading))
        channels_last = [t.permute(0, 2, 3, 1).contiguous().permute(0, 3, 1, 2) for t in (splat, shading)]
        image_last = model(voxels, light, channels_last[0], shading=channels_last[1])
    expected = shading[:, :3] * torch.exp(last[:, :3]) + last[:, 3:]
    torch.testing.assert_close(image, expected, rtol=0, atol=1e-6)
    torch.testing.assert_close(image_last, image, rtol=0, atol=1e-6)
    assert (image - shading[:, :3]).abs().max() > 1e-3  # the correction is not zero


def _bilinear_double(image: np.ndarray) -> np.ndarray:
    """(C, H, W) -> (C, 2H, 2W): each output pixel centre mapped back onto the input, weights from the distance
    to its two nearest input pixels, clamped at the border (half-pixel centres, as image resizers do)."""
    def axis_weights(n: int) -> np.ndarray:
        x = np.clip((np.arange(2 * n) + 0.5) / 2.0 - 0.5, 0.0, n - 1)
        low = np.floor(x).astype(int)
        high = np.minimum(low + 1, n - 1)
        w = np.zeros((2 * n, n))
        w[np.arange(2 * n), low] += 1.0 - (x - low)
        w[np.arange(2 * n), high] += x - low
        return w
    rows, cols = axis_weights(image.shape[1]), axis_weights(image.shape[2])
    return np.einsum("ri,cij,sj->crs", rows, image, cols)


def test_a_half_resolution_refiner_applies_its_coarse_correction_to_the_full_resolution_shaded_image() -> None:
    config = HalfResolutionRefinerConfig(grid_size=16, output_size=32)
    assert config.network_size == 16
    torch.manual_seed(0)
    model = build_model("nvr_plus", config).eval()
    voxels, light, splat = make_inputs(config, batch=1)
    gen = torch.Generator().manual_seed(1)
    shading = torch.rand(1, SHADING_CHANNELS, 32, 32, generator=gen)
    with torch.no_grad():  # untrained: the correction layer is zero, so the image is the shaded one, pixel for pixel
        torch.testing.assert_close(model(voxels, light, splat, shading=shading), shading[:, :3], rtol=0, atol=0)
    for parameter in model.rerender.to_rgb.parameters():
        torch.nn.init.normal_(parameter, std=0.05)
    # A pattern that sums to zero over every 2x2 block: the network reads block means, so only the shaded image's
    # own detail may change the output.
    checker = torch.tensor([[1.0, -1.0], [-1.0, 1.0]]).repeat(16, 16) * 0.01
    with torch.no_grad():
        image = model(voxels, light, splat, shading=shading)
        coarse = model.rerender(model.to_features(model._features(model.encode_voxels(voxels), light))
                                + model.splat_encoder(torch.cat([torch.nn.functional.avg_pool2d(t, 2)
                                                                 for t in (splat, shading)], dim=1)))
        detailed = shading.clone()
        detailed[:, 3:] += checker  # the buffers' detail, not the shaded image's
        same = model(voxels, light, splat + checker, shading=detailed)
    assert coarse.shape == (1, 6, 16, 16)
    correction = _bilinear_double(coarse[0].numpy().astype(np.float64))
    expected = shading[0, :3].numpy() * np.exp(correction[:3]) + correction[3:]
    np.testing.assert_allclose(image[0].numpy(), expected, rtol=0, atol=1e-5)
    torch.testing.assert_close(same, image, rtol=0, atol=1e-5)
    assert (image - shading[:, :3]).abs().max() > 1e-3  # the correction is not zero
