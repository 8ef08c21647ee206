"""The voxel shader in stages, each kept in a StageCache with the scene parts it was computed from.

This chain is the one table of the shader's stages; the standalone shader and the network engine both run it.

    stage       reads                                                         reruns after
    pool        painted object voxels, merge factors (resolution, scale)      paint, a scale across the factors
    geometry    the object's occupancy, merge factors                         another object, the same scale
    placement   geometry, translation, rotation, scale, camera elevation      any placement or camera edit
    surface     placement, image size (what the camera sees, uncolored)       the same
    colors      surface, painted voxels (the seen points' colors)             the same, paint
    reflection  colors (the object mirrored in the floor; optional)           the same
    floor       camera elevation, image size, light position, floor color     camera, floor color, a light move
    floor_sky   surface (under an environment: the sky the object leaves      the same as surface
                open to the floor, per direction)
    lighting    colors, reflection, floor                                     any of the above
                (under an environment, for a glossy object or on a textured floor: colors, reflection, the light, the
                floor color or texture, the environment and the material; it lights the floor itself)

So a light move reruns `floor` and `lighting`; a paint stroke `pool`, `colors`, `reflection` and `lighting`; an
object move, turn or scale `placement` and the stages after it but `floor`; a camera tilt those and `floor`. The
geometry stands at the floor's origin in the object's own frame and `placement` puts it in the scene. The caller names
the painted voxels by a key (anything hashable that changes when they do) and their occupancy by another, so the
cache never compares voxel arrays.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from dataclasses import replace

import numpy as np

from renderer.camera import Camera
from renderer.floor_light import lit_floor_terms
from renderer.floor_texture import floor_texture
from renderer.grid import pool_voxels, shader_pool_factors
from renderer.scene import SHADER_GRID_SIZE, Scene, needs_environment_shading
from renderer.shading.environment_shading import scene_environment, shade_environment
from renderer.shading.geometry import object_geometry, placed
from renderer.shading.lighting import ShadedImage, shade
from renderer.shading.quality import FULL_QUALITY, ShaderQuality
from renderer.shading.surface import floor_reflection, floor_sky_cones, repaint_surface, visible_surface
from renderer.stage_cache import StageCache

Pool = Callable[[tuple[int, int, int]], np.ndarray]  # merge factors -> the painted voxels merged by them


class StagedShader:
    """Shades scenes one after another, rerunning only the stages an edit changed."""

    def __init__(self, grid_size: int = SHADER_GRID_SIZE, quality: ShaderQuality = FULL_QUALITY,
                 cache: StageCache | None = None, prefix: str = "", reflection: bool = True) -> None:
        """`grid_size`: the grid whose merge of the object voxels the shader draws (grid.shader_pool_factors);
        `quality`: silhouette rays and light points, fixed for the cache's life; `cache`, `prefix`: a cache shared with
        a caller's other stages, the shader's stage names prefixed; `reflection`: the object mirrored in the floor
        (a network's input leaves it out)."""
        self.grid_size = grid_size
        self.quality = quality
        self.cache = cache or StageCache()
        self._prefix = prefix
        self._reflection = reflection

    @property
    def stage_ms(self) -> dict[str, float]:
        """The stages the last standalone render ran, and their times."""
        return self.cache.stage_ms

    def render(self, scene: Scene, voxels_key: Hashable, object_rgba: np.ndarray, floor_color, size: int,
               shape_key: Hashable | None = None, keep: bool = True) -> ShadedImage:
        """A standalone pass of `run` (its timings in `stage_ms`)."""
        self.cache.begin()
        return self.run(scene, voxels_key, object_rgba, floor_color, size, shape_key, keep)

    def run(self, scene: Scene, voxels_key: Hashable, object_rgba: np.ndarray, floor_color, size: int,
            shape_key: Hashable | None = None, keep: bool = True, pool: Pool | None = None) -> ShadedImage:
        """The shaded image of `scene` whose painted object voxels are `object_rgba`, named by `voxels_key`; `shape_key`
        names their occupancy (default: `voxels_key`), which paint keeps. `keep`: False computes the stages that
        depend on the image size without keeping them (a one-off image of another size). `pool`: the merged voxels
        from the caller's own cache, instead of this chain's `pool` stage."""
        stage, o, elevation, floor = self._stage, scene.object, scene.camera.elevation_deg, tuple(floor_color)
        n = object_rgba.shape[0]
        factors = shader_pool_factors(n, o.scale, self.grid_size)
        shape_key = voxels_key if shape_key is None else shape_key
        merged = pool(factors) if pool is not None else stage("pool", (voxels_key, factors),
                                                              lambda: pool_voxels(object_rgba, factors))
        shape = stage("geometry", (shape_key, factors), lambda: object_geometry(merged, n, factors,
                                                                              self.quality.ambient_occlusion))
        placed_key = (shape_key, factors, o.translation, o.rotation_deg, o.scale, elevation)
        where = replace(stage("placement", placed_key, lambda: placed(shape, o, elevation)), rgb=merged[..., :3])
        seen = stage("surface", (placed_key, size), lambda: visible_surface(where, size, colors=False,
                                                                           quality=self.quality), keep)
        painted_key = (placed_key, size, voxels_key)
        surface = stage("colors", painted_key, lambda: repaint_surface(seen, where), keep)
        reflection = stage("reflection", painted_key, lambda: floor_reflection(where, surface),
                           keep) if self._reflection else None
        light = scene.light.position
        if not needs_environment_shading(scene):
            floor_terms = stage("floor", (elevation, size, light, floor), lambda: lit_floor_terms(
                Camera(elevation, width=size, height=size), light, floor), keep)
            return stage("lighting", (painted_key, light, floor), lambda: shade(
                where, surface, light, floor, floor_terms, reflection, self.quality), keep)
        environment = scene_environment(scene)
        light = light if scene.light.enabled else None
        cones = stage("floor_sky", (placed_key, size), lambda: floor_sky_cones(where, seen), keep)
        texture = floor_texture(scene)
        shape = scene.floor.shape
        return stage("lighting", (painted_key, light, floor, environment.key, o.material, texture, shape),
                     lambda: shade_environment(where, surface, light, floor, environment, o.material, reflection,
                                               self.quality, cones, texture, shape), keep)

    def _stage(self, name: str, key: Hashable, compute: Callable, keep: bool = True):
        return self.cache(self._prefix + name, key, compute, keep)
