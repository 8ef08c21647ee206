"""The voxel branch computed only around the object: the ground's features once, the object's in a crop.

Without its object the grid holds only the ground, which depends on the camera elevation and
the floor color alone; its features (`Background`) are computed once per pair. An object changes
only the outputs whose receptive field reaches one of its voxels. `plan` finds them with the
arithmetic of models/receptive.py; `encode` runs the network's own layers on a crop of the grid
that holds everything those outputs read (snapped to the strides, so the crop's outputs line up
with the full grid's) and pastes them over the background: first the 3D stack, then the
depth-folding projection and the 2D blocks over the changed latent rows and columns.
The result equals VoxelEncoder on the full grid up to float rounding (tests/test_engine.py).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import torch

from models.nvr import VoxelEncoder
from models.receptive import Span, conv_chain


@dataclass(frozen=True)
class Background:
    """Features of the ground-only grid: the 3D stack's output (1, C, d, h, w) and the latent (1, L, h, w)."""

    volume: torch.Tensor
    latent: torch.Tensor


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

    def background(self, ground: torch.Tensor) -> Background:
        """Features of the ground-only grid (1, 4, D, H, W): the full network, run once per elevation and floor color."""
        volume = self.encoder.residual(self.encoder.stages(ground))
        return Background(volume, self.encoder.blocks(self._project(volume)))

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
        crop_volume = self.encoder.residual(self.encoder.stages(grid_crop))
        offsets = [s.start // t for s, t in zip(plan.grid, self.volume_chain.total_stride)]
        volume = background.volume.clone()
        volume[(..., *_slices(plan.volume))] = crop_volume[(..., *_slices(plan.volume, offsets))]
        (r0, r1), (c0, c1) = plan.plane_read
        features = self.encoder.blocks(self._project(volume[..., r0:r1, c0:c1]))
        latent = background.latent.clone()
        latent[(..., *_slices(plan.plane))] = features[(..., *_slices(plan.plane, (r0, c0)))]
        return latent

    def _project(self, volume: torch.Tensor) -> torch.Tensor:
        """The projection unit: depth folded into channels, then the 1x1 convolution (as VoxelEncoder does)."""
        b, c, d, h, w = volume.shape
        return self.encoder.projection(volume.reshape(b, c * d, h, w))


def _slices(spans: tuple[Span, ...], offsets: tuple[int, ...] | list[int] | None = None) -> tuple[slice, ...]:
    offsets = offsets or (0,) * len(spans)
    return tuple(slice(lo - o, hi - o) for (lo, hi), o in zip(spans, offsets))
