"""The floor's texture: an sRGB image repeated over the ground, read alike by the path tracer and the voxel shader.

The image repeats every `texture_scale` world units along x and z, its first column at x = -FLOOR_HALF_SIZE and its
first row at z = +FLOOR_HALF_SIZE (the floor's corner on the camera's left, nearest it), rows running towards -z:
where Mitsuba's rectangle puts the uv coordinates of renderer/pathtrace/path_tracer.py's floor.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache
from pathlib import Path

import numpy as np

from renderer.color import linear_to_srgb, srgb_to_linear
from renderer.errors import InputError
from renderer.io import load_image
from renderer.limits import MAX_TEXTURE_SIDE
from renderer.resample import resized
from renderer.scene import FLOOR_HALF_SIZE, Scene

TEXTURE_SUFFIXES = (".png", ".jpg", ".jpeg")


@dataclass(frozen=True, eq=False)
class FloorTexture:
    """A floor texture ready to render: its linear albedo and the world units one repeat spans."""

    albedo: np.ndarray  # (h, w, 3) float32 linear, read-only
    scale: float

    @cached_property
    def mean_srgb(self) -> tuple[float, float, float]:
        """The texture's mean albedo as an sRGB color: the floor's color for light it bounces, and for previews."""
        return tuple(float(c) for c in linear_to_srgb(self.albedo.reshape(-1, 3).mean(axis=0)))

    def albedo_at(self, points: np.ndarray, footprint: np.ndarray | None = None) -> np.ndarray:
        """(N, 3) linear albedo at world floor points (N, 3) (y ignored), averaged over `footprint` (N,) world units
        around each (a pixel's width on the floor; None: a point): bilinear in the mip level whose texels are that
        wide, blended with the next (trilinear), so that a fine texture far away shows its mean, not moire."""
        if footprint is None:
            return _bilinear(self.albedo, points, self.scale)
        levels = self.mip_levels
        texel = self.scale / self.albedo.shape[1]
        at = np.clip(np.log2(np.maximum(footprint, 1e-12) / texel), 0.0, len(levels) - 1.0)
        low = np.minimum(at.astype(np.int64), len(levels) - 2) if len(levels) > 1 else np.zeros(len(at), np.int64)
        out = np.empty((len(points), 3), dtype=np.float32)
        for level in np.unique(low):
            chosen = low == level
            here = _bilinear(levels[level], points[chosen], self.scale)
            if level + 1 < len(levels):
                weight = (at[chosen] - level)[:, None]
                here = here * (1.0 - weight) + _bilinear(levels[level + 1], points[chosen], self.scale) * weight
            out[chosen] = here
        return out

    @cached_property
    def mip_levels(self) -> list[np.ndarray]:
        """The albedo and its box-filtered halvings down to one texel."""
        levels = [self.albedo]
        while max(levels[-1].shape[:2]) > 1:
            h, w = levels[-1].shape[:2]
            levels.append(resized(levels[-1], (max(1, w // 2), max(1, h // 2))))
        return levels


def square_uv(x: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where world floor points (x, z) lie in the unit square the whole floor's square spans (0 at x =
    -FLOOR_HALF_SIZE and z = +FLOOR_HALF_SIZE), as Mitsuba's rectangle gives its uv: the texture is placed in it."""
    return (x + FLOOR_HALF_SIZE) / (2.0 * FLOOR_HALF_SIZE), (FLOOR_HALF_SIZE - z) / (2.0 * FLOOR_HALF_SIZE)


def _bilinear(albedo: np.ndarray, points: np.ndarray, scale: float) -> np.ndarray:
    """(N, 3): `albedo` (one repeat over `scale` world units, placed as the module says) at world floor points,
    bilinear between texel centres, wrapping."""
    h, w = albedo.shape[:2]
    repeats = 2.0 * FLOOR_HALF_SIZE / scale
    u, v = square_uv(points[:, 0], points[:, 2])
    u, v = u * repeats * w - 0.5, v * repeats * h - 0.5
    u0, v0 = np.floor(u), np.floor(v)
    fu, fv = (u - u0)[:, None], (v - v0)[:, None]
    c0, r0 = u0.astype(np.int64) % w, v0.astype(np.int64) % h
    c1, r1 = (c0 + 1) % w, (r0 + 1) % h
    top = albedo[r0, c0] * (1.0 - fu) + albedo[r0, c1] * fu
    bottom = albedo[r1, c0] * (1.0 - fu) + albedo[r1, c1] * fu
    return (top * (1.0 - fv) + bottom * fv).astype(np.float32)


def floor_texture(scene: Scene) -> FloorTexture | None:
    """The scene's floor texture, or None; read once per file version (path, modification time, size)."""
    path = scene.floor_texture_path()
    if path is None:
        return None
    try:
        stat = path.stat()
    except OSError:
        raise InputError("floor texture not found", path) from None
    return _cached(str(path.resolve()), stat.st_mtime_ns, stat.st_size, float(scene.floor.texture_scale))


@lru_cache(maxsize=4)
def _cached(path: str, mtime_ns: int, size: int, scale: float) -> FloorTexture:
    return FloorTexture(read_floor_texture(path), scale)


def read_floor_texture(path: str | Path) -> np.ndarray:
    """A texture image as linear albedo (h, w, 3) float32, read-only; larger images are reduced to MAX_TEXTURE_SIDE
    on their long side while decoding. Refused in one line: another format, a file that is not an image."""
    path = Path(path)
    if path.suffix.lower() not in TEXTURE_SUFFIXES:
        raise InputError(f"a floor texture must be a .png or .jpg image, not {path.suffix or 'a file without suffix'}",
                         path)
    rgb, _ = load_image(path, max_side=MAX_TEXTURE_SIDE)
    albedo = np.ascontiguousarray(srgb_to_linear(rgb), dtype=np.float32)
    albedo.flags.writeable = False
    return albedo
