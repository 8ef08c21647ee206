"""Weights files: safetensors round trip, metadata, atomic writes, one-line errors for mismatched files."""

from __future__ import annotations

import json

import pytest
import torch
from safetensors import safe_open
from safetensors.torch import load_file, save_file

from models.networks.checkpoint import FORMAT_VERSION, load_model, save_model
from models.networks.config import CompactConfig, PaperConfig, ShaderRefinerConfig
from models.networks.nvr import NVR, NVRPlus, build_model
from renderer.errors import InputError

TINY_COMPACT = CompactConfig(grid_size=16, output_size=32)
TINY_PAPER = PaperConfig(grid_size=16, output_size=32, voxel_channels=(4, 4, 4, 8, 8), latent_channels=16,
                         light_channels=8, decoder_channels=(8, 8, 8), splat_channels=8, unet_channels=(8, 8, 16))


pytestmark = pytest.mark.usefixtures("single_thread")  # see tests/conftest.py


def trained_looking(arch: str, config) -> NVR | NVRPlus:
    """A model with non-default BatchNorm statistics, so a round trip must carry the buffers too."""
    torch.manual_seed(0)
    model = build_model(arch, config)
    for module in model.modules():
        if isinstance(module, torch.nn.modules.batchnorm._BatchNorm):
            module.running_mean.uniform_(-0.3, 0.3)
            module.running_var.uniform_(0.5, 2.0)
            module.num_batches_tracked.fill_(7)
    return model.eval()


def outputs(model: NVR | NVRPlus) -> torch.Tensor:
    gen = torch.Generator().manual_seed(5)
    c = model.config
    voxels = torch.rand(1, 4, c.grid_size, c.grid_size, c.grid_size, generator=gen)
    light = torch.randn(1, 3, generator=gen)
    splat = torch.rand(1, 3, c.output_size, c.output_size, generator=gen) if isinstance(model, NVRPlus) else None
    floor_light = splat.flip(-1) if splat is not None and c.floor_light_input else None
    with torch.no_grad():
        return model(voxels, light, splat, floor_light)


@pytest.mark.parametrize("arch,config", [("nvr_plus", TINY_COMPACT), ("nvr", TINY_PAPER)])
def test_save_and_load_give_identical_outputs(tmp_path, arch, config) -> None:
    model = trained_looking(arch, config)
    path = tmp_path / "model.safetensors"
    save_model(path, model, config, {"steps": 1200, "data": "chairs-single"})
    loaded, loaded_config, extra = load_model(path)
    assert type(loaded) is type(model) and not loaded.training
    assert loaded_config == config and type(loaded_config) is type(config)
    assert extra == {"steps": 1200, "data": "chairs-single"}
    assert torch.equal(outputs(loaded), outputs(model))
    assert [p.name for p in tmp_path.iterdir()] == ["model.safetensors"]  # no temporary file left behind
    with safe_open(str(path), framework="pt") as f:
        meta = f.metadata()
    assert meta["format_version"] == str(FORMAT_VERSION) and meta["architecture"] == arch
    assert json.loads(meta["config"])["name"] == config.name


def test_a_file_written_before_the_lit_floor_input_loads_as_a_network_without_it(tmp_path) -> None:
    config = CompactConfig(grid_size=16, output_size=32, floor_light_input=False)
    path = tmp_path / "old.safetensors"
    save_model(path, trained_looking("nvr_plus", config), config)
    tensors = load_file(str(path))
    with safe_open(str(path), framework="pt") as f:
        metadata = f.metadata()
    old_config = {k: v for k, v in json.loads(metadata["config"]).items() if k != "floor_light_input"}
    save_file(tensors, str(path), metadata={**metadata, "config": json.dumps(old_config)})
    loaded, loaded_config, _ = load_model(path)
    assert loaded_config == config and not loaded_config.floor_light_input
    assert torch.equal(outputs(loaded), outputs(trained_looking("nvr_plus", config)))


