"""The process's compute threads, for torch and for the compiled numba kernels of renderer/ together.

Numba's OpenMP threading layer sets OpenMP's thread count to its own (every core) when a parallel
kernel starts, and torch's operations follow OpenMP's count: after the first voxel-shader kernel a
`--threads 1` training ran on two threads (and a resumed run no longer matched an uninterrupted one).
Setting both to the same count keeps it.
"""

from __future__ import annotations

import numba
import torch


def set_threads(count: int) -> None:
    """Run torch's operations and numba's parallel kernels on `count` threads (numba: at most its pool's size)."""
    # numba first: its first call starts its thread pool, which sets OpenMP's count (torch's) to the pool's size.
    numba.set_num_threads(max(1, min(count, numba.config.NUMBA_NUM_THREADS)))
    torch.set_num_threads(count)
