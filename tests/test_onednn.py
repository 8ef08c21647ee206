"""The oneDNN inference copy (models/engine/onednn.py): fused activations and residual adds give the same images."""

from __future__ import annotations

import pytest
import torch
from torch import nn

from models.engine.onednn import (
    FusedResidual,
    OneDnnConv,
    OneDnnConvTranspose,
    cpu_has_native_bfloat16,
    use_onednn_convolutions,
)
from models.engine.render_engine import resolve_precision
from models.networks.inference import prepare_for_inference
from tests.test_engine import TINY_COMPACT, TINY_PAPER, random_model


@pytest.mark.parametrize("config", [TINY_COMPACT, TINY_PAPER], ids=["compact", "paper"])
@pytest.mark.parametrize("architecture", ["nvr", "nvr_plus"])
def test_fused_model_equals_the_folded_model(config, architecture, single_thread):
    folded = prepare_for_inference(random_model(config, architecture))
    fused = use_onednn_convolutions(prepare_for_inference(random_model(config, architecture)))
    g, s = config.grid_size, config.output_size
    gen = torch.Generator().manual_seed(0)
    voxels = (torch.rand(1, 4, g, g, g, generator=gen) > 0.8).float()
    voxels[:, :3] *= torch.rand(1, 3, g, g, g, generator=gen)
    light = torch.tensor([[0.4, 0.8, -0.9]])
    splat = torch.rand(1, 3, s, s, generator=gen) if architecture == "nvr_plus" else None
    floor_light = torch.rand(1, 3, s, s, generator=gen) if splat is not None and config.floor_light_input else None
    with torch.inference_mode():
        expected, image = folded(voxels, light, splat, floor_light), fused(voxels, light, splat, floor_light)
    torch.testing.assert_close(image, expected, rtol=0, atol=1e-5)
    assert (expected - expected.mean()).abs().max() > 1e-3  # a real image, not a constant


def test_every_activation_after_a_convolution_is_fused():
    fused = use_onednn_convolutions(prepare_for_inference(random_model(TINY_PAPER, "nvr_plus")))
    kinds = {type(m) for m in fused.modules()}
    assert not kinds & {nn.Conv2d, nn.Conv3d, nn.ConvTranspose2d}
    blocks = [m for m in fused.modules() if isinstance(m, FusedResidual)]
    assert len(blocks) == 2 + 1 + 2 + 1  # 2D residual blocks: pre-light, post-light, U-Net down and middle
    activations = [m for m in fused.modules() if isinstance(m, (nn.ReLU, nn.LeakyReLU))]
    # What stays: the light MLP's ReLU (between linear layers), the 2D blocks' own (fused by FusedResidual, not
    # called) and the two 3D residual blocks' leaky ReLU after their add.
    assert len(activations) == 1 + len(blocks) + 2
    convs = [m for m in fused.modules() if isinstance(m, (OneDnnConv, OneDnnConvTranspose))]
    unfused = [m for m in convs if m.activation == ("none", [])]
    # Without an activation after them: each residual block's last convolution and shortcut, the output heads.
    assert all(m.activation in (("relu", []), ("leaky_relu", [0.2]), ("none", [])) for m in convs)
    assert len(unfused) == len(blocks) + 2 + sum(not isinstance(b.block.shortcut, nn.Identity) for b in blocks) + 2


def test_an_instruction_set_cap_below_bfloat16_runs_the_cpu_as_one_without(monkeypatch):
    """ONEDNN_MAX_CPU_ISA=AVX2 keeps oneDNN off the bfloat16 instructions: the engine must then choose fp32."""
    monkeypatch.delenv("DNNL_MAX_CPU_ISA", raising=False)
    monkeypatch.delenv("ONEDNN_MAX_CPU_ISA", raising=False)
    hardware = bool(torch.cpu._is_avx512_bf16_supported())
    assert cpu_has_native_bfloat16() == hardware
    for cap in ("AVX2", "avx512_core", "AVX512_CORE_VNNI"):
        monkeypatch.setenv("ONEDNN_MAX_CPU_ISA", cap)
        assert not cpu_has_native_bfloat16() and resolve_precision("auto") == "fp32"
    for cap in ("AVX512_CORE_BF16", "avx512_core_amx", "DEFAULT", " "):
        monkeypatch.setenv("ONEDNN_MAX_CPU_ISA", cap)
        assert cpu_has_native_bfloat16() == hardware
    monkeypatch.delenv("ONEDNN_MAX_CPU_ISA")
    monkeypatch.setenv("DNNL_MAX_CPU_ISA", "AVX2")  # the older name
    assert not cpu_has_native_bfloat16()
