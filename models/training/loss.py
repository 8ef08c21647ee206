"""The training loss of equation 2: L1 + beta * perceptual, beta = config.perceptual_weight.

Default beta (2e-3, in models/networks/config.py) balances the two terms by error type, measured on a
synthetic 256^2 scene: for a slight blur (sigma 1 px) the perceptual term is about 4x the L1
term (it is what sharpens the output), for a uniform colour shift of 3/255 the L1 term is about
5x the perceptual one (L1 keeps colours right), for noise they are about equal.
"""

from __future__ import annotations

from pathlib import Path

import torch
from torch import nn

from models.training.perceptual import PerceptualLoss


class RenderLoss(nn.Module):
    """Batch-mean L1 on [0, 1] images plus beta times the batch-mean perceptual distance.

    Returns (total, parts) with parts = {"l1": float, "perceptual": float} for logging;
    `weights_name` names the VGG weights the perceptual term uses.
    """

    def __init__(self, perceptual_weight: float, weights_path: str | Path | None = None):
        super().__init__()
        self.perceptual_weight = perceptual_weight
        self.perceptual = PerceptualLoss(weights_path)
        self.weights_name = self.perceptual.weights_name

    def forward(self, images: torch.Tensor, targets: torch.Tensor,
                crop: tuple[int, int, int] | None = None) -> tuple[torch.Tensor, dict[str, float]]:
        """L1 over the whole images; the perceptual term over the (top, left, side) crop when given."""
        l1 = (images - targets).abs().mean()
        if crop is not None:
            top, left, side = crop
            images = images[..., top : top + side, left : left + side]
            targets = targets[..., top : top + side, left : left + side]
        perceptual = self.perceptual(images, targets).mean()
        total = l1 + self.perceptual_weight * perceptual
        return total, {"l1": float(l1.detach()), "perceptual": float(perceptual.detach())}
