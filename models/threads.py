"""The process's compute threads, for torch, for the compiled numba kernels of renderer/, and for numpy's BLAS.

Numba's OpenMP threading layer sets OpenMP's thread count to its own (every core) when a parallel
kernel starts, and torch's operations follow OpenMP's count: after the first voxel-shader kernel a
`--threads 1` training ran on two threads (and a resumed run no longer matched an uninterrupted one).
Setting both to the same count keeps it.

numpy's OpenBLAS keeps worker threads that, after each matrix product, poll for the next one instead of
sleeping; the renderer's products are small ((N, 3) points by a 3 x 3 matrix, dozens a frame), so on
two cores a polling thread took a whole core from the shader's and the network's threads. With BLAS on
one thread an NVR+ light edit is much faster (docs/results.md, "Measurements behind the code").
"""

from __future__ import annotations

import numpy  # noqa: F401 - loads numpy's OpenBLAS, so limit_blas_threads finds it
from threadpoolctl import threadpool_limits


def limit_blas_threads() -> None:
    """Run the BLAS libraries loaded so far (numpy's OpenBLAS) on one thread, so no worker polls between products."""
    threadpool_limits(limits=1, user_api="blas")


def set_threads(count: int) -> None:
    """Run torch's operations and numba's parallel kernels on `count` threads (numba: at most its pool's size), and
    numpy's BLAS on one."""
    import numba  # here, not above: the CLI limits BLAS before every command, and most need neither
    import torch

    # numba first: its first call starts its thread pool, which sets OpenMP's count (torch's) to the pool's size.
    numba.set_num_threads(max(1, min(count, numba.config.NUMBA_NUM_THREADS)))
    torch.set_num_threads(count)
    limit_blas_threads()
