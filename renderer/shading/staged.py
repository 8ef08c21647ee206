"""The voxel shader for a live editor: each stage kept with the scene parts it was computed from.

    stage      depends on                                                  reruns after
    pool       object voxels after paint, merge factors (resolution, scale) paint, a scale that changes the factors
    geometry   the object's shape (occupancy), merge factors               another object, a scale across the factors
    placed     geometry, placement, elevation                              the same, any placement or camera edit
    surface    placed, image size (what the camera sees, uncolored)        the same
    colors     surface, pool (the seen points' colors)                     the same, paint
    reflection colors (the object mirrored in the floor)                   the same
    floor      elevation, image size, light position, floor color          camera, floor color, a light move
    shade      colors, reflection, floor                                   any of the above

So a light move or a floor color reruns only `floor` and `shade`; a paint stroke `pool`, `colors`, `reflection` and
`shade` (paint keeps every voxel's occupancy, so the geometry and what the camera sees stay); an object move, turn or
scale (within its merge factors) `placed` and the stages after it but `floor`; a camera tilt those and `floor`: the
geometry stands at the floor's origin in the object's own frame and `placed` puts it in the scene
(renderer.shading.shader). The caller names the painted voxels by a key (anything hashable that changes when they
do) and their shape by another (one that changes when the occupancy does), so the cache never compares voxel arrays.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Hashable
from dataclasses import replace
from typing import Any

import numpy as np

from renderer.camera import Camera
from renderer.floor_light import lit_floor_terms
from renderer.grid import pool_voxels, shader_pool_factors
from renderer.scene import SHADER_GRID_SIZE, Scene
from renderer.shading.shader import (
    FULL_QUALITY,
    ShadedImage,
    ShaderQuality,
    floor_reflection,
    object_geometry,
    placed,
    repaint_surface,
    shade,
    visible_surface,
)


class StagedShader:
    """Shades scenes one after another, rerunning only the stages an edit changed."""

    def __init__(self, grid_size: int = SHADER_GRID_SIZE, quality: ShaderQuality = FULL_QUALITY) -> None:
        self.grid_size = grid_size  # the grid whose merge of the object voxels the shader draws (grid.shader_pool_factors)
        self.quality = quality  # silhouette rays and light points (shader.ShaderQuality), fixed for the cache's life
        self._memo: dict[str, tuple[Hashable, Any]] = {}
        self.stage_ms: dict[str, float] = {}  # the stages the last render ran, and their times

    def render(self, scene: Scene, voxels_key: Hashable, object_rgba: np.ndarray, floor_color, size: int,
               shape_key: Hashable | None = None, keep: bool = True) -> ShadedImage:
        """The shaded image of `scene` whose painted object voxels are `object_rgba`, named by `voxels_key`; `shape_key`
        names their occupancy (default: `voxels_key`), which paint keeps. `keep`: False computes the stages that depend
        on the image size without keeping them, for a one-off image of another size (the kept ones stay for the
        next live render)."""
        self.stage_ms = {}
        o, elevation, floor = scene.object, scene.camera.elevation_deg, tuple(floor_color)
        n = object_rgba.shape[0]
        factors = shader_pool_factors(n, o.scale, self.grid_size)
        shape_key = voxels_key if shape_key is None else shape_key
        merged = self._stage("pool", (voxels_key, factors), lambda: pool_voxels(object_rgba, factors))
        shape = self._stage("geometry", (shape_key, factors), lambda: object_geometry(merged, n, factors,
                                                                                    self.quality.ambient_occlusion))
        placed_key = (shape_key, factors, o.translation, o.rotation_deg, o.scale, elevation)
        where = replace(self._stage("placed", placed_key, lambda: placed(shape, o, elevation)), rgb=merged[..., :3])
        sized = self._stage if keep else lambda name, key, compute: compute()
        seen = sized("surface", (placed_key, size), lambda: visible_surface(where, size, colors=False,
                                                                           quality=self.quality))
        painted_key = (placed_key, size, voxels_key)
        surface = sized("colors", painted_key, lambda: repaint_surface(seen, where))
        reflection = sized("reflection", painted_key, lambda: floor_reflection(where, surface))
        light = scene.light.position
        floor_terms = sized("floor", (elevation, size, light, floor), lambda: lit_floor_terms(
            Camera(elevation, width=size, height=size), light, floor))
        return sized("shade", (painted_key, light, floor), lambda: shade(where, surface, light, floor, floor_terms,
                                                                     reflection, self.quality))

    def _stage(self, name: str, key: Hashable, compute: Callable[[], Any]) -> Any:
        if name in self._memo and self._memo[name][0] == key:
            return self._memo[name][1]
        start = time.perf_counter()
        value = compute()
        self.stage_ms[name] = (time.perf_counter() - start) * 1000.0
        self._memo[name] = (key, value)
        return value
