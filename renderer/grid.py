"""The scene grid the network reads: object voxels and ground voxels resampled into the camera's grid.

Axes (renderer/camera.py): the grid is an array (D, H, W, 4) float32 indexed [depth, row,
column], a cube of side GRID_EXTENT centred on the look-at point and aligned with the
camera. Depth 0 is nearest to the camera, row 0 is the top of the image (camera +y),
column 0 the left (camera -x). Channels are R, G, B (sRGB in [0, 1]) and occupancy (0 or 1).

Each grid voxel takes the object voxel (renderer/transform.py) that contains its centre,
mapped grid -> camera -> world -> object; nearest sampling keeps colors crisp. Object voxels
smaller than a grid voxel are first merged into blocks at least one grid voxel wide
(occupied if any member is, colored with the mean of the occupied members): sampling a
one-voxel-thin surface shell at a coarser spacing would otherwise skip it and leave holes
(at resolution 100 and scale 1 an object voxel is half a grid voxel). The ground is three
grid voxels of floor color just below y = 0 (paper section 3); the grid always lies inside
the floor square. Object parts outside the grid are clipped.

Caching: scene_grid is four pure stages, so an engine can keep each result until its inputs change:
    factors = pool_factors(resolution, spec.scale)                        # resolution, scale
    pooled = pool_voxels(rgba, factors)                                   # voxels (paint), factors
    indices = sample_indices(GridPlacement(resolution, factors, spec, elevation_deg))  # placement, camera
    grid = gather(pooled, floor_color, indices)                           # floor color: only this
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np
from numba import njit, prange

from renderer.camera import Camera, camera_to_grid_index
from renderer.scene import GRID_EXTENT, GRID_SIZE, OBJECT_SIZE, ObjectSpec
from renderer.transform import OBJECT_BOX_MIN, world_to_object

FLOOR_VOXELS = 3  # thickness of the ground, in grid voxels


def scene_grid(object_rgba: np.ndarray, object_spec: ObjectSpec, floor_color: tuple[float, float, float],
               elevation_deg: float, grid_size: int = GRID_SIZE) -> np.ndarray:
    """The network's input grid (D, H, W, 4) float32 for object voxels placed by `object_spec`."""
    resolution = object_rgba.shape[0]
    factors = pool_factors(resolution, object_spec.scale, grid_size)
    pooled = pool_voxels(object_rgba, factors)
    indices = sample_indices(GridPlacement(resolution, factors, object_spec, elevation_deg, grid_size))
    return gather(pooled, floor_color, indices)


def ground_grid(floor_color: tuple[float, float, float], elevation_deg: float, grid_size: int = GRID_SIZE,
                columns: int | None = None) -> np.ndarray:
    """The scene grid (D, H, W, 4) of the ground alone, as gather samples it (no object); its first `columns`
    columns."""
    ground = ground_mask(elevation_deg, grid_size, columns)
    grid = np.zeros((*ground.shape, 4), dtype=np.float32)
    grid[ground] = (*floor_color, 1.0)  # the floor row of gather
    return grid


