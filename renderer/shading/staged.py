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

With several objects, each object has its own stages from `pool` to `reflection` (and `floor_sky`), named with its
index ("surface[1]"), and three joins (renderer/shading/compose.py) stand before `lighting`:

    join             every object's colors: the nearest object's point per pixel     an edit of any object
    join_occluders   every object's placement: their shadow occluders together      a placement or camera edit
    join_reflection  every object's reflection                                      as join

So a light move reruns `floor` and `lighting`; a paint stroke `pool`, `colors`, `reflection` and `lighting`; an
object move, turn or scale `placement` and the stages after it but `floor`; a camera tilt those and `floor`. The
geometry stands at the floor's origin in the object's own frame and `placement` puts it in the scene. The caller names
the painted voxels by a key (anything hashable that changes when they do) and their occupancy by another, so the
cache never compares voxel arrays.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from renderer.camera import Camera
from renderer.floor_light import lit_floor_terms
from renderer.floor_texture import floor_texture
from renderer.grid import pool_voxels, shader_pool_factors
from renderer.scene import SHADER_GRID_SIZE, ObjectSpec, Scene, needs_environment_shading
from renderer.shading.compose import join_occluders, join_reflections, join_surfaces
from renderer.shading.environment_shading import scene_environment, shade_environment
from renderer.shading.geometry import ObjectGeometry, object_geometry, placed
from renderer.shading.lighting import ShadedImage, ShadowMaps, shade, shadow_maps
from renderer.shading.quality import FULL_QUALITY, ShaderQuality
from renderer.shading.surface import (
    FloorReflection,
    VisibleSurface,
    floor_reflection,
    floor_sky_cones,
    repaint_surface,
    visible_surface,
)
from renderer.stage_cache import StageCache

Pool = Callable[[tuple[int, int, int]], np.ndarray]  # merge factors -> the painted voxels merged by them
OBJECT_STAGES = ("pool", "geometry", "placement", "surface", "colors", "reflection", "floor_sky", "shadow_maps")  # one set per object


@dataclass(frozen=True)
class ObjectVoxels:
    """One object's painted voxels as the shader's stages read them: `voxels_key` names them, `shape_key` their
    occupancy (which paint keeps); `pool`: their merge from the caller's own cache, if it keeps one."""

    spec: ObjectSpec
    voxels_key: Hashable
    rgba: np.ndarray
    shape_key: Hashable
    pool: Pool | None = None


