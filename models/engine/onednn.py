"""Convolutions that always run on oneDNN on the CPU, whatever their size, with the activation after them fused in.

At batch 1, torch sends a convolution with kernels of at most 3 to a slow reference path
(im2col) unless channels x (first two spatial sizes) exceeds 20480. The full 128^3 grid passes
that test, but the crops of models/engine/cropped_encoder.py often do not, and there the reference
path was up to 6x slower than oneDNN on the same crop. `torch.ops.aten.mkldnn_convolution`
is the oneDNN call torch itself makes for large inputs, so the numbers are the same kind.

A convolution followed by ReLU or leaky ReLU applies it while writing its output (a oneDNN
post-op, `torch.ops.mkldnn._convolution_pointwise`, the call torch's own compiler emits), and a
residual block's last convolution adds the shortcut and applies the block's activation the same
way (2D blocks: oneDNN fuses only ReLU after an add): each saves a pass or two over a feature map.
The arithmetic is unchanged.
"""

from __future__ import annotations

import os

import torch
from torch import nn

from models.networks.layers import ResidualBlock2d

NO_ACTIVATION = ("none", [])


# oneDNN's instruction-set caps (its ONEDNN_MAX_CPU_ISA setting) that leave it the bfloat16 instructions.
_CAPS_WITH_BFLOAT16 = frozenset({"DEFAULT", "ALL", "AVX512_CORE_BF16", "AVX512_CORE_FP16", "AVX512_CORE_AMX",
                                 "AVX512_CORE_AMX_FP16", "AVX10_1_512", "AVX10_1_512_AMX", "AVX10_1_512_AMX_FP16",
                                 "AVX10_2_512", "AVX10_2_512_AMX_2"})


def onednn_isa_cap() -> str | None:
    """The instruction set oneDNN is capped at by the environment (ONEDNN_MAX_CPU_ISA, or its older name), or None."""
    cap = os.environ.get("ONEDNN_MAX_CPU_ISA") or os.environ.get("DNNL_MAX_CPU_ISA")
    return cap.strip().upper() if cap and cap.strip() else None


def cpu_has_native_bfloat16() -> bool:
    """Whether this CPU computes bfloat16 in hardware (AVX512-BF16) and oneDNN may use it; without it oneDNN emulates
    bfloat16, slower than fp32. A cap below AVX512_CORE_BF16 (ONEDNN_MAX_CPU_ISA=AVX2, say) runs a CPU as one without."""
    cap = onednn_isa_cap()
    if cap is not None and cap not in _CAPS_WITH_BFLOAT16:
        return False
    return bool(getattr(torch.cpu, "_is_avx512_bf16_supported", lambda: False)())


def cpu_can_run_bfloat16() -> bool:
    """Whether oneDNN runs bfloat16 convolutions here at all (natively or emulated: AVX512 or AVX-NE-CONVERT)."""
    return bool(torch.backends.mkldnn.is_available() and torch.ops.mkldnn._is_mkldnn_bf16_supported())


class OneDnnConv(nn.Module):
    """A Conv2d or Conv3d (zero padding) that calls oneDNN directly, then applies `activation`; same weights."""

    def __init__(self, conv: nn.Conv2d | nn.Conv3d):
        super().__init__()
        if conv.padding_mode != "zeros" or isinstance(conv.padding, str):
            raise ValueError("OneDnnConv needs explicit zero padding")
        self.weight = conv.weight
        self.bias = conv.bias
        self.padding, self.stride = list(conv.padding), list(conv.stride)
        self.dilation, self.groups = list(conv.dilation), conv.groups
        self.activation = NO_ACTIVATION  # oneDNN post-op name and its scalars (set by fuse_activations)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.activation == NO_ACTIVATION:
            return torch.ops.aten.mkldnn_convolution(x, self.weight, self.bias, self.padding, self.stride,
                                                     self.dilation, self.groups)
        return torch.ops.mkldnn._convolution_pointwise(x, self.weight, self.bias, self.padding, self.stride,
                                                       self.dilation, self.groups, *self.activation, "")

    def add_then_activate(self, x: torch.Tensor, other: torch.Tensor, activation: tuple[str, list]) -> torch.Tensor:
        """activation(conv(x) + other) in one oneDNN call."""
        return torch.ops.mkldnn._convolution_pointwise.binary(x, other, self.weight, self.bias, self.padding, self.stride,
                                                              self.dilation, self.groups, "add", None, *activation, "")


