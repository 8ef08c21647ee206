"""What a mesh file promises before its body is read: element counts and the bytes they need.

Mesh readers believe headers: a PLY that claims 10^9 vertices makes them allocate tens of gigabytes, a
GLB whose chunk claims 2 GB makes them read it. Checking the header against the limits
(renderer/limits.py) and against the file's real size first refuses such files in a few kilobytes of
memory; the promised counts then let load_mesh tell a cut file from a whole one. Written here rather
than taken from a library because the readers (trimesh, open3d) expose no header-only pass.
"""

from __future__ import annotations

import json
import struct
from dataclasses import dataclass
from pathlib import Path

from renderer.errors import InputError
from renderer.limits import MAX_JSON_BYTES, MAX_MESH_FACES, MAX_MESH_FILE_BYTES, MAX_MESH_VERTICES

HEADER_BYTES = 65536  # a PLY or OFF header that needs more is not a header
PLY_TYPE_BYTES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
                  "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}


@dataclass(frozen=True)
class MeshHeader:
    """Counts a file promises; None where the format has no header that says."""

    vertices: int | None = None
    faces: int | None = None
    least_bytes: int = 0  # the fewest bytes a file holding those counts can have


def check_mesh_file(path: Path) -> MeshHeader:
    """Refuse a mesh file whose size or header breaks the limits or cannot be true; return its promised counts."""
    size = path.stat().st_size
    if size == 0:
        raise InputError("file is empty", path)
    if size > MAX_MESH_FILE_BYTES:
        raise InputError(f"file is {size / 2**20:.0f} MB; meshes are read up to {MAX_MESH_FILE_BYTES // 2**20} MB", path)
    suffix = path.suffix.lower()
    with open(path, "rb") as f:
        head = f.read(HEADER_BYTES)
    if suffix == ".ply":
        header = _ply_header(head, path)
    elif suffix == ".off":
        header = _off_header(head, path)
    elif suffix == ".stl":
        header = _stl_header(head, size)
    elif suffix == ".glb":
        header = _glb_header(head, size, path)
    elif suffix == ".gltf":
        header = _gltf_header(size, path)
    else:
        header = MeshHeader()
    for count, limit, what in ((header.vertices, MAX_MESH_VERTICES, "vertices"), (header.faces, MAX_MESH_FACES, "faces")):
        if count is not None and count > limit:
            raise InputError(f"header claims {count:,} {what}; meshes are read up to {limit:,}", path)
    if header.least_bytes > size:
        raise InputError(f"file is cut: its header promises at least {header.least_bytes:,} bytes, the file has {size:,}",
                         path)
    return header


def _ply_header(head: bytes, path: Path) -> MeshHeader:
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        raise InputError("not a PLY file (no 'ply' ... 'end_header' header)", path)
    body_start = head.find(b"\n", end) + 1
    lines = head[:end].decode("ascii", "replace").splitlines()
    binary = any(line.startswith("format binary") for line in lines)
    elements: list[list] = []  # [name, count, fixed bytes per row, list-count bytes per row, properties]
    for words in (line.split() for line in lines):
        if len(words) >= 3 and words[0] == "element":
            try:
                count = int(words[2])
            except ValueError:
                raise InputError(f"PLY header has a bad element count {words[2]!r}", path) from None
            if count < 0:
                raise InputError(f"PLY header has a negative element count {count}", path)
            elements.append([words[1], count, 0, 0, 0])
        elif len(words) >= 3 and words[0] == "property" and elements:
            element = elements[-1]
            element[4] += 1
            if words[1] == "list" and len(words) >= 5:
                element[3] += PLY_TYPE_BYTES.get(words[2], 1)
            else:
                element[2] += PLY_TYPE_BYTES.get(words[1], 1)
    counts = {name: count for name, count, *_ in elements}
    # The least a body can hold: binary rows of fixed-size properties (lists at least their count),
    # text rows of at least one character and a separator per property.
    least = sum(count * ((fixed + lists) if binary else 2 * max(props, 1)) for _, count, fixed, lists, props in elements)
    return MeshHeader(counts.get("vertex"), counts.get("face"), body_start + least)


def _off_header(head: bytes, path: Path) -> MeshHeader:
    words = []
    for line in head.decode("ascii", "replace").splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            words.extend(line.split())
        if len(words) >= 4:
            break
    if not words or not words[0].endswith("OFF"):
        raise InputError("not an OFF file (it does not start with 'OFF')", path)
    try:
        vertices, faces = int(words[1]), int(words[2])
    except (IndexError, ValueError):
        raise InputError("OFF header has no vertex and face counts", path) from None
    if vertices < 0 or faces < 0:
        raise InputError(f"OFF header has negative counts ({vertices}, {faces})", path)
    return MeshHeader(vertices, faces, 6 * vertices + 8 * faces)  # "0 0 0\n" and "3 0 1 2\n"


def _stl_header(head: bytes, size: int) -> MeshHeader:
    if len(head) >= 84:
        (triangles,) = struct.unpack("<I", head[80:84])
        if 84 + 50 * triangles == size:  # a binary STL (a text STL is read line by line, bounded by its size)
            return MeshHeader(faces=triangles)
    return MeshHeader()


def _glb_header(head: bytes, size: int, path: Path) -> MeshHeader:
    if len(head) < 20 or head[:4] != b"glTF":
        raise InputError("not a GLB file (no 'glTF' header)", path)
    _, _, total = struct.unpack("<4sII", head[:12])
    (json_length,) = struct.unpack("<I", head[12:16])
    if total > size or 20 + json_length > size:
        raise InputError(f"file is cut or its header lies: it claims {max(total, 20 + json_length):,} bytes, "
                         f"the file has {size:,}", path)
    if json_length > MAX_JSON_BYTES:
        raise InputError(f"GLB JSON chunk of {json_length:,} bytes (at most {MAX_JSON_BYTES:,})", path)
    return MeshHeader()


def _gltf_header(size: int, path: Path) -> MeshHeader:
    if size > MAX_JSON_BYTES:
        raise InputError(f"glTF file of {size:,} bytes (at most {MAX_JSON_BYTES:,})", path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError):
        raise InputError("not a glTF file (its JSON cannot be read)", path) from None
    buffers = data.get("buffers", []) if isinstance(data, dict) else []
    for i, buffer in enumerate(buffers if isinstance(buffers, list) else []):
        length = buffer.get("byteLength", 0) if isinstance(buffer, dict) else 0
        if not isinstance(length, int) or not 0 <= length <= MAX_MESH_FILE_BYTES:
            raise InputError(f"buffers[{i}].byteLength {length!r} is not a size up to {MAX_MESH_FILE_BYTES:,} bytes", path)
    return MeshHeader()

