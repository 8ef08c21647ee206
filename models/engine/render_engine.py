"""The live renderer of NVR Studio: a scene in, an image out, redoing only the stages an edit touched.

The model is loaded once and turned into an inference copy (BatchNorm folded, channels-last,
convolutions on oneDNN with their activations fused, the light merge split: models/engine/light_merge.py).
Every stage keeps its last result in one StageCache (renderer/stage_cache.py) with the exact scene parts it was
computed from, and reruns only when those change. This table is the one list of the network's stages:

    stage         depends on                                              result
    voxels        mesh file (+ resolution, up) or voxel file              object voxels N^3 (models/engine/paint_replay.py)
    paint         voxels, object color, region/object paint strokes       painted object voxels (one array, painted
                                                                          in place; differing strokes undone first)
    pool          paint, merge factors (resolution, scale)                merged voxels (after a paint edit:
                                                                          only the blocks it touched)
    placement     voxels, resolution, merge factors, translation,         grid row of every voxel, object's crop
                  rotation, scale, camera elevation                       (around its non-empty voxels)
    background    camera elevation, floor color                           voxel-branch features of the ground alone
    gather        pool, placement, floor color                            grid inside the object's crop
    voxel_branch  as gather                                               latent (encode_voxels)
    shell         voxels                                                  the voxels with an exposed face
    splat_layout  shell, translation, rotation, scale, camera elevation   the voxel each pixel shows, the floor
    splat         splat_layout, paint, floor color                        splatted image (NVR+, and previews)
    floor_light   camera elevation, floor color, light position           the lit empty floor (networks that read it)
    lighting      light, environment, material, camera elevation          the light input of a network that reads the
                                                                          environment (config.environment_input)
    shade_*       the voxel shader's stages (renderer/shading/staged.py)  its image and buffers (networks that read
                  prefixed with shade_; shade_pool for a finer grid       the shader), without the floor's reflection
    splat_branch  as splat (and floor_light, shade, if the network        splat features (encode_splat)
                  reads them)
    light         all of the above and the light position                 image (render_from_latent)

Floor color is the scene's floor color (a floor fill sets it). Hence, per edit (plus the shader's own stages
for a network that reads it, floor_light only for one that reads the lit floor, and lighting, with a light,
environment or material edit, for one that reads the environment):

    edit                          stages rerun
    light move                    floor_light, splat_branch, light
    floor color (a floor fill)    background, gather, voxel_branch, splat, floor_light, splat_branch, light
    paint stroke, object color    paint, pool, gather, voxel_branch, splat, splat_branch, light
    object move or rotation       placement, gather, voxel_branch, splat_layout, splat, splat_branch, light
    object scale                  pool (if the merge factors change), placement, gather, voxel_branch,
                                  splat_layout, splat, splat_branch, light
    camera elevation              placement, background, gather, voxel_branch, splat_layout, splat,
                                  floor_light, splat_branch, light
    new mesh, up or resolution    voxels, paint, pool, placement, gather, voxel_branch, shell, splat_layout,
                                  splat, splat_branch, light
    nothing                       none (the last image again)

A scene of several objects keeps each object's stages under its index: voxels[i], paint[i], object_pool[i],
object_grid[i] (where the object fills the grid: renderer.grid.object_cells), shell[i] and splat_layout[i], and the
shader's own (renderer/shading/staged.py). Their joins, scene_grid and splat, feed the voxel branch (rerun around the
cells an edit changed), the splat branch and the light stage. An edit of one object reruns its own stages and the
joins and network stages after them.
A network that reads the environment reads one object's material: of several objects it shows the shader's image.

The voxel branch runs only around the object (models/engine/cropped_encoder.py): the ground's features come from the
background stage (a ground grid a few columns wide, since the ground is the same in every column), the object's from
a crop of the grid around the voxels that differ from the ground; the result equals the full-grid encode_voxels
(`crop=False`). The engine is not thread-safe: one caller at a time (models/engine/async_render.py runs it on a
worker thread).

Precision: on a CPU with native bfloat16 (AVX512-BF16) the network runs in bfloat16 by default (`precision="auto"`),
which is faster there (docs/results.md, "Speed"); images agree with float32 within BF16_BOUND (tests/test_engine.py).
Everything outside the network stays float32. Device: a CUDA GPU if there is one (`device="auto"`), in float32 and
without the oneDNN convolutions, which are CPU kernels; the stages and their caching are the same.
"""

from __future__ import annotations

import functools
import os
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import torch

from models.engine.cropped_encoder import Background, CroppedVoxelEncoder, CropPlan
from models.engine.image_passes import apply_correction, join_and_pool
from models.engine.light_merge import split_light_merge
from models.engine.onednn import cpu_can_run_bfloat16, cpu_has_native_bfloat16, use_onednn_convolutions
from models.engine.paint_replay import PaintReplay
from models.networks.config import IMAGE_CHANNELS
from models.networks.inference import prepare_for_inference
from models.networks.nvr import NVR, NVRPlus, lighting_input, reads_floor_light, reads_scene, reads_shading
from models.threads import set_threads
from renderer.camera import Camera
from renderer.errors import InputError
from renderer.floor_light import lit_floor_image
from renderer.grid import (
    GridPlacement,
    colors_and_changes,
    gather,
    grid_index_to_world,
    ground_grid,
    ground_mask,
    non_empty_voxels,
    object_cells,
    occupied_spans,
    pool_factors,
    pool_voxels,
    repool_voxels,
    sample_indices,
)
from renderer.limits import MAX_OBJECTS
from renderer.pipeline import object_voxels
from renderer.scene import Scene, replaced
from renderer.shading import (
    ShadedImage,
    network_buffers,
    quality_named,
)
from renderer.shading.environment_shading import lighting_key
from renderer.shading.staged import ObjectVoxels, StagedShader
from renderer.splat import SplatLayout, color_splat, compose_splats, splat_layout
from renderer.stage_cache import RenderReport, StageCache
from renderer.surface import Shell, occupancy
from renderer.transform import object_to_world

