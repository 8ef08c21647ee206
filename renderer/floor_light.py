"""The lit empty floor: how the path tracer's floor looks under the area light, without the object.

An analytic image of the empty scene (no object, so no shadows or bounced light): the square
area light and the ambient environment on the floor's diffuse base and its glossy GGX coat,
the same materials `renderer/pathtrace/path_tracer.py` gives Mitsuba, seen by the render camera.

It is an optional input of NVR+ (`NVRConfig.floor_light_input`): most of the error of a
network that has to discover the light's bright spot and fall-off on the floor from a tiled
light code alone is on the floor (79 % of the test MSE of the 2,014-step compact NVR+, mostly at
low spatial frequency), and this image gives it that shading directly, per pixel. The network still has to
learn everything the object does: its shading, its shadow, its reflection.

Cost: the shading varies slowly over the floor, so it is evaluated on a coarse grid of pixel
centres (COARSE_STEP pixels apart) with LIGHT_SAMPLES^2 points on the light, interpolated
bilinearly to full size, and cut at the horizon with the exact floor mask. The voxel shader's terms
(FloorTerms) stay on the coarse grid and are interpolated where it composites its image, which saves full-size
copies on every light edit (docs/results.md, "Measurements behind the code").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit, prange

from renderer.camera import Camera
from renderer.color import linear_to_srgb, srgb_to_linear
from renderer.environment import direction_angles, weighted_mean_angles
from renderer.errors import InputError
from renderer.resample import linear_weights, upsampled
from renderer.scene import AMBIENT_RADIANCE, FLOOR_IOR, FLOOR_ROUGHNESS, LIGHT_RADIANCE, LIGHT_SIZE
from renderer.splat import cached_floor_mask

LIGHT_SAMPLES = 8  # points per side of the light square (the coat's highlight is ~0.2 rad wide)
COARSE_STEP = 8  # pixels between shading samples
HORIZON_DIRECTION_Y = -1e-3  # rays at or above the horizon are bent down to this to keep the shading smooth

COAT_F0 = ((FLOOR_IOR - 1.0) / (FLOOR_IOR + 1.0)) ** 2  # Schlick's reflectance head on
# Fitted by least squares to 8 path-traced empty floors (256 spp + OIDN, random light, elevation
# and floor color; rms error 0.0045 linear): the diffuse base seen through the coat keeps
# DIFFUSE_SCALE - DIFFUSE_FRESNEL_LOSS * F(view) of albedo * irradiance / pi, and the coat
# reflects ENVIRONMENT_SCALE * F(view) of the ambient light (the GGX lobe of the area light
# came out at 1.04 of its analytic value and is used as is).
DIFFUSE_SCALE = 0.94
DIFFUSE_FRESNEL_LOSS = 0.859
ENVIRONMENT_SCALE = 0.69
# The path tracer's coat (rough plastic, GGX alpha FLOOR_ROUGHNESS) lets less light through to the base the nearer
# to the horizon it comes from: Mitsuba's own floor material, evaluated away from its gloss, at incidence cosines 0,
# 0.1, ..., 1, over its value head on (tests/test_floor_light.py measures it again).
COAT_ENTRY = np.array([0.6023, 0.6326, 0.7363, 0.8265, 0.889, 0.9294, 0.9548, 0.9706, 0.9808, 0.9889, 1.0])
# The share DIFFUSE_SCALE holds, fitted on empty floors under 30 training-split environments (docs/results.md,
# "Environment light and materials"). The area light's floor keeps DIFFUSE_SCALE alone.
COAT_ENTRY_REFERENCE = 0.99


def lit_floor_image(camera: Camera, light_position, floor_color) -> np.ndarray:
    """(H, W, 3) float32 sRGB image of the empty floor lit by the light at `light_position` (world)."""
    geometry = _coarse_geometry(camera)
    from_light, from_ambient = _coarse_radiance(geometry, light_position, floor_color)
    floor = upsampled(linear_to_srgb(from_light + from_ambient).astype(np.float32),  # smooth: sRGB interpolates well
                      geometry.row_weights, geometry.col_weights)
    background = np.float32(linear_to_srgb(AMBIENT_RADIANCE))
    return np.where(geometry.floor[..., None], floor, background)


@dataclass(frozen=True)
class FloorTerms:
    """The empty floor's linear radiance split by source, so a shader can shadow and occlude each: what the area light
    gives (diffuse and glossy) and what the ambient light gives, on the coarse grid of pixel centres the shading is
    evaluated on, with the floor mask and the weights that interpolate them to every pixel
    (renderer.resample.bilinear_at). A shader interpolates them where it composites, without full-size copies (two
    256^2 images for each light edit)."""

    from_light: np.ndarray  # (h, w, 3) float32
    from_ambient: np.ndarray  # (h, w, 3) float32
    floor: np.ndarray  # (H, W) bool: the pixels that show the floor
    row_weights: tuple[np.ndarray, np.ndarray, np.ndarray]  # per image row: the coarse rows around it, the lower's weight
    col_weights: tuple[np.ndarray, np.ndarray, np.ndarray]  # per image column: likewise


def lit_floor_terms(camera: Camera, light_position, floor_color) -> FloorTerms:
    """The empty floor's lighting for a shader that shadows and occludes it (FloorTerms)."""
    geometry = _coarse_geometry(camera)
    from_light, from_ambient = _coarse_radiance(geometry, light_position, floor_color)
    return FloorTerms(from_light, from_ambient, geometry.floor, geometry.row_weights, geometry.col_weights)