class OneDnnConvTranspose(nn.Module):
    """A ConvTranspose2d on oneDNN, then `activation`; same weights, same output."""

    def __init__(self, conv: nn.ConvTranspose2d):
        super().__init__()
        if conv.padding_mode != "zeros":
            raise ValueError("OneDnnConvTranspose needs zero padding")
        self.weight = conv.weight
        self.bias = conv.bias
        self.padding, self.output_padding = list(conv.padding), list(conv.output_padding)
        self.stride, self.dilation, self.groups = list(conv.stride), list(conv.dilation), conv.groups
        self.activation = NO_ACTIVATION

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.ops.mkldnn._convolution_transpose_pointwise(x, self.weight, self.bias, self.padding,
                                                                 self.output_padding, self.stride, self.dilation,
                                                                 self.groups, *self.activation, "")


class FusedResidual(nn.Module):
    """A ResidualBlock2d whose last convolution adds the shortcut and applies the block's ReLU.

    (oneDNN fuses only ReLU after an add, so ResidualBlock3d, with leaky ReLU, stays as it is.)
    """

    def __init__(self, block: ResidualBlock2d):
        super().__init__()
        self.block = block
        convs = [i for i, m in enumerate(block.body) if isinstance(m, OneDnnConv)]
        if not convs or any(not isinstance(m, nn.Identity) for m in block.body[convs[-1] + 1:]):
            raise ValueError("a residual block's body must end with a convolution (BatchNorm folded)")
        self._head = tuple(block.body[:convs[-1]])  # the body before its last convolution (a tuple: no new submodules)
        self._last = convs[-1]
        self.activation = _activation(block.act)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = x
        for module in self._head:
            h = module(h)
        return self.block.body[self._last].add_then_activate(h, self.block.shortcut(x), self.activation)


def use_onednn_convolutions(model: nn.Module) -> nn.Module:
    """Replace (in place) every Conv2d, Conv3d and ConvTranspose2d of a float32 CPU model with its oneDNN
    module and fuse the activations after them (`fuse_activations`); returns the model.

    Does nothing when torch was built without oneDNN.
    """
    if not torch.backends.mkldnn.is_available():
        return model
    for parent in list(model.modules()):
        for name, child in parent.named_children():
            if type(child) in (nn.Conv2d, nn.Conv3d):
                setattr(parent, name, OneDnnConv(child))
            elif type(child) is nn.ConvTranspose2d:
                setattr(parent, name, OneDnnConvTranspose(child))
    return fuse_activations(model)


def fuse_activations(model: nn.Module) -> nn.Module:
    """In place: each ReLU / leaky ReLU that directly follows a oneDNN convolution in a Sequential (past folded
    BatchNorms, now Identity) becomes that convolution's post-op, and 2D residual blocks become FusedResidual."""
    for module in list(model.modules()):
        if not isinstance(module, nn.Sequential):
            continue
        for i, conv in enumerate(module):
            if not isinstance(conv, (OneDnnConv, OneDnnConvTranspose)):
                continue
            j = i + 1
            while j < len(module) and isinstance(module[j], nn.Identity):
                j += 1
            if j < len(module) and isinstance(module[j], (nn.ReLU, nn.LeakyReLU)):
                conv.activation = _activation(module[j])
                module[j] = nn.Identity()
    for parent in list(model.modules()):
        for name, child in parent.named_children():
            if isinstance(child, ResidualBlock2d):
                setattr(parent, name, FusedResidual(child))
    return model


def _activation(module: nn.Module) -> tuple[str, list]:
    """The oneDNN post-op of a ReLU or leaky ReLU module."""
    if isinstance(module, nn.ReLU):
        return ("relu", [])
    if isinstance(module, nn.LeakyReLU):
        return ("leaky_relu", [module.negative_slope])
    raise ValueError(f"no oneDNN post-op for {type(module).__name__}")
