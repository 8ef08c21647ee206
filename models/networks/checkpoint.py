"""Network weights on disk: safetensors (no pickle), with the architecture and configuration in its metadata.

Metadata keys (all strings): "format" = "nvr-studio-weights", "format_version", "architecture"
("nvr" or "nvr_plus"), "config" (JSON of NVRConfig.to_dict) and "extra" (JSON of the caller's
metadata, e.g. training steps and data set). Any file that does not match raises InputError.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import torch
from safetensors import SafetensorError, safe_open
from safetensors.torch import save_file

from models.networks.config import NVRConfig
from models.networks.nvr import ARCHITECTURES, NVR, NVRPlus, build_model
from renderer.errors import InputError
from renderer.io import atomic_path
from renderer.limits import MAX_WEIGHT_PARAMETERS

FORMAT_NAME = "nvr-studio-weights"
FORMAT_VERSION = 1
# safetensors' type names for the tensor types a network holds (float weights, integer BatchNorm counters).
SAFETENSORS_DTYPES = {"F32": torch.float32, "F16": torch.float16, "BF16": torch.bfloat16, "F64": torch.float64,
                      "I64": torch.int64, "I32": torch.int32, "U8": torch.uint8, "BOOL": torch.bool}


def save_model(path: str | Path, model: NVR | NVRPlus, config: NVRConfig, extra_metadata: dict[str, Any] | None = None) -> None:
    """Write the model's weights, architecture, config and `extra_metadata` (JSON-ready) atomically."""
    if config != model.config:
        raise ValueError("config differs from the model's own config")
    metadata = {
        "format": FORMAT_NAME,
        "format_version": str(FORMAT_VERSION),
        "architecture": model.architecture,
        "config": json.dumps(config.to_dict()),
        "extra": json.dumps(extra_metadata or {}, allow_nan=False),
    }
    tensors = {k: v.detach().cpu().contiguous() for k, v in model.state_dict().items()}
    try:
        with atomic_path(path) as tmp:
            save_file(tensors, str(tmp), metadata=metadata)
    except OSError as exc:
        raise InputError(f"cannot write: {exc.strerror or exc}", path) from None


def load_model(path: str | Path) -> tuple[NVR | NVRPlus, NVRConfig, dict[str, Any]]:
    """Read a weights file: (model in eval mode, its config, the extra metadata).

    Everything is checked before a layer is allocated (check_weights_file), so a file whose stored
    config asks for a network of many gigabytes is refused in a few megabytes.
    """
    path = Path(path)
    architecture, config, extra = check_weights_file(path)
    model = build_model(architecture, config)
    try:
        with safe_open(str(path), framework="pt") as f:
            state = {key: f.get_tensor(key) for key in f.keys()}
    except (SafetensorError, OSError) as exc:
        raise InputError(f"not a safetensors weights file ({' '.join(str(exc).split())})", path) from None
    model.load_state_dict(state)
    return model.eval(), config, extra


def check_weights_file(path: str | Path) -> tuple[str, NVRConfig, dict[str, Any]]:
    """Validate a weights file without loading its tensors: format, metadata, a size bound on the
    network its config describes, and every tensor's name, shape and type against that network
    (built on torch's meta device, which allocates nothing). Returns (architecture, config, extra)."""
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path)
    try:
        with safe_open(str(path), framework="pt") as f:
            metadata = f.metadata() or {}
            _check_format(metadata, path)
            architecture, config, extra = _parse_metadata(metadata, path)
            expected = network_shapes(architecture, config, path)
            keys = set(f.keys())
            _check_keys(keys, set(expected), architecture, config, path)
            for key in sorted(keys):
                stored = f.get_slice(key)
                shape, dtype = tuple(stored.get_shape()), SAFETENSORS_DTYPES.get(stored.get_dtype())
                if shape != tuple(expected[key].shape) or dtype != expected[key].dtype:
                    raise InputError(f"tensor {key} is {dtype or stored.get_dtype()} {shape}, the network expects "
                                     f"{expected[key].dtype} {tuple(expected[key].shape)}", path)
    except (SafetensorError, OSError) as exc:
        raise InputError(f"not a safetensors weights file ({' '.join(str(exc).split())})", path) from None
    return architecture, config, extra


def network_shapes(architecture: str, config: NVRConfig, path: str | Path | None = None) -> dict[str, torch.Tensor]:
    """The state dict a config describes, built on torch's meta device (shapes only, no memory),
    refused when the network would be larger than the product's limit."""
    with torch.device("meta"):
        expected = build_model(architecture, config).state_dict()
    parameters = sum(t.numel() for t in expected.values())
    if parameters > MAX_WEIGHT_PARAMETERS:
        raise InputError(f"the config describes a network of {parameters:,} parameters (at most {MAX_WEIGHT_PARAMETERS:,})", path)
    return expected


def _check_format(metadata: dict[str, str], path: Path) -> None:
    if metadata.get("format") != FORMAT_NAME:
        raise InputError("not an NVR Studio weights file (no format metadata)", path)
    if metadata.get("format_version") != str(FORMAT_VERSION):
        raise InputError(f"weights format version {metadata.get('format_version')!r}, "
                         f"this program reads version {FORMAT_VERSION}", path)


def _parse_metadata(metadata: dict[str, str], path: Path) -> tuple[str, NVRConfig, dict[str, Any]]:
    architecture = metadata.get("architecture")
    if architecture not in ARCHITECTURES:
        raise InputError(f"unknown architecture {architecture!r}", path)
    try:
        config = NVRConfig.from_dict(json.loads(metadata.get("config", "")))
        extra = json.loads(metadata.get("extra", "{}"))
    except (ValueError, TypeError) as exc:
        raise InputError(f"bad configuration in metadata: {exc}", path) from None
    return architecture, config, extra


def _check_keys(found: set[str], expected: set[str], architecture: str, config: NVRConfig, path: Path) -> None:
    missing, extra = sorted(expected - found), sorted(found - expected)
    if missing or extra:
        parts = []
        if missing:
            parts.append(f"{len(missing)} missing (e.g. {missing[0]})")
        if extra:
            parts.append(f"{len(extra)} unexpected (e.g. {extra[0]})")
        raise InputError(f"tensors do not match the {architecture} '{config.name}' network: {', '.join(parts)}", path)

