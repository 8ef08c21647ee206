"""The physically based reference renderer (paper sections 3.1 and 4.2), built on Mitsuba 3.

One object (diffuse unless its material says otherwise) on a slightly specular floor, lit by a white square area
light facing down (unless switched off) and a uniform white ambient light or the scene's environment (its map and
its sun: renderer/environment.py), seen by the project's one camera model. Path
tracing with MIS gives the soft shadows, floor reflections and color bleeding the network
must learn. Every accuracy figure of the project is measured against these images.

Exposure: LIGHT_RADIANCE = 14. A white Lambertian floor straight below the light at height
2.75 receives 14 * 0.127 = 1.77 from the 1 x 1 light (0.127 = the integral of
cos * cos / r^2 over the square) and 0.2 * (pi - 0.127) = 0.60 from the ambient light around
it, so it reflects (1.77 + 0.60) / pi = 0.76 linear (0.89 sRGB). The floor's glossy coat keeps
a little for itself: measured 0.68 linear (0.84 sRGB) seen from elevation 30, 0.59 from 5.
Bright, with about 1.45x headroom before clipping for highlights and light bounced off the object.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import trimesh

from renderer.camera import Camera
from renderer.color import linear_to_srgb, srgb_to_linear
from renderer.environment import EnvironmentLight, environment_light
from renderer.errors import InputError
from renderer.floor_texture import FloorTexture, floor_texture, square_uv
from renderer.limits import MAX_IMAGE_SIZE, MIN_IMAGE_SIZE
from renderer.pathtrace.mitsuba_object import numpy_mesh, object_shapes
from renderer.pathtrace.mitsuba_variant import active_variant
from renderer.scene import (
    AMBIENT_RADIANCE,
    FLOOR_DISK_RADIUS,
    FLOOR_HALF_SIZE,
    FLOOR_IOR,
    FLOOR_ROUGHNESS,
    LIGHT_RADIANCE,
    LIGHT_SIZE,
    FloorSpec,
    Scene,
)

DISK_SEGMENTS = 512  # sides of the polygon that stands for a disk floor (its edge within a hair of the circle)
MAX_DEPTH = 6  # path segments: direct light plus up to 5 indirect bounces (Russian roulette from 5)
GUIDE_SPP = 16  # samples per pixel of the denoiser's albedo and normal guides (first hit only: cheap)
MAX_SAMPLES_PER_PASS = 1 << 26  # pixels x spp per Mitsuba call: sample indices stay far below 2^32


@dataclass(frozen=True)
class PathtraceResult:
    """A rendered image (float32 sRGB, H x W x 3, in [0, 1]) and how it was made."""

    image: np.ndarray
    variant: str
    spp: int  # samples per pixel actually taken
    denoised: bool
    setup_seconds: float  # building the Mitsuba scene (paid once per PathTracer)
    render_seconds: float  # sampling plus denoising of this image


@dataclass(frozen=True)
class RenderLayers:
    """Linear HDR color and the denoiser's guides (None when not rendered), each float32 H x W x 3."""

    color: np.ndarray
    albedo: np.ndarray | None
    normal: np.ndarray | None
    spp: int  # samples per pixel actually taken


