"""Receptive-field arithmetic of a chain of convolutions, per axis, for cropping a network exactly.

A convolution with kernel k, stride s and zero padding p before and q after maps an axis of n
entries to (n + p + q - k) // s + 1; its output o reads the inputs [o s - p, o s - p + k).
A residual block counts as its body's convolutions: with size-keeping 3x3 bodies their reads
contain the identity path's. Ranges are half-open spans (start, stop); an empty span has
start >= stop.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

from torch import nn

from models.engine.onednn import OneDnnConv
from models.networks.layers import ResidualBlock2d

Span = tuple[int, int]
_CONVS = (nn.Conv2d, nn.Conv3d, OneDnnConv)
_PADS = (nn.ZeroPad2d, nn.ZeroPad3d)


@dataclass(frozen=True)
class ConvAxes:
    """One convolution's kernel, stride and padding before / after, per spatial axis (first axis first)."""

    kernel: tuple[int, ...]
    stride: tuple[int, ...]
    pad_before: tuple[int, ...]
    pad_after: tuple[int, ...]

    def out_size(self, axis: int, n: int) -> int:
        return (n + self.pad_before[axis] + self.pad_after[axis] - self.kernel[axis]) // self.stride[axis] + 1

    def reads(self, axis: int, span: Span) -> Span:
        """Inputs read by the outputs of `span` (may reach into the padding: below 0 or past the end)."""
        k, s, p = self.kernel[axis], self.stride[axis], self.pad_before[axis]
        return span[0] * s - p, (span[1] - 1) * s - p + k

    def along(self, axis: int) -> ConvAxes:
        """This convolution on one of its axes only."""
        return ConvAxes((self.kernel[axis],), (self.stride[axis],), (self.pad_before[axis],), (self.pad_after[axis],))

    def reached(self, axis: int, span: Span, n_out: int) -> Span:
        """Outputs (within [0, n_out)) that read any input of `span`."""
        k, s, p = self.kernel[axis], self.stride[axis], self.pad_before[axis]
        return max(0, math.ceil((span[0] + p - k + 1) / s)), min(n_out, (span[1] - 1 + p) // s + 1)


class ConvChain:
    """The convolutions of a network part in the order they run, and the spans they read and change."""

    def __init__(self, convs: list[ConvAxes], dims: int):
        self.convs = convs
        self.dims = dims

    @property
    def total_stride(self) -> tuple[int, ...]:
        return tuple(math.prod(c.stride[a] for c in self.convs) for a in range(self.dims))

    def sizes(self, n: tuple[int, ...]) -> list[tuple[int, ...]]:
        """Axis lengths before the first convolution and after each one."""
        out = [tuple(n)]
        for conv in self.convs:
            out.append(tuple(conv.out_size(a, m) for a, m in enumerate(out[-1])))
        return out

    def changed_outputs(self, changed: tuple[Span, ...], n: tuple[int, ...]) -> tuple[Span, ...] | None:
        """Output spans that can differ when only the input spans `changed` differ; None if nothing can."""
        sizes = self.sizes(n)
        spans = tuple(changed)
        for conv, size in zip(self.convs, sizes[1:]):
            spans = tuple(conv.reached(a, spans[a], size[a]) for a in range(self.dims))
        return None if any(lo >= hi for lo, hi in spans) else spans

    def needed_inputs(self, outputs: tuple[Span, ...], n: tuple[int, ...]) -> tuple[Span, ...]:
        """Input spans (clipped to the input) that every output of `outputs` depends on."""
        sizes = self.sizes(n)
        spans = tuple(outputs)
        for conv, size in zip(reversed(self.convs), reversed(sizes[:-1])):
            spans = tuple(_clip(conv.reads(a, spans[a]), size[a]) for a in range(self.dims))
        return spans


    def border_contact(self, n: int) -> list[tuple[bool, bool]]:
        """For a one-axis chain on n inputs: per output, whether some layer of its cone reads the zero
        padding before the start, and after the end. Outputs without contact depend on input values only."""
        sizes = [s[0] for s in self.sizes((n,))]
        out = []
        for o in range(sizes[-1]):
            span, before, after = (o, o + 1), False, False
            for conv, size in zip(reversed(self.convs), reversed(sizes[:-1])):
                span = conv.reads(0, span)
                before, after = before or span[0] < 0, after or span[1] > size
            out.append((before, after))
        return out


def _clip(span: Span, n: int) -> Span:
    return max(0, span[0]), min(n, span[1])


def conv_chain(modules: Iterable[nn.Module], dims: int) -> ConvChain:
    """The chain of zero-padded convolutions among `modules` (e.g. `part.modules()`), in order.

    Raises ValueError for structures the arithmetic does not cover: non-zero padding modes,
    dilation, and residual blocks whose shortcut is a convolution (it runs beside the body, not after it).
    """
    convs, pending = [], None
    for module in modules:
        if isinstance(module, ResidualBlock2d) and not isinstance(module.shortcut, nn.Identity):
            raise ValueError("cannot crop a residual block with a convolution shortcut")
        if isinstance(module, _PADS):
            pending = module.padding
        elif isinstance(module, _CONVS):
            convs.append(_conv_axes(module, pending, dims))
            pending = None
    return ConvChain(convs, dims)


def _conv_axes(conv: nn.Module, pad_module: tuple[int, ...] | None, dims: int) -> ConvAxes:
    """A convolution's axes, with the zero padding of a ZeroPadNd just before it added to its own."""
    if getattr(conv, "padding_mode", "zeros") != "zeros" or isinstance(conv.padding, str) or any(d != 1 for d in conv.dilation):
        raise ValueError(f"cannot crop a convolution with padding {conv.padding!r} or dilation {conv.dilation}")
    # ZeroPadNd lists its pads last axis first: (last_before, last_after, ..., first_before, first_after).
    extra = [(0, 0)] * dims if pad_module is None else [
        (pad_module[2 * (dims - 1 - a)], pad_module[2 * (dims - 1 - a) + 1]) for a in range(dims)
    ]
    return ConvAxes(
        kernel=tuple(conv.weight.shape[2:]), stride=tuple(conv.stride),
        pad_before=tuple(p + e[0] for p, e in zip(conv.padding, extra)),
        pad_after=tuple(p + e[1] for p, e in zip(conv.padding, extra)),
    )
