"""Test-session set-up that must happen before torch is imported."""

import os

# Idle OpenMP threads sleep instead of spinning: on a shared 2-core machine spinning threads
# slow every other process (and the tests' own subprocesses) by up to 10x. The live engine sets
# the same; it only takes effect before torch loads, hence here.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


import pytest  # noqa: E402  (after the environment is set, on purpose)


@pytest.fixture()
def single_thread():
    """Tiny tensors: one thread avoids OpenMP barrier stalls when other processes share the CPU."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)