PRECISIONS = {"fp32": torch.float32, "bf16": torch.bfloat16}
OBJECT_STAGES = ("voxels", "paint", "object_pool", "shade_pool", "object_grid", "shell", "splat_layout")  # per object of several, by index
# What a render of a scene the network does not read (an environment, the area light off, a glossy object) shows.
UNCORRECTED_NOTE = "this network is not trained for environment light or glossy materials: the voxel shader's image"
SEVERAL_OBJECTS_NOTE = "this network reads one object's material: the voxel shader's image of several objects"
# bfloat16 against float32 on the same scene, 0-255 scale: largest pixel difference and MSE (measured by
# benchmarks/bench_precision.py).
BF16_BOUND = {"max_abs": 4.0, "mse": 0.5}


class _Placement(NamedTuple):
    indices: np.ndarray | None  # gather row per grid voxel (renderer.grid.sample_indices): of the whole grid
    # (crop=False), else of the crop plan.grid; None if the object changes nothing in the grid
    plan: CropPlan | None  # where the object changes the voxel branch (crop=True); None if nowhere


class _Pooled(NamedTuple):
    voxels: np.ndarray  # merged voxels (renderer.grid.pool_voxels)
    colors: np.ndarray  # (K, 4) the painted voxels they were merged from, at the object's occupied voxels
    source: tuple  # where those voxels were read from (_voxel_source)
    factors: tuple[int, int, int]
    within: tuple | None  # the box of the non-empty merged voxels (as renderer.grid.pool_object finds it); paint keeps it
    object_rows: np.ndarray  # (P + 2,) bool: which rows of renderer.grid.gather hold a non-empty merged voxel; paint
    #                          keeps them (it recolors occupied voxels, whose merged voxels stay occupied)


class _PaintedObject(NamedTuple):
    """The paint stage's result and what it was made from."""

    voxels: np.ndarray  # the painted object voxels (painted again in place by the next paint edit)
    floor: tuple  # the scene's floor color
    key: tuple  # (source, object color, strokes): what the voxels depend on
    replay: PaintReplay  # the voxels stage's result: the object's occupied voxels and their box

    @property
    def source(self) -> tuple:
        """The object's file (_voxel_source): what its occupancy depends on."""
        return self.key[0]


class _Keys(NamedTuple):
    """The scene parts each stage depends on (see the module docstring)."""

    source: tuple  # the object's file (_voxel_source): its occupancy, which paint keeps
    paint: tuple  # the painted voxels (_PaintedObject.key)
    resolution: int
    factors: tuple[int, int, int]  # the network grid's merge factors
    pool: tuple
    placement: tuple
    grid: tuple
    layout: tuple
    splat: tuple
    floor_light: tuple
    painted: tuple  # the painted object and its placement
    shade: tuple
    splat_branch: tuple


class _NetworkInputs(NamedTuple):
    """What the network's light stage reads (RenderEngine._network_inputs) and where it came from."""

    latent: torch.Tensor
    light: torch.Tensor
    features: torch.Tensor | None  # the splat branch's (None for NVR)
    buffers: Callable[[], np.ndarray | None]  # the shader's buffers, made on the first call (None: the network reads none)
    buffers_tensor: Callable[[], torch.Tensor | None]  # the same as the network's input tensor
    key: tuple  # what the light stage reads, besides the light
    shaded: Callable[[int | None], ShadedImage]  # the shader's image without the floor's reflection, at a size


class _JoinedGrid(NamedTuple):
    """The network's grid of several objects, and per object what its cells were made from and the cells."""

    grid: np.ndarray
    parts: tuple[tuple[tuple, np.ndarray], ...]
    ground: tuple  # floor color and camera elevation


class _SceneFeatures(NamedTuple):
    """The voxel branch's features of the last grid of several objects, and what that grid was made from."""

    parts: tuple[tuple[tuple, np.ndarray], ...]
    ground: tuple  # floor color and camera elevation
    features: Background