def test_a_refiner_written_before_the_finer_shading_grid_loads_shading_the_networks_own_grid(tmp_path) -> None:
    config = ShaderRefinerConfig(grid_size=16, output_size=32)
    assert config.shading_grid_factor == 2 and config.shading_grid_size == 32  # new refiners shade a finer grid
    path = tmp_path / "old.safetensors"
    save_model(path, trained_looking("nvr_plus", config), config)
    with safe_open(str(path), framework="pt") as f:
        metadata = f.metadata()
    old_config = {k: v for k, v in json.loads(metadata["config"]).items() if k != "shading_grid_factor"}
    save_file(load_file(str(path)), str(path), metadata={**metadata, "config": json.dumps(old_config)})
    _, loaded_config, _ = load_model(path)
    assert loaded_config.shading_grid_factor == 1 and loaded_config.shading_grid_size == 16


def test_save_refuses_a_config_that_is_not_the_models(tmp_path) -> None:
    with pytest.raises(ValueError, match="config differs"):
        save_model(tmp_path / "m.safetensors", build_model("nvr", TINY_COMPACT), TINY_PAPER)


@pytest.fixture
def saved(tmp_path):
    """A valid weights file and its tensors and metadata, to be altered by each test."""
    path = tmp_path / "model.safetensors"
    save_model(path, trained_looking("nvr", TINY_COMPACT), TINY_COMPACT)
    with safe_open(str(path), framework="pt") as f:
        metadata = f.metadata()
    return path, load_file(str(path)), metadata


def expect_error(path, match: str) -> None:
    with pytest.raises(InputError, match=match) as info:
        load_model(path)
    message = str(info.value)
    assert str(path) in message and "\n" not in message


def test_wrong_format_version(saved) -> None:
    path, tensors, metadata = saved
    save_file(tensors, str(path), metadata={**metadata, "format_version": "99"})
    expect_error(path, "format version '99'")


def test_missing_tensor(saved) -> None:
    path, tensors, metadata = saved
    del tensors["to_rgb.0.weight"]
    save_file(tensors, str(path), metadata=metadata)
    expect_error(path, "1 missing \\(e.g. to_rgb.0.weight\\)")


def test_extra_tensor(saved) -> None:
    path, tensors, metadata = saved
    save_file({**tensors, "surprise.weight": torch.zeros(2)}, str(path), metadata=metadata)
    expect_error(path, "1 unexpected \\(e.g. surprise.weight\\)")


def test_misshaped_tensor(saved) -> None:
    path, tensors, metadata = saved
    tensors["to_rgb.0.bias"] = torch.zeros(4)
    save_file(tensors, str(path), metadata=metadata)
    expect_error(path, "to_rgb.0.bias is torch.float32 \\(4,\\), the network expects torch.float32 \\(3,\\)")


def test_weights_of_another_config(saved) -> None:
    path, tensors, metadata = saved
    save_file(tensors, str(path), metadata={**metadata, "config": json.dumps(TINY_PAPER.to_dict())})
    expect_error(path, "do not match the nvr 'paper' network")


def test_broken_config_metadata(saved) -> None:
    path, tensors, metadata = saved
    save_file(tensors, str(path), metadata={**metadata, "config": "{not json"})
    expect_error(path, "bad configuration")


def test_safetensors_file_without_our_metadata(saved) -> None:
    path, tensors, _ = saved
    save_file(tensors, str(path))
    expect_error(path, "not an NVR Studio weights file")


def test_not_a_safetensors_file(tmp_path) -> None:
    path = tmp_path / "model.safetensors"
    path.write_bytes(b"PK\x03\x04 this is a zip, not safetensors")
    expect_error(path, "not a safetensors weights file")
    expect_error(tmp_path / "absent.safetensors", "file not found")


def test_truncated_file(saved) -> None:
    path, _, _ = saved
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    expect_error(path, "not a safetensors weights file")
