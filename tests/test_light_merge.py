"""The split light merge (models/engine/light_merge.py): equal to the plain light decoder, per latent and per light."""

from __future__ import annotations

import torch

from models.engine.light_merge import SplitLightMerge, split_light_merge
from models.engine.onednn import use_onednn_convolutions
from models.networks.inference import prepare_for_inference
from models.networks.nvr import LightDecoder
from tests.test_engine import TINY_COMPACT, TINY_PAPER, random_model


def test_split_merge_equals_the_plain_decoder_as_latents_and_lights_change(single_thread):
    plain = use_onednn_convolutions(prepare_for_inference(random_model(TINY_COMPACT)))
    split = split_light_merge(use_onednn_convolutions(prepare_for_inference(random_model(TINY_COMPACT))))
    assert isinstance(split.light_decoder, SplitLightMerge)
    gen = torch.Generator().manual_seed(0)
    latents = [torch.randn(1, 16, 16, 16, generator=gen) for _ in range(2)]
    lights = [torch.tensor([[0.3, 0.9, -0.8]]), torch.tensor([[-1.0, 0.2, -0.4]])]
    features = torch.rand(1, 4, 64, 64, generator=gen)
    with torch.inference_mode():
        for latent, light in [(0, 0), (0, 1), (1, 1), (0, 0)]:  # a new light, a new latent, back to the first
            expected = plain.render_from_latent(latents[latent], lights[light], features)
            image = split.render_from_latent(latents[latent], lights[light], features)
            torch.testing.assert_close(image, expected, rtol=0, atol=1e-6)
        assert (plain.render_from_latent(latents[0], lights[1], features) - expected).abs().max() > 1e-4  # light matters


def test_a_wider_merge_kernel_is_left_as_it_is():
    model = split_light_merge(use_onednn_convolutions(prepare_for_inference(random_model(TINY_PAPER))))
    assert type(model.light_decoder) is LightDecoder  # its 4x4 merge reads neighbours and the padding
