"""Data-parallel training helpers: BatchNorm over the global batch of every rank.

Under DDP each process sees only its share of a batch, so plain BatchNorm would normalise with
per-rank statistics and N processes would not train like one process with the same total batch.
On CUDA, torch's SyncBatchNorm fixes that; it does not run on CPU, so `GlobalBatchNorm` does the
same with a differentiable all-reduce that works on any backend (gloo included).
"""

from __future__ import annotations

import torch
import torch.distributed as dist
from torch import nn
from torch.nn.modules.batchnorm import _BatchNorm

_STATS_GROUP = None


def _stats_group():
    """A process group of its own, so these reductions never interleave with DDP's gradient buckets."""
    global _STATS_GROUP
    if _STATS_GROUP is None:
        _STATS_GROUP = dist.new_group()
    return _STATS_GROUP


class _SumOverRanks(torch.autograd.Function):
    """Sum a tensor over all ranks; the gradient of a sum is the sum of the ranks' gradients."""

    @staticmethod
    def forward(ctx, tensor: torch.Tensor) -> torch.Tensor:
        total = tensor.clone()
        dist.all_reduce(total, group=_stats_group())
        return total

    @staticmethod
    def backward(ctx, grad: torch.Tensor) -> torch.Tensor:
        total = grad.clone()
        dist.all_reduce(total, group=_stats_group())
        return total


def sum_over_ranks(tensor: torch.Tensor) -> torch.Tensor:
    return _SumOverRanks.apply(tensor)


class GlobalBatchNorm(_BatchNorm):
    """BatchNorm (any dimension) whose training statistics are summed over all ranks."""

    def _check_input_dim(self, input: torch.Tensor) -> None:
        if input.ndim < 2:
            raise ValueError(f"expected at least 2D input, got {input.ndim}D")

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if not self.training or not dist.is_initialized():
            return super().forward(x)
        channels = x.shape[1]
        dims = [0, *range(2, x.ndim)]
        shape = (1, channels) + (1,) * (x.ndim - 2)
        count = torch.tensor([x.numel() / channels], dtype=x.dtype, device=x.device)
        # Two passes (mean, then squared deviations) as one process would: E[x^2] - E[x]^2 cancels badly.
        sums = sum_over_ranks(torch.cat([x.sum(dims), count]))
        n = sums[-1]
        mean = sums[:channels] / n
        centred = x - mean.view(shape)
        var = sum_over_ranks((centred * centred).sum(dims)) / n
        if self.track_running_stats:
            with torch.no_grad():
                m = self.momentum if self.momentum is not None else 1.0 / float(self.num_batches_tracked + 1)
                self.running_mean.mul_(1 - m).add_(m * mean)
                self.running_var.mul_(1 - m).add_(m * var * n / (n - 1).clamp_min(1.0))
                self.num_batches_tracked += 1
        y = centred * torch.rsqrt(var.view(shape) + self.eps)
        if self.affine:
            y = y * self.weight.view(shape) + self.bias.view(shape)
        return y


def convert_batchnorm(module: nn.Module, device: torch.device) -> nn.Module:
    """Swap every BatchNorm for one over the global batch (SyncBatchNorm on CUDA, GlobalBatchNorm else).

    Parameter and buffer names stay the same, so weights saved from the result load into the original.
    """
    if device.type == "cuda":
        return nn.SyncBatchNorm.convert_sync_batchnorm(module)
    for name, child in module.named_children():
        if isinstance(child, _BatchNorm) and not isinstance(child, GlobalBatchNorm):
            replacement = GlobalBatchNorm(child.num_features, child.eps, child.momentum, child.affine,
                                          child.track_running_stats).to(device)
            replacement.load_state_dict(child.state_dict())
            setattr(module, name, replacement)
        else:
            convert_batchnorm(child, device)
    return module
