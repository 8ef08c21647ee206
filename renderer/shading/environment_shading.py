"""Stage 3 of the voxel shader under an environment, or for an object that is not diffuse.

The environment (renderer/environment.py) is split in two (prepare_environment, once per map): its concentrated
bright parts, and the sun, become at most ENVIRONMENT_LIGHTS directional lights, each shadowed through shadow maps
seen from a point LIGHT_DISTANCE away as the area light's points are; the rest (the residual sky) lights the object
through an irradiance map times its ambient occlusion, and its glossy reflections through maps prefiltered by GGX
roughness (the sky's alone; below the horizon a lobe sees the floor). The floor takes the residual sky through the
object's cones (surface.floor_sky_cones), each weighed by the sky's light from its side; the lights times their
shadows, the small ones (a sun, a lamp) with their highlight on its coat; and its coat mirrors the rest of the
environment. A floor texture varies its diffuse base; past a disk floor's rim, and past the floor, the environment
itself shows. The area light, when on, is drawn as lighting.py draws it, with a GGX highlight on glossy objects.

The material (renderer.scene.MaterialSpec) follows Disney's principled BSDF as the path tracer draws it: diffuse
albedo * (1 - metallic), and a GGX lobe of reflectance F0 = 0.08 * specular for the dielectric, the albedo for the
metal, with Schlick's Fresnel and, for the environment, Karis's fitted split-sum terms.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import numpy as np
from numba import njit, prange
from scipy import ndimage

from renderer.camera import Camera
from renderer.color import linear_to_srgb, srgb_to_linear
from renderer.environment import (
    SUN_APERTURE_DEG,
    EnvironmentLight,
    direction_angles,
    environment_light,
    luminance,
    map_directions,
    reduce_map,
    rotate_y,
    sample_angles,
    sample_map,
    texel_solid_angles,
    uniform_environment,
)
from renderer.floor_light import (
    DIFFUSE_FRESNEL_LOSS,
    DIFFUSE_SCALE,
    ENVIRONMENT_SCALE,
    FloorSky,
    coat_entry,
    coat_reflectance,
    environment_floor_terms,
)
from renderer.floor_texture import FloorTexture
from renderer.resample import bilinear_at
from renderer.scene import (
    AMBIENT_RADIANCE,
    LIGHT_RADIANCE,
    LIGHT_SIZE,
    FloorSpec,
    MaterialSpec,
    Scene,
    needs_environment_shading,
)
from renderer.shading.geometry import ObjectGeometry
from renderer.shading.lighting import (
    ShadedImage,
    ShadowMaps,
    _floor_visibility,
    add_reflection_change,
    composite,
    light_form_factors,
    light_points,
    shadow_receivers,
)
from renderer.shading.quality import (
    BLOCKED_SKY_LIGHT,
    FLOOR_BELOW_LIT,
    FLOOR_BOUNCE,
    FLOOR_SHADOW_BIAS,
    FULL_QUALITY,
    SHADOW_BIAS,
    SHADOW_GRAZING_OFFSET,
    SHADOW_NORMAL_OFFSET,
    ShaderQuality,
)
from renderer.shading.surface import FloorReflection, VisibleSurface, camera_floor_points, floor_sky_axes
from renderer.splat import cached_floor_mask

ENVIRONMENT_LIGHTS = 8  # directional lights drawn from a map's bright parts (the sun is one more)
CONCENTRATED = 2.0  # a texel brighter than this many times the sky's mean belongs to a light
MIN_LIGHT_SHARE = 0.02  # a bright part with less of the sky's light stays in it: its own shadows would cost more than
# they show
LIGHT_DISTANCE = 100.0  # world units: a directional light's shadow maps look from a point this far
LOWEST_LIGHT_DEG = 2.0  # a light lower than this casts its shadows from this elevation (the maps need height)
IRRADIANCE_ROWS = 16  # the irradiance map's rows (twice as many columns)
SPECULAR_ROWS = 32  # the prefiltered maps' rows
SPECULAR_ROUGHNESS = (0.0, 0.15, 0.3, 0.5, 0.75, 1.0)  # the roughness of each prefiltered map
SMALL_LIGHT_SPREAD = 0.1  # radians: a light this small (a sun, a lamp) the floor's coat shows as its own highlight,
# which the object's shadow hides; a larger one (a soft box) stays in the map the coat mirrors, whose shape it keeps
MAX_SHADOW_SPREAD = 0.25  # radians: a wider light's shadows are drawn as this wide (the maps' taps grow sparse)
MIN_ROUGHNESS = 0.05  # as the path tracer's (renderer/pathtrace/mitsuba_object.py)
DIELECTRIC_F0 = 0.08  # times `specular`: principled's reflectance head on
FLOOR_COAT_ROUGHNESS = 0.32  # sqrt of the floor coat's GGX alpha (renderer.scene.FLOOR_ROUGHNESS = 0.1)
DIFFUSE = MaterialSpec()


@dataclass(frozen=True, eq=False)
class PreparedEnvironment:
    """An environment map split for the shader, in the map's frame and at strength 1 (rotation-free)."""

    light_directions: np.ndarray  # (K, 3) unit, towards each light
    light_irradiance: np.ndarray  # (K, 3) facing the light
    light_spread: np.ndarray  # (K,) radians: the angular radius of the part each light stands for
    light_small: np.ndarray  # (K,) bool: small enough for the floor's coat to show it as a highlight of its own
    irradiance: np.ndarray  # (IRRADIANCE_ROWS, 2 x, 3): the residual sky's irradiance on a surface facing each texel
    sky_up: np.ndarray  # (3,) the residual sky's irradiance on the floor
    residual_sky: np.ndarray  # (SPECULAR_ROWS, 2 x, 3): the residual sky above the horizon (0 below)
    specular: PrefilteredSky  # the whole map's sky, prefiltered by GGX
    blurred: np.ndarray  # the map less its small lights (drawn as highlights), blurred by COAT_SAMPLE_BLUR texels
    coat_specular: PrefilteredSky  # the same map less its small lights, prefiltered


