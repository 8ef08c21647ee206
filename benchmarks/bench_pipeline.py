"""Timing of the voxel pipeline: voxelising a 100k-face mesh at the default resolution (target under 1 s),
resampling object voxels into the 128^3 camera grid (target under 50 ms), splatting at 256^2
(target under 20 ms) and coloring voxels from a 256^2 photo.

Run from the repository root: python -m benchmarks.bench_pipeline [--repeats N] [--res N]
Prints the median and minimum wall time of each entry of BENCHMARKS and its median CPU time,
since other processes share the CPU. To time something else, append (name, setup) to BENCHMARKS, where
setup() builds the inputs and returns the call to time.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import numpy as np
import trimesh

from renderer.camera import Camera
from renderer.grid import GridPlacement, gather, pool_factors, pool_voxels, sample_indices, scene_grid
from renderer.limits import DEFAULT_RESOLUTION
from renderer.mesh import normalise_mesh
from renderer.photo import color_voxels_from_photo
from renderer.scene import ObjectSpec
from renderer.splat import splat
from renderer.transform import object_to_world
from renderer.voxels import voxelize

FLOOR = (0.53, 0.64, 0.78)
SPEC = ObjectSpec(mesh="bench", translation=(0.1, -0.1), rotation_deg=30.0)
ELEVATION = 30.0
RESOLUTION = DEFAULT_RESOLUTION  # object voxels per side (--res)


def colored_sphere_100k() -> trimesh.Trimesh:
    """A normalised UV sphere of 101,120 faces with smoothly varying vertex colors."""
    mesh = normalise_mesh(trimesh.creation.uv_sphere(radius=1.0, count=[160, 160]))
    rgb = (mesh.vertices - mesh.vertices.min(axis=0)) / np.ptp(mesh.vertices, axis=0)
    mesh.visual.vertex_colors = np.round(rgb * 255).astype(np.uint8)
    return mesh


def object_voxels() -> np.ndarray:
    return voxelize(colored_sphere_100k(), RESOLUTION)


def voxelize_100k() -> Callable[[], object]:
    mesh = colored_sphere_100k()
    return lambda: voxelize(mesh, RESOLUTION)


def grid_all_stages() -> Callable[[], object]:
    rgba = object_voxels()
    return lambda: scene_grid(rgba, SPEC, FLOOR, ELEVATION)


def grid_geometry_stage() -> Callable[[], object]:
    """What an elevation or placement edit recomputes."""
    factors = pool_factors(RESOLUTION, SPEC.scale)
    return lambda: sample_indices(GridPlacement(RESOLUTION, factors, SPEC, ELEVATION))


def grid_appearance_stage() -> Callable[[], object]:
    """What a paint edit recomputes: merging the voxels and the gather."""
    rgba = object_voxels()
    factors = pool_factors(RESOLUTION, SPEC.scale)
    indices = sample_indices(GridPlacement(RESOLUTION, factors, SPEC, ELEVATION))
    return lambda: gather(pool_voxels(rgba, factors), FLOOR, indices)


def grid_floor_color_stage() -> Callable[[], object]:
    """What a floor color edit recomputes: the gather."""
    rgba = object_voxels()
    factors = pool_factors(RESOLUTION, SPEC.scale)
    pooled = pool_voxels(rgba, factors)
    indices = sample_indices(GridPlacement(RESOLUTION, factors, SPEC, ELEVATION))
    return lambda: gather(pooled, FLOOR, indices)


def splat_256() -> Callable[[], object]:
    """The splatted image S of the sphere's voxels at 256^2."""
    rgba, camera = object_voxels(), Camera(ELEVATION, 256, 256)
    return lambda: splat(rgba, object_to_world(SPEC), FLOOR, camera)


def photo_coloring_256() -> Callable[[], object]:
    """Coloring the sphere's voxels from a 256^2 photo seen 20 degrees to the side."""
    rgba, camera = object_voxels(), Camera(ELEVATION, 256, 256, azimuth_deg=20.0)
    photo = splat(rgba, object_to_world(SPEC), FLOOR, camera)
    return lambda: color_voxels_from_photo(rgba, object_to_world(SPEC), photo, camera, mirror=True)


BENCHMARKS: list[tuple[str, Callable[[], Callable[[], object]]]] = [
    ("voxelize 101k faces", voxelize_100k),
    ("scene grid 128^3, all stages", grid_all_stages),
    ("  geometry (elevation/placement edit)", grid_geometry_stage),
    ("  appearance (paint edit)", grid_appearance_stage),
    ("  gather only (floor color edit)", grid_floor_color_stage),
    ("splat 256^2", splat_256),
    ("color voxels from a 256^2 photo", photo_coloring_256),
]


def times_ms(fn: Callable[[], object], repeats: int) -> tuple[float, float, float]:
    """(median wall, minimum wall, median CPU) time in ms over `repeats` calls after one warm-up call.

    CPU time above the wall time is the part that ran on more than one core (the compiled loops do).
    """
    fn()
    wall, cpu = [], []
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        fn()
        wall.append((time.perf_counter() - start) * 1000.0)
        cpu.append((time.process_time() - start_cpu) * 1000.0)
    return statistics.median(wall), min(wall), statistics.median(cpu)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--res", type=int, default=DEFAULT_RESOLUTION, help="object voxels per side")
    args = parser.parse_args()
    global RESOLUTION
    RESOLUTION = args.res
    print(f"object voxels {RESOLUTION}^3")
    for name, setup in BENCHMARKS:
        median, best, cpu = times_ms(setup(), args.repeats)
        print(f"{name:40s} wall median {median:7.1f} ms  min {best:7.1f} ms   CPU median {cpu:7.1f} ms")


if __name__ == "__main__":
    main()
