"""Timing of splatting (target: under 20 ms at 256^2 for a 100^3 object) and of photo coloring.

Run from the repository root: python -m benchmarks.bench_splat (prints medians; on a shared machine, rerun when noisy)
"""

from __future__ import annotations

import statistics
import time

import numpy as np

from renderer.camera import Camera
from renderer.photo import color_voxels_from_photo
from renderer.scene import ObjectSpec
from renderer.splat import splat
from renderer.surface import occupancy, surface_mask
from renderer.transform import object_to_world

N = 100
SIZE = 256
FLOOR = (0.53, 0.64, 0.78)


def chair(n: int = N) -> np.ndarray:
    """A solid chair-like object: seat, back and four legs, each part its own color."""
    rgba = np.zeros((n, n, n, 4), np.float32)
    a, b = int(0.1 * n), int(0.9 * n)
    rgba[a:b, int(0.45 * n) : int(0.55 * n), a:b] = (0.7, 0.3, 0.2, 1.0)
    rgba[a:b, int(0.55 * n) : int(0.98 * n), a : int(0.2 * n)] = (0.2, 0.5, 0.7, 1.0)
    leg = int(0.08 * n)
    for i in (a, int(0.82 * n)):
        for k in (a, int(0.82 * n)):
            rgba[i : i + leg, : int(0.45 * n), k : k + leg] = (0.3, 0.3, 0.3, 1.0)
    return rgba


def sphere_shell(n: int = N) -> np.ndarray:
    """A two-voxel-thick spherical shell filling the object box."""
    c = (np.arange(n) + 0.5) / n - 0.5
    r = np.sqrt(c[:, None, None] ** 2 + c[None, :, None] ** 2 + c[None, None, :] ** 2)
    rgba = np.zeros((n, n, n, 4), np.float32)
    rgba[(r < 0.5) & (r > 0.5 - 2.0 / n)] = (0.8, 0.6, 0.2, 1.0)
    return rgba


def median_ms(run, repeats: int) -> float:
    run()  # warm-up: caches, first-touch allocations
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return 1000.0 * statistics.median(times)


def main() -> None:
    matrix = object_to_world(ObjectSpec(voxels="bench", rotation_deg=30.0))
    camera = Camera(30.0, SIZE, SIZE)
    for name, rgba in (("chair", chair()), ("sphere shell", sphere_shell())):
        surface = int(surface_mask(occupancy(rgba)).sum())
        ms = median_ms(lambda rgba=rgba: splat(rgba, matrix, FLOOR, camera), 20)
        print(f"splat {name} {N}^3 ({surface} surface voxels) at {SIZE}^2: median {ms:.1f} ms over 20 runs")
    rgba = chair()
    photo_camera = Camera(30.0, SIZE, SIZE, azimuth_deg=20.0)
    photo = splat(rgba, matrix, FLOOR, photo_camera)
    for mirror in (False, True):
        ms = median_ms(lambda m=mirror: color_voxels_from_photo(rgba, matrix, photo, photo_camera, mirror=m), 5)
        print(f"color_voxels_from_photo chair {N}^3 at {SIZE}^2, mirror={mirror}: median {ms:.0f} ms over 5 runs")


if __name__ == "__main__":
    main()
