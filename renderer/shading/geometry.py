"""Stage 1 of the voxel shader: the object's geometry in its own frame, and `placed`, which puts it in the scene.

It depends on the voxels' occupancy alone, so paint and every placement and camera edit keep it: the occupied voxels
cropped to their box; the distance to the nearest occupied voxel (the surface is where it equals SURFACE_LEVEL, a
little inside the voxel hull, which is fatter than the mesh; thin parts stay as tubes); the gradient of that distance
smoothed, at full and half resolution, for normals; the occupancy smoothed broadly for ambient occlusion, and its
blocked lines per block of 4-32 voxels for the sky a hollow hides (far_occupancy); the shadows' occluders (the
occupied voxels' mean centre in each block of about 1 / OCCLUDER_CELLS of the object box).
Its compiled loops (numba) follow the Python that calls them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numba import njit, prange

from renderer.errors import InputError
from renderer.grid import dilate_cube, occupied_spans
from renderer.scene import (
    ObjectSpec,
)
from renderer.shading import filters
from renderer.shading.fields import HIT_GAP
from renderer.shading.quality import (
    BLUR_TRUNCATE,
    BROAD_SCALE,
    BROAD_SIGMA,
    CANDIDATE_DEPTH,
    CANDIDATE_SLACK,
    CELL_RUN,
    COARSE_CELLS,
    CORE_SIZE,
    CROP_MARGIN,
    DISTANCE_SIGMA,
    FAR_BLOCKS,
    NORMAL_SIGMA,
    OCCLUDER_CELLS,
    SURFACE_LEVEL,
    THIN_LEVEL,
)
from renderer.transform import merged_voxel_to_object, object_to_world


@dataclass(frozen=True)
class ObjectGeometry:
    """What the shader derives from the object's voxels alone (stage 1), and where `placed` put them."""

    elevation_deg: float  # the camera's (set by `placed`)
    offset: np.ndarray  # (3,) voxel index of the crop's first voxel (negative: the crop reaches past the voxels' edge)
    occupied: np.ndarray  # (d, r, c) bool: occupied voxels
    rgb: np.ndarray  # (.., .., .., 3) sRGB of the merged voxels it was made from, a view: read at occupied voxels only
    rgb_offset: np.ndarray  # (3,) int: a crop index plus this indexes `rgb`
    distance_and_core: np.ndarray  # (d, r, c, 2) float32: voxels from the nearest occupied voxel centre, and
    # the least of that within CORE_SIZE voxels (side by side: a ray's step reads both with one lookup)
    gradient: np.ndarray  # (D, H, W, 3): the gradient of the distance blurred by NORMAL_SIGMA, the normals' field
    coarse_gradient: np.ndarray  # the same of the distance averaged over 2^3 blocks: read for the normals' disc
    broad: np.ndarray | None  # occupancy blurred by BROAD_SIGMA (None: made without ambient occlusion)
    far_occupancy: tuple[np.ndarray, ...] | None  # blocked lines per block of FAR_BLOCKS voxels (_far_occupancy): the
    # sky a hollow hides beyond the broad occupancy's reach (None: made without ambient occlusion)
    voxel_to_world: np.ndarray  # 4x4, continuous voxel index -> world (object coordinates before `placed`)
    occluders: np.ndarray  # (M, 3) float64 world positions of the shadow occluders: the mean centre of the occupied
    # voxels in each block of voxels (OCCLUDER_CELLS)
    occluder_box: np.ndarray  # (2, 3) their least and greatest world coordinates (0s if none): kept for every light
    occluder_block: float  # voxels per side of the blocks each occluder stands for (OCCLUDER_CELLS; mean of the axes)
    surface_cells: np.ndarray  # (K, 6) int: boxes (first and last i, j, k) of the crop's cells where a camera ray may
    # meet the surface (any camera): runs along k
    coarse_surface_cells: np.ndarray  # the same cells as one box per COARSE_CELLS^3 block of them: fewer boxes for an
    # image whose pixels span several voxels (the floor's reflection)
    # Several objects' occluders joined (renderer/shading/compose.py): per object, the end of its occluders in
    # `occluders`, its occluder block's width in the world and its occluders' box, so each casts from shadow maps of
    # its own. () for one.
    occluder_parts: tuple[tuple[int, float, np.ndarray], ...] = ()

    @property
    def empty(self) -> bool:
        return self.occluders.shape[0] == 0

    @property
    def occluder_width(self) -> float:
        """The side of the block of voxels one occluder stands for, in world units (the voxels' mean side times
        occluder_block): the shadows' occluder radius and biases scale with it."""
        voxel = float(abs(np.linalg.det(self.voxel_to_world[:3, :3])) ** (1.0 / 3.0))
        return self.occluder_block * voxel


