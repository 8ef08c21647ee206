"""MagicaVoxel .vox files in and out: a model's palette colors become the object voxels, and back; a file's models
where its scene graph places them become several objects (read_vox_scene, placed_objects).

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
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from renderer.errors import InputError
from renderer.io import atomic_path
from renderer.limits import MAX_RESOLUTION, MAX_VOXEL_FILE_BYTES, MIN_RESOLUTION
from renderer.scene import ObjectSpec
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
    data = _read_file(path)
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


# --- several models, where the file's scene puts them ----------------------------------------------------------

MAX_NODES = 100_000  # scene graph nodes read at most (a hostile file may claim millions)
MAX_DICT_ENTRIES = 256  # entries of one node's attribute dictionary


@dataclass(frozen=True)
class PlacedModel:
    """One model of a .vox file as its scene graph places it: object voxels (N^3, y up) standing at the height the
    file gives the model above its lowest one, and where the grid's centre stands on the floor."""

    rgba: np.ndarray
    centre: tuple[float, float]  # world x and z of the grid's centre, in the file's voxels (z towards the viewer)
    name: str


def read_vox_scene(path: str | Path) -> list[PlacedModel]:
    """Every model the file's scene graph shows (hidden ones left out), each where the graph puts it (rotations are
    the graph's quarter turns); empty for a file whose graph shows none, or that has none (read_vox reads one model)."""
    path = Path(path)
    data = _read_file(path)
    models, palette = _parse(data, path)
    if not models:
        raise InputError("holds no model (no SIZE and XYZI chunks)", path)
    instances = _scene_instances(data, path, len(models))
    if not instances:
        return []
    placed = []
    for model, rotation, translation, name in instances:
        (sx, sy, sz), voxels = models[model]
        if len(voxels) == 0:
            continue
        local = voxels[:, :3].astype(np.int64) - np.array([sx, sy, sz]) // 2
        world = np.rint(local @ rotation.T + translation).astype(np.int64)  # MagicaVoxel's frame, z up
        placed.append((np.stack([world[:, 0], world[:, 2], -world[:, 1]], axis=1), voxels[:, 3], name))  # y up
    if not placed:
        raise InputError("its models hold no voxels", path)
    lowest = min(int(p[:, 1].min()) for p, _, _ in placed)
    out = []
    for points, colors, name in placed:
        lo, hi = points.min(axis=0), points.max(axis=0) + 1
        ex, ez, height = int(hi[0] - lo[0]), int(hi[2] - lo[2]), int(hi[1] - lowest)
        n = max(ex, ez, height, MIN_RESOLUTION)
        if n > MAX_RESOLUTION:
            raise InputError(f"model {name!r} spans {n} voxels with its height above the floor; object grids go up to "
                             f"{MAX_RESOLUTION}", path)
        i = points[:, 0] - lo[0] + (n - ex) // 2
        j = points[:, 1] - lowest
        k = points[:, 2] - lo[2] + (n - ez) // 2
        rgba = np.zeros((n, n, n, 4), np.float32)
        rgba[i, j, k, :3] = palette[colors] / 255.0
        rgba[i, j, k, 3] = 1.0
        centre = (float(lo[0] - (n - ex) // 2 + n / 2), float(lo[2] - (n - ez) // 2 + n / 2))
        out.append(PlacedModel(rgba, centre, name))
    return out


def placed_objects(models: list[PlacedModel], voxel_files: list[str]) -> tuple[ObjectSpec, ...]:
    """Scene objects for `models`, each read from its file in `voxel_files`: one file voxel is as wide in the world
    for all of them (the largest grid one unit, the whole group at most two across), and the group stands centred on
    the floor's origin."""
    xs = [c for m in models for c in (m.centre[0] - m.rgba.shape[0] / 2, m.centre[0] + m.rgba.shape[0] / 2)]
    zs = [c for m in models for c in (m.centre[1] - m.rgba.shape[0] / 2, m.centre[1] + m.rgba.shape[0] / 2)]
    largest = max(m.rgba.shape[0] for m in models)
    unit = min(1.0 / largest, 2.0 / max(max(xs) - min(xs), max(zs) - min(zs)))
    cx, cz = (max(xs) + min(xs)) / 2, (max(zs) + min(zs)) / 2
    names: set[str] = set()
    objects = []
    for model, voxels in zip(models, voxel_files):
        name = model.name if model.name not in names else f"{model.name}.{len(names):03d}"
        names.add(name)
        n = model.rgba.shape[0]
        objects.append(ObjectSpec(voxels=voxels, resolution=n, scale=(n * unit,) * 3, name=name,
                                  translation=((model.centre[0] - cx) * unit, (model.centre[1] - cz) * unit)))
    return tuple(objects)


def _read_file(path: Path) -> bytes:
    if not path.is_file():
        raise InputError("file not found", path)
    size = path.stat().st_size
    if size > MAX_VOXEL_FILE_BYTES:
        raise InputError(f"file is {size / 2**20:.0f} MB; .vox files are read up to {MAX_VOXEL_FILE_BYTES // 2**20} MB", path)
    return path.read_bytes()


def _scene_instances(data: bytes, path: Path, model_count: int) -> list[tuple[int, np.ndarray, np.ndarray, str]]:
    """(model index, 3x3 rotation, translation, name) of each model the scene graph shows, in MagicaVoxel's frame."""
    transforms: dict[int, tuple[dict, int, dict]] = {}  # node: attributes, child, first frame
    groups: dict[int, list[int]] = {}
    shapes: dict[int, list[int]] = {}
    offset, end = 20 + struct.unpack_from("<i", data, 12)[0], len(data)
    while offset + 12 <= end and len(transforms) + len(groups) + len(shapes) < MAX_NODES:
        chunk_id, content, children = _chunk_header(data, offset, path)
        body, stop = offset + 12, offset + 12 + content
        if stop > end:
            break  # _parse has refused a cut file already; a node past the end is not read
        if chunk_id == b"nTRN":
            node, at = _int(data, body, stop, path), body + 4
            attributes, at = _dict(data, at, stop, path)
            child = _int(data, at, stop, path)
            frames = _int(data, at + 12, stop, path)
            frame, _ = _dict(data, at + 16, stop, path) if frames > 0 else ({}, at)
            transforms[node] = (attributes, child, frame)
        elif chunk_id == b"nGRP":
            node, at = _int(data, body, stop, path), body + 4
            _, at = _dict(data, at, stop, path)
            count = _int(data, at, stop, path)
            if not 0 <= count <= (stop - at - 4) // 4:
                raise InputError(f"a group node claims {count} children", path)
            groups[node] = [_int(data, at + 4 + 4 * c, stop, path) for c in range(count)]
        elif chunk_id == b"nSHP":
            node, at = _int(data, body, stop, path), body + 4
            _, at = _dict(data, at, stop, path)
            count, at = _int(data, at, stop, path), at + 4
            ids = []
            for _ in range(max(0, min(count, MAX_NODES))):
                ids.append(_int(data, at, stop, path))
                _, at = _dict(data, at + 4, stop, path)
            shapes[node] = ids
        offset = stop + children
    if 0 not in transforms:  # no scene graph
        return []
    out: list[tuple[int, np.ndarray, np.ndarray, str]] = []
    pending = [(0, np.eye(3), np.zeros(3), "")]
    while pending and len(out) < MAX_NODES:
        node, rotation, translation, name = pending.pop()
        if node in transforms:
            attributes, child, frame = transforms[node]
            if attributes.get("_hidden") == "1":
                continue
            local_rotation = _rotation(int(frame.get("_r", "4")))
            local_translation = np.array([float(v) for v in frame.get("_t", "0 0 0").split()[:3]] + [0.0] * 3)[:3]
            pending.append((child, rotation @ local_rotation, rotation @ local_translation + translation,
                            attributes.get("_name", name)))
        elif node in groups:
            pending.extend((c, rotation, translation, name) for c in reversed(groups[node]))
        elif node in shapes:
            out.extend((m, rotation, translation, name or f"model{m}") for m in shapes[node] if 0 <= m < model_count)
    return out


def _rotation(packed: int) -> np.ndarray:
    """MagicaVoxel's packed rotation: the column of row 0's and row 1's non-zero entry in bits 0-1 and 2-3, their signs
    (and row 2's) in bits 4, 5 and 6; an impossible packing is read as no rotation."""
    first, second = packed & 3, (packed >> 2) & 3
    if first > 2 or second > 2 or first == second:
        return np.eye(3)
    matrix = np.zeros((3, 3))
    for row, column in enumerate((first, second, 3 - first - second)):
        matrix[row, column] = -1.0 if packed >> (4 + row) & 1 else 1.0
    return matrix


def _int(data: bytes, offset: int, stop: int, path: Path) -> int:
    if offset + 4 > stop:
        raise InputError(f"a scene graph node is cut at byte {offset}", path)
    return struct.unpack_from("<i", data, offset)[0]


def _dict(data: bytes, offset: int, stop: int, path: Path) -> tuple[dict[str, str], int]:
    """A .vox DICT (a count, then key and value strings, each a length and bytes) and where it ends."""
    count, offset = _int(data, offset, stop, path), offset + 4
    if not 0 <= count <= MAX_DICT_ENTRIES:
        raise InputError(f"a scene graph node claims {count} attributes", path)
    out = {}
    for _ in range(count):
        texts = []
        for _ in range(2):
            length = _int(data, offset, stop, path)
            if not 0 <= length <= stop - offset - 4:
                raise InputError(f"a scene graph string at byte {offset} runs past its node", path)
            texts.append(data[offset + 4:offset + 4 + length].decode("utf-8", "replace"))
            offset += 4 + length
        out[texts[0]] = texts[1]
    return out, offset
