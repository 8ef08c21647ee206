"""The voxel branch computed only around the object: the ground's features once, the object's in a crop.

Without its object the grid holds only the ground, which depends on the camera elevation and
the floor color alone; its features (`Background`) are computed once per pair. An object changes
only the outputs whose receptive field reaches one of its voxels. `plan` finds them with the
arithmetic of models/engine/receptive.py; `encode` runs the network's own layers on a crop of the grid
that holds everything those outputs read (snapped to the strides, so the crop's outputs line up
with the full grid's) and pastes them over the background: first the 3D stack, then the
depth-folding projection and the 2D blocks over the changed latent rows and columns.
The ground is the same in every grid column (the camera has no roll), so the background is
computed from a ground grid only a few columns wide (`NarrowGround`): its outputs next to the
two sides are those of the full grid's sides, and its middle column is every column between.
The 3D stack reaches fewer columns than the 2D blocks after it, so it runs on the narrowest
ground for itself (`narrow_volume`), and its output is widened for the 2D blocks (`narrow`).
Both equal VoxelEncoder on the full grid up to float rounding (tests/test_engine.py).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import torch

from models.engine.receptive import ConvChain, Span, conv_chain
from models.networks.nvr import VoxelEncoder


@dataclass(frozen=True)
class Background:
    """Features of the ground-only grid: the 3D stack's output (1, C, d, h, w), the projection unit's (1, L, h, w)
    and the latent (1, L, h, w)."""

    volume: torch.Tensor
    projected: torch.Tensor
    latent: torch.Tensor


@dataclass(frozen=True)
class NarrowGround:
    """A ground grid `width` columns wide gives the full grid's background: its output columns before
    `middle` are the full grid's first ones, those after it the last ones, and `middle` all the others."""

    width: int
    middle: int


@dataclass(frozen=True)
class CropPlan:
    """Where an object's voxels change the voxel branch, and the crops that recompute it exactly."""

    grid: tuple[slice, slice, slice]  # grid region the 3D stack runs on
    volume: tuple[Span, Span, Span]  # 3D stack outputs that change
    plane_read: tuple[Span, Span]  # latent rows and columns the 2D blocks run on
    plane: tuple[Span, Span]  # latent rows and columns that change

    def grid_fraction(self, grid_size: int) -> float:
        """Share of the grid's voxels inside the crop."""
        return math.prod(s.stop - s.start for s in self.grid) / grid_size**3


