"""Network configurations: every width and size of NVR / NVR+ as data, saved with the weights.

`NVRConfig` holds the fields; each named configuration is a subclass that only sets defaults:
`PaperConfig` (the widths of the authors' reference implementation) and `CompactConfig`
(sized to render live on a 2-core CPU; see docs in the class). Any field can be overridden,
e.g. `PaperConfig(grid_size=32, output_size=64)` keeps the paper's structure at a tiny size.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, ClassVar

VOXEL_CHANNELS_IN = 4  # R, G, B, occupancy
LIGHT_DIMS = 3
IMAGE_CHANNELS = 3
# With environment_input, the light input goes on with the area light's switch and the object's material
# (roughness, specular, metallic), then the environment probe (renderer.environment.environment_probe), channels first.
LIGHTING_SCALARS = 4
PROBE_SIZE = 32
PROBE_DIMS = IMAGE_CHANNELS * PROBE_SIZE * PROBE_SIZE


@dataclass(frozen=True)
class NVRConfig:
    """All widths and sizes of the networks (fields without defaults: use a named subclass).

    Voxel branch: 3D conv blocks `voxel_channels` with `voxel_strides` and `voxel_kernels`,
    then `voxel_res_blocks` 3D residual blocks; projection folds depth into channels and a 1x1
    conv maps them to `latent_channels`; `pre_light_blocks` 2D residual blocks finish the latent.
    Light: 2 FC layers to `light_channels`, tiled and concatenated; a merge conv (`merge_kernel`)
    back to `latent_channels`, `post_light_blocks` residual blocks, a decoder doubling the size
    per entry of `decoder_channels` (conv kernel `decoder_kernel`). NVR+: a splat branch of
    `splat_layers` full-resolution convs of `splat_channels`, and a U-Net with one level per
    entry of `unet_channels` and `unet_mid_blocks` residual blocks in its middle.
    With `floor_light_input` the splat branch reads the splat and the lit empty floor (6 channels);
    with `shading_input` also the voxel shader's image and buffers, and the output is the shaded image
    corrected (models/networks/nvr.py).
    """

    name: ClassVar[str] = ""

    grid_size: int
    output_size: int
    voxel_channels: tuple[int, ...]
    voxel_strides: tuple[int, ...]
    voxel_kernels: tuple[int, ...]
    voxel_res_blocks: int
    latent_channels: int
    pre_light_blocks: int
    light_channels: int
    merge_kernel: int
    post_light_blocks: int
    decoder_channels: tuple[int, ...]
    decoder_kernel: int
    splat_channels: int
    splat_layers: int
    splat_kernel: int
    unet_channels: tuple[int, ...]
    unet_mid_blocks: int
    unet_kernel: int
    floor_light_input: bool  # NVR+ only: the splat branch also reads the lit empty floor (renderer/floor_light.py)
    perceptual_weight: float  # beta of the loss L1 + beta * perceptual
    # NVR+ only: the splat branch also reads the voxel shader's image and buffers (renderer/shading/), and the
    # network's output corrects the shaded image instead of drawing the image itself.
    shading_input: bool = False
    # With shading_input: the shader draws from a grid this many times finer than the network's (2 at 128^3: one
    # grid voxel per object voxel, where the network's grid merges two, so thin parts, silhouettes and texture keep
    # the object voxels' detail).
    shading_grid_factor: int = 1
    # With shading_input: the network works at 1/this of the image's side (its inputs area-averaged, its decoder one
    # doubling shorter per halving) and its correction is upsampled bilinearly and applied to the full-resolution
    # shaded image, which holds the detail (the full-resolution refiner's own correction, averaged to 128^2 and
    # upsampled, moved the test sets' MSE by 0.1-1.4).
    correction_downsampling: int = 1
    # The light input also holds the environment, the area light's switch and the object's material
    # (models/networks/nvr.py, lighting_input); an encoder turns them into a code added to the light's.
    environment_input: bool = False

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if isinstance(value, list):
                object.__setattr__(self, f.name, tuple(value))
        self._check()

    # --- derived sizes ------------------------------------------------------------------

    @property
    def voxel_downsampling(self) -> int:
        """Factor by which the voxel branch shrinks the grid (product of its strides)."""
        factor = 1
        for s in self.voxel_strides:
            factor *= s
        return factor

    @property
    def light_dims(self) -> int:
        """Width of the light input: the light's position, and with environment_input the scalars and the probe."""
        return LIGHT_DIMS + (LIGHTING_SCALARS + PROBE_DIMS if self.environment_input else 0)

    @property
    def shading_grid_size(self) -> int:
        """Side of the grid the voxel shader draws from (networks with shading_input)."""
        return self.grid_size * self.shading_grid_factor

    @property
    def network_size(self) -> int:
        """Side of the images the network's 2D layers work on (output_size / correction_downsampling)."""
        return self.output_size // self.correction_downsampling

    @property
    def latent_size(self) -> int:
        """Side of the 2D latent (the voxel grid's side after the strided 3D stages)."""
        return self.grid_size // self.voxel_downsampling

    # --- checks and (de)serialisation ---------------------------------------------------

    def _check(self) -> None:
        ints = [f.name for f in dataclasses.fields(self) if f.type == "int"]
        for key in ints:
            if not isinstance(getattr(self, key), int) or getattr(self, key) < 0:
                raise ValueError(f"config field {key} must be a non-negative integer, got {getattr(self, key)!r}")
        for key in ("voxel_channels", "voxel_strides", "voxel_kernels", "decoder_channels", "unet_channels"):
            values = getattr(self, key)
            if not values or not all(isinstance(v, int) and v > 0 for v in values):
                raise ValueError(f"config field {key} must be a non-empty list of positive integers, got {values!r}")
        if not len(self.voxel_strides) == len(self.voxel_kernels) == len(self.voxel_channels):
            raise ValueError("voxel_channels, voxel_strides and voxel_kernels must have the same length")
        if any(s not in (1, 2) for s in self.voxel_strides):
            raise ValueError("voxel_strides must be 1 or 2")
        if self.grid_size % self.voxel_downsampling:
            raise ValueError(f"grid_size {self.grid_size} is not divisible by the voxel downsampling {self.voxel_downsampling}")
        if self.correction_downsampling not in (1, 2, 4):
            raise ValueError(f"correction_downsampling must be 1, 2 or 4, got {self.correction_downsampling!r}")
        if self.correction_downsampling > 1 and not self.shading_input:
            raise ValueError("correction_downsampling above 1 needs shading_input (it upsamples a correction of the shaded image)")
        expected = self.latent_size * 2 ** len(self.decoder_channels) * self.correction_downsampling
        if self.output_size != expected:
            raise ValueError(f"output_size must be latent size x 2^(decoder stages) x correction_downsampling = {expected}, "
                             f"got {self.output_size}")
        if min(self.unet_channels) < 2:
            raise ValueError("unet_channels must be at least 2 (each level upsamples to half its width)")
        if self.network_size % 2 ** len(self.unet_channels):
            raise ValueError("output_size / correction_downsampling must be divisible by 2^(U-Net levels)")
        for key in ("grid_size", "latent_channels", "light_channels", "merge_kernel",
                    "decoder_kernel", "splat_channels", "splat_kernel", "unet_kernel"):
            if getattr(self, key) < 1:
                raise ValueError(f"config field {key} must be at least 1")
        if self.shading_grid_factor < 1:
            raise ValueError(f"shading_grid_factor must be at least 1, got {self.shading_grid_factor!r}")
        if self.environment_input and not self.shading_input:
            raise ValueError("environment_input needs shading_input (the network corrects the shader's image)")
        for key in ("floor_light_input", "shading_input", "environment_input"):
            if not isinstance(getattr(self, key), bool):
                raise ValueError(f"config field {key} must be true or false, got {getattr(self, key)!r}")
        if not self.perceptual_weight >= 0.0:
            raise ValueError(f"perceptual_weight must be >= 0, got {self.perceptual_weight!r}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form: the configuration's name and every field (tuples as lists)."""
        data: dict[str, Any] = {"name": self.name}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            data[f.name] = list(value) if isinstance(value, tuple) else value
        return data

    @staticmethod
    def from_dict(data: dict[str, Any]) -> NVRConfig:
        """Rebuild a configuration from `to_dict` output; unknown names or fields raise ValueError."""
        if not isinstance(data, dict) or data.get("name") not in CONFIGS:
            raise ValueError(f"unknown configuration name {data.get('name') if isinstance(data, dict) else data!r}")
        cls = CONFIGS[data["name"]]
        # Files written before these fields existed had no such inputs (and shaded the network's own grid).
        data = {"floor_light_input": False, "shading_input": False, "shading_grid_factor": 1, "correction_downsampling": 1,
                "environment_input": False, **data}
        fields = {f.name for f in dataclasses.fields(cls)}
        given = set(data) - {"name"}
        if given != fields:
            missing, extra = sorted(fields - given), sorted(given - fields)
            raise ValueError(f"configuration fields differ (missing {missing}, unexpected {extra})")
        return cls(**{k: data[k] for k in fields})


@dataclass(frozen=True)
class PaperConfig(NVRConfig):
    """The published widths (the authors' reference implementation): 128^3 voxels -> 256^2 image.

    Same stages, widths, kernels and block counts as the reference; where this code differs:
    2D blocks use ReLU (the paper's text) instead of leaky ReLU, the light FCs have a ReLU
    between them, the U-Net upsamples by transposed convolution like the decoder does, and its
    middle blocks get the same long skip as the other residual stacks.
    """

    name: ClassVar[str] = "paper"

    grid_size: int = 128
    output_size: int = 256
    voxel_channels: tuple[int, ...] = (16, 16, 16, 32, 32)
    voxel_strides: tuple[int, ...] = (2, 1, 2, 1, 1)
    voxel_kernels: tuple[int, ...] = (4, 4, 4, 4, 4)
    voxel_res_blocks: int = 5
    latent_channels: int = 512
    pre_light_blocks: int = 5
    light_channels: int = 64
    merge_kernel: int = 4
    post_light_blocks: int = 5
    decoder_channels: tuple[int, ...] = (128, 64, 32)
    decoder_kernel: int = 4
    splat_channels: int = 32
    splat_layers: int = 2
    splat_kernel: int = 4
    unet_channels: tuple[int, ...] = (128, 256, 512)
    unet_mid_blocks: int = 3
    unet_kernel: int = 4
    floor_light_input: bool = False  # the paper's inputs only
    perceptual_weight: float = 0.002


@dataclass(frozen=True)
class CompactConfig(NVRConfig):
    """Sized for live editing on a 2-core CPU at 256^2 (widths chosen by measured forward time).

    NVR+ at batch 1: a full frame is 4.4 GFLOP and a light edit (render_from_latent) 2.2 GFLOP
    (benchmarks/bench_networks.py; their times in docs/benchmarks.md).
    - The two strided 3D stages are non-overlapping 2x2x2 patches: a 4^3 kernel at 128^3 costs
      8x more (1 GFLOP for only 8 channels). One 3x3x3 convolution then works at 32^3.
    - 24 channels at 32^3, because at batch 1 torch runs 3D convolutions with kernels <= 3 on a
      slow reference path unless channels x 32 x 32 > 20480 (16 channels ran 10x slower).
    - A 96-channel latent with 2 residual blocks before and 2 after the light merge, which is
      1x1 since the tiled light code is constant over space.
    - Full-resolution layers are 8 channels wide (a 3x3 16->16 conv at 256^2 is 0.3 GFLOP) and
      the U-Net has two levels (16, 32).
    - The splat branch also reads the lit empty floor (renderer/floor_light.py): a network this small
      learned the light's spot and fall-off on the floor slowly, and that was most of its error.
    """

    name: ClassVar[str] = "compact"

    grid_size: int = 128
    output_size: int = 256
    voxel_channels: tuple[int, ...] = (8, 24, 24)
    voxel_strides: tuple[int, ...] = (2, 2, 1)
    voxel_kernels: tuple[int, ...] = (2, 2, 3)
    voxel_res_blocks: int = 0
    latent_channels: int = 96
    pre_light_blocks: int = 2
    light_channels: int = 32
    merge_kernel: int = 1
    post_light_blocks: int = 2
    decoder_channels: tuple[int, ...] = (32, 16, 8)
    decoder_kernel: int = 3
    splat_channels: int = 8
    splat_layers: int = 2
    splat_kernel: int = 3
    unet_channels: tuple[int, ...] = (16, 32)
    unet_mid_blocks: int = 1
    unet_kernel: int = 3
    floor_light_input: bool = True
    perceptual_weight: float = 0.002


@dataclass(frozen=True)
class ShaderRefinerConfig(CompactConfig):
    """The compact NVR+ refining the voxel shader: its splat branch reads the splat and the shader's image
    and buffers (renderer/shading/: soft shadows, the lit floor, normals, albedo), and it outputs a
    per-pixel correction of the shaded image, so an untrained network renders the shaded image and
    training spends the network on what the shader misses. The shaded image holds the lit floor, so the
    separate lit-floor input is off. The shader draws from a 256^3 grid, which errs less than the network's 128^3
    (docs/results.md, "Design choices, measured")."""

    name: ClassVar[str] = "shader_refiner"

    floor_light_input: bool = False
    shading_input: bool = True
    shading_grid_factor: int = 2


@dataclass(frozen=True)
class HalfResolutionRefinerConfig(ShaderRefinerConfig):
    """The shader refiner at half the image's side: its splat branch and U-Net work at 128^2 on the area-averaged
    256^2 inputs, its decoder stops at 128^2, and its correction is upsampled bilinearly onto the full-resolution
    shaded image. The full-resolution layers of the shader refiner are thin (8 channels) and run far below the
    CPU's peak, so halving the side nearly halves a light edit (docs/results.md, "Measurements behind the code")."""

    name: ClassVar[str] = "half_res_refiner"

    decoder_channels: tuple[int, ...] = (32, 16)
    correction_downsampling: int = 2


@dataclass(frozen=True)
class EnvironmentRefinerConfig(HalfResolutionRefinerConfig):
    """The shipped refiner (half resolution, one residual block after the light merge) that also reads the scene's
    environment as a 32x32 probe (the paper's "Increasing realism" input), whether the area light is on, and the
    object's material. Their code is added to the light's and starts at zero, so from the shipped weights
    (`nvr train --init`) it renders what they render."""

    name: ClassVar[str] = "environment_refiner"

    post_light_blocks: int = 1
    environment_input: bool = True


CONFIGS: dict[str, type[NVRConfig]] = {cls.name: cls for cls in (CompactConfig, PaperConfig, ShaderRefinerConfig,
                                                                   HalfResolutionRefinerConfig,
                                                                   EnvironmentRefinerConfig)}
