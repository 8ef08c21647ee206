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


@pytest.fixture
def two_color_box(tmp_path):
    """A two-colored 16^3 box object (voxel file), scale 0.8, turned 20 degrees, seen from 30 degrees at 64 px."""
    import numpy as np

    from renderer.scene import CameraSpec, FloorSpec, LightSpec, ObjectSpec, Scene
    from renderer.voxels import save_voxels

    rgba = np.zeros((16, 16, 16, 4), np.float32)
    rgba[4:12, 0:10, 4:12] = (0.8, 0.3, 0.2, 1.0)
    rgba[4:12, 10:12, 4:12] = (0.2, 0.3, 0.8, 1.0)
    save_voxels(tmp_path / "box.npz", rgba)
    return Scene.single(object=ObjectSpec(voxels="box.npz", rotation_deg=20.0, scale=(0.8, 0.8, 0.8)),
                 floor=FloorSpec((0.5, 0.6, 0.7)), light=LightSpec((1.0, 2.75, 0.5)), camera=CameraSpec(30.0),
                 image_size=64, base_dir=tmp_path)


@pytest.fixture(scope="module")
def refiner_file(tmp_path_factory):
    """A small NVR+ that corrects the shader's 64 px image, its correction layer random (a fresh one is zero)."""
    import torch

    from models.networks.checkpoint import save_model
    from models.networks.config import ShaderRefinerConfig
    from models.networks.nvr import build_model

    config = ShaderRefinerConfig(grid_size=64, output_size=64, voxel_channels=(4, 8, 8), latent_channels=16,
                                 light_channels=8, decoder_channels=(8, 8), splat_channels=4, unet_channels=(4, 8))
    torch.manual_seed(0)
    model = build_model("nvr_plus", config).eval()
    for parameter in model.rerender.to_rgb.parameters():
        parameter.data.normal_(0.0, 0.05)
    path = tmp_path_factory.mktemp("refiner") / "refiner.safetensors"
    save_model(path, model, config)
    return path