class CroppedVoxelEncoder:
    """`VoxelEncoder.forward` as background + object crop (same weights, same layers)."""

    def __init__(self, encoder: VoxelEncoder, grid_size: int):
        self.encoder = encoder
        self.grid_size = grid_size
        self.volume_chain = conv_chain(itertools.chain(encoder.stages.modules(), encoder.residual.modules()), 3)
        self.plane_chain = conv_chain(encoder.blocks.modules(), 2)
        self.volume_size = self.volume_chain.sizes((grid_size,) * 3)[-1]
        volume_columns = [c.along(2) for c in self.volume_chain.convs]
        self.narrow_volume = narrow_ground(ConvChain(volume_columns, 1), grid_size)
        self.narrow = narrow_ground(ConvChain(volume_columns + [c.along(1) for c in self.plane_chain.convs], 1), grid_size)

    def background(self, ground: torch.Tensor) -> Background:
        """Features of the ground-only grid (1, 4, D, H, W), run once per elevation and floor color.

        W is the full grid size, or `self.narrow_volume.width` for a ground that is the same in every column.
        """
        width, narrow = ground.shape[-1], self.narrow_volume
        if width != self.grid_size and (narrow is None or width != narrow.width):
            raise ValueError(f"a ground grid {width} columns wide: expected {self.grid_size} or the narrow width")
        volume = self.encoder.residual(self.encoder.stages(ground))
        if width == self.grid_size:
            projected = self._project(volume)
            return Background(volume, projected, self.encoder.blocks(projected))
        columns = self.volume_size[2]
        # The 2D blocks run on the 3D stack's output as it is on `self.narrow` (on every column if there is none).
        plane_columns = columns if self.narrow is None else self.narrow.width // self.volume_chain.total_stride[2]
        projected = self._project(_widen(volume, narrow.middle, plane_columns))  # per column: widens like the volume
        latent = self.encoder.blocks(projected)
        if self.narrow is not None:
            latent = _widen(latent, self.narrow.middle, columns)
        return Background(_widen(volume, narrow.middle, columns), _widen(projected, narrow.middle, columns), latent)

    def plan(self, object_spans: tuple[Span, Span, Span]) -> CropPlan | None:
        """The crops for an object whose voxels lie in the grid spans `object_spans`; None if it changes nothing."""
        grid = (self.grid_size,) * 3
        volume = self.volume_chain.changed_outputs(object_spans, grid)
        if volume is None:
            return None
        needed = self.volume_chain.needed_inputs(volume, grid)
        strides = self.volume_chain.total_stride
        crop = tuple(slice(lo // s * s, min(n, -(-hi // s) * s)) for (lo, hi), s, n in zip(needed, strides, grid))
        latent_size = self.volume_size[1:]
        plane = self.plane_chain.changed_outputs(volume[1:], latent_size)
        return CropPlan(crop, volume, self.plane_chain.needed_inputs(plane, latent_size), plane)

    def encode(self, background: Background, plan: CropPlan, grid_crop: torch.Tensor) -> torch.Tensor:
        """The latent of the whole scene from the background and the grid inside `plan.grid` (1, 4, d, h, w)."""
        return self.encode_features(background, plan, grid_crop).latent

    def encode_features(self, background: Background, plan: CropPlan, grid_crop: torch.Tensor) -> Background:
        """Every feature of the whole grid (`background` is any grid's features, the ground's or a scene's last;
        `grid_crop` the new grid inside `plan.grid`, which holds every voxel that differs from it): the next edit's
        background."""
        crop_volume = self.encoder.residual(self.encoder.stages(grid_crop))
        offsets = [s.start // t for s, t in zip(plan.grid, self.volume_chain.total_stride)]
        # The projection is per latent pixel: only the changed rows and columns (every depth of them) are redone.
        (d0, d1), (r0, r1), (c0, c1) = plan.volume
        volume = background.volume.clone()
        volume[..., d0:d1, r0:r1, c0:c1] = crop_volume[(..., *_slices(plan.volume, offsets))]
        projected = background.projected.clone()
        projected[..., r0:r1, c0:c1] = self._project(volume[..., r0:r1, c0:c1])
        (r0, r1), (c0, c1) = plan.plane_read
        features = self.encoder.blocks(projected[..., r0:r1, c0:c1])
        latent = background.latent.clone()
        latent[(..., *_slices(plan.plane))] = features[(..., *_slices(plan.plane, (r0, c0)))]
        return Background(volume, projected, latent)

    def _project(self, volume: torch.Tensor) -> torch.Tensor:
        """The projection unit: depth folded into channels, then the 1x1 convolution (as VoxelEncoder does)."""
        b, c, d, h, w = volume.shape
        return self.encoder.projection(volume.reshape(b, c * d, h, w))


def narrow_ground(columns: ConvChain, grid_size: int) -> NarrowGround | None:
    """The narrowest ground grid that gives every output column of the full one (see NarrowGround), from the
    one-axis chain of all convolutions along the columns; None if it would not be narrower than the grid."""
    contact = columns.border_contact(grid_size)
    first = next((i for i, (before, _) in enumerate(contact) if not before), len(contact))  # reached by the start's padding
    last = next((i for i, (_, after) in enumerate(reversed(contact)) if not after), len(contact))  # ... by the end's
    stride = columns.total_stride[0]
    for width in range((first + last + 1) * stride, grid_size, stride):
        narrow = columns.border_contact(width)
        if (len(narrow) - first - 1 >= last and not any(after for _, after in narrow[:first + 1])
                and not any(before for before, _ in narrow[first:])):
            return NarrowGround(width, first)
    return None


def _widen(narrow: torch.Tensor, middle: int, columns: int) -> torch.Tensor:
    """Repeat the middle column of `narrow` so it is `columns` wide (last axis)."""
    repeats = columns - narrow.shape[-1] + 1
    fill = narrow[..., middle:middle + 1].expand(*narrow.shape[:-1], repeats)
    return torch.cat([narrow[..., :middle], fill, narrow[..., middle + 1:]], dim=-1)


def _slices(spans: tuple[Span, ...], offsets: tuple[int, ...] | list[int] | None = None) -> tuple[slice, ...]:
    offsets = offsets or (0,) * len(spans)
    return tuple(slice(lo - o, hi - o) for (lo, hi), o in zip(spans, offsets))
