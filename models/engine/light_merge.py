"""The light merge of the inference copy split in two, so a light edit does not redo the latent's half.

LightDecoder concatenates the latent with the light code, tiled (so constant over space), and
convolves. With a 1x1 merge (CompactConfig) the convolution is W_latent * latent + W_light * code
+ b: the first term depends on the latent alone and is kept for the last latent seen, the rest is
one number per channel. This saves the concatenation and the merge convolution on every light
edit; the features equal LightDecoder's up to float rounding.
"""

from __future__ import annotations

import torch
from torch import nn

from models.engine.onednn import OneDnnConv
from models.networks.nvr import LightDecoder, light_code


class SplitLightMerge(nn.Module):
    """LightDecoder (its merge a 1x1 OneDnnConv with ReLU) with the merge's latent half kept per latent.

    The latent is recognised by identity: the engine passes the same cached tensor while only the
    light changes. Do not modify a latent in place after passing it.
    """

    def __init__(self, decoder: LightDecoder):
        super().__init__()
        conv = decoder.merge[0]
        if not isinstance(conv, OneDnnConv) or tuple(conv.weight.shape[2:]) != (1, 1) or conv.activation != ("relu", []):
            raise ValueError("SplitLightMerge needs a 1x1 merge convolution on oneDNN with ReLU fused")
        latent_channels = conv.weight.shape[1] - decoder.light_mlp[-1].out_features
        self.latent_weight = nn.Parameter(conv.weight[:, :latent_channels].contiguous(memory_format=torch.channels_last),
                                          requires_grad=False)
        self.light_weight = nn.Parameter(conv.weight[:, latent_channels:, 0, 0].clone(), requires_grad=False)
        self.bias = conv.bias
        self.light_mlp, self.environment = decoder.light_mlp, decoder.environment
        self.blocks, self.decoder = decoder.blocks, decoder.decoder
        self._latent: torch.Tensor | None = None
        self._latent_half: torch.Tensor | None = None

    def forward(self, latent: torch.Tensor, light: torch.Tensor) -> torch.Tensor:
        if latent is not self._latent:
            self._latent_half = torch.ops.aten.mkldnn_convolution(latent, self.latent_weight, None, [0, 0], [1, 1], [1, 1], 1)
            self._latent = latent
        light_half = torch.addmm(self.bias, light_code(self.light_mlp, self.environment, light),
                                self.light_weight.t())  # (B, C)
        merged = torch.relu(self._latent_half + light_half[:, :, None, None])
        return self.decoder(self.blocks(merged))


def split_light_merge(model: nn.Module) -> nn.Module:
    """Give an inference copy (after use_onednn_convolutions) a SplitLightMerge where its merge is 1x1; returns it."""
    try:
        model.light_decoder = SplitLightMerge(model.light_decoder)
    except ValueError:
        pass  # a wider merge kernel reads neighbouring latent pixels and the padding: nothing to split
    return model