class _DrawnObject(NamedTuple):
    """One object's stage results (StagedShader._object_stages)."""

    suffix: str
    where: ObjectGeometry
    seen: VisibleSurface  # uncolored
    surface: VisibleSurface
    reflection: FloorReflection | None
    placed_key: tuple
    painted_key: tuple


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
        self._objects_kept = 0  # objects whose own stages (named with their index) the cache holds

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
        """The shaded image of a one-object `scene` whose painted object voxels are `object_rgba`, named by
        `voxels_key`; `shape_key` names their occupancy (default: `voxels_key`), which paint keeps. `keep`: False
        computes the stages that depend on the image size without keeping them (a one-off image of another size).
        `pool`: the merged voxels from the caller's own cache, instead of this chain's `pool` stage."""
        painted = ObjectVoxels(scene.object, voxels_key, object_rgba, voxels_key if shape_key is None else shape_key,
                               pool)
        return self.run_objects(scene, [painted], floor_color, size, keep)

    def run_objects(self, scene: Scene, objects: Sequence[ObjectVoxels], floor_color, size: int,
                    keep: bool = True) -> ShadedImage:
        """The shaded image of `scene`, its objects' painted voxels `objects` (in the scene's order). Each object has
        its own stages (named "surface[1]" and so on when there are several), so an edit of one reruns its own and
        the joins and lighting after them (renderer/shading/compose.py)."""
        elevation, floor, light = scene.camera.elevation_deg, tuple(floor_color), scene.light.position
        several = len(objects) > 1
        self.forget_objects_beyond(len(objects) if several else 0)
        drawn = [self._object_stages(f"[{i}]" if several else "", o, elevation, size, keep)
                 for i, o in enumerate(objects)]
        painted_key = tuple(d.painted_key for d in drawn) if several else drawn[0].painted_key
        placed_key = tuple(d.placed_key for d in drawn) if several else drawn[0].placed_key
        if several:
            surface, owner = self._stage("join", (painted_key, size), lambda: join_surfaces([d.surface for d in drawn]),
                                         keep)
            where = self._stage("join_occluders", placed_key, lambda: join_occluders([d.where for d in drawn]))
            reflection, reflection_owner = (self._stage("join_reflection", (painted_key, size), lambda: join_reflections(
                [d.reflection for d in drawn], elevation), keep) if self._reflection else (None, None))
        else:
            (where, surface, reflection), owner, reflection_owner = (drawn[0].where, drawn[0].surface,
                                                                     drawn[0].reflection), None, None
        if not needs_environment_shading(scene):
            floor_terms = self._stage("floor", (elevation, size, light, floor), lambda: lit_floor_terms(
                Camera(elevation, width=size, height=size), light, floor), keep)
            shadows = None
            if several:  # each object's shadow maps kept apart: a move builds the moved object's alone
                shadows = ShadowMaps.joined([self._stage(f"shadow_maps{d.suffix}", (d.placed_key, light), lambda d=d:
                                                         shadow_maps(d.where, light, self.quality)) for d in drawn])
            return self._stage("lighting", (painted_key, light, floor), lambda: shade(
                where, surface, light, floor, floor_terms, reflection, self.quality, shadows), keep)
        environment = scene_environment(scene)
        light = light if scene.light.enabled else None
        cones = [self._stage(f"floor_sky{d.suffix}", (d.placed_key, size), lambda d=d: floor_sky_cones(d.where, d.seen),
                             keep) for d in drawn]
        cones = cones[0] if not several or cones[0] is None else np.prod(cones, axis=0).astype(np.float32)
        texture = floor_texture(scene)
        shape = scene.floor.shape
        materials = tuple(o.spec.material for o in objects)
        material = materials if several else materials[0]
        owners = (owner, reflection_owner) if several else None
        return self._stage("lighting", (painted_key, light, floor, environment.key, materials, texture, shape),
                           lambda: shade_environment(where, surface, light, floor, environment, material, reflection,
                                                     self.quality, cones, texture, shape, owners), keep)

    def _object_stages(self, suffix: str, painted: ObjectVoxels, elevation: float, size: int,
                       keep: bool) -> _DrawnObject:
        """One object's stages, their names ending in `suffix`: pool, geometry, placement, surface, colors and
        reflection."""
        o, rgba, n = painted.spec, painted.rgba, painted.rgba.shape[0]
        factors = shader_pool_factors(n, o.scale, self.grid_size)

        def stage(name: str, key: Hashable, compute: Callable, keep: bool = True):
            return self._stage(name + suffix, key, compute, keep)

        merged = painted.pool(factors) if painted.pool is not None else stage(
            "pool", (painted.voxels_key, factors), lambda: pool_voxels(rgba, factors))
        shape = stage("geometry", (painted.shape_key, factors), lambda: object_geometry(
            merged, n, factors, self.quality.ambient_occlusion))
        placed_key = (painted.shape_key, factors, o.translation, o.rotation_deg, o.scale, elevation)
        where = replace(stage("placement", placed_key, lambda: placed(shape, o, elevation)), rgb=merged[..., :3])
        seen = stage("surface", (placed_key, size), lambda: visible_surface(where, size, colors=False,
                                                                           quality=self.quality), keep)
        painted_key = (placed_key, size, painted.voxels_key)
        surface = stage("colors", painted_key, lambda: repaint_surface(seen, where), keep)
        reflection = stage("reflection", painted_key, lambda: floor_reflection(where, surface),
                           keep) if self._reflection else None
        return _DrawnObject(suffix, where, seen, surface, reflection, placed_key, painted_key)

    def forget_objects_beyond(self, count: int) -> None:
        """Drop the per-object stages of objects past the first `count` (a scene that held more: their memory)."""
        for i in range(count, self._objects_kept):
            for name in OBJECT_STAGES:
                self.cache.forget(f"{self._prefix}{name}[{i}]")
        self._objects_kept = count

    def _stage(self, name: str, key: Hashable, compute: Callable, keep: bool = True):
        return self.cache(self._prefix + name, key, compute, keep)


class SceneShaders:
    """Staged shaders kept between one-off scenes, one per role (the objects together, or object k alone; with or
    without the floor's reflection): a test sequence's views of the same objects, one after another, reuse each
    object's merged voxels and geometry instead of building them for every view."""

    def __init__(self, grid_size: int = SHADER_GRID_SIZE, quality: ShaderQuality = FULL_QUALITY) -> None:
        self.grid_size, self.quality = grid_size, quality
        self._shaders: dict[Hashable, StagedShader] = {}

    def shade(self, scene: Scene, painted: Sequence[np.ndarray], keys: Sequence[Hashable], size: int,
              reflection: bool = True, role: Hashable = "together") -> ShadedImage:
        """The shaded image of `scene` (its floor's color), its objects' voxels `painted` named by `keys` (anything
        hashable that names their contents, as a voxel file's path does), drawn by the shader of `role`."""
        shader = self._shaders.get((role, reflection))
        if shader is None:
            shader = self._shaders[role, reflection] = StagedShader(self.grid_size, self.quality, reflection=reflection)
        objects = [ObjectVoxels(o, key, rgba, key) for o, key, rgba in zip(scene.objects, keys, painted)]
        return shader.run_objects(scene, objects, scene.floor.color, size)

    @property
    def caches(self) -> list[StageCache]:
        """Each role's stage cache (what its last scene ran: `stage_ms`)."""
        return [shader.cache for shader in self._shaders.values()]