_PREPARED: dict[tuple, PreparedEnvironment] = {}


def prepared(environment: EnvironmentLight) -> PreparedEnvironment:
    """prepare_environment of the environment's lighting map, kept for the few sources last used."""
    key = environment.source_key
    if key not in _PREPARED:
        if len(_PREPARED) >= 8:
            _PREPARED.pop(next(iter(_PREPARED)))
        _PREPARED[key] = prepare_environment(environment.lighting)
    return _PREPARED[key]


def prepare_environment(lighting: np.ndarray) -> PreparedEnvironment:
    """Split a lighting map (h, 2h, 3) into directional lights, an irradiance map and prefiltered maps."""
    radiance = np.asarray(lighting, dtype=np.float64)
    h, w = radiance.shape[:2]
    directions = map_directions(h, w)
    solid = np.broadcast_to(texel_solid_angles(h, w), (h, w))
    sky = directions[..., 1] > 0.0  # the floor hides the rest from the object
    lum = luminance(radiance)
    mean = float(np.sum(lum * solid * sky) / max(np.sum(solid * sky), 1e-12))
    threshold = CONCENTRATED * mean
    bright = sky & (lum > threshold) & (threshold > 0.0)
    labels, count = ndimage.label(bright)
    residual = radiance.copy()
    coat = radiance.copy()  # what the floor's coat mirrors from the map: all but the small lights
    lights = []
    if count:
        excess_share = np.where(bright, 1.0 - threshold / np.maximum(lum, 1e-30), 0.0)
        excess = radiance * excess_share[..., None]
        power = ndimage.sum_labels(luminance(excess) * solid, labels, index=np.arange(1, count + 1))
        enough = MIN_LIGHT_SHARE * float(np.sum(lum * solid * sky))
        for label in np.argsort(power)[::-1][:ENVIRONMENT_LIGHTS] + 1:
            if power[label - 1] < enough:
                break
            part = labels == label
            weights = (luminance(excess) * solid)[part]
            direction = np.sum(directions[part] * weights[:, None], axis=0)
            direction /= max(np.linalg.norm(direction), 1e-12)
            irradiance = np.sum(excess[part] * solid[part][:, None], axis=0)
            spread = math.sqrt(float(np.sum(solid[part])) / math.pi)
            lights.append((direction, irradiance, spread))
            residual[part] -= excess[part]
            if spread <= SMALL_LIGHT_SPREAD:
                coat[part] -= excess[part]
    residual_sky = residual * sky[..., None]
    up = np.maximum(directions.reshape(-1, 3)[:, 1], 0.0)
    sky_up = (up * coat_entry(up)) @ (residual_sky * solid[..., None]).reshape(-1, 3)
    # The irradiance map from the residual sky reduced as the specular maps are (the cosine lobe is broad).
    reduced = reduce_map(residual_sky.astype(np.float32), 2 * SPECULAR_ROWS).reshape(-1, 3)
    irradiance = (_irradiance_cosines() @ reduced).reshape(IRRADIANCE_ROWS, 2 * IRRADIANCE_ROWS, 3)
    return PreparedEnvironment(
        light_directions=np.array([d for d, _, _ in lights]).reshape(-1, 3),
        light_irradiance=np.array([e for _, e, _ in lights]).reshape(-1, 3),
        light_spread=np.array([s for _, _, s in lights]),
        light_small=np.array([s <= SMALL_LIGHT_SPREAD for _, _, s in lights], dtype=bool),
        irradiance=irradiance.astype(np.float32), sky_up=sky_up,
        residual_sky=reduced.reshape(SPECULAR_ROWS, 2 * SPECULAR_ROWS, 3),
        specular=PrefilteredSky(radiance),
        coat_specular=PrefilteredSky(coat),
        blurred=ndimage.gaussian_filter(coat, (COAT_SAMPLE_BLUR, COAT_SAMPLE_BLUR, 0),
                                        mode=("nearest", "wrap", "nearest")).astype(np.float32))