def object_geometry(merged: np.ndarray, resolution: int, factors: tuple[int, int, int],
                    ambient_occlusion: bool = True) -> ObjectGeometry:
    """The shader's geometry of an object in its own voxels: `merged` (D, H, W, 4) are its N^3 voxels merged by
    `factors` (renderer.grid.pool_voxels), and the result stands at the floor's origin, unturned and unscaled, until
    `placed` puts it in a scene. It depends on the voxels' occupancy alone, so a caller keeps it through paint and every
    placement and camera edit (the merge factors change only with a scale across a merge threshold).

    The object's own voxels, not a camera-aligned grid resampled from them: nothing is skipped or doubled where a grid
    would be turned against them (thin bars keep their width and place), and a turn or a camera tilt redoes no voxel
    work (docs/results.md, "Design choices"). `ambient_occlusion`: False leaves out the broad occupancy that only the
    ambient occlusion reads (ShaderQuality.ambient_occlusion)."""
    merged = np.asarray(merged)
    if merged.ndim != 4 or merged.shape[3] != 4:
        raise InputError(f"merged object voxels must be (D, H, W, 4), got {merged.shape}")
    occupied_all = merged[..., 3] >= 0.5
    voxel_to_world = merged_voxel_to_object(resolution, factors)
    spans = occupied_spans(occupied_all)  # argwhere over the object's box only
    if spans is None:
        found = np.zeros((0, 3), dtype=int)
        lo, hi = np.zeros(3, dtype=int), np.ones(3, dtype=int)
    else:  # the crop reaches CROP_MARGIN past the occupied box, past the merged voxels' own edge too (empty there)
        first, stop = np.array([a for a, _ in spans]), np.array([b for _, b in spans])
        found = filters.occupied_indices(occupied_all[tuple(slice(*span) for span in spans)]) + first
        lo, hi = first - CROP_MARGIN, stop + CROP_MARGIN
    occupied = _in_box(occupied_all, np.zeros(3, dtype=int), lo, hi)
    solid = _solid(occupied)
    raw = (distance_to_occupied(solid) if found.size else np.full(occupied.shape, 1e3, dtype=np.float32))
    distance = filters.gaussian_blur(raw, DISTANCE_SIGMA, BLUR_TRUNCATE)
    # Normals from the distance blurred by NORMAL_SIGMA in all: blur `distance` by what is missing.
    extra = math.sqrt(max(NORMAL_SIGMA**2 - DISTANCE_SIGMA**2, 0.0))
    smooth = filters.gaussian_blur(distance, extra, BLUR_TRUNCATE) if extra > 0.0 else distance
    gradient = np.empty(smooth.shape + (3,), dtype=np.float32)
    field_gradient(smooth, gradient)
    # Averaged over 2^3 blocks; an odd side's last voxel repeated, so no block mixes in zeros past the crop's edge.
    coarse = filters.block_mean2(np.pad(smooth, [(0, n % 2) for n in smooth.shape], mode="edge"))
    coarse_gradient = np.empty(coarse.shape + (3,), dtype=np.float32)
    field_gradient(coarse, coarse_gradient)
    core = filters.minimum_filter(distance, CORE_SIZE)
    distance_and_core = np.stack([distance, core], axis=-1)
    cells = _surface_cells(distance_and_core)
    half = filters.block_mean2(solid) if ambient_occlusion else None  # the solid occupancy at half resolution
    blocks = _occluder_blocks(resolution, factors)
    occluders = (_block_centroids(found, blocks) + 0.5) @ voxel_to_world[:3, :3].T + voxel_to_world[:3, 3]
    return ObjectGeometry(
        elevation_deg=0.0, offset=lo, occupied=occupied, rgb=merged[..., :3], rgb_offset=lo,
        distance_and_core=distance_and_core, surface_cells=_cell_runs(cells),
        coarse_surface_cells=_cells_by_block(cells, COARSE_CELLS), gradient=gradient,
        coarse_gradient=coarse_gradient,
        broad=_broad(half) if half is not None else None,
        far_occupancy=_far_occupancy(solid) if ambient_occlusion else None,
        voxel_to_world=voxel_to_world,
        occluders=np.ascontiguousarray(occluders), occluder_box=points_box(occluders),
        occluder_block=float(np.prod(blocks)) ** (1.0 / 3.0))


