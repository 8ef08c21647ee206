"""The floor's texture: an sRGB image repeated over the ground, read alike by the path tracer and the voxel shader.

The image repeats every `texture_scale` world units along x and z, its first column at x = -FLOOR_HALF_SIZE and its
first row at z = +FLOOR_HALF_SIZE (the floor's corner on the camera's left, nearest it), rows running towards -z:
where Mitsuba's rectangle puts the uv coordinates of renderer/pathtrace/path_tracer.py's floor.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from renderer.color import linear_to_srgb, srgb_to_linear
from renderer.errors import InputError
from renderer.io import load_image
from renderer.limits import MAX_TEXTURE_SIDE
from renderer.scene import FLOOR_HALF_SIZE, Scene

TEXTURE_SUFFIXES = (".png", ".jpg", ".jpeg")


@dataclass(frozen=True, eq=False)
class FloorTexture:
    """A floor texture ready to render: its linear albedo and the world units one repeat spans."""

    albedo: np.ndarray  # (h, w, 3) float32 linear, read-only
    scale: float

    @property
    def mean_srgb(self) -> tuple[float, float, float]:
        """The texture's mean albedo as an sRGB color: the floor's color for light it bounces, and for previews."""
        return tuple(float(c) for c in linear_to_srgb(self.albedo.reshape(-1, 3).mean(axis=0)))

    def albedo_at(self, points: np.ndarray) -> np.ndarray:
        """(N, 3) linear albedo at world floor points (N, 3) (y ignored): bilinear between texel centres, wrapping."""
        h, w = self.albedo.shape[:2]
        u = (points[:, 0] + FLOOR_HALF_SIZE) / self.scale * w - 0.5
        v = (FLOOR_HALF_SIZE - points[:, 2]) / self.scale * h - 0.5
        u0, v0 = np.floor(u), np.floor(v)
        fu, fv = (u - u0)[:, None], (v - v0)[:, None]
        c0, r0 = u0.astype(np.int64) % w, v0.astype(np.int64) % h
        c1, r1 = (c0 + 1) % w, (r0 + 1) % h
        a = self.albedo
        top = a[r0, c0] * (1.0 - fu) + a[r0, c1] * fu
        bottom = a[r1, c0] * (1.0 - fu) + a[r1, c1] * fu
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
