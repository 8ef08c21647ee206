"""Test-session set-up that must happen before torch is imported."""

# OpenMP's waiting as the live engine sets it (models/engine/__init__.py): it takes effect only
# before torch loads, and spinning threads slow the tests' own subprocesses up to 10x.
import models.engine  # noqa: F401

# isort: split
import shutil
import subprocess
import time
from pathlib import Path

import pytest

XVFB_SCREEN = (1280, 800)


@pytest.fixture()
def single_thread():
    """Tiny tensors: one thread avoids OpenMP barrier stalls when other processes share the CPU."""
    import torch

    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture(scope="module")
def display():
    """An Xvfb display of its own (skips the module when Xvfb is not installed)."""
    if shutil.which("Xvfb") is None:
        pytest.skip("Xvfb is not installed (apt-get install xvfb)")
    number = next(n for n in range(150, 250) if not Path(f"/tmp/.X{n}-lock").exists())
    server = subprocess.Popen(["Xvfb", f":{number}", "-screen", "0", f"{XVFB_SCREEN[0]}x{XVFB_SCREEN[1]}x24", "-nolisten", "tcp"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    socket = Path(f"/tmp/.X11-unix/X{number}")
    deadline = time.monotonic() + 10
    while not socket.exists() and time.monotonic() < deadline and server.poll() is None:
        time.sleep(0.05)
    if not socket.exists():
        server.kill()
        pytest.fail(f"Xvfb did not start on :{number}")
    yield f":{number}"
    server.terminate()
    server.wait(timeout=10)
