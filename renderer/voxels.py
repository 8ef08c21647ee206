"""Surface voxelisation of a normalised mesh into the object voxel array of renderer/transform.py.

A voxel is occupied when the surface passes through it: each triangle is tested exactly
against each candidate voxel box with the separating-axis theorem (Akenine-Moller's 13
axes: the box axes as bounding ranges, the triangle's normal as the range its plane sweeps
over a voxel column, the nine edge axes as the 2D edge tests of Schwarz & Seidel 2010). Voxel boxes
are closed and grown by a hair (VOXEL_EPS), so a surface lying exactly on a voxel boundary
marks both sides and the shell of a closed surface never has a hole, not even a diagonal one.

Candidates are enumerated per triangle along its dominant normal axis: for every column of
voxels its projection may touch, only the few voxels the triangle's plane crosses within
that column. Work is thus proportional to the voxels touched, for large and small triangles.

Color: each (triangle, voxel) hit samples the material where the line through the voxel
centre along the triangle's dominant axis meets its plane (snapped into the triangle by
mesh_colors_at); a voxel's color is the mean of its samples. A part of uniform color thus
gives exactly that color.

The interior is left empty: the network, the splatting and the bucket fill only ever see
the surface, and a hollow shell keeps paint strokes on visible voxels. The shell of a
closed mesh is closed, so scipy.ndimage.binary_fill_holes can fill it where needed.
"""

from __future__ import annotations

import zipfile
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import numpy as np
import trimesh

from renderer.color import to_uint8
from renderer.errors import InputError
from renderer.io import atomic_path
from renderer.limits import DEFAULT_RESOLUTION, MAX_RESOLUTION, MAX_VOXEL_FILE_BYTES, MIN_RESOLUTION
from renderer.mesh import mesh_colors_at
from renderer.scene import OBJECT_SIZE
from renderer.transform import OBJECT_BOX_MIN

VOXEL_EPS = 1e-4  # growth of each voxel box, in voxels, against rounding on exact boundaries
FACES_PER_CHUNK = 20_000  # bounds memory and sets the progress steps

ProgressCallback = Callable[[float], None]


def voxelize(mesh: trimesh.Trimesh, resolution: int = DEFAULT_RESOLUTION, progress: ProgressCallback | None = None) -> np.ndarray:
    """Surface voxels (N, N, N, 4) float32 of a mesh already in object coordinates (see normalise_mesh).

    Parts outside the object box are clipped. `progress(fraction)` is called as faces are done.
    """
    n = int(resolution)
    if not MIN_RESOLUTION <= n <= MAX_RESOLUTION:
        raise InputError(f"voxel resolution must be in [{MIN_RESOLUTION}, {MAX_RESOLUTION}], got {resolution}")
    voxel = OBJECT_SIZE / n
    vertices = (np.asarray(mesh.vertices, dtype=np.float64) - OBJECT_BOX_MIN) / voxel  # in voxel units
    faces = np.asarray(mesh.faces, dtype=np.int64)
    hit_voxels, hit_colors = [], []
    for start in range(0, len(faces), FACES_PER_CHUNK):
        face_ids = np.arange(start, min(start + FACES_PER_CHUNK, len(faces)))
        hit_faces, voxels, points = surface_hits(vertices[faces[face_ids]], n)
        hit_voxels.append(np.ravel_multi_index(voxels.T, (n, n, n)))
        hit_colors.append(mesh_colors_at(mesh, points * voxel + OBJECT_BOX_MIN, face_ids[hit_faces]))
        if progress is not None:
            progress((face_ids[-1] + 1) / len(faces))
    flat = np.concatenate(hit_voxels) if hit_voxels else np.zeros(0, dtype=np.int64)
    if len(flat) == 0:
        raise InputError("the mesh has no surface inside the object box (normalise it first)")
    colors = np.concatenate(hit_colors)
    counts = np.bincount(flat, minlength=n**3)
    occupied = np.flatnonzero(counts)
    rgba = np.zeros((n**3, 4), dtype=np.float32)
    for c in range(3):
        rgba[occupied, c] = np.bincount(flat, weights=colors[:, c], minlength=n**3)[occupied] / counts[occupied]
    rgba[occupied, 3] = 1.0
    return np.clip(rgba, 0.0, 1.0).reshape(n, n, n, 4)