class PathTracer:
    """One scene set up in Mitsuba once, rendered at any spp and seed.

    Building the scene (mesh upload, BVH) is paid in the constructor; `render` only samples.
    The denoiser's guides come from a separate first-hit render: wrapping the path tracer in
    Mitsuba's AOV integrator doubled its cost.
    """

    def __init__(self, scene: Scene, mesh: trimesh.Trimesh | Sequence[trimesh.Trimesh], size: int | None = None,
                 floor: bool = True):
        """`mesh`: the object's mesh (object coordinates), or one per object of the scene, in its order."""
        if size is not None and not MIN_IMAGE_SIZE <= size <= MAX_IMAGE_SIZE:
            raise InputError(f"image size must be in [{MIN_IMAGE_SIZE}, {MAX_IMAGE_SIZE}], got {size}")
        start = time.perf_counter()
        self.variant = active_variant()
        import mitsuba as mi

        self.camera = Camera.from_scene(scene, size)
        self._scene = mi.load_dict(_scene_dict(scene, mesh, self.camera, floor))
        self._guide_integrator = mi.load_dict({"type": "aov", "aovs": "albedo:albedo,normal:sh_normal"})
        self.setup_seconds = time.perf_counter() - start

    def render(self, spp: int = 64, seed: int = 0, denoise: bool = False) -> PathtraceResult:
        """Path trace about `spp` samples per pixel (the sampler may round up); the same seed gives the same image."""
        start = time.perf_counter()
        layers = self.render_layers(spp, seed, with_guides=denoise)
        linear = denoise_layers(layers) if denoise else layers.color
        image = linear_to_srgb(linear).astype(np.float32)
        elapsed = time.perf_counter() - start
        return PathtraceResult(image, self.variant, layers.spp, denoise, self.setup_seconds, elapsed)

    def render_layers(self, spp: int, seed: int, with_guides: bool = True) -> RenderLayers:
        """Noisy linear color and, if asked, the albedo and normal of the first hit (at GUIDE_SPP)."""
        if spp < 1:
            raise InputError(f"samples per pixel must be at least 1, got {spp}")
        if seed < 0:
            raise InputError(f"the seed must be a non-negative integer, got {seed}")
        color, taken = self._accumulate(None, spp, seed, stream=0)
        if not with_guides:
            return RenderLayers(color, None, None, taken)
        guides, _ = self._accumulate(self._guide_integrator, GUIDE_SPP, seed, stream=1)
        return RenderLayers(color, guides[..., 0:3], guides[..., 3:6], taken)

    def _accumulate(self, integrator, spp: int, seed: int, stream: int) -> tuple[np.ndarray, int]:
        """Mean of Mitsuba renders in passes small enough for the sample indices, and the samples taken.

        Each pass has its own seed derived from (seed, stream); the multi-jittered sampler may
        round a pass up to a near-square sample count, which is counted.
        """
        import mitsuba as mi

        sampler = self._scene.sensors()[0].sampler()
        passes = sample_passes(spp, self.camera.width * self.camera.height)
        seeds = np.random.SeedSequence([seed, stream]).generate_state(len(passes))
        total, taken = 0.0, 0
        for pass_spp, pass_seed in zip(passes, seeds):
            data = np.array(mi.render(self._scene, integrator=integrator, spp=pass_spp, seed=int(pass_seed)))
            total = total + data * sampler.sample_count()
            taken += sampler.sample_count()
        return np.nan_to_num(total / taken, nan=0.0, posinf=0.0, neginf=0.0).astype(np.float32), taken


def render_pathtraced(scene: Scene, mesh: trimesh.Trimesh | Sequence[trimesh.Trimesh], size: int | None = None,
                      spp: int = 64, seed: int = 0, denoise: bool = False, floor: bool = True) -> PathtraceResult:
    """Path trace one image of `scene` with `mesh` (object coordinates) as its object, or one mesh per object."""
    return PathTracer(scene, mesh, size, floor).render(spp, seed, denoise)


