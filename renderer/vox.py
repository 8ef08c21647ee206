"""MagicaVoxel .vox files in and out: a model's palette colors become the object voxels, and back.

Written here rather than taken from the registry: the two .vox packages there either configure the
process's logging and pull in matplotlib when imported (midvoxio) or are unmaintained since 2017
(py-vox-io), and neither bounds what a hostile file can make it allocate.

The format (MagicaVoxel's own description, version 150 and 200): "VOX " and a version, then a MAIN
chunk whose children are chunks of a 4-byte id, content size, children size. A model is a SIZE chunk
(x, y, z) followed by an XYZI chunk (count, then x, y, z, color index bytes); RGBA holds 256 colors,
of which entry i is color index i + 1 (index 0 means empty); without RGBA the default palette holds.
MagicaVoxel is z up; the object grid here is y up: (x, y, z) -> (i, j, k) = (x, z, size_y - 1 - y),
a rotation, so a model keeps its handedness.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
from PIL import Image

from renderer.errors import InputError
from renderer.io import atomic_path
from renderer.limits import MAX_RESOLUTION, MAX_VOXEL_FILE_BYTES, MIN_RESOLUTION
from renderer.surface import occupancy

VOX_VERSIONS = (150, 200)
MAX_PALETTE_COLORS = 255  # index 0 is empty


def default_palette() -> np.ndarray:
    """MagicaVoxel's default palette, (256, 3) uint8 by color index: the 6x6x6 cube of 0x33 steps (white first,
    blue varying fastest, black left out), then ramps of red, green, blue and grey in ten steps each."""
    steps = [0xFF, 0xCC, 0x99, 0x66, 0x33, 0x00]
    cube = [(r, g, b) for r in steps for g in steps for b in steps][:-1]
    ramp = [0xEE, 0xDD, 0xBB, 0xAA, 0x88, 0x77, 0x55, 0x44, 0x22, 0x11]
    ramps = ([(v, 0, 0) for v in ramp] + [(0, v, 0) for v in ramp] + [(0, 0, v) for v in ramp]
             + [(v, v, v) for v in ramp])
    return np.array([(0, 0, 0), *cube, *ramps], dtype=np.uint8)


def read_vox(path: str | Path, model: int | None = None) -> np.ndarray:
    """The object voxels (N, N, N, 4) float32 of a .vox model: `model` (0-based), or the one with most voxels.

    The model stands on the grid's floor, centred across; N is its longest side (at least MIN_RESOLUTION).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path)
    size = path.stat().st_size
    if size > MAX_VOXEL_FILE_BYTES:
        raise InputError(f"file is {size / 2**20:.0f} MB; .vox files are read up to {MAX_VOXEL_FILE_BYTES // 2**20} MB", path)
    data = path.read_bytes()
    models, palette = _parse(data, path)
    if not models:
        raise InputError("holds no model (no SIZE and XYZI chunks)", path)
    if model is None:
        model = max(range(len(models)), key=lambda m: len(models[m][1]))
    if not 0 <= model < len(models):
        raise InputError(f"has {len(models)} models (0 to {len(models) - 1}); model {model} was asked for", path)
    (sx, sy, sz), voxels = models[model]
    if len(voxels) == 0:
        raise InputError(f"model {model} has no voxels", path)
    n = max(sx, sy, sz, MIN_RESOLUTION)
    if n > MAX_RESOLUTION:
        raise InputError(f"model {model} is {sx}x{sy}x{sz}; object grids go up to {MAX_RESOLUTION}", path)
    x, y, z, color = (voxels[:, c].astype(np.int64) for c in range(4))
    i, j, k = x + (n - sx) // 2, z, (sy - 1 - y) + (n - sy) // 2
    rgba = np.zeros((n, n, n, 4), np.float32)
    rgba[i, j, k, :3] = palette[color] / 255.0
    rgba[i, j, k, 3] = 1.0
    return rgba


