"""An inference copy of a trained network: BatchNorm folded into convolutions, channels-last weights.

Folding removes one full pass over every feature map per BatchNorm; channels-last (NHWC/NDHWC)
lets oneDNN use its fastest CPU kernels. Outputs equal the eval-mode model's up to float rounding.
Inputs may stay in the default layout (the first convolution converts them), but a voxel tensor
made as `torch.from_numpy(grid_dhwc).permute(3, 0, 1, 2)[None]` is already channels-last for free.
"""

from __future__ import annotations

import copy

import torch
from torch import nn
from torch.nn.utils.fusion import fuse_conv_bn_eval

_CONVS = (nn.Conv2d, nn.Conv3d, nn.ConvTranspose2d)
_NORMS = (nn.BatchNorm2d, nn.BatchNorm3d)


def prepare_for_inference(model: nn.Module) -> nn.Module:
    """An eval-mode copy of `model` with conv+BatchNorm pairs fused and channels-last weights."""
    model = copy.deepcopy(model).eval()
    for module in model.modules():
        if not isinstance(module, nn.Sequential):
            continue
        for i in range(len(module) - 1):
            conv, norm = module[i], module[i + 1]
            if isinstance(conv, _CONVS) and isinstance(norm, _NORMS):
                module[i] = fuse_conv_bn_eval(conv, norm, transpose=isinstance(conv, nn.ConvTranspose2d))
                module[i + 1] = nn.Identity()
    for tensor in list(model.parameters()) + list(model.buffers()):
        if tensor.ndim == 4:
            tensor.data = tensor.data.contiguous(memory_format=torch.channels_last)
        elif tensor.ndim == 5:
            tensor.data = tensor.data.contiguous(memory_format=torch.channels_last_3d)
    return model
