"""The engine's compiled passes over the network's image inputs and output against torch's operations."""

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from models.engine.image_passes import apply_correction, join_and_pool


def _tensor(image: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(image)).permute(2, 0, 1)[None]


@pytest.mark.parametrize("factor", [1, 2, 3])
def test_join_and_pool_is_torch_concatenation_then_average_pool(factor):
    rng = np.random.default_rng(factor)
    images = [rng.random((24, 24, 3), dtype=np.float32), rng.standard_normal((24, 24, 13), dtype=np.float32)]
    expected = F.avg_pool2d(torch.cat([_tensor(image) for image in images], dim=1), factor)
    got = join_and_pool(images, factor)
    assert got.shape == (24 // factor, 24 // factor, 16)
    np.testing.assert_allclose(got, expected[0].permute(1, 2, 0).numpy(), rtol=0, atol=1e-6)


@pytest.mark.parametrize("factor", [1, 2, 4])
def test_apply_correction_is_torch_upsampling_then_gain_and_offset(factor):
    rng = np.random.default_rng(factor)
    size = 32
    correction = rng.standard_normal((size // factor, size // factor, 6), dtype=np.float32) * 0.5
    buffers = rng.random((size, size, 13), dtype=np.float32)  # the shaded image is their first three channels
    up = _tensor(correction)
    if factor > 1:
        up = F.interpolate(up, scale_factor=factor, mode="bilinear", align_corners=False)
    expected = (_tensor(buffers[..., :3]) * up[:, :3].exp() + up[:, 3:]).clamp(0.0, 1.0)[0].permute(1, 2, 0).numpy()
    got = apply_correction(correction, buffers[..., :3])
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-6)
    assert 0.0 < got.mean() < 1.0 and (got == 1.0).any() and (got == 0.0).any()  # both clamps were exercised


def test_apply_correction_gives_no_nan_or_inf():
    correction = np.zeros((4, 4, 6), dtype=np.float32)
    correction[0, 0, 0] = 200.0  # exp overflows to inf: the pixel saturates
    correction[3, 3, 3] = np.nan  # an offset that is not a number: the pixels it reaches show black
    shaded = np.full((8, 8, 3), 0.5, dtype=np.float32)
    image = apply_correction(correction, shaded)
    assert np.all(np.isfinite(image)) and image.min() >= 0.0 and image.max() <= 1.0
    assert image[0, 0, 0] == 1.0 and image[7, 7, 0] == 0.0 and image[3, 4, 0] == 0.5
