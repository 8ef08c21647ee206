"""The environment light: radiance arriving from every direction around the scene, and the sun when there is one.

A map is equirectangular in Mitsuba's convention, so the path tracer takes the same array: row 0 is the zenith (+y),
the row's centre angle from +y is pi * v, and the column's angle phi = 2 pi u sees the direction
(sin(theta) sin(phi), cos(theta), -sin(theta) cos(phi)), so the middle column looks at +z, from behind the camera.
`rotation_deg` turns the environment about +y (right-handed), as Mitsuba's `to_world` rotation does.

The sky is Mitsuba's physical sun-and-sky model (`sunsky`, Hosek-Wilkie), baked once per setting into a map of the
sky alone; its sun, half a degree wide, is kept apart as a directional light of the same irradiance. Both renderers
read these two parts, so they are lit alike. SKY_EXPOSURE scales the model's physical units so that a sun 45 degrees
high in a clear sky lights the floor as brightly as the area light does below itself.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

import numpy as np
from numba import njit, prange

from renderer.color import linear_to_srgb, srgb_to_linear
from renderer.errors import InputError
from renderer.io import load_image
from renderer.limits import MAX_MAP_SIDE
from renderer.scene import EnvironmentSpec, Scene, SkySpec

HDR_SUFFIXES = (".hdr", ".exr")  # linear radiance
LDR_SUFFIXES = (".png", ".jpg", ".jpeg")  # sRGB, read as 0-1 radiance
BACKGROUND_WIDTH = 2048  # the map kept for the background the camera sees past the floor
LIGHTING_WIDTH = 128  # the map the shader lights with (64 rows: about 3 degrees a texel)
ASPECT_RANGE = (1.8, 2.2)  # width / height of an equirectangular map
SKY_WIDTH = 256  # the baked sky map's width
SUN_APERTURE_DEG = 0.5358  # the sun's angular diameter (Mitsuba's sunsky default)
GROUND_ALBEDO = 0.3  # the ground beyond the floor (Mitsuba's sunsky default albedo)
SUN_SAMPLES = 512  # directions over the sun's disc whose mean radiance gives its irradiance
REFERENCE_SKY = SkySpec(sun_elevation_deg=45.0, sun_azimuth_deg=0.0, turbidity=3.0)
REFERENCE_IRRADIANCE = 2.37  # on the floor, from REFERENCE_SKY: what the area light gives the floor below it


@dataclass(frozen=True, eq=False)
class EnvironmentLight:
    """An environment as renderers take it. The maps are in the map's own frame and at strength 1 (so that work
    done on them outlives a turn or a change of strength); sample_map turns them into the world."""

    background: np.ndarray  # (h, 2h, 3) float32 linear radiance, at most BACKGROUND_WIDTH wide
    lighting: np.ndarray  # (64, 128, 3) the same, area-averaged, for lighting
    rotation_deg: float
    strength: float
    sun_direction: np.ndarray | None  # (3,) world unit vector towards the sun (rotation applied), or None
    sun_irradiance: np.ndarray  # (3,) linear irradiance on a plane facing the sun, strength applied (0: no sun)
    source_key: tuple  # names the maps (not the rotation or strength), for caches

    @property
    def key(self) -> tuple:
        """Names everything a render reads of the environment (the sun follows from the sky and the turn)."""
        return (*self.source_key, self.rotation_deg, self.strength)

    def radiance(self, directions: np.ndarray, sharp: bool = False) -> np.ndarray:
        """Linear radiance (..., 3) arriving from world directions (..., 3): from the background map when `sharp`."""
        found = sample_map(self.background if sharp else self.lighting, directions, self.rotation_deg)
        return found * np.float32(self.strength)


def uniform_environment(radiance: float) -> EnvironmentLight:
    """The same radiance from every direction (the scene's ambient light as an environment)."""
    flat = np.full((LIGHTING_WIDTH // 2, LIGHTING_WIDTH, 3), radiance, dtype=np.float32)
    return EnvironmentLight(background=flat, lighting=flat, rotation_deg=0.0, strength=1.0, sun_direction=None,
                            sun_irradiance=np.zeros(3), source_key=("uniform", float(radiance)))


def rotate_y(directions: np.ndarray, degrees: float) -> np.ndarray:
    """Directions (..., 3) turned by `degrees` about +y (right-handed: +z towards +x)."""
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    d = np.asarray(directions, dtype=np.float64)
    return np.stack([c * d[..., 0] + s * d[..., 2], d[..., 1], -s * d[..., 0] + c * d[..., 2]], axis=-1)


def map_directions(height: int, width: int) -> np.ndarray:
    """(height, width, 3) unit directions at the texel centres of an equirectangular map."""
    theta = np.pi * (np.arange(height) + 0.5) / height
    phi = 2.0 * np.pi * (np.arange(width) + 0.5) / width
    st = np.sin(theta)[:, None]
    return np.stack([st * np.sin(phi)[None], np.cos(theta)[:, None] + 0 * phi[None], -st * np.cos(phi)[None]], axis=-1)


def texel_solid_angles(height: int, width: int) -> np.ndarray:
    """(height, 1) solid angle of each row's texels (they sum to 4 pi over the map)."""
    edges = np.pi * np.arange(height + 1) / height
    return ((np.cos(edges[:-1]) - np.cos(edges[1:])) * (2.0 * np.pi / width))[:, None]


def direction_angles(directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The polar angle from +y and the azimuth phi (as the maps count it) of directions (..., 3), in radians."""
    d = np.asarray(directions, dtype=np.float64)
    norm = np.maximum(np.linalg.norm(d, axis=-1), 1e-12)
    return np.arccos(np.clip(d[..., 1] / norm, -1.0, 1.0)), np.arctan2(d[..., 0], -d[..., 2])


def sample_map(radiance: np.ndarray, directions: np.ndarray, turn_deg: float = 0.0) -> np.ndarray:
    """The map bilinearly interpolated (wrapping around in phi, clamped at the poles) along `directions` (..., 3) of
    the world in which the map is turned by `turn_deg` about +y (0: the map's own frame)."""
    theta, phi = direction_angles(directions)
    return sample_angles(radiance, theta, phi, turn_deg)


def sample_angles(radiance: np.ndarray, theta: np.ndarray, phi: np.ndarray, turn_deg: float = 0.0) -> np.ndarray:
    """sample_map along directions given by their angles (direction_angles), which a caller may keep."""
    shape = np.shape(theta)
    out = np.empty((int(np.prod(shape, dtype=np.int64)), 3), dtype=np.float32)
    _bilinear_angles(np.ascontiguousarray(radiance, dtype=np.float32), np.ravel(theta).astype(np.float64),
                     np.ravel(phi).astype(np.float64), math.radians(turn_deg), out)
    return out.reshape(*shape, 3)


def weighted_mean_angles(radiance: np.ndarray, theta: np.ndarray, phi: np.ndarray, weights: np.ndarray,
                        turn_deg: float = 0.0) -> np.ndarray:
    """(..., 3): per point, the mean over the last axis of `weights` times the map along those angles (..., S)."""
    shape = np.shape(theta)
    points, count = int(np.prod(shape[:-1], dtype=np.int64)), shape[-1]
    out = np.empty((points, 3), dtype=np.float32)
    _weighted_angles(np.ascontiguousarray(radiance, dtype=np.float32), np.reshape(theta, (points, count)),
                     np.reshape(phi, (points, count)), np.reshape(weights, (points, count)).astype(np.float64),
                     math.radians(turn_deg), out)
    return out.reshape(*shape[:-1], 3)


@njit(cache=True, inline="always")
def _texels(theta, phi, h, w):
    """The rows and columns around map angles (theta, phi) and the weights of the second of each, for bilinear
    interpolation between texel centres: wrapping around in phi, clamped at the poles."""
    two_pi = 2.0 * math.pi
    y = min(max(theta / math.pi * h - 0.5, 0.0), h - 1.0)
    x = (phi % two_pi) / two_pi * w - 0.5
    y0 = min(int(math.floor(y)), h - 1)
    xf = math.floor(x)
    x0 = int(xf) % w
    return y0, min(y0 + 1, h - 1), y - y0, x0, (x0 + 1) % w, x - xf


@njit(cache=True, parallel=True)
def _weighted_angles(radiance, theta, phi, weights, turn, out):
    h, w = radiance.shape[0], radiance.shape[1]
    count = theta.shape[1]
    for i in prange(theta.shape[0]):
        r, g, b = 0.0, 0.0, 0.0
        for j in range(count):
            weight = weights[i, j]
            if weight == 0.0:
                continue
            y0, y1, fy, x0, x1, fx = _texels(theta[i, j], phi[i, j] + turn, h, w)
            w00, w01 = (1.0 - fy) * (1.0 - fx), (1.0 - fy) * fx
            w10, w11 = fy * (1.0 - fx), fy * fx
            r += weight * (w00 * radiance[y0, x0, 0] + w01 * radiance[y0, x1, 0] + w10 * radiance[y1, x0, 0]
                           + w11 * radiance[y1, x1, 0])
            g += weight * (w00 * radiance[y0, x0, 1] + w01 * radiance[y0, x1, 1] + w10 * radiance[y1, x0, 1]
                           + w11 * radiance[y1, x1, 1])
            b += weight * (w00 * radiance[y0, x0, 2] + w01 * radiance[y0, x1, 2] + w10 * radiance[y1, x0, 2]
                           + w11 * radiance[y1, x1, 2])
        out[i, 0], out[i, 1], out[i, 2] = r / count, g / count, b / count


@njit(cache=True, parallel=True)
def _bilinear_angles(radiance, theta, phi, turn, out):
    """out[i] = the map at (theta[i], phi[i] + turn) (a world turned by `turn` sees the map's phi + turn there),
    bilinear between texel centres, wrapping in phi, clamped at the poles: one compiled pass, no temporaries."""
    h, w = radiance.shape[0], radiance.shape[1]
    for i in prange(theta.shape[0]):
        y0, y1, fy, x0, x1, fx = _texels(theta[i], phi[i] + turn, h, w)
        for k in range(3):
            top = radiance[y0, x0, k] * (1.0 - fx) + radiance[y0, x1, k] * fx
            bottom = radiance[y1, x0, k] * (1.0 - fx) + radiance[y1, x1, k] * fx
            out[i, k] = top * (1.0 - fy) + bottom * fy


def reduce_map(radiance: np.ndarray, width: int) -> np.ndarray:
    """The map area-averaged down to `width` x width / 2 (never up)."""
    import cv2

    h, w = radiance.shape[:2]
    if w <= width:
        return np.ascontiguousarray(radiance, dtype=np.float32)
    return cv2.resize(np.ascontiguousarray(radiance, dtype=np.float32), (width, width // 2),
                      interpolation=cv2.INTER_AREA)


# --- reading a map --------------------------------------------------------------------------------


def read_environment_image(path: str | Path) -> np.ndarray:
    """An equirectangular map as linear radiance (h, w, 3) float32, reduced to at most BACKGROUND_WIDTH wide.

    HDR files are read by Mitsuba (the renderer's own reader) after their header's size is checked, so that no file
    can ask for more memory than MAX_MAP_SIDE allows; LDR files are sRGB and decoded by Pillow at a bounded size.
    Refused in one line: another format, a truncated or unreadable file, the wrong shape, NaN, infinite or negative
    values.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in HDR_SUFFIXES + LDR_SUFFIXES:
        raise InputError(f"an environment must be an .hdr, .exr, .png or .jpg image, not {suffix or 'a file without suffix'}",
                         path)
    if not path.is_file():
        raise InputError("file not found", path)
    if suffix in LDR_SUFFIXES:
        rgb, _ = load_image(path, max_side=BACKGROUND_WIDTH)
        radiance = srgb_to_linear(rgb).astype(np.float32)
    else:
        width, height = hdr_image_size(path)
        if max(width, height) > MAX_MAP_SIDE:
            raise InputError(f"map is {width} x {height} pixels; environments are read up to {MAX_MAP_SIDE} wide", path)
        radiance = _read_hdr(path)
    h, w = radiance.shape[:2]
    if not ASPECT_RANGE[0] <= w / h <= ASPECT_RANGE[1]:
        raise InputError(f"an equirectangular map is twice as wide as it is high; this one is {w} x {h}", path)
    if not np.all(np.isfinite(radiance)):
        raise InputError("map holds NaN or infinite values", path)
    if radiance.min() < 0.0:
        raise InputError("map holds negative radiance", path)
    return reduce_map(radiance, BACKGROUND_WIDTH)


def _read_hdr(path: Path) -> np.ndarray:
    from renderer.pathtrace.mitsuba_variant import active_variant

    active_variant()
    import mitsuba as mi

    try:
        bitmap = mi.Bitmap(str(path))
        bitmap = bitmap.convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, srgb_gamma=False)
        radiance = np.array(bitmap, dtype=np.float32)
    except (RuntimeError, ValueError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(f"not a readable HDR image ({first[:120]})", path) from None
    if radiance.ndim != 3 or radiance.shape[2] != 3 or radiance.size == 0:
        raise InputError("not an RGB image", path)
    return radiance


def hdr_image_size(path: Path) -> tuple[int, int]:
    """(width, height) from a Radiance .hdr or OpenEXR header, without decoding the pixels.

    Written here because the readers at hand (Mitsuba, OpenCV) decode the whole image to report its size."""
    with open(path, "rb") as f:
        head = f.read(65536)
    if head.startswith(b"\x76\x2f\x31\x01"):
        return _exr_size(head, path)
    if head.startswith(b"#?"):
        return _radiance_size(head, path)
    raise InputError("not an HDR image (neither Radiance .hdr nor OpenEXR)", path)


def _radiance_size(head: bytes, path: Path) -> tuple[int, int]:
    blank = head.find(b"\n\n")
    if blank < 0:
        raise InputError("truncated Radiance header", path)
    line = head[blank + 2:].split(b"\n", 1)[0].split()
    if len(line) != 4 or line[0] not in (b"-Y", b"+Y") or line[2] not in (b"+X", b"-X"):
        raise InputError("Radiance header without a -Y H +X W resolution line", path)
    try:
        return int(line[3]), int(line[1])
    except ValueError:
        raise InputError("Radiance resolution line is not two integers", path) from None


def _exr_size(head: bytes, path: Path) -> tuple[int, int]:
    at = 8  # magic and version
    while at < len(head):
        end = head.find(b"\0", at)
        if end < 0:
            break
        name = head[at:end]
        if not name:
            break
        type_end = head.find(b"\0", end + 1)
        if type_end < 0 or type_end + 5 > len(head):
            break
        size = struct.unpack_from("<i", head, type_end + 1)[0]
        value = type_end + 5
        if name == b"dataWindow" and size == 16 and value + 16 <= len(head):
            x0, y0, x1, y1 = struct.unpack_from("<4i", head, value)
            return x1 - x0 + 1, y1 - y0 + 1
        if size < 0:
            break
        at = value + size
    raise InputError("truncated OpenEXR header (no dataWindow)", path)


# --- the sky ----------------------------------------------------------------------------------------


def sun_direction(sky: SkySpec) -> np.ndarray:
    """World unit vector towards the sun (azimuth from +z towards +x)."""
    el, az = math.radians(sky.sun_elevation_deg), math.radians(sky.sun_azimuth_deg)
    return np.array([math.sin(az) * math.cos(el), math.sin(el), math.cos(az) * math.cos(el)])


def scene_sun_direction(scene: Scene) -> np.ndarray | None:
    """World unit vector towards the scene's sun (its sky's, turned with the environment), or None without a sky."""
    env = scene.environment
    if env is None or env.sky is None:
        return None
    return rotate_y(sun_direction(env.sky), env.rotation_deg)


@lru_cache(maxsize=16)
def sky_light(sky: SkySpec) -> tuple[np.ndarray, np.ndarray]:
    """The sky alone as a map (SKY_WIDTH wide, linear, exposed) and the sun's irradiance (3,) facing it."""
    sky_map, sun = _sunsky(sky)
    exposure = sky_exposure()
    return (sky_map * exposure).astype(np.float32), sun * exposure


@lru_cache(maxsize=1)
def sky_exposure() -> float:
    """The factor that gives the floor REFERENCE_IRRADIANCE under REFERENCE_SKY (sun and sky)."""
    sky_map, sun = _sunsky(REFERENCE_SKY)
    h, w = sky_map.shape[:2]
    up = np.maximum(map_directions(h, w)[..., 1], 0.0)  # the ground below the horizon adds nothing here
    from_sky = np.sum(luminance(sky_map) * up * texel_solid_angles(h, w))
    from_sun = luminance(sun) * math.sin(math.radians(REFERENCE_SKY.sun_elevation_deg))
    return REFERENCE_IRRADIANCE / float(from_sky + from_sun)


THUMBNAIL_WIDTH = 192  # the Light tab's picture of the environment


def environment_thumbnail(environment: EnvironmentLight, width: int = THUMBNAIL_WIDTH) -> np.ndarray:
    """(width / 2, width, 3) float32 sRGB: the environment around the scene, turned and scaled as it lights it, in
    the maps' layout (the middle column looks from behind the camera, the top row is overhead), tone-mapped as
    x / (1 + x) so that a bright sky keeps its shape; the sun, which no map holds, a yellow dot."""
    directions = map_directions(width // 2, width)
    radiance = np.maximum(environment.radiance(directions, sharp=True), 0.0)
    image = linear_to_srgb(radiance / (1.0 + radiance)).astype(np.float32)
    if environment.sun_direction is not None and environment.sun_irradiance.max() > 0.0:
        row, col = np.unravel_index(np.argmax(directions @ environment.sun_direction), directions.shape[:2])
        image[max(row - 1, 0):row + 2, max(col - 1, 0):col + 2] = (1.0, 0.85, 0.2)
    return image


def environment_probe(environment: EnvironmentLight, size: int) -> np.ndarray:
    """(size, size, 3) float32 linear radiance: the environment as it lights the scene (turned, strength applied),
    area-averaged into an equirectangular grid of `size` rows (polar angle) and `size` columns (azimuth), the sun's
    irradiance spread over the texel that holds its direction: what a network reads of the environment."""
    import cv2

    h, w = environment.lighting.shape[:2]
    world = environment.radiance(map_directions(h, w))  # the lighting map in the world's frame
    probe = cv2.resize(np.ascontiguousarray(world, dtype=np.float32), (size, size), interpolation=cv2.INTER_AREA)
    if environment.sun_direction is not None and environment.sun_irradiance.max() > 0.0:
        theta, phi = direction_angles(environment.sun_direction)
        row = min(int(theta / math.pi * size), size - 1)
        col = int((phi % (2.0 * math.pi)) / (2.0 * math.pi) * size) % size
        probe[row, col] += (environment.sun_irradiance / texel_solid_angles(size, size)[row, 0]).astype(np.float32)
    return np.maximum(probe, 0.0)


def luminance(rgb: np.ndarray) -> np.ndarray:
    return rgb[..., 0] * 0.2126 + rgb[..., 1] * 0.7152 + rgb[..., 2] * 0.0722


def _sunsky(sky: SkySpec) -> tuple[np.ndarray, np.ndarray]:
    """Mitsuba's sunsky in physical units: the sky's map and the sun's irradiance (the mean radiance over its disc
    times the disc's solid angle). Mitsuba's sky has +z up; ours +y."""
    from renderer.pathtrace.mitsuba_variant import active_variant

    active_variant()
    import mitsuba as mi

    sun = sun_direction(sky)
    sun_local = _to_sky_frame(sun)
    # The sunsky model is undefined below the horizon: a sun at 0 degrees is raised a hair.
    sun_local[2] = max(sun_local[2], 1e-3)
    common = {"type": "sunsky", "sun_direction": sun_local.tolist(), "turbidity": float(sky.turbidity)}
    only_sky = mi.load_dict({**common, "sun_scale": 0.0})
    only_sun = mi.load_dict({**common, "sky_scale": 0.0})
    h = SKY_WIDTH // 2
    directions = map_directions(h, SKY_WIDTH).reshape(-1, 3)
    sky_map = _evaluate(only_sky, _to_sky_frame(directions)).reshape(h, SKY_WIDTH, 3)
    sky_map = np.nan_to_num(sky_map, nan=0.0, posinf=0.0).clip(0.0)
    half = math.radians(SUN_APERTURE_DEG) / 2.0
    disc = _cone_directions(sun_local / np.linalg.norm(sun_local), half, SUN_SAMPLES)
    solid_angle = 2.0 * math.pi * (1.0 - math.cos(half))
    sun_irradiance = np.nan_to_num(_evaluate(only_sun, disc).mean(axis=0) * solid_angle).clip(0.0)
    # Below the horizon: a diffuse ground of GROUND_ALBEDO under this sun and sky, as the sky model assumes.
    below = directions.reshape(h, SKY_WIDTH, 3)[..., 1] < 0.0
    up = np.maximum(directions.reshape(h, SKY_WIDTH, 3)[..., 1], 0.0)
    ground = (np.sum(sky_map * (up * texel_solid_angles(h, SKY_WIDTH))[..., None], axis=(0, 1))
              + sun_irradiance * max(math.sin(math.radians(sky.sun_elevation_deg)), 0.0))
    sky_map[below] = GROUND_ALBEDO * ground / math.pi
    return sky_map, sun_irradiance


def _to_sky_frame(directions: np.ndarray) -> np.ndarray:
    """Our +y-up directions in sunsky's +z-up frame (a proper rotation: (x, y, z) -> (x, -z, y))."""
    d = np.asarray(directions, dtype=np.float64)
    return np.stack([d[..., 0], -d[..., 2], d[..., 1]], axis=-1)


def _cone_directions(axis: np.ndarray, half_angle: float, count: int) -> np.ndarray:
    """`count` directions spread evenly (a Fibonacci spiral) over the cone of `half_angle` around `axis`."""
    i = np.arange(count) + 0.5
    cos_t = 1.0 - (i / count) * (1.0 - math.cos(half_angle))
    sin_t = np.sqrt(np.maximum(1.0 - cos_t**2, 0.0))
    phi = i * math.pi * (3.0 - math.sqrt(5.0))
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = np.cross(axis, helper)
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(axis, t1)
    return (cos_t[:, None] * axis + sin_t[:, None] * (np.cos(phi)[:, None] * t1 + np.sin(phi)[:, None] * t2))


def _evaluate(emitter, directions: np.ndarray) -> np.ndarray:
    """An infinite emitter's radiance (N, 3) arriving from directions (N, 3), vectorised where the variant is."""
    import drjit as dr
    import mitsuba as mi

    d = np.asarray(directions, dtype=np.float64)
    if mi.variant().startswith("scalar"):
        out = np.empty((len(d), 3))
        si = mi.SurfaceInteraction3f()
        for i, v in enumerate(d):
            si.wi = mi.Vector3f(-v)
            out[i] = np.array(emitter.eval(si))
        return out
    si = dr.zeros(mi.SurfaceInteraction3f, len(d))
    si.wi = mi.Vector3f(np.ascontiguousarray(-d.T, dtype=np.float32))
    return np.array(emitter.eval(si), dtype=np.float64).T.reshape(len(d), 3)


# --- the scene's environment ----------------------------------------------------------------------


def environment_light(scene: Scene) -> EnvironmentLight | None:
    """The scene's environment, ready to render, or None when the uniform ambient light stands in for it."""
    env = scene.environment
    if env is None:
        return None
    if env.sky is not None:
        # The sky turns with its sun's azimuth: it is baked with the sun at azimuth 0 and turned by the rest, so that a
        # sun dragged around the sky reuses the bake and all the work renderers keep on its map.
        facing = replace(env.sky, sun_azimuth_deg=0.0)
        sky_map, sun = sky_light(facing)
        turned = replace(env, rotation_deg=env.rotation_deg + env.sky.sun_azimuth_deg)
        return _assemble(sky_map, turned, scene_sun_direction(scene), sun, ("sky", facing))
    path = scene.environment_path()
    try:
        stat = path.stat()
    except OSError:
        raise InputError("environment image not found", path) from None
    radiance = _cached_image(str(path.resolve()), stat.st_mtime_ns, stat.st_size)
    return _assemble(radiance, env, None, np.zeros(3), ("image", str(path.resolve()), stat.st_mtime_ns))


@lru_cache(maxsize=4)
def _cached_image(path: str, mtime_ns: int, size: int) -> np.ndarray:
    image = read_environment_image(path)
    image.setflags(write=False)
    return image


def _assemble(radiance: np.ndarray, env: EnvironmentSpec, sun: np.ndarray | None, sun_irradiance: np.ndarray,
              source_key: tuple) -> EnvironmentLight:
    lighting = _reduced(source_key, radiance)
    return EnvironmentLight(background=radiance, lighting=lighting, rotation_deg=float(env.rotation_deg),
                            strength=float(env.strength), sun_direction=sun,
                            sun_irradiance=np.asarray(sun_irradiance, dtype=np.float64) * float(env.strength),
                            source_key=source_key)


_REDUCED: dict[tuple, np.ndarray] = {}


def _reduced(source_key: tuple, radiance: np.ndarray) -> np.ndarray:
    """The lighting map of a source, kept for the few sources last used (reducing a large map takes a while)."""
    if source_key not in _REDUCED:
        if len(_REDUCED) >= 8:
            _REDUCED.pop(next(iter(_REDUCED)))
        _REDUCED[source_key] = reduce_map(radiance, LIGHTING_WIDTH)
    return _REDUCED[source_key]
