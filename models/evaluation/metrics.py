"""The paper's table 1 metrics, one implementation: MSE (0-255 scale), DSSIM and the perceptual distance.

All functions take sRGB image batches (B, 3, H, W) in [0, 1] and return one value per image (B,).
- MSE: mean over pixels and channels of the squared difference on the 0-255 scale.
- DSSIM = (1 - SSIM) / 2, SSIM after Wang et al. 2004: 11x11 Gaussian window (sigma 1.5), only
  windows fully inside the image, constants C1 = (0.01 L)^2 and C2 = (0.03 L)^2 with L = 1 (the
  data range of [0, 1] images), computed per channel in float64 and averaged over channels.
- perceptual: the loss term of equation 2 (models/training/perceptual.py), same layers and weights.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F

from models.training.perceptual import PerceptualLoss

SSIM_WINDOW = 11
SSIM_SIGMA = 1.5
SSIM_K1, SSIM_K2 = 0.01, 0.03
DATA_RANGE = 1.0


def _check_pair(images: torch.Tensor, targets: torch.Tensor) -> None:
    if images.shape != targets.shape or images.ndim != 4:
        raise ValueError(f"need two (B, C, H, W) batches of one shape, got {tuple(images.shape)} and {tuple(targets.shape)}")


def mse_255(images: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """Per-image mean squared error on the 0-255 scale."""
    _check_pair(images, targets)
    return ((images.double() - targets.double()) * 255.0).pow(2).mean(dim=(1, 2, 3))


def gaussian_window(size: int = SSIM_WINDOW, sigma: float = SSIM_SIGMA) -> torch.Tensor:
    """Normalised 2D Gaussian window (size x size), float64."""
    x = torch.arange(size, dtype=torch.float64) - (size - 1) / 2
    g = torch.exp(-(x**2) / (2 * sigma**2))
    g = g / g.sum()
    return g[:, None] * g[None, :]


def ssim(images: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """Per-image mean SSIM over all full windows and channels; images must be at least 11x11."""
    _check_pair(images, targets)
    if min(images.shape[2:]) < SSIM_WINDOW:
        raise ValueError(f"SSIM needs images of at least {SSIM_WINDOW}x{SSIM_WINDOW}, got {tuple(images.shape[2:])}")
    b, c, h, w = images.shape
    x = images.double().reshape(b * c, 1, h, w)
    y = targets.double().reshape(b * c, 1, h, w)
    window = gaussian_window().to(x.device)[None, None]

    def local_mean(t: torch.Tensor) -> torch.Tensor:
        return F.conv2d(t, window)

    mu_x, mu_y = local_mean(x), local_mean(y)
    var_x = local_mean(x * x) - mu_x**2
    var_y = local_mean(y * y) - mu_y**2
    cov = local_mean(x * y) - mu_x * mu_y
    c1, c2 = (SSIM_K1 * DATA_RANGE) ** 2, (SSIM_K2 * DATA_RANGE) ** 2
    ssim_map = ((2 * mu_x * mu_y + c1) * (2 * cov + c2)) / ((mu_x**2 + mu_y**2 + c1) * (var_x + var_y + c2))
    return ssim_map.reshape(b, c, -1).mean(dim=(1, 2))


def dssim(images: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
    """Per-image structural dissimilarity (1 - SSIM) / 2, in [0, 1]."""
    return (1.0 - ssim(images, targets)) / 2.0


class ImageMetrics:
    """The three table 1 metrics per image; `perceptual.weights_name` tells which VGG weights were used."""

    def __init__(self, perceptual: PerceptualLoss | None = None):
        self.perceptual = PerceptualLoss() if perceptual is None else perceptual

    @torch.no_grad()
    def __call__(self, images: torch.Tensor, targets: torch.Tensor) -> dict[str, torch.Tensor]:
        return {
            "mse": mse_255(images, targets),
            "dssim": dssim(images, targets),
            "perceptual": self.perceptual(images.float(), targets.float()).double(),
        }