class RenderEngine:
    """NVR or NVR+ rendering scenes, caching every stage on exactly the scene parts it depends on."""

    def __init__(self, model: NVR | NVRPlus, model_name: str = "", crop: bool = True, threads: int | None = None,
                 precision: str = "auto", device: str = "auto", shading_grid_factor: int | None = None,
                 object_source: Callable[[Scene], np.ndarray] = object_voxels, shader_quality: str = "full",
                 weights: Path | None = None):
        """`shading_grid_factor`: shade the object voxels merged as for a grid this many times finer than the network's
        instead of the one the model's configuration names (1: as for the network's own grid, in pairs at scale 1:
        fewer voxels to trace, less accurate; nvr bench times both). `object_source`: a scene's unpainted object voxels
        (read, never changed), e.g. from a cache the caller shares, so a mesh is not voxelised twice. `shader_quality`:
        'full' (what the networks were trained on) or 'fast' (fewer silhouette rays and light points: faster, less
        accurate; renderer.shading.QUALITIES). `weights`: the file the model came from, if any."""
        set_threads(threads or default_threads())
        self.device = resolve_device(device)
        self.config = model.config
        if shading_grid_factor is not None:
            self.config = replace(self.config, shading_grid_factor=shading_grid_factor)
        self.architecture = model.architecture
        self.weights = weights
        self.own_shading_grid = shading_grid_factor is None  # the shader's grid the weights were trained with
        self._reads_splat = isinstance(model, NVRPlus)
        self.model_name = model_name or f"random {self.config.name}"
        self.crop = crop
        self._quality = quality_named(shader_quality)
        self.shader_quality = shader_quality
        self.precision = resolve_precision(precision, self.device)
        self.dtype = PRECISIONS[self.precision]
        self._reads_floor_light = reads_floor_light(model.architecture, self.config)
        self._reads_shading = reads_shading(model.architecture, self.config)
        # NVR+ correcting the shaded image on the CPU: its image inputs and output in compiled passes, not torch's
        self._passes_on_cpu = self._reads_shading and self.device.type == "cpu"
        inference = prepare_for_inference(model)
        if self.device.type == "cpu":
            inference = use_onednn_convolutions(inference)
        self.model = split_light_merge(inference).to(self.device, self.dtype)
        self.encoder = CroppedVoxelEncoder(self.model.voxel_encoder, self.config.grid_size)
        self.last_report: RenderReport | None = None
        self._object_source = object_source
        self._cache = StageCache(settle=(lambda: torch.cuda.synchronize(self.device)) if self.device.type == "cuda"
                                 else None)  # GPU work is asynchronous: time it, not its launch
        self._grid_fraction: float | None = None  # share of the grid the voxel branch read in this render, if it ran
        self._note = ""  # what the last render's image is, when it is not the network's (RenderReport.note)
        # The voxel shader's stages, in this cache: without the floor's reflection, which the network does not read.
        self._shader = StagedShader(self.config.shading_grid_size, self._quality, cache=self._cache, prefix="shade_",
                                    reflection=False)
        # A scene of several objects, which no network reads yet: the shader's own image, the floor's reflection too.
        self._scene_shader = StagedShader(self.config.shading_grid_size, self._quality, cache=self._cache,
                                          prefix="scene_")

    @classmethod
    def load(cls, path: str | Path | None, architecture: str = "nvr_plus", **options: Any) -> RenderEngine:
        """The engine for a weights file (None: the shipped model of `architecture`, 'nvr_plus' or 'nvr')."""
        from models.networks.checkpoint import load_model
        from models.networks.shipped import SHIPPED_WEIGHTS, shipped_weights

        if architecture not in SHIPPED_WEIGHTS:
            raise InputError(f"unknown network architecture {architecture!r} (choose from {', '.join(SHIPPED_WEIGHTS)})")
        path = Path(path) if path else shipped_weights(architecture)
        model, config, _ = load_model(path)
        if model.architecture != architecture:
            raise InputError(f"holds a {model.architecture} network, not {architecture}", path)
        return cls(model, model_name=f"{path.name} ({config.name})", weights=path, **options)

    @property
    def description(self) -> str:
        """What renders, for status lines and reports."""
        quality = "" if self.shader_quality == "full" else f", {self.shader_quality} shading"
        return f"model {self.model_name}, {self.precision} on {self.device.type}{quality}"

    @property
    def output_size(self) -> int:
        return self.config.output_size

    def reads_scene(self, scene: Scene) -> bool:
        """Whether the network renders the scene (models.networks.nvr.reads_scene); else the shader's image shows."""
        return reads_scene(self.config, scene)

    def clear(self) -> None:
        """Forget every cached stage (the next render computes all of them)."""
        self._cache.clear()

    # --- rendering ------------------------------------------------------------------------

    def render(self, scene: Scene) -> np.ndarray:
        """The image (S, S, 3) float32 sRGB of `scene` at the model's output size S (scene.image_size is not used)."""
        start = self._begin(scene)
        with torch.inference_mode():
            image = self._render(scene)
        self._finish(start, preview=False)
        return image.copy()

    def preview(self, scene: Scene) -> np.ndarray:
        """A fast image while the user drags: the full render when only the light changed (that is cheap), else for a
        network that reads the shader the shaded image (its geometry kept through every placement and camera edit),
        else the splatted object over the lit empty floor; from stages the full render then reuses."""
        if len(scene.objects) > 1:
            return self._preview_objects(scene)
        start = self._begin(scene)
        with torch.inference_mode():
            painted = self._painted(scene)
            keys = self._keys(scene, painted)
            # Only the light changed: the voxel branch and the splat are kept, the rest is a light edit.
            if self._cached("voxel_branch", (keys.grid, self.crop)) and (not self._reads_splat or self._cached("splat", keys.splat)):
                image = self._render(scene)
            elif self._reads_shading:  # the shaded image, which the full render then corrects
                image = np.clip(self._shaded(scene, painted, keys).image, 0.0, 1.0)
            else:
                splat = self._splat(scene, painted, keys)
                on_object = self._splat_layout(scene, painted, keys).voxel >= 0
                image = np.where(on_object[..., None], splat, self._floor_light(scene))
        self._finish(start, preview=True)
        return image.copy()

    @property
    def renders_any_size(self) -> bool:
        """Whether `render_sized` renders sizes other than output_size: a network that corrects the shader's image."""
        return self._reads_shading

    def render_sized(self, scene: Scene, size: int) -> np.ndarray:
        """The image (size, size, 3) float32 sRGB of `scene`: at output_size, `render`'s. At another size (an export, the
        editor panel's redraw of a settled image), for a network that corrects the voxel shader's image, the shader's
        image at `size` corrected by the gain and offset the network computes from its usual inputs at its own size:
        they are smooth (computed at config.network_size and upsampled bilinearly either way), so edges and texture
        come from the shader at the asked resolution instead of a resized image. The live caches keep their own size's
        stages. A network that draws the image itself renders its own size only (InputError)."""
        if size == self.output_size:
            return self.render(scene)
        if len(scene.objects) > 1 and not self.reads_scene(scene):
            start = self._begin(scene)
            image = self._shaded_objects(scene, size)
            self._finish(start, preview=False)
            return image
        if not self.renders_any_size:
            raise InputError(f"the model renders {self.output_size}x{self.output_size} only ({self.config.name} draws "
                             f"the image itself), not {size}x{size}")
        start = self._begin(scene)
        with torch.inference_mode():
            several = len(scene.objects) > 1
            inputs = self._objects_network_inputs(scene) if several else self._network_inputs(scene)
            _, correction = self._light(scene, inputs)  # kept by the light stage: a redraw after a render reuses it
            shaded = inputs.shaded(size)
            image = (np.clip(shaded.image, 0.0, 1.0) if correction is None
                     else apply_correction(_to_array(correction.cpu()), shaded.image))
        self._finish(start, preview=False)
        return image

    def _render(self, scene: Scene) -> np.ndarray:
        if len(scene.objects) > 1:
            if not self.reads_scene(scene):
                return self._shaded_objects(scene)
            return self._light(scene, self._objects_network_inputs(scene))[0]
        self._forget_objects_beyond(0)  # a scene that held several objects: their own stages' memory
        self._scene_shader.forget_objects_beyond(0)
        for name in ("ground_grid", "scene_grid", "scene_features"):
            self._cache.forget(name)
        return self._light(scene, self._network_inputs(scene))[0]

    def _preview_objects(self, scene: Scene) -> np.ndarray:
        """preview for several objects: the full render when only the light changed or the network does not read the
        scene (the shader's image), else for a network that reads the shader its image, else the splat."""
        if not self.reads_scene(scene):
            return self.render(scene)
        start = self._begin(scene)
        with torch.inference_mode():
            painted = self._painted_objects(scene)
            if self._cached("scene_grid", self._objects_grid_key(scene, painted)):
                image = self._light(scene, self._objects_network_inputs(scene, painted))[0]
            elif self._reads_shading:
                image = np.clip(self._objects_shaded(scene, self._objects(scene, painted)).image, 0.0, 1.0)
            else:
                image = self._objects_splat(scene, self._objects(scene, painted))
        self._finish(start, preview=True)
        return image.copy()

    def _light(self, scene: Scene, inputs: _NetworkInputs) -> tuple[np.ndarray, torch.Tensor | None]:
        """The light stage: the image, and for a network that corrects the shader's image the correction it applied
        (correction_from_latent's output), which render_sized applies at other sizes."""
        latent, light, features = inputs.latent, inputs.light, inputs.features
        key = (*inputs.key, lighting_key(scene))

        def render() -> tuple[np.ndarray, torch.Tensor | None]:
            if not self.reads_scene(scene):  # this network is not trained for it: the shader's image as it is
                return np.clip(inputs.shaded(None).image, 0.0, 1.0), None
            if not self._reads_shading:
                return _to_image(self.model.render_from_latent(latent, light, features)), None
            correction = self.model.correction_from_latent(latent, light, features)
            if self._passes_on_cpu:  # the correction applied in compiled passes (models/engine/image_passes.py)
                return apply_correction(_to_array(correction), inputs.buffers()[..., :IMAGE_CHANNELS]), correction
            shaded = inputs.buffers_tensor()[:, :IMAGE_CHANNELS]
            return _to_image(self.model.apply_correction(correction, shaded)), correction

        return self._stage("light", key, render)

    def _network_inputs(self, scene: Scene) -> _NetworkInputs:
        """What the light stage reads, from the stages before it."""
        painted = self._painted(scene)
        keys = self._keys(scene, painted)
        latent = self._latent(scene, painted, keys)
        # The shader's buffers (S, S, SHADING_CHANNELS), and as a tensor (off the compiled passes), made only if a
        # stage that reads them reruns.
        buffers = functools.cache(lambda: self._shading(scene, painted, keys) if self._reads_shading else None)
        buffers_tensor = functools.cache(lambda: None if buffers() is None else self._image_tensor(buffers()))
        features = None
        if self._reads_splat:
            splat = self._splat(scene, painted, keys)
            floor_light = self._floor_light(scene) if self._reads_floor_light else None
            features = self._stage("splat_branch", keys.splat_branch,
                                   lambda: self._encode_splat(splat, floor_light, buffers, buffers_tensor))
        def light_input() -> torch.Tensor:
            return torch.from_numpy(lighting_input(scene, self.config.environment_input))[None].to(self.device, self.dtype)

        # The environment's probe is worth keeping; the light's position alone is three numbers.
        key = (scene.light, scene.environment, scene.object.material, scene.camera.elevation_deg)  # what it reads
        light = self._stage("lighting", key, light_input) if self.config.environment_input else light_input()
        return _NetworkInputs(latent, light, features, buffers, buffers_tensor,
                              (keys.grid, keys.splat, keys.shade if self._reads_shading else None),
                              lambda size: self._shaded(scene, painted, keys, size))

    def _objects_network_inputs(self, scene: Scene, painted: list[_PaintedObject] | None = None) -> _NetworkInputs:
        """What the light stage reads for a scene of several objects: their joined grid's latent (_objects_latent), the
        splat of them all, and the shader's image and buffers of them all."""
        painted = painted or self._painted_objects(scene)
        objects = self._objects(scene, painted)
        grid_key = self._objects_grid_key(scene, painted)  # also what the splat reads
        joined = self._stage("scene_grid", grid_key, lambda: self._objects_grid(scene, painted))
        latent = self._stage("voxel_branch", (grid_key, self.crop), lambda: self._objects_latent(scene, joined))
        shade_key = (grid_key, lighting_key(scene))
        buffers = functools.cache(lambda: network_buffers(self._objects_shaded(scene, objects))
                                  if self._reads_shading else None)
        buffers_tensor = functools.cache(lambda: None if buffers() is None else self._image_tensor(buffers()))
        features = None
        if self._reads_splat:
            splat = self._stage("splat", grid_key, lambda: self._objects_splat(scene, objects))
            floor_light = self._floor_light(scene) if self._reads_floor_light else None
            branch_key = (grid_key, scene.light.position if self._reads_floor_light else None,
                          shade_key if self._reads_shading else None)
            features = self._stage("splat_branch", branch_key,
                                   lambda: self._encode_splat(splat, floor_light, buffers, buffers_tensor))
        light = torch.from_numpy(lighting_input(scene, False))[None].to(self.device, self.dtype)
        return _NetworkInputs(latent, light, features, buffers, buffers_tensor,
                              (grid_key, shade_key if self._reads_shading else None),
                              lambda size: self._objects_shaded(scene, objects, size))

    def _objects_grid_key(self, scene: Scene, painted: list[_PaintedObject]) -> tuple:
        """What the joined grid (and the splat) of several objects reads: each object's painted voxels and placement,
        the floor color and the camera elevation."""
        keys = tuple((one.key, _pose(o)) for o, one in zip(scene.objects, painted))
        return keys, tuple(scene.floor.color), scene.camera.elevation_deg

    def _objects_latent(self, scene: Scene, joined: _JoinedGrid) -> torch.Tensor:
        """The voxel branch on the grid of several objects. From the last such grid's features (same ground, same
        objects), only around the cells the edited objects left and entered (models/engine/cropped_encoder.py);
        otherwise, or with crop=False, on the whole grid."""
        ground = (tuple(scene.floor.color), scene.camera.elevation_deg)
        last = self._cache.last("scene_features")
        features, fraction = None, 1.0
        if self.crop and last is not None and last.ground == ground and len(last.parts) == len(joined.parts):
            changed = [cells for (was, before), (now, after) in zip(last.parts, joined.parts) if was != now
                       for cells in (before, after)]
            changed = np.concatenate(changed) if changed else np.zeros(0, dtype=np.int64)
            features, fraction = last.features, 0.0
            if len(changed):
                g = self.config.grid_size
                at = np.unravel_index(changed, (g, g, g))
                plan = self.encoder.plan(tuple((int(a.min()), int(a.max()) + 1) for a in at))
                if plan is not None:
                    crop = self._grid_tensor(np.ascontiguousarray(joined.grid[plan.grid]))
                    features, fraction = self.encoder.encode_features(last.features, plan, crop), plan.grid_fraction(g)
        if features is None:
            features = self.encoder.background(self._grid_tensor(joined.grid))
        self._cache.forget("scene_features")
        self._stage("scene_features", None, lambda: _SceneFeatures(joined.parts, ground, features))
        self._grid_fraction = fraction
        return features.latent

    def _objects_grid(self, scene: Scene, painted: list[_PaintedObject]) -> _JoinedGrid:
        """The network's grid of several objects (renderer.pipeline.scene_grid_for): the ground, then where each object
        fills it, from stages of each object's own (its merged voxels, its cells), so a move samples one object."""
        floor, elevation, g = tuple(scene.floor.color), scene.camera.elevation_deg, self.config.grid_size
        ground = self._stage("ground_grid", (floor, elevation), lambda: ground_grid(floor, elevation, g))
        last = self._cache.last("scene_grid")
        if last is not None and last.ground == (floor, elevation) and len(last.parts) == len(painted):
            # The last grid, taken over (the stage forgets it): the cells its objects' edits left go back to the
            # ground, and every object's cells are written again in order below (a copy of the grid costs more).
            self._cache.forget("scene_grid")
            grid = last.grid
            for (was, cells), o, one in zip(last.parts, scene.objects, painted):
                if was != (one.key, _pose(o), floor, elevation):
                    grid.reshape(-1, 4)[cells] = ground.reshape(-1, 4)[cells]
        else:
            grid = ground.copy()
        parts = []
        for i, (o, one) in enumerate(zip(scene.objects, painted)):
            factors = pool_factors(one.voxels.shape[0], o.scale, g)
            pooled = self._stage(f"object_pool[{i}]", (one.key, factors),
                                 lambda i=i, one=one, factors=factors: self._pool(f"object_pool[{i}]", one, factors))
            key = (one.key, _pose(o), floor, elevation)
            cells, rows = self._stage(f"object_grid[{i}]", key, lambda o=o, one=one, pooled=pooled: object_cells(
                one.voxels, o, floor, elevation, g, (pooled.voxels, pooled.within)))
            grid.reshape(-1, 4)[cells] = rows
            parts.append((key, cells))
        return _JoinedGrid(grid, tuple(parts), (floor, elevation))

    def _objects_splat(self, scene: Scene, objects: list[ObjectVoxels]) -> np.ndarray:
        """The splat of several objects (renderer.splat.splat_objects) from each object's shell and layout stages."""
        camera = Camera.from_scene(scene, self.output_size)
        layouts = []
        for i, o in enumerate(objects):
            shell = self._stage(f"shell[{i}]", o.shape_key, lambda o=o: Shell(occupancy(o.rgba)))
            layouts.append(self._stage(f"splat_layout[{i}]", (o.shape_key, _pose(o.spec), scene.camera.elevation_deg),
                                       lambda o=o, shell=shell: splat_layout(shell, object_to_world(o.spec), camera)))
        return compose_splats(layouts, [o.rgba for o in objects], scene.floor.color)

    def _objects_shaded(self, scene: Scene, objects: list[ObjectVoxels], size: int | None = None) -> ShadedImage:
        """The shader's image of several objects without the floor's reflection, as the network reads it."""
        size = size or self.output_size
        return self._shader.run_objects(scene, objects, scene.floor.color, size, keep=size == self.output_size)

    def _encode_splat(self, splat: np.ndarray, floor_light: np.ndarray | None,
                      buffers: Callable[[], np.ndarray | None], buffers_tensor: Callable[[], torch.Tensor | None]
                      ) -> torch.Tensor:
        """The splat branch's features; on the CPU its inputs joined and area-averaged in one compiled pass."""
        if self._passes_on_cpu:
            inputs = [image for image in (splat, floor_light, buffers()) if image is not None]
            return self.model.encode_joined(self._image_tensor(join_and_pool(inputs, self.config.correction_downsampling)))
        return self.model.encode_splat(self._image_tensor(splat),
                                       None if floor_light is None else self._image_tensor(floor_light), buffers_tensor())

    # --- stages ---------------------------------------------------------------------------

    def _painted(self, scene: Scene) -> _PaintedObject:
        """Painted object voxels, the floor color, and the paint stage's key."""
        source = _voxel_source(scene)
        plain = replaced(scene, object=replace(scene.object, color=None))  # the base color is painted below
        replay = self._stage("voxels", source, lambda: PaintReplay(self._object_source(plain)))
        strokes = scene.paint
        paint_key = (source, scene.object.color, strokes)
        painted = self._stage("paint", paint_key, lambda: replay.painted(scene.object.color, strokes))
        floor = scene.floor.color
        return _PaintedObject(painted, tuple(floor), paint_key, replay)

    def _keys(self, scene: Scene, painted: _PaintedObject) -> _Keys:
        o, elevation, floor, paint_key = scene.object, scene.camera.elevation_deg, painted.floor, painted.key
        source, n = painted.source, painted.voxels.shape[0]
        factors = pool_factors(n, o.scale, self.config.grid_size)
        # Placement reads which object rows are empty, and layout the occupancy: neither changes with paint.
        placement = (source, n, factors, o.translation, o.rotation_deg, o.scale, elevation)
        layout = (source, o.translation, o.rotation_deg, o.scale, elevation)
        splat = (paint_key, layout, floor)
        floor_light = (elevation, floor, scene.light.position)
        grid = (paint_key, placement, floor)
        painted_placed = (paint_key, placement)
        shade = (painted_placed, floor, lighting_key(scene))
        splat_branch = (splat, floor_light if self._reads_floor_light else None, shade if self._reads_shading else None)
        return _Keys(source=source, paint=paint_key, resolution=n, factors=factors, pool=(paint_key, factors),
                     placement=placement, grid=grid, layout=layout, splat=splat,
                     floor_light=floor_light, painted=painted_placed, shade=shade, splat_branch=splat_branch)

    def _placed(self, scene: Scene, painted: _PaintedObject, keys: _Keys) -> tuple[np.ndarray, _Placement]:
        """The merged voxels and where each grid voxel samples them."""
        n, factors = keys.resolution, keys.factors
        pooled = self._network_pool(painted, keys)
        # The crop's placement is not the whole grid's: the key says which (`crop` can change between renders).
        return pooled.voxels, self._stage("placement", (keys.placement, self.crop),
                                          lambda: self._place(n, factors, scene, pooled))

    def _network_pool(self, painted: _PaintedObject, keys: _Keys) -> _Pooled:
        """The object voxels merged for the network's grid (keys.pool: the paint and the merge factors)."""
        return self._stage("pool", keys.pool, lambda: self._pool("pool", painted, keys.factors))

    def _latent(self, scene: Scene, painted: _PaintedObject, keys: _Keys) -> torch.Tensor:
        floor = painted.floor
        pooled, placement = self._placed(scene, painted, keys)
        grid_key = (keys.grid, self.crop)
        if not self.crop:
            grid = self._stage("gather", grid_key, lambda: gather(pooled, floor, placement.indices))
            self._grid_fraction = 1.0
            return self._stage("voxel_branch", grid_key, lambda: self.model.encode_voxels(self._grid_tensor(grid)))
        elevation = scene.camera.elevation_deg
        background = self._stage("background", (elevation, floor), lambda: self._background(floor, elevation))
        plan = placement.plan
        if plan is None:  # the object lies outside the grid
            self._grid_fraction = 0.0
            return background.latent
        crop = self._stage("gather", grid_key, lambda: gather(pooled, floor, placement.indices))
        self._grid_fraction = plan.grid_fraction(self.config.grid_size)
        return self._stage("voxel_branch", grid_key, lambda: self.encoder.encode(background, plan, self._grid_tensor(crop)))

    def _pool(self, stage: str, painted: _PaintedObject, factors: tuple[int, int, int]) -> _Pooled:
        """Merged voxels (the network's grid's, or the shader's finer grid's); after a paint edit (same object, same
        merge factors) only the blocks it touched are merged again, in the last merge's array (the stage keeps one
        result and nothing else reads it), and their box stays. Paint changes the colors of occupied voxels alone,
        so only they are compared: work in proportion to the surface, not the grid."""
        replay, source, voxels = painted.replay, painted.source, painted.voxels
        occupied = replay.occupied
        last = self._cache.last(stage)
        if last is None or (last.source, last.factors) != (source, factors):
            pooled = pool_voxels(voxels, factors, replay.box)  # only the blocks the object reaches
            non_empty = non_empty_voxels(pooled)  # for the box to sample and the rows the placement reads
            object_rows = np.append(non_empty.reshape(-1), [False, False])  # the empty and floor rows: no object
            return _Pooled(pooled, voxels.reshape(-1, 4)[occupied], source, factors, occupied_spans(non_empty),
                           object_rows)
        self._cache.forget(stage)  # updated in place below: never a stale entry under the old key
        colors, changed = colors_and_changes(voxels, occupied, last.colors)
        return _Pooled(repool_voxels(last.voxels, voxels, factors, changed, in_place=True), colors, source, factors,
                       last.within, last.object_rows)

    def _background(self, floor: tuple, elevation: float) -> Background:
        """The ground's features, from a ground grid a few columns wide when the ground is the same in every column."""
        g, narrow = self.config.grid_size, self.encoder.narrow_volume
        columns = narrow.width if narrow is not None and ground_is_column_invariant(elevation, g) else g
        return self.encoder.background(self._grid_tensor(ground_grid(floor, elevation, g, columns)))

    def _place(self, n: int, factors: tuple[int, int, int], scene: Scene, pooled: _Pooled) -> _Placement:
        """Where the grid samples the object: for the whole grid (crop=False), else for the crop around what it
        changes, found from the grid ranges the object can reach (the grid's other voxels are not visited)."""
        g, elevation = self.config.grid_size, scene.camera.elevation_deg
        placement = GridPlacement(n, factors, scene.object, elevation, g, pooled.within)
        if not self.crop:
            return _Placement(sample_indices(placement), None)
        window = placement.window
        if any(lo >= hi for lo, hi in window):
            return _Placement(None, None)  # the object changes nothing in the grid
        taken = sample_indices(placement, window)
        spans = changed_spans(taken, pooled.object_rows, ground_mask(elevation, g), window)
        plan = None if spans is None else self.encoder.plan(spans)
        if plan is None:
            return _Placement(None, None)
        # The crop's rows: the ground and empty rows, then the window's, which hold every object row and were just
        # sampled.
        box = [(crop.start, crop.stop) for crop in plan.grid]
        indices = sample_indices(placement, box, with_object=False)
        overlap = [(max(lo, start), min(hi, stop)) for (lo, hi), (start, stop) in zip(window, box)]
        if all(lo < hi for lo, hi in overlap):
            indices[tuple(slice(lo - start, hi - start) for (lo, hi), (start, _) in zip(overlap, box))] = \
                taken[tuple(slice(lo - start, hi - start) for (lo, hi), (start, _) in zip(overlap, window))]
        return _Placement(indices, plan)

    def _splat_layout(self, scene: Scene, painted: _PaintedObject, keys: _Keys) -> SplatLayout:
        shell = self._stage("shell", keys.source, lambda: Shell(occupancy(painted.voxels)))  # paint keeps occupancy
        return self._stage("splat_layout", keys.layout, lambda: splat_layout(
            shell, object_to_world(scene.object), Camera.from_scene(scene, self.output_size)))

    def _splat(self, scene: Scene, painted: _PaintedObject, keys: _Keys) -> np.ndarray:
        layout = self._splat_layout(scene, painted, keys)
        return self._stage("splat", keys.splat, lambda: color_splat(layout, painted.voxels, painted.floor))

    def _shaded(self, scene: Scene, painted: _PaintedObject, keys: _Keys, size: int | None = None) -> ShadedImage:
        """The voxel shader's image of the scene (renderer/shading/staged.py, its stages in this engine's cache),
        drawing the object voxels merged as for the grid the network's shader input stands for
        (config.shading_grid_size). `size`: another size than the network's (render_sized), whose stages from the
        surface on are computed, not kept."""
        def pool(factors: tuple[int, int, int]) -> np.ndarray:
            if self.config.shading_grid_factor > 1:  # the finer grid's own merged voxels
                return self._stage("shade_pool", (keys.paint, factors),
                                   lambda: self._pool("shade_pool", painted, factors)).voxels
            return self._network_pool(painted, keys).voxels  # shader_pool_factors are the network's on its own grid

        size = size or self.output_size
        return self._shader.run(scene, keys.paint, painted.voxels, painted.floor, size, shape_key=keys.source,
                                keep=size == self.output_size, pool=pool)

    def _painted_objects(self, scene: Scene) -> list[_PaintedObject]:
        """Each object's painted voxels, from stages of its own (voxels[i], paint[i]), named by what they read."""
        painted = []
        for i, o in enumerate(scene.objects):
            one = replaced(scene.alone(i), object=replace(o, color=None))  # the base color is painted below
            source = _voxel_source(one)
            replay = self._stage(f"voxels[{i}]", source, lambda one=one: PaintReplay(self._object_source(one)))
            key = (source, o.color, o.paint)
            voxels = self._stage(f"paint[{i}]", key, lambda o=o, replay=replay: replay.painted(o.color, o.paint))
            painted.append(_PaintedObject(voxels, tuple(scene.floor.color), key, replay))
        self._forget_objects_beyond(len(painted))
        return painted

    def _objects(self, scene: Scene, painted: list[_PaintedObject] | None = None) -> list[ObjectVoxels]:
        """Each object's painted voxels as the shader's stages read them, merged in stages of the engine's own (after
        a paint edit only the blocks it touched are merged again)."""
        objects = []
        for i, (o, one) in enumerate(zip(scene.objects, painted or self._painted_objects(scene))):
            def pool(factors: tuple[int, int, int], i: int = i, one: _PaintedObject = one) -> np.ndarray:
                name = f"shade_pool[{i}]" if self.config.shading_grid_factor > 1 else f"object_pool[{i}]"
                return self._stage(name, (one.key, factors), lambda: self._pool(name, one, factors)).voxels

            objects.append(ObjectVoxels(o, one.key, one.voxels, one.source, pool))
        return objects

    def _shaded_objects(self, scene: Scene, size: int | None = None) -> np.ndarray:
        """The voxel shader's own image of a scene of several objects, the floor's reflection too (for a network that
        does not read the scene), at `size` (default the network's)."""
        objects = self._objects(scene)
        size = size or self.output_size
        shaded = self._scene_shader.run_objects(scene, objects, scene.floor.color, size, keep=size == self.output_size)
        return np.clip(shaded.image, 0.0, 1.0)

    def _forget_objects_beyond(self, count: int) -> None:
        """Drop the stages kept for objects past the first `count` of a scene that held more (a 200^3 object's
        painted voxels take 128 MB); 0 when the scene is down to one object, drawn by the one-object stages."""
        for i in range(count, MAX_OBJECTS):
            for name in OBJECT_STAGES:
                self._cache.forget(f"{name}[{i}]")

    def _shading(self, scene: Scene, painted: _PaintedObject, keys: _Keys) -> np.ndarray:
        """The shader's image and buffers as the network reads them, (S, S, SHADING_CHANNELS)."""
        return network_buffers(self._shaded(scene, painted, keys))

    def _floor_light(self, scene: Scene) -> np.ndarray:
        """The lit empty floor (the floor_light stage: keys.floor_light)."""
        floor = tuple(scene.floor.color)
        key = (scene.camera.elevation_deg, floor, scene.light.position)
        return self._stage("floor_light", key, lambda: lit_floor_image(
            Camera.from_scene(scene, self.output_size), scene.light.position, floor))

    def _grid_tensor(self, grid: np.ndarray) -> torch.Tensor:
        """A (D, H, W, 4) grid as the network's (1, 4, D, H, W) input; channels-last, and without a copy in float32."""
        return torch.from_numpy(grid).permute(3, 0, 1, 2)[None].to(self.device, self.dtype)

    def _image_tensor(self, image: np.ndarray) -> torch.Tensor:
        return torch.from_numpy(image).permute(2, 0, 1)[None].to(self.device, self.dtype)

    # --- the memo and the report ------------------------------------------------------------

    def _stage(self, name: str, key: Any, compute: Callable[[], Any]) -> Any:
        """The stage's cached result if it was computed for `key`, else compute, time and keep it."""
        return self._cache(name, key, compute)

    def _cached(self, name: str, key: Any) -> bool:
        return self._cache.cached(name, key)

    def _begin(self, scene: Scene) -> float:
        self._cache.begin()
        self._grid_fraction = None
        several = len(scene.objects) > 1 and self.config.environment_input
        self._note = "" if self.reads_scene(scene) else SEVERAL_OBJECTS_NOTE if several else UNCORRECTED_NOTE
        return time.perf_counter()

    def _finish(self, start: float, preview: bool) -> None:
        stages = self._cache.stage_ms
        self.last_report = RenderReport(tuple(stages), dict(stages), (time.perf_counter() - start) * 1000.0, preview,
                                        self._grid_fraction, self._note)