def sample_passes(spp: int, pixels: int, max_samples: int = MAX_SAMPLES_PER_PASS) -> list[int]:
    """Split spp into near-equal passes of at most `max_samples` samples over the image."""
    per_pass = max(1, max_samples // pixels)
    count = math.ceil(spp / per_pass)
    base, extra = divmod(spp, count)
    return [base + 1] * extra + [base] * (count - extra)


def denoise_layers(layers: RenderLayers) -> np.ndarray:
    """Intel Open Image Denoise on linear HDR color, guided by albedo and normals; linear result."""
    import pyoidn

    color = np.ascontiguousarray(np.maximum(layers.color, 0.0), dtype=np.float32)
    albedo = np.ascontiguousarray(np.clip(layers.albedo, 0.0, 1.0), dtype=np.float32)
    normal = np.ascontiguousarray(np.clip(layers.normal, -1.0, 1.0), dtype=np.float32)
    out = pyoidn.denoise(color, albedo, normal, hdr=True, quality="high")
    return np.maximum(np.nan_to_num(out, nan=0.0, posinf=0.0, neginf=0.0), 0.0)


# --- the Mitsuba scene ----------------------------------------------------------------------


def _scene_dict(scene: Scene, mesh: trimesh.Trimesh | Sequence[trimesh.Trimesh], camera: Camera,
                floor: bool = True) -> dict:
    """The Mitsuba scene; without `floor` the objects float in the ambient light (a studio photo's plain backdrop)."""
    meshes = [mesh] if isinstance(mesh, trimesh.Trimesh) else list(mesh)
    if len(meshes) != len(scene.objects):
        raise ValueError(f"{len(meshes)} meshes for a scene of {len(scene.objects)} objects")
    parts = {
        "type": "scene",
        "integrator": _path_integrator(),
        "sensor": _sensor(camera),
        **_environment(environment_light(scene)),
    }
    for i, (obj, one) in enumerate(zip(scene.objects, meshes)):
        parts.update(object_shapes(obj, one, scene.file(obj.mesh), key="object" if i == 0 else f"object{i}"))
    if scene.light.enabled:
        parts["light"] = _light(scene.light.position)
    if floor:
        parts["floor"] = _floor(scene.floor, floor_texture(scene))
    return parts


def _environment(environment: EnvironmentLight | None) -> dict:
    """The light from around the scene: the uniform ambient light, or the environment's map and its sun."""
    import mitsuba as mi

    if environment is None:
        return {"ambient": {"type": "constant", "radiance": {"type": "rgb", "value": [AMBIENT_RADIANCE] * 3}}}
    parts = {"ambient": {"type": "envmap", "bitmap": mi.Bitmap(np.array(environment.background, dtype=np.float32)),
                         "scale": environment.strength,
                         "to_world": mi.ScalarTransform4f().rotate([0, 1, 0], environment.rotation_deg)}}
    if environment.sun_direction is not None and environment.sun_irradiance.max() > 0.0:
        parts["sun"] = {"type": "directional", "direction": (-environment.sun_direction).tolist(),
                        "irradiance": {"type": "rgb", "value": environment.sun_irradiance.tolist()}}
    return parts


def _path_integrator() -> dict:
    return {"type": "path", "max_depth": MAX_DEPTH}


def _sensor(camera: Camera) -> dict:
    """A Mitsuba pinhole matching the render camera (centred principal point).

    Mitsuba's camera frame (x left, y up, looking along +z) is ours turned 180 degrees about y.
    """
    import mitsuba as mi

    to_world = camera.camera_to_world() @ np.diag([-1.0, 1.0, -1.0, 1.0])
    return {
        "type": "perspective",
        "to_world": mi.ScalarTransform4f(to_world.tolist()),
        "fov": camera.fov_x_deg,
        "fov_axis": "x",
        "near_clip": 0.01,
        "far_clip": 1000.0,
        "sampler": {"type": "multijitter"},
        "film": {
            "type": "hdrfilm",
            "width": camera.width,
            "height": camera.height,
            "pixel_format": "rgb",
            "rfilter": {"type": "box"},
        },
    }


def _light(position: tuple[float, float, float]) -> dict:
    """The square area light of side LIGHT_SIZE centred at `position`, emitting downwards only."""
    import mitsuba as mi

    half = 0.5 * LIGHT_SIZE
    # Mitsuba's rectangle spans [-1, 1]^2 in the xy plane facing +z; turning +90 degrees about x faces it down.
    to_world = mi.ScalarTransform4f().translate(list(position)).rotate([1, 0, 0], 90).scale([half, half, 1.0])
    return {
        "type": "rectangle",
        "to_world": to_world,
        "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}},  # a pure emitter
        "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [LIGHT_RADIANCE] * 3}},
    }


def floor_bsdf(albedo: dict) -> dict:
    """The floor's Mitsuba material: a diffuse base of `albedo` (an rgb or bitmap texture dict) under a glossy coat."""
    return {"type": "roughplastic", "distribution": "ggx", "alpha": FLOOR_ROUGHNESS, "int_ior": FLOOR_IOR,
            "diffuse_reflectance": albedo}


def _floor(floor: FloorSpec, texture: FloorTexture | None = None):
    """The plane y = 0 under the scene: diffuse floor color, or `texture` repeated over it (renderer/floor_texture.py
    says where), under a thin glossy coat; a square of half side FLOOR_HALF_SIZE, or a disk of FLOOR_DISK_RADIUS (a
    mesh with the square's texture coordinates, so that the texture lies alike on both)."""
    import mitsuba as mi

    albedo = {"type": "rgb", "value": srgb_to_linear(floor.color).tolist()}
    if texture is not None:
        repeats = 2.0 * FLOOR_HALF_SIZE / texture.scale
        albedo = {"type": "bitmap", "bitmap": mi.Bitmap(np.array(texture.albedo, dtype=np.float32)), "raw": True,
                  "filter_type": "bilinear", "wrap_mode": "repeat",
                  "to_uv": mi.ScalarTransform3f().scale([repeats, repeats])}
    bsdf = floor_bsdf(albedo)
    if floor.shape == "disk":
        angles = np.linspace(0.0, 2.0 * math.pi, DISK_SEGMENTS, endpoint=False)
        rim = np.column_stack([FLOOR_DISK_RADIUS * np.cos(angles), np.zeros(DISK_SEGMENTS),
                               FLOOR_DISK_RADIUS * np.sin(angles)])
        vertices = np.vstack([[0.0, 0.0, 0.0], rim])
        k = np.arange(1, DISK_SEGMENTS + 1)
        faces = np.column_stack([np.zeros(DISK_SEGMENTS, dtype=np.int64), k % DISK_SEGMENTS + 1, k])  # facing up
        uv = np.column_stack(square_uv(vertices[:, 0], vertices[:, 2]))
        return numpy_mesh("floor", vertices, faces, bsdf, uv)
    to_world = mi.ScalarTransform4f().rotate([1, 0, 0], -90).scale([FLOOR_HALF_SIZE, FLOOR_HALF_SIZE, 1.0])
    return {"type": "rectangle", "to_world": to_world, "bsdf": bsdf}
