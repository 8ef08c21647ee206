"""Float image resizing (renderer.resample): area averages when made smaller, float values kept, shapes kept."""

import numpy as np
from PIL import Image

from renderer.capture.capture import mask_at_size
from renderer.resample import downscaled, downscaled_mask, resized


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


def test_a_thin_part_of_a_mask_survives_downscaling_at_every_offset():
    """A bar of 1-2 pixels (about half of the 3.2 that make a new pixel) keeps a line of pixels wherever it stands;
    the nearest pixel, sampled every 3.2 pixels, misses it at some offsets (a chair's leg lost from a segmentation
    prior)."""
    missed_by_nearest = 0
    for offset in range(10):
        mask = np.zeros((1024, 1024), dtype=bool)
        start = 500 + offset / 3.0
        columns = (np.arange(1024) + 0.5 >= start) & (np.arange(1024) + 0.5 < start + 1.6)
        mask[100:900, columns] = True
        small = downscaled_mask(mask, 320)
        assert small.shape == (320, 320)
        assert small[40:270].any(axis=1).all() and not small[:, :150].any()
        missed_by_nearest += not mask_at_size(mask, (320, 320)).any()
    assert missed_by_nearest > 0
