"""The shader's compiled volume filters (renderer/shading/filters.py) against scipy.ndimage and numpy, to the last bit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from renderer.shading.filters import block_mean2, connected_to_border, gaussian_blur, minimum_filter, occupied_indices

SHAPES = [(1, 1, 1), (2, 3, 1), (5, 1, 7), (4, 9, 3), (17, 12, 23)]


def volume(shape, seed=0) -> np.ndarray:
    return (np.random.default_rng(seed).random(shape) * 10.0).astype(np.float32)


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("sigma", [1.0, 1.118, 1.25, 4.0])
def test_gaussian_blur_is_scipys(shape, sigma):
    """Including volumes thinner than the kernel, where scipy's reflected border folds more than once."""
    v = volume(shape)
    np.testing.assert_array_equal(gaussian_blur(v, sigma, 2.5), ndimage.gaussian_filter(v, sigma, truncate=2.5))


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("size", [1, 3, 5])
def test_minimum_filter_is_scipys(shape, size):
    v = volume(shape, 1)
    np.testing.assert_array_equal(minimum_filter(v, size), ndimage.minimum_filter(v, size))


def test_minimum_filter_refuses_an_even_size():
    with pytest.raises(ValueError, match="odd"):
        minimum_filter(volume((3, 3, 3)), 4)


@pytest.mark.parametrize("shape", SHAPES)
def test_block_mean_is_the_mean_over_zero_padded_blocks(shape):
    occupied = np.random.default_rng(2).random(shape) < 0.4
    padded = np.pad(occupied.astype(np.float32), [(0, n % 2) for n in shape])
    blocks = padded.reshape(padded.shape[0] // 2, 2, padded.shape[1] // 2, 2, padded.shape[2] // 2, 2)
    np.testing.assert_array_equal(block_mean2(occupied), blocks.mean(axis=(1, 3, 5)))


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("density", [0.0, 0.3, 0.6, 1.0])
def test_connected_to_border_is_the_outside_component(shape, density):
    """Random mazes (many sweeps to converge) against scipy's labelling of the free voxels padded by free ones."""
    blocked = np.random.default_rng(3).random(shape) < density
    labels, _ = ndimage.label(np.pad(~blocked, 1, constant_values=True))
    outside = (labels[1:-1, 1:-1, 1:-1] == labels[0, 0, 0]) & ~blocked
    np.testing.assert_array_equal(connected_to_border(blocked), outside)


def test_a_closed_box_keeps_its_inside():
    blocked = np.zeros((9, 9, 9), dtype=bool)
    blocked[2:7, 2:7, 2:7] = True
    blocked[3:6, 3:6, 3:6] = False  # a hollow cube: its cavity is not reached
    reached = connected_to_border(blocked)
    assert not reached[3:6, 3:6, 3:6].any() and reached[0].all() and reached.sum() == 9**3 - 5**3


@pytest.mark.parametrize("shape", [(1, 1, 1), (0, 3, 4), (5, 7, 4), (20, 31, 17)])
@pytest.mark.parametrize("density", [0.0, 0.05, 1.0])
def test_occupied_indices_are_numpys_argwhere(shape, density):
    mask = np.random.default_rng(4).random(shape) < density
    np.testing.assert_array_equal(occupied_indices(mask), np.argwhere(mask).reshape(-1, 3))
