"""Where the shipped weights lie, by network architecture: the engine finds them without the training code."""

from __future__ import annotations

from pathlib import Path

from renderer.errors import InputError

ASSET_MODELS = Path(__file__).resolve().parents[2] / "assets" / "models"
# NVR+ refines the voxel shader at half the image's side (one block after the light merge), trained further on scenes
# of several objects; the other files in assets/models stay for comparison (docs/results.md, "The renderers").
SHIPPED_WEIGHTS = {"nvr_plus": ASSET_MODELS / "nvrplus_several_objects.safetensors",
                   "nvr": ASSET_MODELS / "nvr_compact.safetensors"}


def shipped_weights(architecture: str) -> Path:
    """The weights file shipped in assets/models for a network architecture ('nvr_plus' or 'nvr')."""
    path = SHIPPED_WEIGHTS[architecture]
    if not path.is_file():
        raise InputError(f"no shipped {architecture} model yet; train one with `nvr train` and pass --model", path)
    return path