def object_cells(object_rgba: np.ndarray, object_spec: ObjectSpec, floor_color: tuple[float, float, float],
                 elevation_deg: float, grid_size: int = GRID_SIZE,
                 pooled: tuple[np.ndarray, tuple | None] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Where an object fills the scene grid: the flat indices of the cells holding an occupied merged voxel and their
    rows; the ground grid with them written over it is scene_grid's grid. Only the object's window is sampled.
    `pooled`: pool_object's result for the object's merge factors, if the caller keeps it."""
    resolution = object_rgba.shape[0]
    factors = pool_factors(resolution, object_spec.scale, grid_size)
    merged, within = pool_object(object_rgba, factors) if pooled is None else pooled
    nothing = np.zeros(0, dtype=np.int64), np.zeros((0, 4), dtype=np.float32)
    if within is None:
        return nothing
    placement = GridPlacement(resolution, factors, object_spec, elevation_deg, grid_size, within)
    window = placement.window
    if any(lo >= hi for lo, hi in window):
        return nothing
    block = gather(merged, floor_color, sample_indices(placement, window))
    ground = ground_mask(elevation_deg, grid_size)[tuple(slice(lo, hi) for lo, hi in window)]
    local = np.nonzero((block[..., 3] > 0.5) & ~ground)
    cells = np.ravel_multi_index(tuple(i + lo for i, (lo, _) in zip(local, window)), (grid_size,) * 3)
    return cells.astype(np.int64), block[local]


# --- appearance: merged object voxels, and the grid gathered from them ------------------------------


def pool_factors(resolution: int, scale: tuple[float, float, float], grid_size: int = GRID_SIZE) -> tuple[int, int, int]:
    """Object voxels to merge per axis so a merged block is at least one grid voxel wide in the world."""
    grid_voxel = GRID_EXTENT / grid_size
    object_voxel = OBJECT_SIZE / resolution
    return tuple(min(resolution, max(1, math.ceil(grid_voxel / (object_voxel * s) - 1e-9))) for s in scale)


def pool_voxels(rgba: np.ndarray, factors: tuple[int, int, int],
                box: tuple[tuple[int, int], ...] | None = None) -> np.ndarray:
    """Merge blocks of factors[0] x factors[1] x factors[2] voxels (the last block may be partial).

    A block is occupied if any member is; its color is the mean of its occupied members, summed in float32 along
    axis 0, then 1, then 2. With nothing to merge the voxels are returned as they are (voxelize, load_voxels and the
    paint tools keep empty voxels black). A compiled loop over the blocks on every core: numpy's per-plane block
    sums were a third of preparing a training sample. `box`: the (start, stop) span per axis that
    holds every occupied voxel (occupied_spans), if the caller keeps it: only the blocks it reaches are merged, the
    others are empty (a chair's box is a fifth to three quarters of its 200^3 voxels).
    """
    if tuple(factors) == (1, 1, 1):
        return np.asarray(rgba, dtype=np.float32)
    f = np.asarray(factors, dtype=np.int64)
    shape = tuple(-(-n // k) for n, k in zip(rgba.shape[:3], factors))
    if box is None:
        out = np.empty((*shape, 4), dtype=np.float32)
        lo, hi = np.zeros(3, dtype=np.int64), np.asarray(shape, dtype=np.int64)
    else:
        out = np.zeros((*shape, 4), dtype=np.float32)
        lo = np.array([start // k for (start, _), k in zip(box, factors)], dtype=np.int64)
        hi = np.array([-(-stop // k) for (_, stop), k in zip(box, factors)], dtype=np.int64)
    _merge_all_blocks(np.ascontiguousarray(rgba, dtype=np.float32), f, out, lo, hi)
    return out


def repool_voxels(pooled: np.ndarray, after: np.ndarray, factors: tuple[int, int, int], changed: np.ndarray,
                  in_place: bool = False) -> np.ndarray:
    """pool_voxels(after, factors), given pooled = pool_voxels(before, factors) for a grid of the same shape that
    differs from `after` at the flat voxel indices `changed` (colors_and_changes): only their blocks are merged again (a
    paint stroke touches a few), as pool_voxels merges them. `in_place`: write into `pooled` (when nothing else
    reads it) rather than a new array."""
    if tuple(factors) == (1, 1, 1):
        return np.asarray(after, dtype=np.float32)
    out = pooled if in_place else np.array(pooled, dtype=np.float32, copy=True)
    if len(changed) == 0:
        return out
    f = np.asarray(factors, dtype=np.int64)
    blocks = _touched_blocks(np.asarray(changed, dtype=np.int64), np.asarray(after.shape[:3], dtype=np.int64), f,
                             np.zeros(out.shape[:3], dtype=np.bool_))
    if len(blocks) * 4 > np.prod(out.shape[:3]):  # most blocks changed (a new base color): merge them all
        out[...] = pool_voxels(after, factors)
        return out
    _merge_blocks(np.asarray(after, dtype=np.float32), blocks, f, out)
    return out


@njit(cache=True)
def _touched_blocks(changed, shape, factors, seen):
    """(K, 3) the merge blocks holding the flat voxel indices `changed`, each once (`seen`: False over the blocks)."""
    blocks = np.empty((len(changed), 3), dtype=np.int64)
    count = 0
    for v in changed:
        i, rest = divmod(v, shape[1] * shape[2])
        j, k = divmod(rest, shape[2])
        a, b, c = i // factors[0], j // factors[1], k // factors[2]
        if not seen[a, b, c]:
            seen[a, b, c] = True
            blocks[count, 0], blocks[count, 1], blocks[count, 2] = a, b, c
            count += 1
    return blocks[:count]


@njit(cache=True)
def _merge_blocks(rgba, blocks, factors, out):
    """out[block] = the block's merge for each block index in `blocks` (K, 3), as pool_voxels merges it. A loop over
    the blocks' members, since numpy's gather of them is slow for large strokes."""
    for b in range(blocks.shape[0]):
        _merge_block(rgba, blocks[b, 0], blocks[b, 1], blocks[b, 2], factors, out)


@njit(cache=True, parallel=True)
def _merge_all_blocks(rgba, factors, out, lo, hi):
    """The merge of every block from `lo` to `hi` (block indices per axis) into `out` (pool_voxels), the block rows
    along axis 0 spread over the cores."""
    for a in prange(lo[0], hi[0]):
        for b in range(lo[1], hi[1]):
            for c in range(lo[2], hi[2]):
                _merge_block(rgba, a, b, c, factors, out)


@njit(cache=True, inline="always")
def _merge_block(rgba, a, b, c, factors, out):
    """out[a, b, c]: the occupied members' mean color and the block's occupancy, the float32 sums taken along axis 0,
    then 1, then 2 (one order, so a block merged again after paint equals the first merge bit for bit)."""
    n0, n1, n2 = rgba.shape[0], rgba.shape[1], rgba.shape[2]
    i0, j0, k0 = a * factors[0], b * factors[1], c * factors[2]
    zero = np.float32(0.0)
    total_r = total_g = total_b = total_n = zero
    for k in range(k0, min(k0 + factors[2], n2)):
        along_j_r = along_j_g = along_j_b = along_j_n = zero
        for j in range(j0, min(j0 + factors[1], n1)):
            along_i_r = along_i_g = along_i_b = along_i_n = zero
            for i in range(i0, min(i0 + factors[0], n0)):
                if rgba[i, j, k, 3] >= 0.5:
                    along_i_r += rgba[i, j, k, 0]
                    along_i_g += rgba[i, j, k, 1]
                    along_i_b += rgba[i, j, k, 2]
                    along_i_n += np.float32(1.0)
            along_j_r += along_i_r
            along_j_g += along_i_g
            along_j_b += along_i_b
            along_j_n += along_i_n
        total_r += along_j_r
        total_g += along_j_g
        total_b += along_j_b
        total_n += along_j_n
    mean = max(total_n, np.float32(1.0))
    out[a, b, c, 0] = total_r / mean
    out[a, b, c, 1] = total_g / mean
    out[a, b, c, 2] = total_b / mean
    out[a, b, c, 3] = np.float32(1.0) if total_n > 0 else zero


def colors_and_changes(rgba: np.ndarray, voxels: np.ndarray, before: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows (K, 4) of `rgba` at the flat voxel indices `voxels` (ascending), and the indices among them (ascending)
    whose row differs from `before` (K, 4), the same voxels' rows of another grid: what repool_voxels needs after a
    paint stroke, in one pass over the occupied voxels (paint recolors nothing else)."""
    rows = np.empty((len(voxels), 4), dtype=np.float32)
    changed = np.empty(len(voxels), dtype=np.int64)
    count = _gather_changes(np.asarray(rgba, dtype=np.float32).reshape(-1, 4), np.asarray(voxels, dtype=np.int64),
                            np.asarray(before, dtype=np.float32), rows, changed)
    return rows, changed[:count]


@njit(cache=True)
def _gather_changes(table, voxels, before, rows, changed):
    count = 0
    for n in range(len(voxels)):
        differs = False
        for c in range(4):
            rows[n, c] = table[voxels[n], c]
            differs |= rows[n, c] != before[n, c]
        if differs:
            changed[count] = voxels[n]
            count += 1
    return count


def gather(pooled: np.ndarray, floor_color: tuple[float, float, float], indices: np.ndarray) -> np.ndarray:
    """The grid (D, H, W, 4) float32: for each grid voxel, row indices[d, r, c] of the P merged voxels `pooled`, or
    for row P the empty voxel, for row P + 1 the floor voxel (floor color, occupied). The merged voxels are read where
    they are: a table of them with the two rows appended was a copy of them all per move."""
    rows = np.ascontiguousarray(pooled, dtype=np.float32).reshape(-1, 4)
    floor = np.array([*floor_color, 1.0], dtype=np.float32)
    out = np.empty((*np.shape(indices), 4), dtype=np.float32)
    _gather_rows(rows, floor, np.ascontiguousarray(indices).reshape(-1), out.reshape(-1, 4))
    return out


@njit(cache=True, parallel=True)
def _gather_rows(rows, floor, indices, out):
    """out[i] = rows[indices[i]], zeros for row len(rows), `floor` for row len(rows) + 1."""
    count = rows.shape[0]
    for i in prange(indices.shape[0]):
        row = indices[i]
        for channel in range(4):
            if row < count:
                out[i, channel] = rows[row, channel]
            elif row == count:
                out[i, channel] = 0.0
            else:
                out[i, channel] = floor[channel]


# --- geometry: which merged voxel (row of gather) each grid voxel takes -----------------------------


def grid_index_to_world(elevation_deg: float, grid_size: int = GRID_SIZE) -> np.ndarray:
    """4x4 matrix from continuous grid coordinates (depth, row, column) to world coordinates.

    Built from camera.py's own camera_to_grid_index (an affine map) so the grid convention
    lives in one place.
    """
    origin = camera_to_grid_index(np.zeros(3), grid_size)
    camera_to_grid = np.eye(4)
    camera_to_grid[:3, :3] = np.column_stack([camera_to_grid_index(axis, grid_size) - origin for axis in np.eye(3)])
    camera_to_grid[:3, 3] = origin
    return Camera(elevation_deg).camera_to_world() @ np.linalg.inv(camera_to_grid)


@dataclass(frozen=True)
class GridPlacement:
    """Where an N^3 object's voxels, merged by `factors`, stand in a `grid_size`^3 camera grid: one object pose and
    camera, built once and handed to the grid functions, which read its derived maps (computed once, when asked)."""

    resolution: int  # N, object voxels per side
    factors: tuple[int, int, int]  # the merge factors (pool_factors)
    object_spec: ObjectSpec  # translation, rotation, scale
    elevation_deg: float  # the camera's
    grid_size: int = GRID_SIZE
    # A box of merged voxels, (start, stop) per axis, outside which every merged voxel is empty (pool_object finds
    # it), if the caller knows one: only it is sampled.
    within: tuple[tuple[int, int], ...] | None = None

    @cached_property
    def pooled_shape(self) -> tuple[int, int, int]:
        """The merged voxels' shape, (P0, P1, P2): P = their product rows of `gather`."""
        return tuple(-(-self.resolution // f) for f in self.factors)

    @cached_property
    def merged_box(self) -> tuple[np.ndarray, np.ndarray]:
        """(first, stop): the merged voxels that may be non-empty, per axis."""
        if self.within is None:
            return np.zeros(3), np.asarray(self.pooled_shape, dtype=np.float64)
        return tuple(np.asarray(self.within, dtype=np.float64).T)

    @cached_property
    def grid_to_object(self) -> np.ndarray:
        """4x4: continuous grid coordinates (depth, row, column) to object coordinates."""
        return world_to_object(self.object_spec) @ grid_index_to_world(self.elevation_deg, self.grid_size)

    @cached_property
    def window(self) -> list[tuple[int, int]]:
        """The grid ranges, (start, stop) per axis, that sample_indices samples the object in: every grid voxel it
        gives a merged voxel lies inside them (they may be empty)."""
        first, stop = self.merged_box
        block = np.asarray(self.factors, dtype=np.float64) * (OBJECT_SIZE / self.resolution)
        return _grid_ranges_covering(self.grid_to_object, OBJECT_BOX_MIN + first * block, OBJECT_BOX_MIN + stop * block,
                                     self.grid_size)


def sample_indices(placement: GridPlacement, box: list[tuple[int, int]] | None = None,
                   with_object: bool = True) -> np.ndarray:
    """Row of `gather` (D, H, W) int32 for every grid voxel: a merged object voxel, empty (P) or floor (P + 1).

    The P merged voxels are those pool_voxels makes with the placement's factors; outside its `within` box grid
    voxels take the empty row P instead, the same values. (The ground lies below every object box, so no ground
    voxel is affected.) `box`: only the grid voxels in these ranges, (start, stop) per axis (default: the whole grid;
    a crop around the object costs a fraction of it). `with_object`: False gives the ground and empty rows alone.
    """
    g = placement.grid_size
    n_rows = int(np.prod(placement.pooled_shape))
    box = [(0, g)] * 3 if box is None else box
    indices = np.full(tuple(hi - lo for lo, hi in box), n_rows, dtype=np.int32)
    np.copyto(indices, n_rows + 1, where=ground_mask(placement.elevation_deg, g)[tuple(slice(*span) for span in box)])
    if not with_object:
        return indices
    ranges = [(max(lo, start), min(hi, stop)) for (lo, hi), (start, stop) in zip(placement.window, box)]
    if all(lo < hi for lo, hi in ranges):
        out = indices[tuple(slice(lo - start, hi - start) for (lo, hi), (start, _) in zip(ranges, box))]  # a view
        _sample_window(placement, ranges, out)
    return indices


def pool_object(object_rgba: np.ndarray, factors: tuple[int, int, int],
                box: tuple[tuple[int, int], ...] | None = None) -> tuple[np.ndarray, tuple | None]:
    """The merged voxels, and the box of those that are not all zero (None if none is): only it need be sampled.
    Depends on the voxels and the merge factors alone, so a caller keeps it while the object moves. `box`: see
    pool_voxels."""
    pooled = pool_voxels(object_rgba, factors, box)
    return pooled, occupied_spans(non_empty_voxels(pooled))


def _sample_window(placement: GridPlacement, ranges: list[tuple[int, int]], out: np.ndarray) -> None:
    """Over the grid ranges `ranges` (inside the placement's window; `out` has their shape), the merged voxel (flat
    row index) each grid voxel centre falls in, written into `out` where it falls in one (elsewhere left as it is)."""
    first, stop = placement.merged_box
    block = np.asarray(placement.factors, dtype=np.float64) * (OBJECT_SIZE / placement.resolution)  # merged voxel sides
    cell = placement.grid_to_object[:3] / block[:, None]  # the merged-voxel coordinate, affine in (d, r, c, 1)
    cell[:, 3] -= OBJECT_BOX_MIN / block
    centres = [np.arange(lo, hi) + 0.5 for lo, hi in ranges]
    _merged_voxel_rows(cell, *centres, np.asarray(first, dtype=np.float64), np.asarray(stop, dtype=np.float64),
                       np.asarray(placement.pooled_shape, dtype=np.int64), out)


@njit(cache=True, parallel=True)
def _merged_voxel_rows(cell, d, r, c, first, stop, shape, out):
    """out[i, j, k] = flat index of the merged voxel holding grid voxel centre (d[i], r[j], c[k]), whose cell along
    object axis a is floor(cell[a] . (d, r, c, 1)) (summed as depth + (row + constant), then column), if every cell
    lies in [first, stop); else left as it is. One pass, no (D, H, W) temporaries."""
    for i in prange(d.shape[0]):
        for j in range(r.shape[0]):
            p0 = cell[0, 0] * d[i] + (cell[0, 1] * r[j] + cell[0, 3])
            p1 = cell[1, 0] * d[i] + (cell[1, 1] * r[j] + cell[1, 3])
            p2 = cell[2, 0] * d[i] + (cell[2, 1] * r[j] + cell[2, 3])
            for k in range(c.shape[0]):
                a = math.floor(p0 + cell[0, 2] * c[k])
                b = math.floor(p1 + cell[1, 2] * c[k])
                e = math.floor(p2 + cell[2, 2] * c[k])
                if first[0] <= a < stop[0] and first[1] <= b < stop[1] and first[2] <= e < stop[2]:
                    out[i, j, k] = (int(a) * shape[1] + int(b)) * shape[2] + int(e)


def shader_pool_factors(resolution: int, scale: tuple[float, float, float], grid_size: int) -> tuple[int, int, int]:
    """How the voxel shader merges an N^3 object's voxels when it stands in for a `grid_size`^3 grid: as pool_factors
    for the network's grid (in pairs at scale 1), and for a finer one as for a grid four times as fine again, which
    merges none of the product's 200^3 voxels at scales of a half and above (the shader draws the object's own voxels:
    renderer.shading.geometry.object_geometry). Merged in pairs (as for a grid twice as fine), the test chairs' coverage,
    most scaled below 1, differed from the mesh's by 0.00073-0.00087 (mean squared) against 0.00049-0.00058, and the
    NVR+ erred 8-12 % more (docs/results.md, "Design choices")."""
    return pool_factors(resolution, scale, 4 * grid_size if grid_size > GRID_SIZE else grid_size)


def dilate_cube(mask: np.ndarray) -> np.ndarray:
    """Binary dilation by the 3x3x3 cube, one axis at a time (the cube is the product of three segments)."""
    out = mask.copy()
    for axis in range(3):
        grown = out.copy()
        _shifted(grown, axis, 1)[...] |= _shifted(out, axis, -1)
        _shifted(grown, axis, -1)[...] |= _shifted(out, axis, 1)
        out = grown
    return out


def _shifted(array: np.ndarray, axis: int, side: int) -> np.ndarray:
    """The view of `array` without its first (side 1) or last (side -1) slice along `axis`."""
    index = [slice(None)] * 3
    index[axis] = slice(1, None) if side == 1 else slice(None, -1)
    return array[tuple(index)]


def non_empty_voxels(pooled: np.ndarray) -> np.ndarray:
    """Which merged voxels (D, H, W) of `pooled` (D, H, W, 4) are not all zero (-0.0 counts as non-zero: a larger crop)."""
    bits = np.ascontiguousarray(pooled, dtype=np.float32).reshape(-1, 4).view(np.uint64)  # a voxel: two 8-byte words
    return ((bits[:, 0] | bits[:, 1]) != 0).reshape(pooled.shape[:-1])


def occupied_spans(mask: np.ndarray) -> tuple[tuple[int, int], ...] | None:
    """Bounding box of the True entries of a 3D mask as one (start, stop) span per axis; None if there are none."""
    plane = mask.any(axis=2)  # one pass over the mask; the three projections come from this and its columns
    spans = []
    for projection in (plane.any(axis=1), plane.any(axis=0), mask.any(axis=(0, 1))):
        hits = np.flatnonzero(projection)
        if hits.size == 0:
            return None
        spans.append((int(hits[0]), int(hits[-1]) + 1))
    return tuple(spans)


def _affine_over_grid(kd: float, kr: float, kc: float, k0: float, d: np.ndarray, r: np.ndarray, c: np.ndarray,
                      dtype: type = np.float64) -> np.ndarray:
    """kd d + kr r + kc c + k0 for every (d, r, c) of the given coordinate vectors, shape (len d, len r, len c);
    (len d, len r, 1) when kc is 0, the same values, to broadcast."""
    plane = ((kd * d)[:, None] + (kr * r + k0)[None, :]).astype(dtype)
    if kc == 0.0:
        return plane[:, :, None]
    return plane[:, :, None] + (kc * c).astype(dtype)[None, None, :]


@lru_cache(maxsize=8)
def ground_mask(elevation_deg: float, grid_size: int = GRID_SIZE, columns: int | None = None) -> np.ndarray:
    """Grid voxels (D, H, W) of the ground slab, as sample_indices marks them; only the first `columns` columns if given.

    Cached (read-only): an object transform keeps the camera, so its ground is the same.
    """
    mask = np.ascontiguousarray(np.broadcast_to(
        _floor_mask(grid_index_to_world(elevation_deg, grid_size), grid_size, columns),
        (grid_size, grid_size, grid_size if columns is None else min(columns, grid_size))))
    mask.flags.writeable = False
    return mask


def _floor_mask(grid_to_world: np.ndarray, grid_size: int, columns: int | None = None) -> np.ndarray:
    """Grid voxels whose centre lies in the ground slab: world y in [-FLOOR_VOXELS voxels, 0); over the grid's
    first `columns` columns. (D, H, 1) to broadcast when the ground does not change along the columns.

    float32 is ample for a slab several voxels thick and four times faster on the full grid.
    """
    shape = (grid_size, grid_size, grid_size if columns is None else min(columns, grid_size))
    d, r, c = (np.arange(n, dtype=np.float64) + 0.5 for n in shape)
    y = _affine_over_grid(*grid_to_world[1], d, r, c, dtype=np.float32)
    return (y >= np.float32(-FLOOR_VOXELS * GRID_EXTENT / grid_size)) & (y < 0.0)


def _grid_ranges_covering(grid_to_object: np.ndarray, lo: np.ndarray, hi: np.ndarray, grid_size: int) -> list[tuple[int, int]]:
    """Index ranges [start, stop) per grid axis, clipped to the grid, whose voxels may see the object box [lo, hi]."""
    corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    in_grid = corners @ np.linalg.inv(grid_to_object).T
    first = np.clip(np.floor(in_grid[:, :3].min(axis=0)) - 1, 0, grid_size).astype(int)
    last = np.clip(np.ceil(in_grid[:, :3].max(axis=0)) + 1, 0, grid_size).astype(int)
    return list(zip(first.tolist(), last.tolist()))