# --- helpers ------------------------------------------------------------------------------------


def resolve_device(device: str) -> torch.device:
    """'cpu' or 'cuda' (or 'cuda:N') as asked; 'auto': the first CUDA GPU if there is one, else the CPU."""
    if device == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if device != "cpu" and not device.startswith("cuda"):
        raise InputError(f"unknown device {device!r} (choose from auto, cpu, cuda)")
    if device.startswith("cuda") and not torch.cuda.is_available():
        raise InputError(f"device {device!r} was asked for, but no CUDA GPU is available")
    return torch.device(device)


def resolve_precision(precision: str, device: torch.device | None = None) -> str:
    """'fp32' or 'bf16' as asked; 'auto': bf16 on a CPU that computes it natively (AVX512-BF16), else fp32."""
    on_cpu = device is None or device.type == "cpu"
    if precision == "auto":
        return "bf16" if on_cpu and cpu_has_native_bfloat16() else "fp32"
    if precision not in PRECISIONS:
        raise InputError(f"unknown precision {precision!r} (choose from auto, {', '.join(PRECISIONS)})")
    if precision == "bf16" and on_cpu and not cpu_can_run_bfloat16():
        raise InputError("this CPU cannot run bf16 convolutions (oneDNN needs AVX512 or AVX-NE-CONVERT): use fp32")
    return precision