class PrefilteredSky:
    """A map's sky, reduced to SPECULAR_ROWS rows, convolved with the GGX lobe of a roughness (about the reflected
    direction, as if normal, view and reflection coincided) over the texels above the floor alone, normalised so that
    a constant sky stays constant: what a lobe sees below the horizon is the floor, which the shader adds itself
    (_floor_seen). Each roughness is made on first use and kept: a new sky pays only for the lobes drawn. The
    cosines between the reduced map's texels are computed once (_specular_cosines)."""

    def __init__(self, radiance: np.ndarray):
        radiance = np.asarray(radiance, dtype=np.float32)
        self._sources = {rows: np.ascontiguousarray(reduce_map(radiance, 2 * rows).reshape(-1, 3))
                         for rows in (SPECULAR_ROWS, SPECULAR_ROWS // 2)}
        self._levels: dict[float, np.ndarray] = {}

    def at(self, roughness: float) -> np.ndarray:
        """(SPECULAR_ROWS, 2 x, 3): the sky prefiltered at `roughness` (0: the reduced map itself)."""
        if roughness not in self._levels:
            if roughness == 0.0:
                out = self._sources[SPECULAR_ROWS]
            else:
                rows = SPECULAR_ROWS if roughness < 0.5 else SPECULAR_ROWS // 2  # a broad lobe reads a coarser map
                cosine, solid = _specular_cosines(rows)
                out = np.empty((2 * SPECULAR_ROWS**2, 3), dtype=np.float32)
                _ggx_convolve(cosine, solid[0] * _above_floor(rows), self._sources[rows],
                              max(roughness, MIN_ROUGHNESS) ** 4, out)
            self._levels[roughness] = out.reshape(SPECULAR_ROWS, 2 * SPECULAR_ROWS, 3)
        return self._levels[roughness]


@njit(cache=True, parallel=True)
def _ggx_convolve(cosine, solid, source, a2, out):
    """out[i] = the mean of `source` weighted by GGX's D at the half angle times the cosine, over the texels within
    90 degrees of texel i (cosine: between texels; solid: their solid angles), in one compiled pass."""
    for i in prange(cosine.shape[0]):
        total, r, g, b = 0.0, 0.0, 0.0, 0.0
        for j in range(cosine.shape[1]):
            c = cosine[i, j]
            if c <= 0.0:
                continue
            denominator = (1.0 + c) * 0.5 * (a2 - 1.0) + 1.0
            weight = c * solid[j] / (denominator * denominator)
            total += weight
            r += weight * source[j, 0]
            g += weight * source[j, 1]
            b += weight * source[j, 2]
        total = max(total, 1e-30)
        out[i, 0], out[i, 1], out[i, 2] = r / total, g / total, b / total


@lru_cache(maxsize=2)
def _specular_cosines(rows: int) -> tuple[np.ndarray, np.ndarray]:
    """The cosines (float32) between the texel directions of a SPECULAR_ROWS-row map and those of a `rows`-row map,
    and the latter's solid angles."""
    into = map_directions(SPECULAR_ROWS, 2 * SPECULAR_ROWS).reshape(-1, 3)
    directions = map_directions(rows, 2 * rows).reshape(-1, 3)
    solid = np.broadcast_to(texel_solid_angles(rows, 2 * rows), (rows, 2 * rows))
    return (np.clip(into @ directions.T, -1.0, 1.0).astype(np.float32), solid.reshape(1, -1).astype(np.float32))


@lru_cache(maxsize=2)
def _above_floor(rows: int) -> np.ndarray:
    """(rows x 2 rows,) float32: 1 at the texels of a `rows`-row map above the horizon, 0 below."""
    return (map_directions(rows, 2 * rows)[..., 1] > 0.0).reshape(-1).astype(np.float32)


@lru_cache(maxsize=1)
def _irradiance_cosines() -> np.ndarray:
    """max(0, cos) (float32) between the irradiance map's normals and a SPECULAR_ROWS-row map's texels, times the
    texels' solid angles: the irradiance map is this times the reduced map."""
    normals = map_directions(IRRADIANCE_ROWS, 2 * IRRADIANCE_ROWS).reshape(-1, 3)
    directions = map_directions(SPECULAR_ROWS, 2 * SPECULAR_ROWS).reshape(-1, 3)
    solid = texel_solid_angles(SPECULAR_ROWS, 2 * SPECULAR_ROWS)
    solid = np.broadcast_to(solid, (SPECULAR_ROWS, 2 * SPECULAR_ROWS)).reshape(1, -1)
    return (np.maximum(normals @ directions.T, 0.0) * solid).astype(np.float32)


@dataclass(frozen=True)
class _Lights:
    """The environment's directional lights in the world, the sun among them, scaled by the strength."""

    directions: np.ndarray  # (K, 3)
    irradiance: np.ndarray  # (K, 3)
    spread: np.ndarray  # (K,)
    delta: np.ndarray  # (K,) bool: the sun, which no map holds (its gloss is drawn from it; the others' from the map)
    small: np.ndarray  # (K,) bool: the sun and the map's small lights, whose gloss on the floor is drawn from them


def _world_lights(environment: EnvironmentLight, ready: PreparedEnvironment) -> _Lights:
    directions = rotate_y(ready.light_directions, environment.rotation_deg).reshape(-1, 3)
    irradiance = ready.light_irradiance.reshape(-1, 3) * environment.strength
    spread = np.minimum(ready.light_spread.reshape(-1), MAX_SHADOW_SPREAD)
    delta = np.zeros(len(directions), dtype=bool)
    small = ready.light_small.reshape(-1)
    if environment.sun_direction is not None and environment.sun_irradiance.max() > 0.0:
        directions = np.vstack([environment.sun_direction, directions])
        irradiance = np.vstack([environment.sun_irradiance, irradiance])
        spread = np.concatenate([[math.radians(SUN_APERTURE_DEG / 2.0)], spread])
        delta = np.concatenate([[True], delta])
        small = np.concatenate([[True], small])
    keep = irradiance.max(axis=1) > 0.0
    return _Lights(directions[keep], irradiance[keep], spread[keep], delta[keep], small[keep])


def lighting_key(scene: Scene) -> tuple:
    """Names everything of the scene that the shader's lighting stage reads besides the object and the floor color."""
    light = scene.light
    if not needs_environment_shading(scene):
        return light.position
    return (light.position, light.enabled, scene.environment, scene.object.material, scene.floor)


def scene_environment(scene: Scene) -> EnvironmentLight:
    """The scene's environment, or its uniform ambient light as one."""
    environment = environment_light(scene)
    return uniform_environment(AMBIENT_RADIANCE) if environment is None else environment


def shade_environment(geometry: ObjectGeometry, surface: VisibleSurface, light_position, floor_color,
                      environment: EnvironmentLight, material: MaterialSpec = DIFFUSE,
                      reflection: FloorReflection | None = None,
                      quality: ShaderQuality = FULL_QUALITY, floor_cones: np.ndarray | None = None,
                      floor_texture: FloorTexture | None = None, floor_shape: str = "square",
                      owners: tuple[np.ndarray, np.ndarray | None] | None = None) -> ShadedImage:
    """The shaded image under `environment` and, unless `light_position` is None, the area light; the object of
    `material`, or of several objects each of its material (`material` a sequence, `owners` the object of each
    surface point and of each reflection point: renderer/shading/compose.py). `reflection`: the floor's mirror image
    of the object, if drawn. `floor_cones`: the sky the object
    leaves open to each floor point, per direction (surface.floor_sky_cones), which the sky's light weighs.
    `floor_texture`: the floor's albedo instead of `floor_color` (whose place its mean takes). `floor_shape`: one of
    renderer.scene.FLOOR_SHAPES; past a disk's edge the environment shows."""
    if floor_texture is not None:
        floor_color = floor_texture.mean_srgb
    ready = prepared(environment)
    lights = _world_lights(environment, ready)
    size = surface.size
    camera = Camera(geometry.elevation_deg, width=size, height=size)
    floor_albedo = srgb_to_linear(np.asarray(floor_color, dtype=np.float64))
    # The coat's reflection averages the map over a fixed set of directions a few degrees apart: it reads the map
    # blurred by about as much, so that a small bright source shows as a highlight, not as streaks of samples.
    sky_up = ready.sky_up * environment.strength  # the residual sky's irradiance on the floor
    floor_sky = FloorSky(sky_up, ready.blurred, environment.rotation_deg, environment.strength)
    empty_floor = environment_floor_terms(camera, light_position, floor_color, floor_sky, lights.directions,
                                          lights.irradiance, lights.small, lights.spread, floor_texture is not None)
    floor_terms, per_light = empty_floor.terms, empty_floor.per_light
    block = geometry.occluder_width
    area = _ShadowMaps.area(geometry, light_position, quality, block) if light_position is not None else None
    suns = [_ShadowMaps.directional(geometry, d, s, block) for d, s in zip(lights.directions, lights.spread)]

    square = floor_terms.floor  # the floor's terms, shadows and points are the square's; a disk shows part of it
    floor, held = _shown_floor(geometry.elevation_deg, size, floor_shape)
    visibility = np.ones((size, size), dtype=np.float32)
    if area is not None and not geometry.empty:
        visibility[square] = area.floor_visibility(surface, block)
    image = np.empty((size, size, 3), dtype=np.float32)
    radiance, seen = np.zeros((0, 3), dtype=np.float32), np.zeros(0, dtype=np.float32)
    if len(surface.points):
        radiance, seen = _radiance_by_material(
            owners[0] if owners else None, material, surface.points, surface.normals, surface.albedo,
            surface.occlusion, camera.position, light_position, area, suns, lights, ready, environment,
            block=block, sky_up=sky_up, floor_albedo=floor_albedo)
    r, c = surface.pixels[:, 0], surface.pixels[:, 1]
    cover = surface.coverage[r, c]
    floor_occlusion = surface.images.floor_occlusion
    if floor_cones is not None:
        open_sky = floor_cones @ _cone_sky_shares(ready, environment).astype(np.float32)
        floor_occlusion = floor_occlusion.copy()
        floor_occlusion[square] = np.minimum(floor_occlusion[square],
                                             1.0 - (1.0 - open_sky) * (1.0 - BLOCKED_SKY_LIGHT))
    composite(floor_terms.from_light, floor_terms.from_ambient, *floor_terms.row_weights, *floor_terms.col_weights,
              floor, visibility, floor_occlusion, np.zeros(3, dtype=np.float32), r, c, radiance, cover, image)
    shown = 1.0 - surface.coverage
    rows, cols, theta, phi = _background_rays(geometry.elevation_deg, size, floor_shape)
    if len(rows):
        background = sample_angles(environment.background, theta, phi, environment.rotation_deg)
        image[rows, cols] += background * np.float32(environment.strength) * shown[rows, cols, None]
    floor_rows, floor_cols = _floor_pixels(geometry.elevation_deg, size)
    shadowed = np.ones((len(per_light), len(floor_rows)), dtype=np.float32)
    if not geometry.empty:
        for k, maps in enumerate(suns):
            shadowed[k] = maps.floor_visibility(surface, block)
    if held is not None:
        floor_rows, floor_cols, shadowed = floor_rows[held], floor_cols[held], np.ascontiguousarray(shadowed[:, held])
    if len(per_light):
        add_floor_lights(image, np.stack(per_light), shadowed, floor_rows, floor_cols, *floor_terms.row_weights,
                         *floor_terms.col_weights, shown)
    if floor_texture is not None:
        # The texture varies the diffuse base alone: the base lit as the floor is, once more, times the texture's
        # albedo over its mean less one, added where the floor shows (the coat reflects as it did).
        base_terms, base_lights = empty_floor.base_terms, empty_floor.base_per_light
        base = np.zeros_like(image)
        none = np.zeros(0, dtype=np.int64)
        composite(base_terms.from_light, base_terms.from_ambient, *base_terms.row_weights, *base_terms.col_weights,
                  floor, visibility, floor_occlusion, np.zeros(3, dtype=np.float32), none, none,
                  np.zeros((0, 3), dtype=np.float32), np.zeros(0, dtype=np.float32), base)
        if len(base_lights):
            add_floor_lights(base, np.stack(base_lights), shadowed, floor_rows, floor_cols, *base_terms.row_weights,
                             *base_terms.col_weights, np.ones_like(shown))
        change = _texture_change(floor_texture, camera)
        change = change if held is None else change[held]
        image[floor_rows, floor_cols] += (base[floor_rows, floor_cols] * change
                                          * shown[floor_rows, floor_cols, None]).astype(np.float32)
    if reflection is not None and len(reflection.points):
        _add_reflection(image, surface, reflection, camera, light_position, area, suns, lights, ready, environment,
                        material, block, sky_up, floor_albedo, floor, owners[1] if owners else None)
    visibility[r, c] = seen
    images = surface.images
    return ShadedImage(image=linear_to_srgb(np.maximum(image, 0.0)), coverage=surface.coverage, albedo=images.albedo,
                       albedo_srgb=images.albedo_srgb, normal=images.normal, depth=images.depth,
                       visibility=visibility, occlusion=images.occlusion)


def _cone_sky_shares(ready: PreparedEnvironment, environment: EnvironmentLight) -> np.ndarray:
    """(K,): the share of the residual sky's light on the floor (luminance) that arrives nearest each axis of
    surface.floor_sky_axes(), with the environment turned."""
    axes = floor_sky_axes()
    rows = SPECULAR_ROWS
    directions = rotate_y(map_directions(rows, 2 * rows), environment.rotation_deg).reshape(-1, 3)
    weight = (luminance(ready.residual_sky).reshape(-1) * np.maximum(directions[:, 1], 0.0)
              * np.broadcast_to(texel_solid_angles(rows, 2 * rows), (rows, 2 * rows)).reshape(-1))
    shares = np.bincount(np.argmax(directions @ axes.T, axis=1), weights=weight, minlength=len(axes))
    total = float(shares.sum())
    return shares / total if total > 0.0 else np.full(len(axes), 1.0 / len(axes))


COAT_SAMPLE_BLUR = 0.3  # texels of the lighting map: the blur of the map the floor's coat reflection samples


@lru_cache(maxsize=8)
def _shown_floor(elevation_deg: float, size: int, shape: str) -> tuple[np.ndarray, np.ndarray | None]:
    """The pixels that show a floor of `shape` (H, W), and which of the square floor's pixels (row-major) they are
    (None for the square itself), per camera (read-only)."""
    camera = Camera(elevation_deg, width=size, height=size)
    square = cached_floor_mask(camera)
    if shape == "square":
        return square, None
    _, points, _ = camera_floor_points(camera)
    held = FloorSpec(shape=shape).holds(points[:, 0], points[:, 2])
    shown = np.zeros_like(square)
    shown[square] = held
    shown.flags.writeable = False
    held.flags.writeable = False
    return shown, held


@lru_cache(maxsize=8)
def _background_rays(elevation_deg: float, size: int, shape: str = "square") -> tuple[np.ndarray, ...]:
    """The pixels that show no floor of `shape` and the angles of their rays (direction_angles), per camera
    (read-only)."""
    camera = Camera(elevation_deg, width=size, height=size)
    rows, cols = np.nonzero(~_shown_floor(elevation_deg, size, shape)[0])
    _, rays = camera.pixel_rays(cols + 0.5, rows + 0.5)
    out = (rows, cols, *direction_angles(rays))
    for array in out:
        array.flags.writeable = False
    return out


@lru_cache(maxsize=8)
def _floor_pixels(elevation_deg: float, size: int) -> tuple[np.ndarray, np.ndarray]:
    """The rows and columns of the pixels that show the floor, row-major (as VisibleSurface's floor points), per
    camera (read-only)."""
    rows, cols = np.nonzero(cached_floor_mask(Camera(elevation_deg, width=size, height=size)))
    rows.flags.writeable = False
    cols.flags.writeable = False
    return rows, cols


@lru_cache(maxsize=4)
def _texture_change(texture: FloorTexture, camera: Camera) -> np.ndarray:
    """(F, 3) float32: the texture's albedo over each floor pixel (FloorTexture.albedo_at, the pixel's footprint) over
    its mean, less one, per texture and camera (read-only)."""
    _, points, _ = camera_floor_points(camera)
    rows, cols = _floor_pixels(camera.elevation_deg, camera.width)
    # A pixel's footprint on the floor: how far the floor point moves to the next pixel across and down.
    footprint = np.zeros(len(points))
    for du, dv in ((1.0, 0.0), (0.0, 1.0)):
        origin, dirs = camera.pixel_rays(cols + 0.5 + du, rows + 0.5 + dv)
        dirs[:, 1] = np.minimum(dirs[:, 1], -1e-6)
        step = origin + (-origin[1] / dirs[:, 1])[:, None] * dirs - points
        footprint = np.maximum(footprint, np.linalg.norm(step, axis=1))
    mean = srgb_to_linear(np.asarray(texture.mean_srgb, dtype=np.float64))
    change = (texture.albedo_at(points, footprint) / np.maximum(mean, 1e-6) - 1.0).astype(np.float32)
    change.flags.writeable = False
    return change


@njit(cache=True, parallel=True)
def add_floor_lights(image, terms, shadowed, rows, cols, top, bottom, down, left, right, across, shown):
    """image[rows[i], cols[i]] += the sum over lights k of their coarse floor radiance terms[k] (K, h, w, 3),
    interpolated bilinearly at the pixel (bilinear_at), times the share of the light the point sees, shadowed[k, i],
    times the share of the pixel that shows the floor, `shown`: one pass instead of full-size images per light."""
    for i in prange(rows.shape[0]):
        r, c = rows[i], cols[i]
        for channel in range(3):
            total = np.float32(0.0)
            for k in range(terms.shape[0]):
                total += bilinear_at(terms[k], top[r], bottom[r], down[r], left[c], right[c], across[c],
                                     channel) * shadowed[k, i]
            image[r, c, channel] += total * shown[r, c]


class _ShadowMaps:
    """Shadow maps of one light: the area light's points, or one far point standing for a directional light."""

    def __init__(self, geometry: ObjectGeometry, points: np.ndarray, spacing: float, block: float):
        self.points = points
        self.spacing = spacing  # the side of the light's square each point stands for (0: a point)
        self.shadows = ShadowMaps(geometry, points, block)

    @classmethod
    def area(cls, geometry: ObjectGeometry, light_position, quality: ShaderQuality, block: float) -> _ShadowMaps:
        return cls(geometry, light_points(light_position, quality.light_points), LIGHT_SIZE / quality.light_points,
                   block)

    @classmethod
    def directional(cls, geometry: ObjectGeometry, direction: np.ndarray, spread: float, block: float) -> _ShadowMaps:
        lowest = math.sin(math.radians(LOWEST_LIGHT_DEG))
        d = np.array([direction[0], max(direction[1], lowest), direction[2]])
        d /= np.linalg.norm(d)
        centre = np.asarray(geometry.occluder_box, dtype=np.float64).mean(axis=0) * np.array([1.0, 0.0, 1.0])
        return cls(geometry, (centre + LIGHT_DISTANCE * d)[None], 2.0 * LIGHT_DISTANCE * math.tan(spread), block)

    def visibility(self, receivers: np.ndarray, bias: float) -> np.ndarray:
        out = np.empty(len(receivers))
        self.shadows.visibility(receivers, bias, self.spacing, out)
        return out

    def floor_visibility(self, surface: VisibleSurface, block: float) -> np.ndarray:
        return _floor_visibility(surface, self.shadows, FLOOR_SHADOW_BIAS * block, self.spacing)

    def object_visibility(self, points: np.ndarray, normals: np.ndarray, toward: np.ndarray, block: float,
                          facing: np.ndarray) -> np.ndarray:
        """Share of the light the points facing it see (`toward`: a point on the light, for the receivers' offset)."""
        seen = np.zeros(len(points))
        if len(facing):
            receivers = np.empty((len(facing), 3))
            shadow_receivers(points, normals, facing, np.asarray(toward, dtype=np.float64),
                             block * SHADOW_NORMAL_OFFSET, block * SHADOW_GRAZING_OFFSET, receivers)
            seen[facing] = self.visibility(receivers, SHADOW_BIAS * block)
        return seen


def _radiance_by_material(owner: np.ndarray | None, material: MaterialSpec | Sequence[MaterialSpec], points: np.ndarray,
                          *args: Any, **kwargs: Any) -> tuple[np.ndarray, np.ndarray]:
    """_object_radiance of points of one `material`, or of several objects' points, `owner` (N,) naming each point's
    object and `material` a sequence of the objects' materials: each material's points apart."""
    if isinstance(material, MaterialSpec):
        return _object_radiance(points, *args, material=material, **kwargs)
    radiance, seen = np.zeros((len(points), 3), dtype=np.float32), np.ones(len(points), dtype=np.float32)
    for kind in dict.fromkeys(material):
        mine = np.isin(owner, [k for k, m in enumerate(material) if m == kind])
        if mine.any():
            radiance[mine], seen[mine] = _object_radiance(points[mine], *(a[mine] for a in args[:3]), *args[3:],
                                                          material=kind, **kwargs)
    return radiance, seen


def _object_radiance(points: np.ndarray, normals: np.ndarray, albedo: np.ndarray, occlusion: np.ndarray,
                     eye: np.ndarray, light_position, area: _ShadowMaps | None, suns: list[_ShadowMaps],
                     lights: _Lights, ready: PreparedEnvironment, environment: EnvironmentLight,
                     material: MaterialSpec, block: float, sky_up: np.ndarray,
                     floor_albedo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Linear radiance (N, 3) of object points and the share of the strongest light each sees."""
    n = len(points)
    normals = np.asarray(normals, dtype=np.float64)
    view = eye[None, :] - points
    view /= np.maximum(np.linalg.norm(view, axis=1, keepdims=True), 1e-12)
    diffuse_albedo = albedo * (1.0 - material.metallic)
    f0 = DIELECTRIC_F0 * material.specular * (1.0 - material.metallic) + albedo * material.metallic
    roughness = max(material.roughness, MIN_ROUGHNESS)
    glossy = not material.diffuse_only
    irradiance = np.zeros((n, 3))
    specular = np.zeros((n, 3))
    seen = np.ones(n)
    strongest = -1.0
    floor_lit = np.broadcast_to(sky_up, (n, 3)).copy()  # the floor's irradiance: the sky's, unshadowed
    floor_irradiance = floor_lit.copy()  # under the object: its shadow takes a share of the lights
    if area is not None:
        form = np.empty(n)
        form_below = np.empty(n)
        light_form_factors(points, normals, area.points, LIGHT_SIZE**2 / len(area.points), form, form_below)
        share = area.object_visibility(points, normals, light_position, block, np.flatnonzero(form > 0.0))
        irradiance += (LIGHT_RADIANCE * share * form)[:, None]
        floor_irradiance += (LIGHT_RADIANCE * form_below * FLOOR_BELOW_LIT)[:, None]
        floor_lit += (LIGHT_RADIANCE * form_below)[:, None]
        seen, strongest = share, LIGHT_RADIANCE * float(np.max(form, initial=0.0))
        if glossy:
            for point in area.points:
                to_light = point[None, :] - points
                distance2 = np.maximum(np.sum(to_light**2, axis=1), 1e-8)
                direction = to_light / np.sqrt(distance2)[:, None]
                power = LIGHT_RADIANCE * LIGHT_SIZE**2 / len(area.points) * np.maximum(direction[:, 1], 0.0) / distance2
                widened = min(1.0, roughness + 0.5 * LIGHT_SIZE / len(area.points) ** 0.5 / math.sqrt(float(np.mean(distance2))))
                specular += (_ggx_reflectance(normals, view, direction, widened, f0)
                             * (power * share)[:, None])
    for direction, power, maps, delta in zip(lights.directions, lights.irradiance, suns, lights.delta):
        cosine = normals @ direction
        share = maps.object_visibility(points, normals, maps.points[0], block, np.flatnonzero(cosine > 0.0))
        irradiance += np.maximum(cosine, 0.0)[:, None] * share[:, None] * power[None, :]
        on_floor = max(direction[1], 0.0) * float(coat_entry(direction[1]))  # what the floor's base receives
        floor_irradiance += (on_floor * FLOOR_BELOW_LIT) * power[None, :]
        floor_lit += on_floor * power[None, :]
        if glossy and delta:  # the other lights' gloss is in the prefiltered map
            widened = min(1.0, roughness + float(maps.spacing / (2.0 * LIGHT_DISTANCE)))
            specular += _ggx_reflectance(normals, view, np.broadcast_to(direction, normals.shape), widened,
                                         f0) * (share[:, None] * power[None, :])
        if float(np.max(power)) * max(direction[1], 0.0) > strongest:
            seen, strongest = share, float(np.max(power)) * max(direction[1], 0.0)
    sky = sample_map(ready.irradiance, normals, environment.rotation_deg) * environment.strength * occlusion[:, None]
    bounce = FLOOR_BOUNCE * floor_irradiance * floor_albedo[None, :] * 0.5 * (1.0 - normals[:, 1:2])
    radiance = diffuse_albedo * (irradiance + sky + bounce) / math.pi
    if glossy:
        reflected = 2.0 * np.sum(normals * view, axis=1, keepdims=True) * normals - view
        cos_view = np.clip(np.sum(normals * view, axis=1), 1e-4, 1.0)
        a, b = _split_sum(cos_view, roughness)
        above = _above_horizon(reflected, roughness)
        floor_seen = _floor_seen(reflected, floor_albedo, floor_lit, ready, environment, roughness)
        # The floor near the point is shaded by the object as its sky is: both take its occlusion.
        seen_around = (_specular(ready, environment, reflected, roughness) * above
                       + floor_seen * (1.0 - above)) * occlusion[:, None]
        # What a rough lobe loses to single scattering comes back, in the lobe's own color (Fdez-Aguera's
        # multiple-scattering term on the split sum): rough metal is otherwise darker than the path tracer's.
        energy = 1.0 + f0 * (1.0 / np.maximum(a + b, 0.05) - 1.0)[:, None]
        radiance = radiance + seen_around * (f0 * a[:, None] + b[:, None]) * energy + specular
    return radiance.astype(np.float32), seen.astype(np.float32)


def _specular(ready: PreparedEnvironment, environment: EnvironmentLight, directions: np.ndarray,
              roughness: float) -> np.ndarray:
    """The residual sky prefiltered at `roughness`, seen along world `directions` (..., 3)."""
    levels = np.asarray(SPECULAR_ROUGHNESS)
    upper = int(np.clip(np.searchsorted(levels, roughness), 1, len(levels) - 1))
    t = (roughness - levels[upper - 1]) / (levels[upper] - levels[upper - 1])
    theta, phi = direction_angles(directions)
    turn = environment.rotation_deg
    found = ((1.0 - t) * sample_angles(ready.specular.at(float(levels[upper - 1])), theta, phi, turn)
             + t * sample_angles(ready.specular.at(float(levels[upper])), theta, phi, turn))
    return found * environment.strength


def _floor_seen(directions: np.ndarray, floor_albedo: np.ndarray, floor_lit: np.ndarray, ready: PreparedEnvironment,
                environment: EnvironmentLight, roughness: float) -> np.ndarray:
    """The lit floor (no shadow) as a glossy object sees it along `directions` that point below the horizon: its base
    through the coat, and the coat mirroring the sky, strongest at grazing angles (renderer/floor_light.py's fit)."""
    grazing = coat_reflectance(np.clip(np.abs(directions[:, 1]), 0.0, 1.0))[:, None]
    base = floor_albedo[None, :] * floor_lit / math.pi * (DIFFUSE_SCALE - DIFFUSE_FRESNEL_LOSS * grazing)
    mirrored = directions * np.array([1.0, -1.0, 1.0])
    return base + ENVIRONMENT_SCALE * grazing * _specular(ready, environment, mirrored, max(roughness, FLOOR_COAT_ROUGHNESS))


def _above_horizon(directions: np.ndarray, roughness: float) -> np.ndarray:
    """(N, 1): how much of a glossy lobe about each direction sees the sky rather than the floor (a ramp across the
    horizon as wide as the lobe: about twice GGX's alpha = roughness^2, which measures the half vector's spread)."""
    y = directions[:, 1] / np.maximum(np.linalg.norm(directions, axis=1), 1e-12)
    return np.clip(0.5 + y / (4.0 * max(roughness**2, 0.02)), 0.0, 1.0)[:, None]


def _ggx_reflectance(normals: np.ndarray, view: np.ndarray, light: np.ndarray, roughness: float,
                     f0: np.ndarray) -> np.ndarray:
    """The GGX lobe's BRDF times the cosine at the surface (N, 3), for unit light directions (N, 3)."""
    half = view + light
    half /= np.maximum(np.linalg.norm(half, axis=1, keepdims=True), 1e-12)
    cos_n_l = np.clip(np.sum(normals * light, axis=1), 0.0, 1.0)
    cos_n_v = np.clip(np.sum(normals * view, axis=1), 1e-4, 1.0)
    cos_n_h = np.clip(np.sum(normals * half, axis=1), 0.0, 1.0)
    cos_v_h = np.clip(np.sum(view * half, axis=1), 0.0, 1.0)
    a2 = roughness**4
    d = a2 / (math.pi * (cos_n_h**2 * (a2 - 1.0) + 1.0) ** 2)
    k = roughness**2 / 2.0
    g = (cos_n_l / (cos_n_l * (1.0 - k) + k)) * (cos_n_v / (cos_n_v * (1.0 - k) + k))
    fresnel = f0 + (1.0 - f0) * ((1.0 - cos_v_h) ** 5)[:, None]
    return fresnel * (d * g / (4.0 * cos_n_v))[:, None]


def _split_sum(cos_view: np.ndarray, roughness: float) -> tuple[np.ndarray, np.ndarray]:
    """Karis's analytic fit of the GGX environment BRDF's scale and bias on F0 (the split-sum approximation)."""
    c0 = np.array([-1.0, -0.0275, -0.572, 0.022])
    c1 = np.array([1.0, 0.0425, 1.04, -0.04])
    r = roughness * c0 + c1
    a004 = np.minimum(r[0] * r[0], np.exp2(-9.28 * cos_view)) * r[0] + r[1]
    return a004 * -1.04 + r[2], a004 * 1.04 + r[3]


def _add_reflection(image: np.ndarray, surface: VisibleSurface, reflection: FloorReflection, camera: Camera,
                    light_position, area: _ShadowMaps | None, suns: list[_ShadowMaps], lights: _Lights,
                    ready: PreparedEnvironment, environment: EnvironmentLight,
                    material: MaterialSpec | Sequence[MaterialSpec], block: float, sky_up: np.ndarray,
                    floor_albedo: np.ndarray, floor: np.ndarray, owner: np.ndarray | None = None) -> None:
    """The floor's reflection of the object at the pixels that show the `floor`, where the coat mirrored the
    environment: the object's points lit and seen from the camera mirrored below the floor, less the environment the
    coat showed there (`material`, `owner`: as _radiance_by_material's)."""
    mirror_camera = Camera(camera.elevation_deg, width=reflection.side, height=reflection.side)
    below = mirror_camera.position * np.array([1.0, -1.0, 1.0])
    radiance, _ = _radiance_by_material(owner, material, reflection.points, reflection.normals, reflection.albedo,
                                        reflection.occlusion, below, light_position, area, suns, lights, ready,
                                        environment, block=block, sky_up=sky_up, floor_albedo=floor_albedo)
    _, rays = mirror_camera.pixel_rays(reflection.pixels[:, 1] + 0.5, reflection.pixels[:, 0] + 0.5)
    theta, phi = direction_angles(rays * np.array([1.0, -1.0, 1.0]))
    replaced = (sample_angles(ready.coat_specular.at(FLOOR_COAT_ROUGHNESS), theta, phi, environment.rotation_deg)
                * environment.strength)
    add_reflection_change(image, surface, reflection, radiance - replaced, floor)
