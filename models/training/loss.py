"""The training loss of equation 2, L1 + beta * perceptual (beta = config.perceptual_weight), plus an optional
squared-error term, gamma * MSE (gamma = TrainConfig.mse_weight, 0 in the paper's loss).

Default beta (2e-3, in models/networks/config.py) balances the two terms by error type, measured on a
synthetic 256^2 scene: for a slight blur (sigma 1 px) the perceptual term is about 4x the L1
term (it is what sharpens the output), for a uniform colour shift of 3/255 the L1 term is about
5x the perceptual one (L1 keeps colours right), for noise they are about equal.

Why a squared term: where the inputs cannot tell what the target holds (a texture finer than the voxels,
a seam the voxels merge), L1 is least for the median of the possible targets, MSE for their mean; the
evaluation measures MSE. Per pixel, the squared term's gradient equals L1's at an error of 1 / (2 gamma).
"""

from __future__ import annotations

from pathlib import Path

import torch
from torch import nn

from models.training.perceptual import PerceptualLoss


class RenderLoss(nn.Module):
    """Batch-mean L1 on [0, 1] images, plus beta times the batch-mean perceptual distance, plus gamma times the MSE.

    Returns (total, parts) with parts = {"l1": float, "perceptual": float, "mse": float} for logging;
    `weights_name` names the VGG weights the perceptual term uses.
    """

    def __init__(self, perceptual_weight: float, weights_path: str | Path | None = None, mse_weight: float = 0.0):
        super().__init__()
        self.perceptual_weight = perceptual_weight
        self.mse_weight = mse_weight
        self.perceptual = PerceptualLoss(weights_path)
        self.weights_name = self.perceptual.weights_name

    def forward(self, images: torch.Tensor, targets: torch.Tensor,
                crop: tuple[int, int, int] | None = None) -> tuple[torch.Tensor, dict[str, float]]:
        """L1 over the whole images; the perceptual term over the (top, left, side) crop when given."""
        difference = images - targets
        l1 = difference.abs().mean()
        mse = difference.square().mean()
        if crop is not None:
            top, left, side = crop
            images = images[..., top : top + side, left : left + side]
            targets = targets[..., top : top + side, left : left + side]
        perceptual = self.perceptual(images, targets).mean()
        total = l1 + self.perceptual_weight * perceptual + self.mse_weight * mse
        return total, {"l1": float(l1.detach()), "perceptual": float(perceptual.detach()), "mse": float(mse.detach())}