def default_threads() -> int:
    """Torch threads for rendering: every core this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def ground_is_column_invariant(elevation_deg: float, grid_size: int) -> bool:
    """Whether world height is exactly constant along grid columns, so every column of the ground grid is the same.

    True for the project's camera (no roll): the column coefficient of world y is exactly 0.
    """
    return bool(grid_index_to_world(elevation_deg, grid_size)[1, 2] == 0.0)


def changed_spans(taken: np.ndarray, object_rows: np.ndarray, ground: np.ndarray,
                  window: list[tuple[int, int]]) -> tuple[tuple[int, int], ...] | None:
    """Bounding box (one span per axis) of the grid voxels that differ from the ground-only grid; None if none do.

    `taken` are renderer.grid.sample_indices over the grid ranges `window` (GridPlacement.window, non-empty);
    every voxel that takes a merged voxel lies in the window, `object_rows` (P + 2,) says which of gather's rows hold a
    non-empty one, and `ground` is the grid's ground_mask. A voxel differs where it takes a non-empty merged voxel,
    or a ground voxel took an object row. The object's box is mostly empty, and its all-zero rows equal the empty
    row, so they are left out: the object's crop covered 14-21 % of the grid instead of 35-42 % on the bench objects.
    """
    box = tuple(slice(*span) for span in window)
    floor_row = len(object_rows) - 1
    changed = np.take(object_rows.view(np.uint8), taken).view(bool)  # np.take: twice as fast as fancy indexing
    changed |= ground[box] & (taken != floor_row)
    spans = occupied_spans(changed)
    return None if spans is None else tuple((lo + s.start, hi + s.start) for (lo, hi), s in zip(spans, box))


def _voxel_source(scene: Scene) -> tuple:
    """What the object voxels are read from, with the file's modification stamp so an edited file is reread."""
    voxels = scene.voxels_path()
    if voxels is not None:
        return ("voxels", *_file_stamp(voxels))
    return ("mesh", *_file_stamp(scene.mesh_path()), scene.object.resolution, scene.object.up)


def _file_stamp(path: Path) -> tuple:
    try:
        stat = path.stat()
    except OSError:
        return (str(path), None, None)  # the loader reports the missing file
    return (str(path.resolve()), stat.st_mtime_ns, stat.st_size)


def _to_array(batch: torch.Tensor) -> np.ndarray:
    """The first image of a (B, C, H, W) CPU batch as a float32 (H, W, C) array (no copy from channels-last float32)."""
    return batch[0].permute(1, 2, 0).float().contiguous().numpy()


def _to_image(batch: torch.Tensor) -> np.ndarray:
    """(S, S, 3) float32 sRGB in [0, 1] (a network that corrects the shaded image can overshoot it)."""
    return batch[0].permute(1, 2, 0).float().clamp(0.0, 1.0).cpu().contiguous().numpy()


def _pose(o) -> tuple:
    """An object's place, turn and size: what its placed stages read besides its voxels and the camera."""
    return o.translation, o.rotation_deg, o.scale