def surface_hits(triangles: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every (triangle, voxel) pair where a triangle meets a voxel of the n^3 grid.

    `triangles` (T, 3, 3) are in voxel units (voxel (i, j, k) spans [i, i+1] x [j, j+1] x [k, k+1]).
    Returns per hit: the triangle index (H,), the voxel index (H, 3), and a point of the
    triangle's plane within about a voxel of the voxel centre (H, 3), for sampling its color.
    """
    with np.errstate(invalid="ignore", over="ignore"):
        normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    usable = np.isfinite(triangles).all(axis=(1, 2)) & np.isfinite(normals).all(axis=1)
    keep = np.flatnonzero(usable & (np.abs(normals).max(axis=1) > 0.0))  # zero-area faces cover nothing
    # Per triangle, reorder the axes to (u, v, w) with w its dominant normal axis; a cyclic
    # reordering keeps handedness, so the normal in (u, v, w) is the reordered normal.
    axes = (np.abs(normals[keep]).argmax(axis=1)[:, None] + np.array([1, 2, 0])) % 3
    tri = np.take_along_axis(triangles[keep], axes[:, None, :], axis=2)
    normal = np.take_along_axis(normals[keep], axes, axis=1)

    # Columns along w that the triangle's projection onto (u, v) overlaps.
    owner, u = _expand(*_cell_range(tri[:, :, 0].min(axis=1), tri[:, :, 0].max(axis=1), n))
    v_first, v_last = _cell_range(tri[:, :, 1].min(axis=1), tri[:, :, 1].max(axis=1), n)
    sub, v = _expand(v_first[owner], v_last[owner])
    tri_id, u = owner[sub], u[sub]
    inside = _inside_edges(_edge_coefficients(tri, normal, 0, 1), tri_id, u, v)
    tri_id, u, v = tri_id[inside], u[inside], v[inside]

    # Voxels of each column that the triangle's plane crosses, tested against the other two projections.
    planes = _planes(tri, normal)
    sub, w = _expand(*_cell_range(*_column_w_range(planes, tri_id, u, v), n))
    tri_id, u, v = tri_id[sub], u[sub], v[sub]
    inside = _inside_edges(_edge_coefficients(tri, normal, 1, 2), tri_id, v, w)
    inside &= _inside_edges(_edge_coefficients(tri, normal, 2, 0), tri_id, w, u)
    tri_id, cells = tri_id[inside], np.column_stack([u[inside], v[inside], w[inside]])

    # Color sample: the plane point straight along w from the voxel centre.
    u_mid, v_mid = cells[:, 0] + 0.5, cells[:, 1] + 0.5
    w_on_plane = planes.w00[tri_id] + planes.du[tri_id] * u_mid + planes.dv[tri_id] * v_mid
    points_uvw = np.column_stack([u_mid, v_mid, w_on_plane])
    voxels, points = np.empty_like(cells), np.empty_like(points_uvw)
    np.put_along_axis(voxels, axes[tri_id], cells, axis=1)  # back from (u, v, w) to (x, y, z)
    np.put_along_axis(points, axes[tri_id], points_uvw, axis=1)
    return keep[tri_id], voxels, points


def _cell_range(lo: np.ndarray, hi: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """First and last voxel index of the grid whose grown box meets [lo, hi]; last < first when none."""
    first = np.clip(np.floor(lo - VOXEL_EPS), 0, n).astype(np.int64)
    last = np.clip(np.floor(hi + VOXEL_EPS), -1, n - 1).astype(np.int64)
    return first, last


def _expand(first: np.ndarray, last: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All integers of each range [first, last], as (range index, integer) pairs."""
    count = np.maximum(last - first + 1, 0)
    owner = np.repeat(np.arange(len(first)), count)
    offset = np.arange(len(owner)) - np.repeat(np.cumsum(count) - count, count)
    return owner, first[owner] + offset


def _edge_coefficients(tri: np.ndarray, normal: np.ndarray, a: int, b: int) -> np.ndarray:
    """Edge functions (T, 3 edges, 3) of the triangles projected onto axes (a, b), for grown voxel boxes.

    A box with lowest voxel index (ca, cb) on those axes overlaps the projected triangle iff
    k_a ca + k_b cb + k_0 >= 0 for all three edges (Schwarz-Seidel: each edge is tested at
    the box corner deepest inside it). (a, b, third axis) must be a cyclic order of (0, 1, 2)
    so the normal's third component gives the triangle's winding in the projection.
    """
    sign = np.where(normal[:, 3 - a - b] >= 0.0, 1.0, -1.0)[:, None]
    qa, qb = tri[:, :, a], tri[:, :, b]
    ka = -(np.roll(qb, -1, axis=1) - qb) * sign  # inward edge normal
    kb = (np.roll(qa, -1, axis=1) - qa) * sign
    size = 1.0 + 2.0 * VOXEL_EPS
    k0 = -ka * (qa + VOXEL_EPS) - kb * (qb + VOXEL_EPS) + (np.maximum(ka, 0.0) + np.maximum(kb, 0.0)) * size
    return np.stack([ka, kb, k0], axis=-1)


def _inside_edges(coefficients: np.ndarray, tri_id: np.ndarray, ca: np.ndarray, cb: np.ndarray) -> np.ndarray:
    """Whether each candidate box passes all three edge functions of its triangle."""
    k = coefficients[tri_id]
    return (k[:, :, 0] * ca[:, None] + k[:, :, 1] * cb[:, None] + k[:, :, 2] >= 0.0).all(axis=1)


class _Planes(NamedTuple):
    """Per triangle: its plane as w = w00 + du u + dv v (|du|, |dv| <= 1, w being the dominant
    normal axis) and the range [w_min, w_max] of the triangle itself."""

    w00: np.ndarray
    du: np.ndarray
    dv: np.ndarray
    w_min: np.ndarray
    w_max: np.ndarray


def _planes(tri: np.ndarray, normal: np.ndarray) -> _Planes:
    du, dv = -normal[:, 0] / normal[:, 2], -normal[:, 1] / normal[:, 2]
    w00 = tri[:, 0, 2] - du * tri[:, 0, 0] - dv * tri[:, 0, 1]
    return _Planes(w00, du, dv, tri[:, :, 2].min(axis=1), tri[:, :, 2].max(axis=1))


def _column_w_range(planes: _Planes, tri_id: np.ndarray, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Range of w a triangle's plane sweeps over each grown voxel column (u, v), within the triangle's own range."""
    du, dv = planes.du[tri_id], planes.dv[tri_id]
    size = 1.0 + 2.0 * VOXEL_EPS
    at_corner = planes.w00[tri_id] + du * (u - VOXEL_EPS) + dv * (v - VOXEL_EPS)  # at the column's lowest (u, v)
    lo = at_corner + (np.minimum(du, 0.0) + np.minimum(dv, 0.0)) * size
    hi = at_corner + (np.maximum(du, 0.0) + np.maximum(dv, 0.0)) * size
    return np.maximum(lo, planes.w_min[tri_id]), np.minimum(hi, planes.w_max[tri_id])


# --- files -----------------------------------------------------------------------------------


def save_voxels(path: str | Path, rgba: np.ndarray) -> None:
    """Write object voxels as a compressed .npz holding `rgba` as uint8, atomically."""
    data = to_uint8(np.asarray(rgba))
    try:
        with atomic_path(path) as tmp, open(tmp, "wb") as f:
            np.savez_compressed(f, rgba=data)
    except OSError as exc:
        raise InputError(f"cannot write: {exc.strerror or exc}", path) from None


def load_voxels(path: str | Path) -> np.ndarray:
    """Read object voxels (N, N, N, 4) float32 from a .npz with key `rgba` (uint8 or floats in [0, 1]).

    The array's shape and type are read from its header first, so an oversized grid is refused unread.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path)
    if path.stat().st_size > MAX_VOXEL_FILE_BYTES:
        raise InputError(f"file is {path.stat().st_size / 2**20:.0f} MB; voxel files are read up to "
                         f"{MAX_VOXEL_FILE_BYTES // 2**20} MB", path)
    try:
        with np.load(path, allow_pickle=False) as npz:
            if "rgba" not in npz.files:
                raise InputError(f"no 'rgba' array (found {', '.join(npz.files) or 'nothing'})", path)
            shape, dtype = _npz_array_header(npz, "rgba")
            n = shape[0] if len(shape) == 4 else 0
            if shape != (n, n, n, 4) or not MIN_RESOLUTION <= n <= MAX_RESOLUTION:
                raise InputError(f"rgba must have shape (N, N, N, 4) with N in [{MIN_RESOLUTION}, {MAX_RESOLUTION}], "
                                 f"got {shape}", path)
            if dtype != np.uint8 and dtype.kind != "f":
                raise InputError(f"rgba must be uint8 or float, got {dtype}", path)
            raw = npz["rgba"]
    except InputError:
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        raise InputError(f"not a readable .npz voxel file ({exc})", path) from None
    if raw.dtype == np.uint8:
        rgba = raw.astype(np.float32) / 255.0
    else:
        rgba = np.nan_to_num(raw.astype(np.float32), nan=0.0, posinf=1.0, neginf=0.0).clip(0.0, 1.0)
    occupied = rgba[..., 3] >= 0.5
    rgba[..., 3] = occupied
    rgba[~occupied, :3] = 0.0
    return rgba


def _npz_array_header(npz: np.lib.npyio.NpzFile, key: str) -> tuple[tuple[int, ...], np.dtype]:
    """The shape and type of an array in a .npz, read from its .npy header without loading the data."""
    with npz.zip.open(f"{key}.npy") as member:
        version = np.lib.format.read_magic(member)
        read_header = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
        shape, _, dtype = read_header(member)
    return tuple(shape), dtype


def downsample_voxels(rgba: np.ndarray, resolution: int) -> np.ndarray:
    """The same object at a coarser `resolution`: a coarse voxel is occupied when any fine voxel in
    its span is, and takes the mean color of those occupied fine voxels (the paper's table 2 study)."""
    n = rgba.shape[0]
    if not 1 <= resolution <= n:
        raise InputError(f"a {n}^3 grid cannot be downsampled to {resolution}^3")
    coarse_of = (np.arange(n) * resolution) // n  # fine index -> coarse index along every axis
    i, j, k = np.nonzero(rgba[..., 3] > 0.5)
    flat = (coarse_of[i] * resolution + coarse_of[j]) * resolution + coarse_of[k]
    cells = resolution**3
    count = np.bincount(flat, minlength=cells).astype(np.float64)
    out = np.zeros((cells, 4), np.float32)
    for channel in range(3):
        sums = np.bincount(flat, weights=rgba[i, j, k, channel], minlength=cells)
        out[:, channel] = np.divide(sums, count, out=np.zeros(cells), where=count > 0)
    out[:, 3] = count > 0
    return out.reshape(resolution, resolution, resolution, 4)
