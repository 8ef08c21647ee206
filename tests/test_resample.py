"""Float image resizing (renderer.resample): area averages when made smaller, float values kept, shapes kept."""

import numpy as np
from PIL import Image

from renderer.resample import downscaled, resized


def test_downscaling_by_two_averages_each_two_by_two_block():
    image = np.arange(4 * 6 * 3, dtype=np.float64).reshape(4, 6, 3) / 100.0
    small = downscaled(image, 3)
    expected = image.reshape(2, 2, 3, 2, 3).mean(axis=(1, 3))
    assert small.shape == (2, 3, 3) and small.dtype == np.float32
    np.testing.assert_allclose(small, expected, atol=1e-6)


def test_an_image_already_small_enough_is_returned_unchanged():
    image = np.random.default_rng(0).random((5, 7, 3))
    assert downscaled(image, 7) is image


def test_values_outside_eight_bits_survive_and_a_single_channel_stays_two_dimensional():
    image = np.array([[-2.0, 1e-4], [3.5, 1000.0]], dtype=np.float64)
    nearest = resized(image, (4, 4), Image.Resampling.NEAREST)
    assert nearest.shape == (4, 4)
    np.testing.assert_array_equal(nearest[::2, ::2], image.astype(np.float32))
    assert resized(image, (1, 1)).item() == np.float32(image.mean())