def _occluder_blocks(resolution: int, factors: tuple[int, int, int]) -> np.ndarray:
    """Merged voxels per side of the blocks each shadow occluder stands for, per axis (see OCCLUDER_CELLS)."""
    return np.array([max(1, resolution // f // OCCLUDER_CELLS) for f in factors], dtype=np.int64)


def _block_centroids(found: np.ndarray, blocks: np.ndarray) -> np.ndarray:
    """The mean of the voxel indices `found` (N, 3) in each block of `blocks` voxels that holds any, in C order of the
    blocks (found itself, as floats, when the blocks are single voxels)."""
    if not len(found) or np.all(blocks == 1):
        return found.astype(np.float64)
    keys = found // blocks
    keys -= keys.min(axis=0)
    dims = keys.max(axis=0) + 1
    linear = (keys[:, 0] * dims[1] + keys[:, 1]) * dims[2] + keys[:, 2]
    counts = np.bincount(linear, minlength=int(np.prod(dims)))
    held = np.flatnonzero(counts)
    sums = np.stack([np.bincount(linear, weights=found[:, axis], minlength=len(counts))[held] for axis in range(3)],
                    axis=1)
    return sums / counts[held, None]


def points_box(points: np.ndarray) -> np.ndarray:
    """(2, 3): the least and greatest coordinates of `points` (zeros if there are none); column by column, which
    is several times quicker than reducing the (N, 3) array along its first axis."""
    if not len(points):
        return np.zeros((2, 3))
    columns = [points[:, axis] for axis in range(3)]
    return np.array([[column.min() for column in columns], [column.max() for column in columns]])


def _surface_cells(distance_and_core: np.ndarray) -> np.ndarray:
    """(N, 3) indices of the crop's cells where a traced ray may stop (near_surface_cell_mask), in C order;
    none in a crop thinner than two voxels, where every pixel is a candidate instead. The pixel mask projects them
    as boxes: `_cell_runs` for the camera's image, `_cells_by_block` for one whose pixels span several voxels."""
    if min(distance_and_core.shape[:3]) < 2:
        return np.zeros((0, 3), dtype=np.int64)
    return filters.occupied_indices(near_surface_cell_mask(distance_and_core, SURFACE_LEVEL, THIN_LEVEL,
                                                                   CANDIDATE_SLACK, CANDIDATE_DEPTH))


def _cell_runs(cells: np.ndarray) -> np.ndarray:
    """(K, 6): boxes (first and last i, j, k) of runs of up to CELL_RUN consecutive `cells` (N, 3, C order) along the
    last axis."""
    if not len(cells):
        return np.zeros((0, 6), dtype=np.int64)
    # A run starts where the cell before it (along k) is not marked or the run so far is CELL_RUN long.
    follows = np.zeros(len(cells), dtype=bool)
    follows[1:] = (cells[1:, 0] == cells[:-1, 0]) & (cells[1:, 1] == cells[:-1, 1]) & (cells[1:, 2] == cells[:-1, 2] + 1)
    starts = np.flatnonzero(~follows)
    run_of = np.cumsum(~follows) - 1
    position = np.arange(len(cells)) - starts[run_of]
    first = ~follows | (position % CELL_RUN == 0)
    heads = np.flatnonzero(first)
    lasts = np.append(heads[1:] - 1, len(cells) - 1)
    i, j = cells[heads, 0], cells[heads, 1]
    return np.column_stack([i, i, j, j, cells[heads, 2], cells[lasts, 2]]).astype(np.int64)


def _cells_by_block(cells: np.ndarray, block: int) -> np.ndarray:
    """(K, 6): boxes (the least and greatest i, j, k) of the `cells` (N, 3) in each `block`^3 block that holds any."""
    if not len(cells):
        return np.zeros((0, 6), dtype=np.int64)
    keys = cells // block
    dims = keys.max(axis=0) + 1
    linear = (keys[:, 0] * dims[1] + keys[:, 1]) * dims[2] + keys[:, 2]
    order = np.argsort(linear, kind="stable")
    heads = np.flatnonzero(np.diff(linear[order], prepend=-1))  # each block's first cell in that order
    sorted_cells = cells[order]
    columns = []
    for axis in range(3):
        columns += [np.minimum.reduceat(sorted_cells[:, axis], heads), np.maximum.reduceat(sorted_cells[:, axis], heads)]
    return np.column_stack(columns).astype(np.int64)


def placed(geometry: ObjectGeometry, object_spec: ObjectSpec, elevation_deg: float) -> ObjectGeometry:
    """`geometry` (object_geometry's, at the floor's origin) placed as `object_spec` says (translation, rotation about
    the vertical, scale) and seen from a camera at `elevation_deg`: only its frame and its occluders' world positions
    change, so every placement and camera edit keeps the voxel work."""
    to_world = object_to_world(object_spec)
    occluders = geometry.occluders @ to_world[:3, :3].T + to_world[:3, 3]
    return replace(geometry, elevation_deg=float(elevation_deg), voxel_to_world=to_world @ geometry.voxel_to_world,
                   occluders=occluders, occluder_box=points_box(occluders))


def _in_box(window: np.ndarray, start: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The box [lo, hi) of the grid (grid indices) from a window of it that starts at `start`; zero outside the window."""
    out = np.zeros(tuple(hi - lo) + window.shape[3:], dtype=window.dtype)
    a, b = np.maximum(lo, start), np.minimum(hi, start + window.shape[:3])
    if np.all(a < b):
        out[tuple(slice(x - y, z - y) for x, y, z in zip(a, lo, b))] = window[tuple(slice(x - y, z - y)
                                                                                    for x, y, z in zip(a, start, b))]
    return out


def _solid(occupied: np.ndarray) -> np.ndarray:
    """The occupied voxels with their insides: voxelised surfaces are shells, and a slanted one-voxel shell
    is only diagonally connected, so the diagonal gaps a ray could slip through are closed first; then
    everything not connected to the crop's border (6-connected) is inside."""
    closed = _erode_cube(dilate_cube(occupied)) | occupied
    return ~filters.connected_to_border(closed)


def _erode_cube(mask: np.ndarray) -> np.ndarray:
    """Binary erosion by the 3x3x3 cube, outside the array counting as empty."""
    return ~dilate_cube(np.pad(~mask, 1, constant_values=True))[1:-1, 1:-1, 1:-1]


def _broad(half: np.ndarray) -> np.ndarray:
    """The solid occupancy averaged over 2^3 blocks (`half`) and blurred by BROAD_SIGMA voxels (at half resolution:
    occlusion is a broad effect), sampled at BROAD_SCALE times the crop's coordinates."""
    return filters.gaussian_blur(half, BROAD_SIGMA * BROAD_SCALE, BLUR_TRUNCATE)


def _far_occupancy(solid: np.ndarray) -> tuple[np.ndarray, ...]:
    """The levels the cones of the far sky occlusion read, one per block size of FAR_BLOCKS voxels, a level's cell i
    centred at crop coordinate (i + 0.5) * block: (.., .., .., 3) the share of the cell's face a line across it along
    each axis finds blocked by the solid occupancy (filters.block_coverage2; a mean would let a thin wall leak)."""
    levels, level, block = [], filters.mask_coverage2(solid), 2
    while block < FAR_BLOCKS[-1]:
        level, block = filters.block_coverage2(level), block * 2
        if block in FAR_BLOCKS:
            levels.append(level)
    return tuple(levels)


# --- compiled loops (numba, cached on disk) ---------------------------------------------------------

EMPTY_DISTANCE2 = np.float32(1e20)  # squared distance from a line with nothing occupied (any transform stays below)


@njit(cache=True, inline="always")
def _column_bounds(fields, i, j, k):
    """The least and the most distance (fields[..., 0]) and core (fields[..., 1]) of the four voxel centres (i, j, k),
    (i + 1, j, k), (i, j + 1, k), (i + 1, j + 1, k): one face of a cell."""
    d_lo = d_hi = fields[i, j, k, 0]
    c_lo = c_hi = fields[i, j, k, 1]
    for a, b in ((1, 0), (0, 1), (1, 1)):
        d, c = fields[i + a, j + b, k, 0], fields[i + a, j + b, k, 1]
        d_lo, d_hi, c_lo, c_hi = min(d_lo, d), max(d_hi, d), min(c_lo, c), max(c_hi, c)
    return d_lo, d_hi, c_lo, c_hi


@njit(cache=True, parallel=True)
def near_surface_cell_mask(fields, level, thin, slack, depth):
    """(n0 - 1, n1 - 1, n2 - 1) bool: the cells (voxel centres i..i+1, j..j+1, k..k+1) where a ray of
    `trace_surface` may stop. A ray stops only at a sample whose gap is below HIT_GAP, and never deeper inside than
    the last interval of its bisection, a few hundredths of a voxel; a sample in a cell interpolates its eight
    corners, so its distance lies between their least and most and its core likewise: its gap is at least
    least distance - max(level, most core + thin) and at most most distance - max(level, least core + thin). Marked
    where the first is under HIT_GAP + `slack` and the second at least -`depth`: not the cells wholly inside a part,
    which a ray reaches only through the surface's (the inside of a chair's seat held four in five marked cells). It
    reads the geometry alone, so the shader finds these once per object shape, not per placement or camera ray.
    Each row of cells along k reads each face of four corners once, shared by the two cells it bounds (a
    pass per axis through an array of every cell's bounds was a fifth of the geometry stage)."""
    mask = np.empty((fields.shape[0] - 1, fields.shape[1] - 1, fields.shape[2] - 1), dtype=np.bool_)
    for i in prange(mask.shape[0]):
        for j in range(mask.shape[1]):
            d_lo, d_hi, c_lo, c_hi = _column_bounds(fields, i, j, 0)
            for k in range(mask.shape[2]):
                e_lo, e_hi, f_lo, f_hi = _column_bounds(fields, i, j, k + 1)
                least_d, most_d, least_c, most_c = min(d_lo, e_lo), max(d_hi, e_hi), min(c_lo, f_lo), max(c_hi, f_hi)
                mask[i, j, k] = (least_d - max(level, most_c + thin) < HIT_GAP + slack
                                 and most_d - max(level, least_c + thin) >= -depth)
                d_lo, d_hi, c_lo, c_hi = e_lo, e_hi, f_lo, f_hi
    return mask


@njit(cache=True, parallel=True)
def field_gradient(field, out):
    """out[i, j, k] = the difference of `field` a voxel either side of voxel (i, j, k) along each axis (clamped at
    the edges). A trilinear read of it at any point equals those differences of the trilinear field there, so the
    normals at a point cost one read instead of six."""
    n0, n1, n2 = field.shape
    for i in prange(n0):
        i0, i1 = max(i - 1, 0), min(i + 1, n0 - 1)
        for j in range(n1):
            j0, j1 = max(j - 1, 0), min(j + 1, n1 - 1)
            for k in range(n2):
                k0, k1 = max(k - 1, 0), min(k + 1, n2 - 1)
                out[i, j, k, 0] = field[i1, j, k] - field[i0, j, k]
                out[i, j, k, 1] = field[i, j1, k] - field[i, j0, k]
                out[i, j, k, 2] = field[i, j, k1] - field[i, j, k0]


@njit(cache=True, inline="always")
def _lower_envelope(f, n, out, v, numerator, denominator):
    """Felzenszwalb and Huttenlocher's 1-D squared distance transform of the samples f[0:n] into out, in integers.

    The samples are squared distances (whole numbers, exact in float32) or EMPTY_DISTANCE2, which never wins
    against a finite one and so is left out of the envelope; a line of nothing else stays EMPTY_DISTANCE2.
    Each boundary between parabolas is kept as a fraction and compared by cross-multiplying, so no comparison
    is rounded (and there is no division)."""
    k = -1
    for q in range(n):
        if f[q] >= EMPTY_DISTANCE2:
            continue
        g = np.int64(f[q]) + q * q
        while k >= 0:
            top = g - (np.int64(f[v[k]]) + v[k] * v[k])  # the boundary with parabola v[k]: top / bottom
            bottom = 2 * (q - v[k])
            if k > 0 and top * denominator[k] <= numerator[k] * bottom:
                k -= 1  # parabola v[k] is nowhere lowest: drop it
                continue
            numerator[k + 1], denominator[k + 1] = top, bottom
            break
        k += 1
        v[k] = q
    if k < 0:
        for q in range(n):
            out[q] = EMPTY_DISTANCE2
        return
    last, k = k, 0
    for q in range(n):
        while k < last and numerator[k + 1] < q * denominator[k + 1]:
            k += 1
        out[q] = (q - v[k]) ** 2 + np.int64(f[v[k]])


@njit(cache=True, parallel=True)
def _nearest_along_lines(occupied, out):
    """out = squared distance along the last axis to the line's nearest occupied voxel (EMPTY_DISTANCE2 if none):
    the transform's first pass, two scans per line (on a binary input the lower envelope is not needed)."""
    rows, n = occupied.shape[0] * occupied.shape[1], occupied.shape[2]
    lines, found = occupied.reshape(rows, n), out.reshape(rows, n)
    for line in prange(rows):
        last = -1
        for q in range(n):
            if lines[line, q]:
                last = q
            found[line, q] = EMPTY_DISTANCE2 if last < 0 else np.float32((q - last) ** 2)
        after = -1
        for q in range(n - 1, -1, -1):
            if lines[line, q]:
                after = q
            if after >= 0:
                found[line, q] = min(found[line, q], np.float32((after - q) ** 2))


@njit(cache=True, parallel=True)
def _distance_pass(grid, axis, root):
    """One separable pass of the squared distance transform along `axis` (0 or 1), in place, each line gathered into
    a buffer and written back; `root`: write the square root (the last pass)."""
    n0, n1, n2 = grid.shape
    outer, length = (n1, n0) if axis == 0 else (n0, n1)
    for o in prange(outer):
        line = np.empty(length, dtype=np.float32)
        out = np.empty(length, dtype=np.float32)
        v = np.empty(length, dtype=np.int64)
        numerator = np.empty(length + 1, dtype=np.int64)
        denominator = np.empty(length + 1, dtype=np.int64)
        for k in range(n2):
            for p in range(length):
                line[p] = grid[p, o, k] if axis == 0 else grid[o, p, k]
            _lower_envelope(line, length, out, v, numerator, denominator)
            for p in range(length):
                value = out[p]
                if root:
                    value = np.float32(math.sqrt(value))
                if axis == 0:
                    grid[p, o, k] = value
                else:
                    grid[o, p, k] = value


def distance_to_occupied(occupied: np.ndarray) -> np.ndarray:
    """Euclidean distance (float32, in voxels) from every voxel centre to the nearest occupied one: the
    exact separable transform (Felzenszwalb and Huttenlocher 2012), compiled, the last axis by two scans per line,
    then the other two in place; scipy's distance_transform_edt gives the same but also computes the nearest
    voxel's index, 3x slower here."""
    grid = np.empty(occupied.shape, dtype=np.float32)
    _nearest_along_lines(np.ascontiguousarray(occupied, dtype=np.bool_), grid)
    _distance_pass(grid, 1, False)
    _distance_pass(grid, 0, True)
    return grid
