"""Environment maps the project makes itself, for training and testing: studios, rooms and outdoor skies.

Each map is drawn from its seed alone (equirectangular, MAP_WIDTH x MAP_WIDTH / 2, linear radiance, renderer/environment.py's
convention), so a data set names a map by its kind and seed. Training and test maps come from disjoint seed ranges
(map_seed). Photographed maps are never drawn from here: a map a user photographed is what the product must generalise
to. Every map is scaled so that the floor under it receives an irradiance drawn from IRRADIANCE_RANGE (the area light
gives its floor about 2.4), so that no map is much darker or brighter than the scenes the renderers were tuned on.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from renderer.environment import luminance, map_directions, texel_solid_angles

MAP_WIDTH = 256
KINDS = ("studio", "indoor", "outdoor")  # besides "sky", the physical sun and sky (renderer/environment.py)
IRRADIANCE_RANGE = (1.2, 3.6)
TEST_SEED_OFFSET = 1_000_000  # test maps' seeds start here; training maps' stay below


def map_seed(split: str, index: int) -> int:
    """The seed of a split's index-th map: training and test maps never share one."""
    return index if split == "train" else TEST_SEED_OFFSET + index


def make_map(kind: str, seed: int) -> np.ndarray:
    """The `kind` map (one of KINDS) of `seed`, (MAP_WIDTH / 2, MAP_WIDTH, 3) float32 linear radiance."""
    rng = np.random.default_rng([KINDS.index(kind), seed])
    directions = map_directions(MAP_WIDTH // 2, MAP_WIDTH)
    radiance = {"studio": _studio, "indoor": _indoor, "outdoor": _outdoor}[kind](rng, directions)
    return _normalised(radiance, float(rng.uniform(*IRRADIANCE_RANGE)))


def _normalised(radiance: np.ndarray, irradiance: float) -> np.ndarray:
    """The map scaled so that a surface facing up receives `irradiance` (luminance) from it."""
    h, w = radiance.shape[:2]
    up = np.maximum(map_directions(h, w)[..., 1], 0.0)
    received = float(np.sum(luminance(radiance) * up * texel_solid_angles(h, w)))
    return (radiance * (irradiance / max(received, 1e-12))).astype(np.float32)


def _tint(rng: np.random.Generator, spread: float) -> np.ndarray:
    """A color near white: each channel 1 - spread .. 1, then scaled to a mean of 1."""
    color = 1.0 - spread * rng.random(3)
    return color / color.mean()


def _soft_spot(directions: np.ndarray, centre: np.ndarray, radius: float, softness: float) -> np.ndarray:
    """1 inside the cone of `radius` radians around `centre`, falling to 0 over `softness` radians."""
    angle = np.arccos(np.clip(directions @ centre, -1.0, 1.0))
    return np.clip((radius + softness - angle) / max(softness, 1e-6), 0.0, 1.0)


def _soft_box(directions: np.ndarray, azimuth: float, elevation: float, width: float, height: float,
              softness: float) -> np.ndarray:
    """A rectangle in azimuth and elevation (radians) with soft edges: a soft box, a window."""
    az = np.arctan2(directions[..., 0], directions[..., 2])
    el = np.arcsin(np.clip(directions[..., 1], -1.0, 1.0))
    d_az = np.abs((az - azimuth + math.pi) % (2.0 * math.pi) - math.pi)
    inside_az = np.clip((width / 2 + softness - d_az) / softness, 0.0, 1.0)
    inside_el = np.clip((height / 2 + softness - np.abs(el - elevation)) / softness, 0.0, 1.0)
    return inside_az * inside_el


def _direction(azimuth: float, elevation: float) -> np.ndarray:
    return np.array([math.sin(azimuth) * math.cos(elevation), math.sin(elevation),
                     math.cos(azimuth) * math.cos(elevation)])


def _studio(rng: np.random.Generator, d: np.ndarray) -> np.ndarray:
    """A dark studio with a graded backdrop and one to three soft boxes, sometimes a small hard light."""
    up = d[..., 1:2]
    radiance = (0.04 + 0.06 * rng.random()) * (1.0 + 0.6 * up) * _tint(rng, 0.2)
    for _ in range(int(rng.integers(1, 4))):
        box = _soft_box(d, rng.uniform(-math.pi, math.pi), rng.uniform(0.15, 1.2), rng.uniform(0.2, 0.8),
                        rng.uniform(0.15, 0.6), rng.uniform(0.02, 0.15))
        radiance = radiance + box[..., None] * rng.uniform(2.0, 10.0) * _tint(rng, 0.3)
    if rng.random() < 0.4:
        spot = _soft_spot(d, _direction(rng.uniform(-math.pi, math.pi), rng.uniform(0.3, 1.3)), 0.04, 0.01)
        radiance = radiance + spot[..., None] * rng.uniform(40.0, 150.0) * _tint(rng, 0.2)
    return radiance


def _indoor(rng: np.random.Generator, d: np.ndarray) -> np.ndarray:
    """A room: colored walls by direction, a lighter ceiling, a darker floor, windows near the horizon, a lamp."""
    azimuth = np.arctan2(d[..., 0], d[..., 2])
    walls = rng.uniform(0.2, 0.9, size=(4, 3))
    quarter = ((azimuth + math.pi) / (math.pi / 2)).astype(np.int64) % 4
    blend = ndimage.gaussian_filter1d(walls[quarter], sigma=6, axis=1, mode="wrap")
    up = d[..., 1:2]
    radiance = 0.15 * blend * np.where(up > 0.7, 1.6, 1.0) * np.where(up < 0.0, 0.5, 1.0)
    for _ in range(int(rng.integers(1, 3))):
        window = _soft_box(d, rng.uniform(-math.pi, math.pi), rng.uniform(0.05, 0.45), rng.uniform(0.3, 0.9),
                           rng.uniform(0.3, 0.7), 0.03)
        radiance = radiance + window[..., None] * rng.uniform(3.0, 12.0) * np.array([0.85, 0.95, 1.15])
    if rng.random() < 0.6:
        lamp = _soft_spot(d, _direction(rng.uniform(-math.pi, math.pi), rng.uniform(0.8, 1.5)), 0.06, 0.02)
        radiance = radiance + lamp[..., None] * rng.uniform(20.0, 60.0) * np.array([1.2, 1.0, 0.7])
    return radiance


def _outdoor(rng: np.random.Generator, d: np.ndarray) -> np.ndarray:
    """Open air: a sky graded from horizon to zenith with soft clouds, a ground below, sometimes a bright sun."""
    up = d[..., 1:2]
    zenith = np.array([0.25, 0.45, 0.95]) * rng.uniform(0.5, 1.0)
    horizon = np.array([0.85, 0.9, 1.0]) * rng.uniform(0.6, 1.2)
    sky = horizon + (zenith - horizon) * np.sqrt(np.clip(up, 0.0, 1.0))
    h, w = d.shape[:2]
    noise = ndimage.gaussian_filter(rng.random((h, w)), sigma=(3, 6), mode="wrap")
    noise = (noise - noise.min()) / max(float(np.ptp(noise)), 1e-12)
    clouds = np.clip((noise - rng.uniform(0.35, 0.75)) * 4.0, 0.0, 1.0)[..., None]
    sky = sky * (1.0 - clouds) + clouds * rng.uniform(0.8, 1.4)
    ground = rng.uniform(0.08, 0.3, size=3) * np.array([1.0, 0.9, 0.6])
    radiance = np.where(up > 0.0, sky, ground)
    if rng.random() < 0.6:
        sun = _soft_spot(d, _direction(rng.uniform(-math.pi, math.pi), rng.uniform(0.15, 1.3)), 0.02, 0.01)
        radiance = radiance + sun[..., None] * rng.uniform(300.0, 1200.0) * np.array([1.1, 1.0, 0.85])
    return radiance