@dataclass(frozen=True)
class FloorSky:
    """An environment as the floor receives it: the diffuse irradiance from the sky above it (rgb), and the map whose
    radiance the coat reflects (renderer/environment.py's convention), turned by `turn_deg` and scaled by
    `strength`."""

    irradiance: np.ndarray
    radiance_map: np.ndarray
    turn_deg: float = 0.0
    strength: float = 1.0


COAT_SAMPLES = 12  # per side: GGX half vectors the coat's reflection of an environment is averaged over


def coat_reflection(geometry: _Geometry, sky: FloorSky) -> np.ndarray:
    """The radiance (h, w, 3) the floor's coat reflects towards the camera at the coarse floor points from an
    environment: GGX half vectors drawn from the coat's distribution on a fixed stratified grid (the same for every
    point, so the result is smooth), each reflection weighted by Fresnel and masking over the distribution's own
    share (the usual importance-sampling estimator). The directions and weights depend on the camera alone and are
    kept with the geometry; a turn of the environment only shifts where they read the map."""
    theta, phi, weights = geometry.coat_samples()
    return weighted_mean_angles(sky.radiance_map, theta, phi, weights, sky.turn_deg) * np.float32(sky.strength)


def _coat_samples(view: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """coat_reflection's directions (as angles) and weights, (h, w, S) each, for unit `view` directions (h, w, 3)."""
    n = COAT_SAMPLES
    u1, u2 = ((np.arange(n) + 0.5) / n for _ in range(2))
    u1, u2 = (g.ravel() for g in np.meshgrid(u1, u2, indexing="ij"))
    alpha = FLOOR_ROUGHNESS
    theta = np.arctan(alpha * np.sqrt(u1 / (1.0 - u1)))
    phi = 2.0 * math.pi * u2
    half = np.stack([np.sin(theta) * np.cos(phi), np.cos(theta), np.sin(theta) * np.sin(phi)], axis=1)  # (S, 3)
    v = np.asarray(view, dtype=np.float64)[..., None, :]  # (h, w, 1, 3)
    cos_vh = np.sum(v * half, axis=-1, keepdims=True)  # (h, w, S, 1)
    light = 2.0 * cos_vh * half - v  # the view mirrored about each half vector
    cos_l = np.clip(light[..., 1], 1e-4, 1.0)
    cos_v = np.clip(v[..., 1], 1e-4, 1.0)
    above = (light[..., 1] > 0.0) & (cos_vh[..., 0] > 0.0)
    weight = (coat_fresnel(np.clip(cos_vh[..., 0], 0.0, 1.0)) * _smith_g1(cos_l) * _smith_g1(cos_v)
              * np.clip(cos_vh[..., 0], 0.0, 1.0) / (half[:, 1] * cos_v))
    polar, azimuth = direction_angles(light)
    return polar, azimuth, np.where(above, weight, 0.0)


@dataclass(frozen=True)
class EnvironmentFloor:
    """The empty floor under an environment (environment_floor_terms): its FloorTerms and per directional light its
    coarse (h, w, 3) radiance, unshadowed; and, if asked for, the same of its diffuse base alone (what a texture
    varies; the coat reflects as it does)."""

    terms: FloorTerms
    per_light: list[np.ndarray]
    base_terms: FloorTerms | None = None
    base_per_light: list[np.ndarray] | None = None


def environment_floor_terms(camera: Camera, light_position, floor_color, sky: FloorSky, directions: np.ndarray,
                            irradiance: np.ndarray, glossy: np.ndarray, spread: np.ndarray | None = None,
                            with_base: bool = False) -> EnvironmentFloor:
    """The empty floor under an environment: FloorTerms whose `from_light` is the area light's (zero when
    `light_position` is None) and whose `from_ambient` is the sky's, and per directional light (unit world
    `directions` (K, 3) towards it, rgb `irradiance` (K, 3) facing it) its radiance, with the coat's highlight where
    `glossy` says (a light the mirrored sky does not hold already), widened by the light's angular radius `spread`
    (K,) radians (default 0: a point). `with_base`: the diffuse base alone too, from the same pass."""
    geometry = _coarse_geometry(camera)
    albedo = srgb_to_linear(np.asarray(floor_color, dtype=np.float64)).astype(np.float32)
    through_coat = (DIFFUSE_SCALE - DIFFUSE_FRESNEL_LOSS * geometry.view_fresnel) / math.pi
    if light_position is None:
        light_base = light_coat = np.zeros((*geometry.cos_view.shape, 3), dtype=np.float32)
    else:
        light_base, light_coat, _, _ = _coarse_radiance_parts(geometry, light_position, floor_color)
    view = geometry.view
    sky_base = (through_coat[..., None] * np.asarray(sky.irradiance, dtype=np.float32) * albedo).astype(np.float32)
    sky_coat = coat_reflection(geometry, sky)
    per_light, base_per_light = [], []
    spread = np.zeros(len(glossy)) if spread is None else spread
    for direction, power, gloss, radius in zip(np.asarray(directions, dtype=np.float64),
                                               np.asarray(irradiance, dtype=np.float64), glossy, spread):
        cos_in = max(float(direction[1]), 0.0)
        power = power.astype(np.float32)
        base = (cos_in * float(coat_entry(cos_in)) * through_coat[..., None] * albedo * power).astype(np.float32)
        base_per_light.append(base)
        if not gloss:
            per_light.append(base)
            continue
        half = view + direction.astype(np.float32)
        half /= np.maximum(np.linalg.norm(half, axis=-1, keepdims=True), 1e-12)
        cos_half = np.clip(half[..., 1], 0.0, 1.0)
        cos_in_half = np.clip(np.sum(half * direction.astype(np.float32), axis=-1), 0.0, 1.0)
        highlight = (coat_fresnel(cos_in_half) * _ggx_widened(cos_half, 0.5 * float(radius))
                     * _smith_g1(max(cos_in, 1e-4)) * geometry.view_masking / (4.0 * geometry.cos_view))
        per_light.append((base + highlight[..., None] * power).astype(np.float32))

    def floor_terms(from_light: np.ndarray, from_sky: np.ndarray) -> FloorTerms:
        return FloorTerms(from_light.astype(np.float32), from_sky.astype(np.float32), geometry.floor,
                          geometry.row_weights, geometry.col_weights)

    terms = floor_terms(light_base + light_coat, sky_base + sky_coat)
    if not with_base:
        return EnvironmentFloor(terms, per_light)
    return EnvironmentFloor(terms, per_light, floor_terms(light_base, sky_base), base_per_light)


def _coarse_radiance(geometry: _Geometry, light_position, floor_color) -> tuple[np.ndarray, np.ndarray]:
    """Linear radiance (h, w, 3) of the coarse floor points: from the area light, from the ambient light."""
    light_base, light_coat, ambient_base, ambient_coat = _coarse_radiance_parts(geometry, light_position, floor_color)
    return (light_base + light_coat).astype(np.float32), (ambient_base + ambient_coat).astype(np.float32)


def _coarse_radiance_parts(geometry: _Geometry, light_position, floor_color) -> tuple[np.ndarray, ...]:
    """_coarse_radiance split: the area light's through the coat and off it, the ambient light's likewise."""
    light = np.asarray(light_position, dtype=np.float64)
    color = np.asarray(floor_color, dtype=np.float64)
    if light.shape != (3,) or not np.all(np.isfinite(light)) or light[1] <= 0.0:
        raise InputError(f"light position must be 3 finite values above the floor, got {light_position!r}")
    if color.shape != (3,) or not np.all(np.isfinite(color)):
        raise InputError(f"floor color must be 3 finite sRGB values, got {floor_color!r}")
    albedo = srgb_to_linear(color).astype(np.float32)
    diffuse_irradiance, glossy = _light_terms(geometry, light)
    through_coat = (DIFFUSE_SCALE - DIFFUSE_FRESNEL_LOSS * geometry.view_fresnel) / math.pi
    light_base = LIGHT_RADIANCE * diffuse_irradiance * through_coat
    ambient_base = AMBIENT_RADIANCE * np.maximum(math.pi - diffuse_irradiance, 0.0) * through_coat
    return (light_base[..., None] * albedo, (LIGHT_RADIANCE * glossy)[..., None], ambient_base[..., None] * albedo,
            (ENVIRONMENT_SCALE * AMBIENT_RADIANCE * geometry.view_fresnel)[..., None])


# --- per-camera geometry (cached: the editor lights many frames with one camera) ------------


class _Geometry:
    """Floor points of the coarse pixel grid, their view terms, and the full-size interpolation."""

    def __init__(self, camera: Camera):
        self.floor = cached_floor_mask(camera)
        points, self.row_weights, self.col_weights = coarse_floor_grid(camera, COARSE_STEP)
        to_camera = camera.position - points
        self.points = points.astype(np.float32)
        self.view = (to_camera / np.linalg.norm(to_camera, axis=-1, keepdims=True)).astype(np.float32)
        self.cos_view = np.clip(self.view[..., 1], 1e-4, 1.0)
        self.view_fresnel = coat_reflectance(self.cos_view)
        self.view_masking = _smith_g1(self.cos_view)
        for array in (self.floor, self.points, self.view):
            array.flags.writeable = False
        self._coat = None

    def coat_samples(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """_coat_samples of these points' view directions, made on first use (only environments read them)."""
        if self._coat is None:
            self._coat = _coat_samples(self.view)
        return self._coat


def coarse_floor_grid(camera: Camera, step: int) -> tuple[np.ndarray, tuple, tuple]:
    """Where the rays of pixel centres `step` pixels apart (and at the image's last row and column, so that
    interpolation never extrapolates) meet the floor, (h, w, 3), rays at or above the horizon bent down to
    HORIZON_DIRECTION_Y; and the weights that interpolate values there to every pixel (linear_weights of the rows,
    of the columns)."""
    rows = np.arange(0.5, camera.height, step)
    cols = np.arange(0.5, camera.width, step)
    rows = np.append(rows, camera.height - 0.5) if rows[-1] < camera.height - 0.5 else rows
    cols = np.append(cols, camera.width - 0.5) if cols[-1] < camera.width - 0.5 else cols
    v, u = np.meshgrid(rows, cols, indexing="ij")
    origin, dirs = camera.pixel_rays(u, v)
    dirs[..., 1] = np.minimum(dirs[..., 1], HORIZON_DIRECTION_Y)
    points = origin + (-origin[1] / dirs[..., 1])[..., None] * dirs  # y = 0
    return points, linear_weights(rows, camera.height), linear_weights(cols, camera.width)


@lru_cache(maxsize=8)
def _coarse_geometry(camera: Camera) -> _Geometry:
    return _Geometry(camera)


def _light_terms(geometry: _Geometry, light: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per coarse pixel: the diffuse irradiance factor (integral of cos cos / r^2 over the light)
    and the coat's glossy reflectance towards the camera (the same integral weighted by its BRDF)."""
    offsets = ((np.arange(LIGHT_SAMPLES) + 0.5) / LIGHT_SAMPLES - 0.5) * LIGHT_SIZE
    samples_x = (light[0] + offsets).astype(np.float32)
    samples_z = (light[2] + offsets).astype(np.float32)
    area = np.float32(LIGHT_SIZE**2 / LIGHT_SAMPLES**2)
    diffuse, glossy = (np.empty(geometry.cos_view.shape, dtype=np.float32) for _ in range(2))
    _light_sums(geometry.points, geometry.view, geometry.cos_view, geometry.view_masking, samples_x, samples_z,
                np.float32(light[1]), area, diffuse, glossy)
    return diffuse, glossy


@njit(cache=True, parallel=True)
def _light_sums(points, view, cos_view, view_masking, samples_x, samples_z, height, area, diffuse, glossy):
    """_light_terms' sums over the light's samples x samples_z (at `height`, facing down), per coarse floor point:
    compiled, one pass instead of numpy's passes over (h, w, samples) arrays."""
    for r in prange(points.shape[0]):
        for c in range(points.shape[1]):
            vx, vy, vz = view[r, c, 0], view[r, c, 1], view[r, c, 2]
            view_term = view_masking[r, c] / (4.0 * cos_view[r, c])
            solid_sum, glossy_sum = np.float32(0.0), np.float32(0.0)
            for lx in samples_x:
                for lz in samples_z:
                    dx, dz = lx - points[r, c, 0], lz - points[r, c, 2]
                    distance2 = max(dx * dx + height * height + dz * dz, np.float32(1e-12))
                    inv_distance = 1.0 / math.sqrt(distance2)
                    cos_in = height * inv_distance  # the light faces straight down: the same cosine at the light
                    solid = cos_in * cos_in / distance2 * area  # cos_floor * cos_light / r^2 dA
                    # The half vector between the light direction and the view direction.
                    hx, hy, hz = dx * inv_distance + vx, cos_in + vy, dz * inv_distance + vz
                    inv_half = 1.0 / max(math.sqrt(hx * hx + hy * hy + hz * hz), np.float32(1e-12))
                    cos_half = min(max(hy * inv_half, 0.0), 1.0)
                    cos_in_half = min(max((dx * inv_distance * hx + cos_in * hy + dz * inv_distance * hz) * inv_half,
                                          0.0), 1.0)
                    cos_in = max(cos_in, np.float32(1e-4))
                    solid_sum += solid
                    glossy_sum += coat_reflectance(cos_in_half) * _ggx(cos_half) * _smith_g1(cos_in) * view_term / cos_in * solid
            diffuse[r, c] = solid_sum
            glossy[r, c] = glossy_sum


# The coat's terms, compiled: _light_sums calls them per light sample, _Geometry on its arrays.
@njit(cache=True)
def _ggx(cos_half):
    a2 = FLOOR_ROUGHNESS**2
    denominator = cos_half**2 * (a2 - 1.0) + 1.0
    return a2 / (math.pi * denominator**2)


def _ggx_widened(cos_half: np.ndarray, half_radius: float) -> np.ndarray:
    """The coat's GGX distribution convolved, roughly, with a light `half_radius` radians wide in half-vector angle
    (the light's own angular radius halved): the lobe's alpha^2 grows by its square, its integral stays 1."""
    a2 = FLOOR_ROUGHNESS**2 + half_radius**2
    return a2 / (math.pi * (cos_half**2 * (a2 - 1.0) + 1.0) ** 2)


@njit(cache=True)
def _smith_g1(cos_theta):
    a2 = FLOOR_ROUGHNESS**2
    tan2 = (1.0 - cos_theta**2) / (cos_theta**2)
    return 2.0 / (1.0 + np.sqrt(1.0 + a2 * tan2))


def coat_entry(cos_theta):
    """The share of an environment's light from a direction (its cosine to the floor's normal) that passes the coat
    to the diffuse base (COAT_ENTRY at that cosine), over the share DIFFUSE_SCALE holds (COAT_ENTRY_REFERENCE)."""
    entry = np.interp(np.clip(cos_theta, 0.0, 1.0), np.linspace(0.0, 1.0, len(COAT_ENTRY)), COAT_ENTRY)
    return entry / COAT_ENTRY_REFERENCE


def coat_fresnel(cos_theta):
    """The coat's exact Fresnel reflectance (unpolarised light, index FLOOR_IOR) at the cosine to the half vector, as
    the path tracer's. With Schlick's (coat_reflectance, which the area light's fitted floor keeps) the coat reflected
    15-17 % too little of a uniform sky seen 45-60 degrees from the normal (docs/results.md)."""
    cos_i = np.clip(np.asarray(cos_theta, dtype=np.float64), 1e-6, 1.0)
    cos_t = np.sqrt(np.maximum(1.0 - (1.0 - cos_i**2) / FLOOR_IOR**2, 0.0))
    across = (cos_i - FLOOR_IOR * cos_t) / (cos_i + FLOOR_IOR * cos_t)
    along = (FLOOR_IOR * cos_i - cos_t) / (FLOOR_IOR * cos_i + cos_t)
    return 0.5 * (across**2 + along**2)


@njit(cache=True)
def coat_reflectance(cos_theta):
    """The coat's Fresnel reflectance (Schlick) at the cosine between the direction and the floor's normal."""
    return COAT_F0 + (1.0 - COAT_F0) * (1.0 - cos_theta) ** 5
