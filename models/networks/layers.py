"""Building blocks of the networks: convolution blocks and residual blocks in 2D and 3D.

The 3D blocks (voxel branch) use BatchNorm and leaky ReLU, the 2D blocks BatchNorm and ReLU,
as the paper describes (section 3.3). Convolutions followed by BatchNorm carry no bias.
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from torch import nn

LEAKY_SLOPE = 0.2


def _conv(dims: int, c_in: int, c_out: int, kernel: int, stride: int, bias: bool) -> list[nn.Module]:
    """A convolution that keeps the size (stride 1) or halves it exactly (stride 2).

    Even kernels at stride 1 get an explicit zero padding, one more on the far side (as Keras'
    'same' does), instead of torch's implicit asymmetric padding.
    """
    conv_cls, pad_cls = (nn.Conv2d, nn.ZeroPad2d) if dims == 2 else (nn.Conv3d, nn.ZeroPad3d)
    if stride != 1 or kernel % 2:
        padding = (kernel - 1) // 2 if stride != 1 else kernel // 2
        return [conv_cls(c_in, c_out, kernel, stride=stride, padding=padding, bias=bias)]
    near, far = (kernel - 1) // 2, kernel // 2
    return [pad_cls((near, far) * dims), conv_cls(c_in, c_out, kernel, bias=bias)]


def conv_2d(c_in: int, c_out: int, kernel: int) -> nn.Sequential:
    """Plain size-keeping 2D convolution with bias (the output heads)."""
    return nn.Sequential(*_conv(2, c_in, c_out, kernel, 1, bias=True))


def conv_block_3d(c_in: int, c_out: int, kernel: int, stride: int = 1) -> nn.Sequential:
    """3D convolution + BatchNorm + leaky ReLU; stride 2 halves every side exactly."""
    return nn.Sequential(*_conv(3, c_in, c_out, kernel, stride, bias=False), nn.BatchNorm3d(c_out), nn.LeakyReLU(LEAKY_SLOPE))


def conv_block_2d(c_in: int, c_out: int, kernel: int, stride: int = 1) -> nn.Sequential:
    """2D convolution + BatchNorm + ReLU."""
    return nn.Sequential(*_conv(2, c_in, c_out, kernel, stride, bias=False), nn.BatchNorm2d(c_out), nn.ReLU())


def up_block_2d(c_in: int, c_out: int) -> nn.Sequential:
    """Transposed convolution (kernel 4, stride 2) + BatchNorm + ReLU: doubles every side exactly."""
    return nn.Sequential(
        nn.ConvTranspose2d(c_in, c_out, 4, stride=2, padding=1, bias=False),
        nn.BatchNorm2d(c_out),
        nn.ReLU(),
    )


class ResidualBlock3d(nn.Module):
    """Two 3x3x3 convolutions with BatchNorm, added to the input, then leaky ReLU."""

    def __init__(self, channels: int):
        super().__init__()
        self.body = nn.Sequential(
            nn.Conv3d(channels, channels, 3, padding=1, bias=False),
            nn.BatchNorm3d(channels),
            nn.LeakyReLU(LEAKY_SLOPE),
            nn.Conv3d(channels, channels, 3, padding=1, bias=False),
            nn.BatchNorm3d(channels),
        )
        self.act = nn.LeakyReLU(LEAKY_SLOPE)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.act(x + self.body(x))


class ResidualBlock2d(nn.Module):
    """Two 3x3 convolutions with BatchNorm, added to the (projected) input, then ReLU.

    With stride 2 or a change of width, the shortcut is a strided 1x1 convolution + BatchNorm.
    """

    def __init__(self, c_in: int, c_out: int | None = None, stride: int = 1):
        super().__init__()
        c_out = c_in if c_out is None else c_out
        self.body = nn.Sequential(
            nn.Conv2d(c_in, c_out, 3, stride=stride, padding=1, bias=False),
            nn.BatchNorm2d(c_out),
            nn.ReLU(),
            nn.Conv2d(c_out, c_out, 3, padding=1, bias=False),
            nn.BatchNorm2d(c_out),
        )
        self.shortcut = (
            nn.Identity()
            if stride == 1 and c_in == c_out
            else nn.Sequential(nn.Conv2d(c_in, c_out, 1, stride=stride, bias=False), nn.BatchNorm2d(c_out))
        )
        self.act = nn.ReLU()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.act(self.shortcut(x) + self.body(x))


class ResidualStack(nn.Module):
    """`count` residual blocks with one long skip around them all (none when count is 0)."""

    def __init__(self, block_factory: Callable[[], nn.Module], count: int):
        super().__init__()
        self.blocks = nn.Sequential(*(block_factory() for _ in range(count)))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.blocks(x) if len(self.blocks) else x


def cat_channels(tensors: list[torch.Tensor]) -> torch.Tensor:
    """(B, C, H, W) tensors joined along C, channels-last when all of them are (torch.cat would return a
    channels-first copy, and oneDNN's convolutions read channels-last at 256^2 about 1.4x faster)."""
    if len(tensors) == 1:
        return tensors[0]
    if all(t.dim() == 4 and t.is_contiguous(memory_format=torch.channels_last) for t in tensors):
        return torch.cat([t.permute(0, 2, 3, 1) for t in tensors], dim=3).permute(0, 3, 1, 2)
    return torch.cat(tensors, dim=1)
