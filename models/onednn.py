"""Convolutions that always run on oneDNN on the CPU, whatever their size.

At batch 1, torch sends a convolution with kernels of at most 3 to a slow reference path
(im2col) unless channels x (first two spatial sizes) exceeds 20480. The full 128^3 grid passes
that test, but the crops of models/cropped_encoder.py often do not, and there the reference
path was up to 6x slower than oneDNN on the same crop. `torch.ops.aten.mkldnn_convolution`
is the oneDNN call torch itself makes for large inputs, so the numbers are the same kind.
"""

from __future__ import annotations

import torch
from torch import nn


class OneDnnConv(nn.Module):
    """A Conv2d or Conv3d (zero padding) that calls oneDNN directly; same weights, same output."""

    def __init__(self, conv: nn.Conv2d | nn.Conv3d):
        super().__init__()
        if conv.padding_mode != "zeros" or isinstance(conv.padding, str):
            raise ValueError("OneDnnConv needs explicit zero padding")
        self.weight = conv.weight
        self.bias = conv.bias
        self.padding, self.stride = list(conv.padding), list(conv.stride)
        self.dilation, self.groups = list(conv.dilation), conv.groups

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.ops.aten.mkldnn_convolution(x, self.weight, self.bias, self.padding, self.stride,
                                                 self.dilation, self.groups)


def use_onednn_convolutions(model: nn.Module) -> nn.Module:
    """Replace (in place) every Conv2d and Conv3d of a float32 CPU model with OneDnnConv; returns the model.

    Does nothing when torch was built without oneDNN.
    """
    if not torch.backends.mkldnn.is_available():
        return model
    for parent in list(model.modules()):
        for name, child in parent.named_children():
            if type(child) in (nn.Conv2d, nn.Conv3d):
                setattr(parent, name, OneDnnConv(child))
    return model