def _parse(data: bytes, path: Path) -> tuple[list[tuple[tuple[int, int, int], np.ndarray]], np.ndarray]:
    """The models ((size, (M, 4) uint8 x y z index)) and the palette (256, 3) by color index."""
    if len(data) < 8 or data[:4] != b"VOX ":
        raise InputError("not a MagicaVoxel file (no 'VOX ' header)", path)
    (version,) = struct.unpack_from("<i", data, 4)
    if version not in VOX_VERSIONS:
        raise InputError(f"unknown .vox version {version} (this program reads {', '.join(map(str, VOX_VERSIONS))})", path)
    chunk_id, content, children = _chunk_header(data, 8, path)
    if chunk_id != b"MAIN":
        raise InputError("the first chunk is not MAIN", path)
    offset, end = 20 + content, 20 + content + children
    if end > len(data):
        raise InputError(f"file is cut: MAIN promises {end:,} bytes, the file has {len(data):,}", path)
    models: list[tuple[tuple[int, int, int], np.ndarray]] = []
    palette = default_palette()
    size: tuple[int, int, int] | None = None
    while offset < end:  # MAIN's children are flat: the scene graph chunks (nTRN, nGRP, ...) are skipped
        chunk_id, content, children = _chunk_header(data, offset, path)
        body = offset + 12
        if body + content + children > end:
            raise InputError(f"file is cut: chunk {chunk_id!r} at byte {offset} runs past the end", path)
        if chunk_id == b"SIZE":
            if content < 12:
                raise InputError("a SIZE chunk is too short", path)
            size = struct.unpack_from("<3i", data, body)
            if not all(1 <= s <= 256 for s in size):
                raise InputError(f"model size {size} is not 1 to 256 per side", path)
        elif chunk_id == b"XYZI":
            if size is None:
                raise InputError("an XYZI chunk comes before its SIZE chunk", path)
            (count,) = struct.unpack_from("<i", data, body) if content >= 4 else (-1,)
            if count < 0 or 4 + 4 * count > content:
                raise InputError(f"an XYZI chunk claims {count} voxels but holds {max(content - 4, 0) // 4}", path)
            voxels = np.frombuffer(data, dtype=np.uint8, count=4 * count, offset=body + 4).reshape(count, 4)
            inside = (voxels[:, :3] < np.array(size)).all(axis=1) & (voxels[:, 3] > 0)
            models.append((size, voxels[inside]))
            size = None
        elif chunk_id == b"RGBA":
            if content < 1024:
                raise InputError("an RGBA chunk is too short (256 colors are 1024 bytes)", path)
            colors = np.frombuffer(data, dtype=np.uint8, count=1024, offset=body).reshape(256, 4)
            palette = np.concatenate([[[0, 0, 0]], colors[:255, :3]]).astype(np.uint8)
        offset = body + content + children
    return models, palette


def _chunk_header(data: bytes, offset: int, path: Path) -> tuple[bytes, int, int]:
    if offset + 12 > len(data):
        raise InputError(f"file is cut: a chunk header at byte {offset} runs past the end", path)
    chunk_id, content, children = struct.unpack_from("<4sii", data, offset)
    if content < 0 or children < 0:
        raise InputError(f"chunk {chunk_id!r} at byte {offset} has a negative size", path)
    return chunk_id, content, children


def write_vox(path: str | Path, rgba: np.ndarray) -> int:
    """Write object voxels (N, N, N, 4) as a one-model .vox (N <= 256) with at most 255 palette colors, atomically;
    returns the number of colors used. More colors than that are reduced by PIL's median cut."""
    occupied = occupancy(rgba)
    n = rgba.shape[0]
    if not occupied.any():
        raise InputError("the object has no voxels to write", path)
    i, j, k = np.nonzero(occupied)
    colors = np.round(np.clip(rgba[i, j, k, :3], 0.0, 1.0) * 255.0).astype(np.uint8)
    palette, index = _palette_of(colors)
    x, y, z = i, n - 1 - k, j  # y up -> MagicaVoxel's z up (the inverse of read_vox's mapping)
    xyzi = np.stack([x, y, z, index + 1], axis=1).astype(np.uint8)
    rgba_chunk = np.zeros((256, 4), np.uint8)
    rgba_chunk[: len(palette), :3], rgba_chunk[: len(palette), 3] = palette, 255
    chunks = (_chunk(b"SIZE", struct.pack("<3i", n, n, n))
              + _chunk(b"XYZI", struct.pack("<i", len(xyzi)) + xyzi.tobytes())
              + _chunk(b"RGBA", rgba_chunk.tobytes()))
    data = b"VOX " + struct.pack("<i", 150) + struct.pack("<4sii", b"MAIN", 0, len(chunks)) + chunks
    try:
        with atomic_path(path) as tmp:
            tmp.write_bytes(data)
    except OSError as exc:
        raise InputError(f"cannot write: {exc.strerror or exc}", path) from None
    return len(palette)


def _palette_of(colors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """At most MAX_PALETTE_COLORS colors (P, 3) and each voxel's palette position (M,)."""
    unique, inverse = np.unique(colors, axis=0, return_inverse=True)
    if len(unique) <= MAX_PALETTE_COLORS:
        return unique, inverse.reshape(-1)
    strip = Image.fromarray(colors.reshape(1, -1, 3), "RGB")
    quantized = strip.quantize(MAX_PALETTE_COLORS, method=Image.Quantize.MEDIANCUT)
    palette = np.asarray(quantized.getpalette()[: 3 * MAX_PALETTE_COLORS], dtype=np.uint8).reshape(-1, 3)
    return palette, np.asarray(quantized).reshape(-1).astype(np.int64)


def _chunk(chunk_id: bytes, content: bytes) -> bytes:
    return struct.pack("<4sii", chunk_id, len(content), 0) + content
