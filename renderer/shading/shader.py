"""The voxel shader: a physically based image of the network's inputs, in three cacheable stages.

From the object's voxels, where the scene places them, the light position, the camera elevation and the floor color
(what the network reads), and the scene's fixed constants (renderer/scene.py), it draws what the path tracer would,
approximately. It draws the object's own voxels, merged as for the grid it stands in for
(renderer.grid.shader_pool_factors: none on the 256^3 grid at the data's scales, in pairs on the network's 128^3 one);
lengths below in voxels are those merged voxels.

1. object_geometry (depends on the voxels' occupancy alone, in the object's own frame; `placed` puts the result where
   the scene has the object and sets the camera, so paint and every placement and camera edit keep this stage): the
   object's occupied voxels, cropped to their box; the distance to the nearest occupied voxel
   (the surface is where it equals SURFACE_LEVEL, a little inside the voxel hull, which is fatter
   than the mesh; thin parts stay as tubes); the gradient of that distance smoothed, at full and half resolution,
   for normals; the occupancy smoothed broadly for ambient occlusion; the shadows' occluders (the occupied voxels'
   mean centre in each block of about 1 / OCCLUDER_CELLS of the object box).
2. visible_surface (adds the image size): per pixel, the first surface point a camera ray meets
   (sphere tracing the distance), anti-aliased at silhouettes by 2 x 2 rays (ShaderQuality), its normal (averaged over the
   surface around it where the surface is flat), albedo (the voxels' colors averaged over the pixel's footprint)
   and ambient occlusion; the floor points, and how much of their sky the object blocks; these as
   images too (SurfaceImages), shared by every light's shaded image. floor_reflection: the same, coarser, of the
   object mirrored in the floor, where the floor shows (for the shader's own image, not a network's input).
3. shade (adds the light and the floor color): soft shadows from shadow maps seen from
   LIGHT_POINTS^2 (ShaderQuality) points on the square light (the floor reads each as its square of the light: one smooth
   penumbra, not LIGHT_POINTS^2 copies), direct light (Lambert), ambient light with occlusion,
   light bounced up from the floor, the lit floor (renderer/floor_light.py, which a caller may keep
   while the object moves) times the object's shadow, and the object's reflection in the floor's glossy coat, if
   given; composited over the background, in sRGB.

A light move reruns only `shade`; a placement or camera edit stages 2 and 3; only another object (or a scale across a
merge threshold) all three. Known gaps (a network's job): the reflection's exact blur and contact, color bleeding
between object parts, exact penumbra shape, and whatever shading stays in photo-colored voxels (renderer/photo.py divides the photo's light out
when it is known, with this shader's own light, so its errors stay in the colors).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache

import numba
import numpy as np
from scipy import ndimage, special

from renderer.camera import Camera
from renderer.color import linear_to_srgb, srgb_to_linear
from renderer.errors import InputError
from renderer.floor_light import FloorTerms, coat_reflectance, lit_floor_terms
from renderer.grid import dilate_cube, occupied_spans, pool_voxels, shader_pool_factors
from renderer.resample import downscaled_mask, linear_weights
from renderer.scene import (
    AMBIENT_RADIANCE,
    CAMERA_DISTANCE,
    GRID_EXTENT,
    LIGHT_RADIANCE,
    LIGHT_SIZE,
    SHADER_GRID_SIZE,
    ObjectSpec,
    Scene,
)
from renderer.shading import filters, kernels
from renderer.splat import cached_floor_mask
from renderer.transform import merged_voxel_to_object, object_to_world

# Each value below was chosen by measuring the shader and the shipped NVR+ against the path tracer on the test sets;
# the figures are in docs/results.md, "Design choices, measured" (DC below) and "Measurements behind the code" (MC).
THIN_LEVEL = 0.35  # voxels above a thin part's core where its surface is drawn (if more than SURFACE_LEVEL)
SURFACE_LEVEL = 0.8  # voxels from the nearest occupied voxel centre to the drawn surface (the hull is fatter than the mesh)
DISTANCE_SIGMA = 1.0  # voxels: blur of the distance field the surface is drawn from (smooth, not beaded)
NORMAL_SIGMA = 1.5  # voxels: blur of the distance field the normals come from (no staircases; wider blurs err more: DC)
# Normals are averaged over a disc of the surface's tangent plane: a face a few degrees off a voxel axis is a staircase
# of long treads that the blur above cannot flatten (bands of light across a leaning chair back). Samples whose
# normal is more than about 45 degrees from the point's own are left out, so edges between faces stay sharp (DC).
NORMAL_DISC = 16.0  # voxels: the disc's radius
NORMAL_RINGS = 2  # rings of 8 samples on it
NORMAL_AGREE = 0.7  # a sample counts by how far the cosine to the point's normal exceeds this
BROAD_SIGMA = 2.5  # voxels: occupancy blur for ambient occlusion
BROAD_SCALE = 0.5  # the broad occupancy is stored at half resolution
BLUR_TRUNCATE = 2.5  # gaussian kernels reach this many sigmas
CROP_MARGIN = 6  # voxels around the object's box (blur and occlusion reach)
# Per side of the light square: shadow maps and the direct-light sum. 3 x 3 instead of 4 x 4 takes a quarter off the
# light stage at a negligible cost in error (DC).
LIGHT_POINTS = 3
SHADOW_MAP_SIZE = 96  # texels per side
# Radius of the sphere around each occluder that the shadow maps draw, in sides of the block it stands for. The hull
# is fatter than the mesh, and a thin part's band of voxels most of all: the drawn surface's distance cast lattices'
# floor shadows too dark; 0.2 erred least of the radii tried (MC).
OCCLUDER_RADIUS = 0.2
# Each occluder stands for the occupied voxels of a block, at their mean centre, the blocks about 1 / OCCLUDER_CELLS of
# the object box on a side (2^3 of the product's 200^3 voxels; an object voxelised at 100^3 or merged in pairs casts
# from its own voxels), and covers its block's square in the maps. A quarter of the occluders casts shadows as good
# for the NVR+, whose data's shadows 100^3 voxels cast, and the light stage is quicker (DC).
OCCLUDER_CELLS = 100
# The shadow maps' offsets and biases below are in sides of an occluder's block (OCCLUDER_CELLS), to which the maps
# know an occluder's place; half as far erred more, further changed nothing (DC).
SHADOW_NORMAL_OFFSET = 1.0  # how far along the normal an object point is moved before the shadow maps are read
SHADOW_GRAZING_OFFSET = 1.5  # how much further, times the sine of the angle between the normal and the light
SHADOW_BIAS = 0.5  # how much nearer the light an occluder must be than the moved point to shadow it
FLOOR_SHADOW_BIAS = 0.25  # the same for a floor point
FLOOR_SHADOW_STEP = 0.025  # world units between the floor points the shadow maps are read at
OCCLUSION_DISTANCES = np.array([1.5, 3.0, 6.0, 12.0], dtype=np.float32)  # voxels along the normal
OCCLUSION_WEIGHTS = np.array([0.35, 0.3, 0.25, 0.2], dtype=np.float32)
FLOOR_OCCLUSION_DISTANCES = np.array([2.0, 5.0, 10.0, 20.0], dtype=np.float32)  # voxels straight up
FLOOR_OCCLUSION_WEIGHTS = np.array([0.3, 0.3, 0.25, 0.2], dtype=np.float32)
BLOCKED_SKY_LIGHT = 0.35  # share of the ambient light a blocked sky direction still brings (the lit object)
FLOOR_BOUNCE = 1.0  # weight of the light the floor sends back up onto the object (0: none)
FLOOR_BELOW_LIT = 0.5  # share of the direct light the floor under an object point gets (its shadow falls there)
# A pixel shows the texture averaged over its footprint: a point takes the colors of the voxels around it, weighted
# by a Gaussian centred on the point of COLOR_SPREAD pixel sides at its depth, not its voxel's color alone (the spread
# that erred least, DC). At least COLOR_LEAST voxel sides, so that a close-up's colors blend between voxels instead of
# showing them as blocks.
COLOR_SPREAD = 0.6
COLOR_LEAST = 0.5
# Rays per side at silhouette pixels: 3 errs as 2 and traces longer; 1 makes the NVR+ err more on single-colored
# chairs (MC).
SUBPIXELS = 2
# A ray covers its pixel by how deep it goes into the part it meets: not at all when it only touches
# SURFACE_LEVEL, fully when within COVERAGE_PROBE voxels past the surface it gets COVERAGE_FULL of the
# way from there to the part's core (the least distance around it: 0 in a thick part, more in a thin
# one). This thins the hull's silhouettes towards the mesh's and keeps thin parts opaque face on.
CORE_SIZE = 5  # voxels: the neighbourhood a part's core is the least distance of
COVERAGE_FULL = 0.7
COVERAGE_PROBE = 4.0
# A ray through a thin panel seen at a slant does not go deep either, so the coverage above leaves specks of floor
# showing through solid panels (about 9 % of one test chair's interior pixels). A group of partly covered pixels
# that no empty pixel touches, at most SPECK_PIXELS at 256^2 (in proportion to the image's area), is covered fully;
# openings a ray passes through keep their empty pixels and stay open.
SPECK_PIXELS = 40
# The floor's glossy coat mirrors the object, in the shader's own image: the object mirrored in the floor is traced
# where the floor shows, at 1/REFLECTION_SUBSAMPLING of the image's side, lit like the object, blurred by REFLECTION_BLUR
# of its pixels (the coat's roughness), and replaces the sky the coat mirrored there by the coat's Fresnel reflectance
# times REFLECTION_SCALE. These values erred least of those tried; a finer trace did no better. A network's input
# leaves it out: the shipped NVR+ learned a reflection from its data and errs more when given it (DC).
REFLECTION_SUBSAMPLING = 4
REFLECTION_BLUR = 1.0
REFLECTION_SCALE = 0.5
CANDIDATE_SLACK = 0.01  # voxels of gap a cell may have beyond a hit's and still mark its pixels as ray candidates
CANDIDATE_DEPTH = 0.25  # voxels of gap inside the surface a cell's points must reach to count (a ray stops within 0.1)
CELL_RUN = 4  # cells along the last axis whose pixels are marked as one box (more: fewer boxes, more pixels traced)
COARSE_CELLS = 4  # cells per side of the blocks marked as one box for the floor's reflection


@dataclass(frozen=True)
class ShaderQuality:
    """How finely the shader samples its dearest terms: rays per side at silhouette pixels (anti-aliasing), points
    per side of the square light (shadow maps, soft shadows), rings of the normals' disc (NORMAL_RINGS; 0: the
    smoothed field's gradient alone) and the spread of a point's color over its pixel's footprint (COLOR_SPREAD
    pixel sides; 0: its voxel's color), and whether the sky light is occluded (`ambient_occlusion`: the object's
    points probed along their normals, the floor's straight up; False: every point sees the whole sky, which changed
    the fast NVR+'s error by under 2 %). FULL_QUALITY is what the networks were trained on; FAST_QUALITY takes about a
    fifth off an NVR+ frame after an object move and errs more (docs/results.md, "Speed")."""

    silhouette_rays: int = SUBPIXELS
    light_points: int = LIGHT_POINTS
    normal_rings: int = NORMAL_RINGS
    color_spread: float = COLOR_SPREAD
    ambient_occlusion: bool = True

    def __post_init__(self) -> None:
        if not (1 <= self.silhouette_rays <= 8 and 1 <= self.light_points <= 8):
            raise InputError(f"shader quality: silhouette rays and light points per side must be in [1, 8], got "
                             f"{self.silhouette_rays} and {self.light_points}")
        if not (0 <= self.normal_rings <= 8 and 0.0 <= self.color_spread <= 4.0):
            raise InputError(f"shader quality: normal rings must be in [0, 8] and the color spread in [0, 4] pixel "
                             f"sides, got {self.normal_rings} and {self.color_spread}")


FULL_QUALITY = ShaderQuality()
FAST_QUALITY = ShaderQuality(silhouette_rays=1, light_points=2, normal_rings=0, color_spread=0.0,
                             ambient_occlusion=False)
QUALITIES = {"full": FULL_QUALITY, "fast": FAST_QUALITY}  # by the name the command line and the editor use


def quality_named(name: str) -> ShaderQuality:
    """The ShaderQuality a name of QUALITIES stands for; an InputError for any other name."""
    if name not in QUALITIES:
        raise InputError(f"unknown shader quality {name!r} (choose from {', '.join(QUALITIES)})")
    return QUALITIES[name]


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
    voxel_to_world: np.ndarray  # 4x4, continuous voxel index -> world (object coordinates before `placed`)
    occluders: np.ndarray  # (M, 3) float64 world positions of the shadow occluders: the mean centre of the occupied
    # voxels in each block of voxels (OCCLUDER_CELLS)
    occluder_box: np.ndarray  # (2, 3) their least and greatest world coordinates (0s if none): kept for every light
    occluder_block: float  # voxels per side of the blocks each occluder stands for (OCCLUDER_CELLS; mean of the axes)
    surface_cells: np.ndarray  # (K, 6) int: boxes (first and last i, j, k) of the crop's cells where a camera ray may
    # meet the surface (any camera): runs along k
    coarse_surface_cells: np.ndarray  # the same cells as one box per COARSE_CELLS^3 block of them: fewer boxes for an
    # image whose pixels span several voxels (the floor's reflection)

    @property
    def empty(self) -> bool:
        return self.occluders.shape[0] == 0


@dataclass(frozen=True)
class VisibleSurface:
    """What a camera sees of the object and the floor (stage 2); pixel arrays are (H, W, ...)."""

    size: int
    coverage: np.ndarray  # (H, W) float32: share of the pixel the object covers
    pixels: np.ndarray  # (N, 2) int: row, column of the pixels with an object point
    points: np.ndarray  # (N, 3) world
    normals: np.ndarray  # (N, 3) world, unit
    color_voxels: np.ndarray  # (N, 3) int: crop index of the voxel the point's color is looked up around (-1: grey)
    color_points: np.ndarray  # (N, 3) the points in crop coordinates, where their colors' weights are centred
    color_spread: np.ndarray  # (N,) world units: how far around the point the color is averaged (COLOR_SPREAD)
    albedo: np.ndarray  # (N, 3) linear
    occlusion: np.ndarray  # (N,) ambient light reaching the point from the sky, 0..1
    depth: np.ndarray  # (N,) distance along the view axis
    floor: np.ndarray  # (H, W) bool
    floor_points: np.ndarray  # (F, 3) world points of the floor pixels, row-major over `floor`
    floor_extent: np.ndarray  # (2, 2): their least and greatest x and z, [[x, z], [x, z]]
    floor_occlusion: np.ndarray  # (F,) ambient light reaching the floor point, 0..1
    images: SurfaceImages  # the same per pixel: what a shaded image shows that does not depend on the light


@dataclass(frozen=True)
class FloorReflection:
    """The object as the floor's glossy coat mirrors it, for the shader's own image (stage 2): the points of the object
    mirrored in the floor that the camera sees where the floor shows, traced at 1/REFLECTION_SUBSAMPLING of the
    image's side, as the real object's points (stage 3 lights them as it lights the object), and how much of each
    the coat reflects."""

    side: int  # of the reflection's image
    pixels: np.ndarray  # (N, 2) int: row, column in it
    points: np.ndarray  # (N, 3) world: the real object's points
    normals: np.ndarray  # (N, 3) world, unit
    albedo: np.ndarray  # (N, 3) linear
    occlusion: np.ndarray  # (N,) sky light reaching the point, 0..1
    weight: np.ndarray  # (N,) float32: the coat's reflectance towards the camera times REFLECTION_SCALE and the coverage


@dataclass(frozen=True)
class SurfaceImages:
    """The light-independent buffers of a shaded image (H, W, ...), made once per surface and shared (read-only)."""

    albedo: np.ndarray  # linear object albedo (0 where no object)
    albedo_srgb: np.ndarray  # the same in sRGB, as a network reads it
    normal: np.ndarray  # world normal (0 where no object)
    depth: np.ndarray  # view-axis distance of the object point (0 where none)
    occlusion: np.ndarray  # share of the sky seen: object points, and floor points
    floor_occlusion: np.ndarray  # the floor's alone, behind the object too (what the ground under it gets)


@dataclass(frozen=True)
class ShadedImage:
    """The shaded image and the buffers a network can read, all (H, W, ...) float32."""

    image: np.ndarray  # sRGB in [0, 1]
    coverage: np.ndarray  # object share of the pixel
    albedo: np.ndarray  # linear object albedo (0 where no object)
    albedo_srgb: np.ndarray  # the same in sRGB
    normal: np.ndarray  # world normal (0 where no object)
    depth: np.ndarray  # view-axis distance of the object point (0 where none)
    visibility: np.ndarray  # share of the light seen: object points, and floor points
    occlusion: np.ndarray  # share of the sky seen: object points, and floor points


# --- stage 1 ----------------------------------------------------------------------------------


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
    raw = (kernels.distance_to_occupied(solid) if found.size else np.full(occupied.shape, 1e3, dtype=np.float32))
    distance = filters.gaussian_blur(raw, DISTANCE_SIGMA, BLUR_TRUNCATE)
    # Normals from the distance blurred by NORMAL_SIGMA in all: blur `distance` by what is missing.
    extra = math.sqrt(max(NORMAL_SIGMA**2 - DISTANCE_SIGMA**2, 0.0))
    smooth = filters.gaussian_blur(distance, extra, BLUR_TRUNCATE) if extra > 0.0 else distance
    gradient = np.empty(smooth.shape + (3,), dtype=np.float32)
    kernels.field_gradient(smooth, gradient)
    # Averaged over 2^3 blocks; an odd side's last voxel repeated, so no block mixes in zeros past the crop's edge.
    coarse = filters.block_mean2(np.pad(smooth, [(0, n % 2) for n in smooth.shape], mode="edge"))
    coarse_gradient = np.empty(coarse.shape + (3,), dtype=np.float32)
    kernels.field_gradient(coarse, coarse_gradient)
    core = filters.minimum_filter(distance, CORE_SIZE)
    distance_and_core = np.stack([distance, core], axis=-1)
    cells = _surface_cells(distance_and_core)
    blocks = _occluder_blocks(resolution, factors)
    occluders = (_block_centroids(found, blocks) + 0.5) @ voxel_to_world[:3, :3].T + voxel_to_world[:3, 3]
    return ObjectGeometry(
        elevation_deg=0.0, offset=lo, occupied=occupied, rgb=merged[..., :3], rgb_offset=lo,
        distance_and_core=distance_and_core, surface_cells=_cell_runs(cells),
        coarse_surface_cells=_cells_by_block(cells, COARSE_CELLS), gradient=gradient,
        coarse_gradient=coarse_gradient,
        broad=_broad(solid) if ambient_occlusion else None, voxel_to_world=voxel_to_world,
        occluders=np.ascontiguousarray(occluders), occluder_box=_box(occluders),
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


def _box(points: np.ndarray) -> np.ndarray:
    """(2, 3): the least and greatest coordinates of `points` (zeros if there are none); column by column, which
    is several times quicker than reducing the (N, 3) array along its first axis."""
    if not len(points):
        return np.zeros((2, 3))
    columns = [points[:, axis] for axis in range(3)]
    return np.array([[column.min() for column in columns], [column.max() for column in columns]])


def _surface_cells(distance_and_core: np.ndarray) -> np.ndarray:
    """(N, 3) indices of the crop's cells where a traced ray may stop (kernels.near_surface_cell_mask), in C order;
    none in a crop thinner than two voxels, where every pixel is a candidate instead. The pixel mask projects them
    as boxes: `_cell_runs` for the camera's image, `_cells_by_block` for one whose pixels span several voxels."""
    if min(distance_and_core.shape[:3]) < 2:
        return np.zeros((0, 3), dtype=np.int64)
    return filters.occupied_indices(kernels.near_surface_cell_mask(distance_and_core, SURFACE_LEVEL, THIN_LEVEL,
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
                   occluders=occluders, occluder_box=_box(occluders))


def _in_box(window: np.ndarray, start: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The box [lo, hi) of the grid (grid indices) from a window of it that starts at `start`; zero outside the window."""
    out = np.zeros(tuple(hi - lo) + window.shape[3:], dtype=window.dtype)
    a, b = np.maximum(lo, start), np.minimum(hi, start + window.shape[:3])
    if np.all(a < b):
        out[tuple(slice(x - y, z - y) for x, y, z in zip(a, lo, b))] = window[tuple(slice(x - y, z - y)
                                                                                    for x, y, z in zip(a, start, b))]
    return out


# --- stage 2 ----------------------------------------------------------------------------------


def visible_surface(geometry: ObjectGeometry, size: int, cover_behind: bool = True, colors: bool = True,
                    quality: ShaderQuality = FULL_QUALITY) -> VisibleSurface:
    """The object points and floor points a `size`^2 render camera sees, with their occlusion. `cover_behind`: a ray
    that grazes a part and goes on to a part behind it covers its pixel (no floor shows through at a part drawn over
    another); False counts it as partly covered, for photo delighting, where such a pixel mixes two parts. `colors`:
    False leaves the object grey, for a caller that repaints the surface next (repaint_surface) and so need not pay
    for the colors twice. `quality`: its rays per side at silhouette pixels, normals' disc, colors' spread and
    ambient occlusion."""
    if quality.ambient_occlusion and geometry.broad is None:
        raise ValueError("visible_surface: this quality occludes the sky, and the geometry was made without occlusion")
    camera = Camera(geometry.elevation_deg, width=size, height=size)
    coverage, pixels, points_crop = _first_hits(geometry, camera, cover_behind, quality.silhouette_rays)
    normals_crop, color_voxels, occlusion = _point_normals(geometry, points_crop, quality.normal_rings,
                                                          quality.ambient_occlusion)
    points_world, normals_world, depth = _in_world(geometry, camera, points_crop, normals_crop)
    color_spread = quality.color_spread * np.maximum(depth, 0.0) / camera.focal_px  # pixel sides at its depth

    floor, floor_points, floor_extent = _floor_points(camera)
    floor_occlusion = (_floor_occlusion(geometry, floor_points, np.linalg.inv(geometry.voxel_to_world))
                       if quality.ambient_occlusion else np.ones(len(floor_points), dtype=np.float32))
    lookup = color_voxels if colors else np.full_like(color_voxels, -1)  # -1: no voxel, grey
    srgb, albedo = _surface_colors(geometry, lookup, points_crop, color_spread)
    images = _surface_images(size, pixels, srgb, albedo, normals_world, depth, occlusion, floor, floor_occlusion)
    return VisibleSurface(size=size, coverage=coverage, pixels=pixels, points=points_world, normals=normals_world,
                          color_voxels=color_voxels, color_points=points_crop, color_spread=color_spread,
                          albedo=albedo, occlusion=occlusion, depth=depth, floor=floor, floor_points=floor_points,
                          floor_extent=floor_extent, floor_occlusion=floor_occlusion, images=images)


def _first_hits(geometry: ObjectGeometry, camera: Camera, cover_behind: bool = True, subpixels: int = SUBPIXELS,
                where: np.ndarray | None = None, coarse: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The coverage (H, W) of the object a camera sees, the pixels (N, 2: row, column) it covers, and the crop point
    (N, 3) of each, where its centre ray (or at a silhouette, its first `subpixels`^2 ray to hit) meets the surface.
    `where` (H, W) bool: only these pixels are traced (the others are left uncovered). `coarse`: the pixels that may
    meet the surface are found from the geometry's coarse boxes of cells."""
    coverage = np.zeros((camera.height, camera.width), dtype=np.float32)
    if geometry.empty:
        return coverage, np.zeros((0, 2), dtype=np.int64), np.zeros((0, 3))
    world_to_voxel = np.linalg.inv(geometry.voxel_to_world)
    origin = world_to_voxel[:3, :3] @ camera.position + world_to_voxel[:3, 3] - geometry.offset
    rows, cols = _pixel_window(geometry, camera)
    cells = geometry.coarse_surface_cells if coarse else geometry.surface_cells
    candidates, nearest, farthest = _ray_candidates(geometry, camera, rows, cols, cells)
    if where is not None:
        candidates &= where[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1]
    centre_t, centre_p, centre_cover = _trace_candidates(geometry, camera, world_to_voxel, origin, rows, cols,
                                                         candidates, nearest, farthest, cover_behind)
    hit = centre_t < kernels.FAR
    cover = centre_cover
    point = centre_p
    if subpixels > 1:
        edge = _differs_from_a_neighbour(hit)
        edge |= hit & (centre_cover < 1.0)
        if where is not None:
            edge &= candidates
        if edge.any():
            er, ec = np.nonzero(edge)
            offsets = (np.arange(subpixels) + 0.5) / subpixels
            sub_v = rows[er][:, None, None] + offsets[None, :, None]  # (edges, subpixels, 1)
            sub_u = cols[ec][:, None, None] + offsets[None, None, :]  # (edges, 1, subpixels): _trace broadcasts
            sub_t, sub_p, sub_cover = _trace(geometry, camera, world_to_voxel, origin, sub_v, sub_u,
                                             nearest[er, ec][:, None, None], farthest[er, ec][:, None, None],
                                             cover_behind)
            sub_t, sub_p = sub_t.reshape(len(er), -1), sub_p.reshape(len(er), -1, 3)
            sub_hit = sub_t < kernels.FAR
            cover[er, ec] = sub_cover.reshape(len(er), -1).mean(axis=1)
            # A silhouette pixel whose centre ray misses takes its first hitting subpixel's point.
            take = ~hit[er, ec] & sub_hit.any(axis=1)
            first = np.argmax(sub_hit, axis=1)
            point = point.copy()
            point[er[take], ec[take]] = sub_p[take, first[take]]
        cover = _close_specks(cover, camera.width)
    r_idx, c_idx = np.nonzero(cover > 0.0)
    coverage[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1] = cover
    return coverage, np.stack([rows[r_idx], cols[c_idx]], axis=1), point[r_idx, c_idx]


def _point_normals(geometry: ObjectGeometry, points_crop: np.ndarray, rings: int,
                   occluded: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each crop point's normal (in crop coordinates, averaged over `rings` rings of the tangent plane's disc), the
    crop index of the voxel its color is centred on (-1: none), and the sky light reaching it (all of it unless
    `occluded`)."""
    normals = np.zeros((len(points_crop), 3))
    color_voxels = np.full((len(points_crop), 3), -1, dtype=np.int64)
    if not len(points_crop):
        return normals, color_voxels, np.ones(0, dtype=np.float32)
    kernels.surface_normals_and_voxels(geometry.gradient, geometry.coarse_gradient, geometry.occupied, points_crop,
                                       normals, color_voxels, NORMAL_DISC, rings, NORMAL_AGREE)
    sky = _surface_occlusion(geometry, points_crop, normals) if occluded else np.ones(len(points_crop), np.float32)
    return normals, color_voxels, sky


def _in_world(geometry: ObjectGeometry, camera: Camera, points_crop: np.ndarray,
              normals_crop: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Crop points and normals in the world (normals unit), and the points' distances along the view axis."""
    linear = geometry.voxel_to_world[:3, :3]
    points = (points_crop + geometry.offset) @ linear.T + geometry.voxel_to_world[:3, 3]
    normals = normals_crop @ np.linalg.inv(linear)  # a gradient's transform: the inverse transpose
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    return points, normals, (points - camera.position) @ _view_axis(camera)


_MIRROR = np.diag([1.0, -1.0, 1.0, 1.0])  # world y -> -y: the floor (y = 0) as a mirror


def floor_reflection(geometry: ObjectGeometry, surface: VisibleSurface) -> FloorReflection:
    """The object mirrored in the floor as the camera sees it past the object in `surface` (a ray the coat reflects
    off the floor goes on as the camera's ray through the same pixel goes on to the object mirrored below the floor).
    Blurred and faint, it is drawn from centre rays alone, normals without the disc and one voxel's color, its sky
    occluded if the geometry was made with the ambient occlusion."""
    side = max(surface.size // REFLECTION_SUBSAMPLING, 1)
    camera = Camera(geometry.elevation_deg, width=side, height=side)
    mirrored = replace(geometry, voxel_to_world=_MIRROR @ geometry.voxel_to_world)
    # The reflection's pixels where any of the image's pixels they cover shows floor.
    where = downscaled_mask(surface.floor & (surface.coverage < 1.0), side, min_cover=1e-6)
    coverage, pixels, points_crop = _first_hits(mirrored, camera, subpixels=1, where=where, coarse=True)
    normals_crop, color_voxels, occlusion = _point_normals(mirrored, points_crop, rings=0,
                                                          occluded=geometry.broad is not None)
    points, normals, _ = _in_world(mirrored, camera, points_crop, normals_crop)
    _, albedo = _surface_colors(mirrored, color_voxels, points_crop, np.zeros(len(points)))
    flip = _MIRROR.diagonal()[:3]
    _, directions = camera.pixel_rays(pixels[:, 1] + 0.5, pixels[:, 0] + 0.5)
    reflectance = coat_reflectance(np.clip(-directions[:, 1], 0.0, 1.0))
    weight = REFLECTION_SCALE * reflectance * coverage[pixels[:, 0], pixels[:, 1]]
    return FloorReflection(side=side, pixels=pixels, points=points * flip, normals=normals * flip, albedo=albedo,
                           occlusion=occlusion, weight=weight.astype(np.float32))


def repaint_surface(surface: VisibleSurface, geometry: ObjectGeometry) -> VisibleSurface:
    """`surface` with the colors of `geometry`, an object of the same shape and placement painted differently: a
    paint stroke keeps every voxel's occupancy, so what the camera sees stays and only its colors are looked up."""
    colors, albedo = _surface_colors(geometry, surface.color_voxels, surface.color_points, surface.color_spread)
    return replace(surface, albedo=albedo, images=replace(surface.images, **_color_images(surface.size, surface.pixels,
                                                                                           colors, albedo)))


def _surface_colors(geometry: ObjectGeometry, color_voxels: np.ndarray, points: np.ndarray,
                    spread: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The sRGB colors (clipped to [0, 1]) and linear albedos (N, 3) float32 of the visible points (`points`, crop
    coordinates): the colors of the voxels around crop indices `color_voxels` averaged over `spread` (world units, at
    least COLOR_LEAST voxel sides; kernels.filtered_colors; grey where -1)."""
    colors = np.empty(color_voxels.shape, dtype=np.float32)
    sides = np.linalg.norm(geometry.voxel_to_world[:3, :3], axis=0)  # a voxel's side along each crop axis
    kernels.filtered_colors(geometry.rgb, np.asarray(geometry.rgb_offset, dtype=np.int64), geometry.occupied,
                            color_voxels, np.ascontiguousarray(points, dtype=np.float64), sides,
                            np.asarray(spread, dtype=np.float64), COLOR_LEAST, colors)
    colors = np.clip(colors, 0.0, 1.0)
    return colors, srgb_to_linear(colors).astype(np.float32)


def _close_specks(cover: np.ndarray, size: int) -> np.ndarray:
    """`cover` in which each group of partly covered pixels (8-connected) that no empty pixel touches and that has
    at most SPECK_PIXELS * (size / 256)^2 pixels is covered fully (see SPECK_PIXELS)."""
    partial = (cover > 0.0) & (cover < 1.0)
    labels, count = ndimage.label(partial, structure=np.ones((3, 3), dtype=bool))
    if count == 0:
        return cover
    near_empty = _any_in_3x3(cover <= 0.0)  # the image's edge counts as empty
    open_group = np.zeros(count + 1, dtype=bool)
    open_group[labels[near_empty & partial]] = True
    area = np.bincount(labels.ravel(), minlength=count + 1)
    speck = ~open_group & (area <= SPECK_PIXELS * (size / 256) ** 2)
    speck[0] = False
    return np.where(speck[labels], np.float32(1.0), cover)


def _differs_from_a_neighbour(mask: np.ndarray) -> np.ndarray:
    """Where `mask` (2D bool) differs from one of its 4 neighbours, outside the array counting as False: the pixels
    on either side of its edge (slices, far quicker than scipy's erosion and dilation)."""
    padded = np.pad(mask, 1)
    return ((mask != padded[:-2, 1:-1]) | (mask != padded[2:, 1:-1]) | (mask != padded[1:-1, :-2])
            | (mask != padded[1:-1, 2:]))


def _any_in_3x3(mask: np.ndarray) -> np.ndarray:
    """Whether `mask` (2D bool) holds anywhere in each pixel's 3 x 3 neighbourhood, outside the array counting as
    True (scipy.ndimage.maximum_filter of size 3 with mode "constant", cval True; as two passes of slices)."""
    padded = np.pad(mask, 1, constant_values=True)
    rows = padded[:-2] | padded[1:-1] | padded[2:]
    return rows[:, :-2] | rows[:, 1:-1] | rows[:, 2:]


def _surface_images(size: int, pixels: np.ndarray, colors: np.ndarray, albedo: np.ndarray, normals: np.ndarray,
                    depth: np.ndarray, occlusion: np.ndarray, floor: np.ndarray, floor_occlusion: np.ndarray) -> SurfaceImages:
    """The visible points' values drawn into images (the floor's occlusion too); read-only, as they are shared."""
    r, c = pixels[:, 0], pixels[:, 1]
    images = {name: np.zeros((size, size) + shape, dtype=np.float32) for name, shape in (("normal", (3,)), ("depth", ()))}
    images["floor_occlusion"] = np.ones((size, size), dtype=np.float32)
    images["floor_occlusion"][floor] = floor_occlusion
    images["occlusion"] = images["floor_occlusion"].copy()
    for name, values in (("normal", normals), ("depth", depth), ("occlusion", occlusion)):
        images[name][r, c] = values
    for image in images.values():
        image.flags.writeable = False
    return SurfaceImages(**images, **_color_images(size, pixels, colors, albedo))


def _color_images(size: int, pixels: np.ndarray, colors: np.ndarray, albedo: np.ndarray) -> dict[str, np.ndarray]:
    """The albedo images (linear, and sRGB as a network reads it) of the visible points; read-only."""
    images = {}
    for name, values in (("albedo", albedo), ("albedo_srgb", colors)):
        image = np.zeros((size, size, 3), dtype=np.float32)
        image[pixels[:, 0], pixels[:, 1]] = values
        image.flags.writeable = False
        images[name] = image
    return images


def _pixel_window(geometry: ObjectGeometry, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of the image rectangle the crop box projects into (a pixel of margin)."""
    u, v, _ = camera.project(_crop_corners(geometry))
    c0, c1 = (int(np.clip(math.floor(u.min()) - 1, 0, camera.width - 1)), int(np.clip(math.ceil(u.max()) + 1, 0, camera.width - 1)))
    r0, r1 = (int(np.clip(math.floor(v.min()) - 1, 0, camera.height - 1)), int(np.clip(math.ceil(v.max()) + 1, 0, camera.height - 1)))
    return np.arange(r0, r1 + 1), np.arange(c0, c1 + 1)


def _crop_corners(geometry: ObjectGeometry) -> np.ndarray:
    """World positions (8, 3) of the corners of the crop box."""
    shape = geometry.occupied.shape
    corners = np.array([[a, b, c] for a in (0, shape[0]) for b in (0, shape[1]) for c in (0, shape[2])], dtype=np.float64)
    return (corners + geometry.offset) @ geometry.voxel_to_world[:3, :3].T + geometry.voxel_to_world[:3, 3]


def _trace_candidates(geometry: ObjectGeometry, camera: Camera, world_to_voxel: np.ndarray, origin: np.ndarray,
                      rows: np.ndarray, cols: np.ndarray, candidates: np.ndarray, nearest: np.ndarray,
                      farthest: np.ndarray, cover_behind: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`_trace` through the centres of the pixel window's `candidates` (_ray_candidates), each between its `nearest` and
    `farthest` depths; the other pixels (about two in three of a chair's window) miss (FAR, a zero point, no coverage)
    as `_trace` would find."""
    shape = (len(rows), len(cols))
    t, points, cover = np.full(shape, kernels.FAR, dtype=np.float64), np.zeros(shape + (3,)), np.zeros(shape, np.float32)
    r, c = np.nonzero(candidates)
    t[r, c], points[r, c], cover[r, c] = _trace(geometry, camera, world_to_voxel, origin, rows[r] + 0.5, cols[c] + 0.5,
                                                nearest[r, c], farthest[r, c], cover_behind)
    return t, points, cover


def _ray_candidates(geometry: ObjectGeometry, camera: Camera, rows: np.ndarray, cols: np.ndarray,
                    cells: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For the pixel window (rows, cols): which pixels' centre rays may stop on the surface (bool), and the camera
    depths nearer and farther than which no ray through the pixel can stop (kernels.mark_surface_pixels of `cells`,
    boxes of the cells where a ray may stop: ObjectGeometry.surface_cells or coarse_surface_cells)."""
    shape = (len(rows), len(cols))
    if min(geometry.occupied.shape) < 2:
        return np.ones(shape, dtype=bool), np.zeros(shape), np.full(shape, np.inf)
    threads = numba.get_num_threads()
    mask, nearest, farthest = (np.zeros(shape, dtype=bool), np.full((threads,) + shape, np.inf),
                               np.full((threads,) + shape, -np.inf))
    voxel_to_camera = camera.world_to_camera()[:3] @ geometry.voxel_to_world
    crop_to_camera = voxel_to_camera + np.column_stack([np.zeros((3, 3)), voxel_to_camera[:, :3] @ geometry.offset])
    image = camera.intrinsics() @ np.diag([1.0, -1.0, -1.0])  # camera point -> (u, v, 1) * depth
    kernels.mark_surface_pixels(cells, np.asarray(geometry.occupied.shape), image @ crop_to_camera,
                                int(rows[0]), int(cols[0]), mask, nearest, farthest)
    return mask, nearest.min(axis=0), farthest.max(axis=0)


def _trace(geometry: ObjectGeometry, camera: Camera, world_to_voxel: np.ndarray, origin: np.ndarray,
           v: np.ndarray, u: np.ndarray, nearest: np.ndarray | float = 0.0, farthest: np.ndarray | float = np.inf,
           cover_behind: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ray parameter, crop point and coverage of the first surface hit through pixel coordinates (u, v), each ray
    traced from about camera depth `nearest` to about `farthest` (_ray_candidates; 0 and inf: from where it enters the
    crop to where it leaves; `cover_behind`: see visible_surface)."""
    u, v, nearest, farthest = np.broadcast_arrays(u, v, nearest, farthest)
    count = u.size
    # The camera-space ray through (u, v) is ((u - cx) / f, -(v - cy) / f, -1): affine in (u, v, 1).
    (cx, cy), f = camera.principal_point, camera.focal_px
    camera_ray = np.array([[1.0 / f, 0.0, -cx / f], [0.0, -1.0 / f, cy / f], [0.0, 0.0, -1.0]])
    pixel_to_ray = world_to_voxel[:3, :3] @ camera.camera_to_world()[:3, :3] @ camera_ray
    t = np.empty(count)
    points = np.zeros((count, 3))
    deepest = np.empty(count)
    cores = np.zeros(count)
    behind = np.zeros(count, dtype=bool)
    kernels.trace_surface(geometry.distance_and_core, SURFACE_LEVEL, THIN_LEVEL, COVERAGE_PROBE, COVERAGE_FULL,
                          cover_behind, origin,
                          pixel_to_ray, _depth_axis(geometry, camera),
                          np.stack([u.ravel(), v.ravel()], axis=1).astype(np.float64),
                          np.ascontiguousarray(nearest, dtype=np.float64).ravel(),
                          np.ascontiguousarray(farthest, dtype=np.float64).ravel(), t, points, deepest, cores, behind)
    level = np.maximum(SURFACE_LEVEL, cores + THIN_LEVEL)  # the surface level where each ray stopped
    cover = np.clip((level - deepest) / ((level - cores) * COVERAGE_FULL), 0.0, 1.0).astype(np.float32)
    cover[behind] = 1.0  # it grazed a part in front of another: no floor shows through
    return t.reshape(u.shape), points.reshape(u.shape + (3,)), cover.reshape(u.shape)


def _depth_axis(geometry: ObjectGeometry, camera: Camera) -> np.ndarray:
    """(3,): the camera depth (world units along the view axis) gained per unit step along each crop axis."""
    return -(camera.world_to_camera()[2, :3] @ geometry.voxel_to_world[:3, :3])


def _surface_occlusion(geometry: ObjectGeometry, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Sky light reaching each surface point: 1 minus the broad occupancy found along its normal, less
    what an open flat surface itself puts there."""
    found = np.empty(len(points))
    kernels.occlusion_along(geometry.broad, BROAD_SCALE, points, normals, OCCLUSION_DISTANCES, OCCLUSION_WEIGHTS, found)
    flat = float(np.sum(OCCLUSION_WEIGHTS * _half_space_blur(OCCLUSION_DISTANCES + SURFACE_LEVEL, BROAD_SIGMA)))
    blocked = np.clip((found - flat) / max(1.0 - flat, 1e-6), 0.0, 1.0)
    return (1.0 - blocked * (1.0 - BLOCKED_SKY_LIGHT)).astype(np.float32)


def _solid(occupied: np.ndarray) -> np.ndarray:
    """The occupied voxels with their insides: voxelised surfaces are shells, and a slanted one-voxel shell
    is only diagonally connected, so the diagonal gaps a ray could slip through are closed first; then
    everything not connected to the crop's border (6-connected) is inside."""
    closed = _erode_cube(dilate_cube(occupied)) | occupied
    return ~filters.connected_to_border(closed)


def _erode_cube(mask: np.ndarray) -> np.ndarray:
    """Binary erosion by the 3x3x3 cube, outside the array counting as empty."""
    return ~dilate_cube(np.pad(~mask, 1, constant_values=True))[1:-1, 1:-1, 1:-1]


def _broad(solid: np.ndarray) -> np.ndarray:
    """The solid occupancy averaged over 2^3 blocks and blurred by BROAD_SIGMA voxels (at half resolution:
    occlusion is a broad effect), sampled at BROAD_SCALE times the crop's coordinates."""
    return filters.gaussian_blur(filters.block_mean2(solid), BROAD_SIGMA * BROAD_SCALE, BLUR_TRUNCATE)


def _half_space_blur(distance: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian-blurred occupancy of a filled half space, `distance` voxels outside its boundary."""
    return 0.5 * special.erfc(distance / (sigma * math.sqrt(2.0)))


@lru_cache(maxsize=8)
def _floor_points(camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The floor mask, the world points (F, 3) where the floor pixels' centre rays meet y = 0, and their least and
    greatest x and z ((2, 2): [[x, z] least, [x, z] greatest]; zeros if there are none) (cached, read-only: an
    object move keeps the camera)."""
    floor = cached_floor_mask(camera)
    rows, cols = np.nonzero(floor)
    origin, dirs = camera.pixel_rays(cols + 0.5, rows + 0.5)
    t = -origin[1] / dirs[:, 1]
    points = origin + t[:, None] * dirs
    extent = _box(points)[:, [0, 2]]
    for array in (floor, points, extent):
        array.flags.writeable = False
    return floor, points, extent


def _floor_occlusion(geometry: ObjectGeometry, floor_points: np.ndarray, world_to_voxel: np.ndarray) -> np.ndarray:
    """Sky light reaching each floor point: 1 minus the broad occupancy straight above it."""
    occlusion = np.ones(len(floor_points), dtype=np.float32)
    if geometry.empty or not len(floor_points):
        return occlusion
    # Only floor points under the crop box (its world bounds in x and z) can be occluded.
    world = _crop_corners(geometry)
    (x0, _, z0), (x1, _, z1) = world.min(axis=0), world.max(axis=0)
    near = np.empty(len(floor_points), dtype=bool)
    kernels.mark_within_xz(floor_points, x0, z0, x1, z1, near)
    if not near.any():
        return occlusion
    crop = floor_points[near] @ world_to_voxel[:3, :3].T + world_to_voxel[:3, 3] - geometry.offset
    up = world_to_voxel[:3, :3] @ np.array([0.0, 1.0, 0.0])
    up /= np.linalg.norm(up)
    found = np.empty(int(near.sum()))
    kernels.occlusion_along(geometry.broad, BROAD_SCALE, np.ascontiguousarray(crop),
                            np.broadcast_to(up, (int(near.sum()), 3)).copy(),
                            FLOOR_OCCLUSION_DISTANCES, FLOOR_OCCLUSION_WEIGHTS, found)
    blocked = np.clip(found, 0.0, 1.0)
    occlusion[near] = 1.0 - blocked * (1.0 - BLOCKED_SKY_LIGHT)
    return occlusion


def _view_axis(camera: Camera) -> np.ndarray:
    return -camera.camera_to_world()[:3, 2]


# --- stage 3 ----------------------------------------------------------------------------------


def light_points(light_position, per_side: int = LIGHT_POINTS) -> np.ndarray:
    """(per_side^2, 3) world points at the centres of a regular grid over the square light."""
    offsets = ((np.arange(per_side) + 0.5) / per_side - 0.5) * LIGHT_SIZE
    x, z = np.meshgrid(offsets, offsets, indexing="ij")
    light = np.asarray(light_position, dtype=np.float64)
    return np.stack([light[0] + x.ravel(), np.full(x.size, light[1]), light[2] + z.ravel()], axis=1)


def shade(geometry: ObjectGeometry, surface: VisibleSurface, light_position, floor_color,
          floor_terms: FloorTerms | None = None,
          reflection: FloorReflection | None = None, quality: ShaderQuality = FULL_QUALITY) -> ShadedImage:
    """The shaded image of the visible surface under the light at `light_position` (world). `floor_terms`: the
    empty floor's lighting, lit_floor_terms(camera, light_position, floor_color), if the caller keeps it (it does
    not change when the object does). `reflection`: the floor's mirror image of the object (floor_reflection) to draw,
    if any (a network's input has none: it learned its own). `quality`: its light points per side."""
    if floor_terms is None:
        floor_terms = lit_floor_terms(Camera(geometry.elevation_deg, width=surface.size, height=surface.size),
                                      light_position, floor_color)
    floor = floor_terms.floor
    lights = light_points(light_position, quality.light_points)
    voxel = float(abs(np.linalg.det(geometry.voxel_to_world[:3, :3])) ** (1.0 / 3.0))  # a voxel's mean side in the world
    maps = np.empty((len(lights), SHADOW_MAP_SIZE, SHADOW_MAP_SIZE), dtype=np.float32)
    bounds = np.zeros((len(lights), 3))
    block = geometry.occluder_block * voxel  # the side of an occluder's block in the world
    kernels.build_shadow_maps(geometry.occluders, OCCLUDER_RADIUS * block, block / math.sqrt(2.0), lights,
                              SHADOW_MAP_SIZE, maps, bounds)
    nearest = maps.reshape(len(lights), -1).min(axis=1).astype(np.float64)  # each map's occluder nearest the light

    size = surface.size
    visibility = np.ones((size, size), dtype=np.float32)
    visibility[floor] = (1.0 if geometry.empty else
                         _floor_visibility(surface, geometry, lights, maps, bounds, nearest,
                                           FLOOR_SHADOW_BIAS * block, LIGHT_SIZE / quality.light_points))
    image = np.empty((size, size, 3), dtype=np.float32)
    radiance, seen = np.zeros((0, 3), dtype=np.float32), np.zeros(0, dtype=np.float32)
    if len(surface.points):
        radiance, seen = _object_radiance(surface.points, surface.normals, surface.albedo, surface.occlusion,
                                          light_position, lights, maps, bounds, nearest, block, floor_color)
    r, c = surface.pixels[:, 0], surface.pixels[:, 1]
    kernels.composite(floor_terms.from_light, floor_terms.from_ambient, *floor_terms.row_weights,
                      *floor_terms.col_weights, floor, visibility, surface.images.floor_occlusion,
                      np.full(3, AMBIENT_RADIANCE, dtype=np.float32), r, c, radiance, surface.coverage[r, c], image)
    if reflection is not None and len(reflection.points):
        _add_reflection(image, surface, reflection, light_position, lights, maps, bounds, nearest, block, floor_color)
    visibility[r, c] = seen  # the floor's visibility lit the floor behind partly covered pixels; now the object's
    images = surface.images
    return ShadedImage(image=linear_to_srgb(image), coverage=surface.coverage,  # in [0, 1], NaN as 0: no clip needed
                       albedo=images.albedo, albedo_srgb=images.albedo_srgb, normal=images.normal, depth=images.depth,
                       visibility=visibility, occlusion=images.occlusion)


def _floor_visibility(surface: VisibleSurface, geometry: ObjectGeometry, lights: np.ndarray, maps: np.ndarray,
                      bounds: np.ndarray, nearest: np.ndarray, bias: float, spacing: float) -> np.ndarray:
    """Share of the light each of the surface's floor points sees, each light point reading as its square of the
    light (`spacing` on a side). The shadow maps are read on a grid of
    FLOOR_SHADOW_STEP over the box the object's shadow can reach (its occupied voxels' box cast from the light's corner
    points onto y = 0), and the floor points inside it interpolate that grid; the rest see all the light."""
    floor_points = surface.floor_points
    seen = np.ones(len(floor_points))
    if not len(floor_points):
        return seen
    lo, hi = geometry.occluder_box
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    if corners[:, 1].max() >= lights[:, 1].min() - 1e-6:  # part of the object reaches the light's height
        kernels.light_visibility(floor_points, bias, lights, maps, bounds, nearest, spacing, seen)
        return seen
    ends = lights[[0, -1]][:, None, :]  # opposite corners of the grid of light points
    cast = ends + (corners[None] - ends) * (ends[..., 1:2] / (ends[..., 1:2] - corners[None, :, 1:2]))
    cast = np.concatenate([cast.reshape(-1, 3), corners * np.array([1.0, 0.0, 1.0])])
    (x0, z0), (x1, z1) = cast[:, [0, 2]].min(axis=0) - FLOOR_SHADOW_STEP, cast[:, [0, 2]].max(axis=0) + FLOOR_SHADOW_STEP
    (x_min, z_min), (x_max, z_max) = surface.floor_extent
    # No wider than the floor the camera sees (on the same grid of samples): an object whose top comes near the
    # light's height casts a box that grows without bound, and nothing clips a large object to a grid.
    x0 += max(math.floor((float(x_min) - x0) / FLOOR_SHADOW_STEP), 0) * FLOOR_SHADOW_STEP
    z0 += max(math.floor((float(z_min) - z0) / FLOOR_SHADOW_STEP), 0) * FLOOR_SHADOW_STEP
    x1, z1 = min(x1, float(x_max) + FLOOR_SHADOW_STEP), min(z1, float(z_max) + FLOOR_SHADOW_STEP)
    if x0 > x1 or z0 > z1:
        return seen
    xs = np.arange(x0, x1 + FLOOR_SHADOW_STEP, FLOOR_SHADOW_STEP)
    zs = np.arange(z0, z1 + FLOOR_SHADOW_STEP, FLOOR_SHADOW_STEP)
    gx, gz = np.meshgrid(xs, zs, indexing="ij")
    samples = np.stack([gx.ravel(), np.zeros(gx.size), gz.ravel()], axis=1)
    on_grid = np.empty(len(samples))
    kernels.light_visibility(samples, bias, lights, maps, bounds, nearest, spacing, on_grid)
    kernels.interpolate_grid(on_grid.reshape(gx.shape), x0, z0, FLOOR_SHADOW_STEP, floor_points, x1, z1, seen)
    return seen


def _object_radiance(points: np.ndarray, normals: np.ndarray, albedo: np.ndarray, occlusion: np.ndarray, light_position,
                     lights: np.ndarray, maps: np.ndarray, bounds: np.ndarray, nearest: np.ndarray, block: float,
                     floor_color) -> tuple[np.ndarray, np.ndarray]:
    """Linear radiance (N, 3) of object points (world points and unit normals, linear albedo, the sky light reaching
    each) and the share of the light each sees (`block`: the side of an occluder's block in the world)."""
    form = np.empty(len(points))
    form_below = np.empty(len(points))
    kernels.light_form_factors(points, normals, lights, LIGHT_SIZE**2 / len(lights), form, form_below)
    # Shadows matter only where the light reaches the surface at all (points facing away see none of it).
    seen = np.zeros(len(points))
    facing = np.flatnonzero(form > 0.0)
    seen_facing = np.empty(len(facing))
    # Each point is read off the shadow maps a little way out along its normal, further where the light grazes it
    # (there the depth the maps hold changes fastest across a texel).
    receivers = np.empty((len(facing), 3))
    kernels.shadow_receivers(points, normals, facing, np.asarray(light_position, dtype=np.float64),
                             block * SHADOW_NORMAL_OFFSET, block * SHADOW_GRAZING_OFFSET, receivers)
    kernels.light_visibility(receivers, SHADOW_BIAS * block, lights, maps, bounds, nearest, 0.0, seen_facing)
    seen[facing] = seen_facing
    direct = LIGHT_RADIANCE * seen * form
    # Ambient from the sky above the horizon, and light the floor below sends back up (the floor there
    # lies partly in the object's shadow: FLOOR_BELOW_LIT of its direct light).
    sky = AMBIENT_RADIANCE * math.pi * 0.5 * (1.0 + normals[:, 1]) * occlusion
    floor_irradiance = LIGHT_RADIANCE * form_below * FLOOR_BELOW_LIT + AMBIENT_RADIANCE * math.pi
    floor_albedo = srgb_to_linear(np.asarray(floor_color, dtype=np.float64))
    bounce = FLOOR_BOUNCE * floor_irradiance[:, None] * floor_albedo[None, :] * 0.5 * (1.0 - normals[:, 1:2])
    irradiance = (direct + sky)[:, None] + bounce
    return (albedo * irradiance / math.pi).astype(np.float32), seen.astype(np.float32)


def _add_reflection(image: np.ndarray, surface: VisibleSurface, reflection: FloorReflection, light_position,
                    lights: np.ndarray, maps: np.ndarray, bounds: np.ndarray, nearest: np.ndarray, block: float,
                    floor_color) -> None:
    """Adds to the linear `image` the floor's reflection of the object, where the object leaves the floor uncovered:
    the coat mirrors the lit object where it mirrored the sky (an object darker than the sky darkens the floor). The
    reflection's pixels are blurred (the coat's roughness) and upsampled bilinearly over the box they reach."""
    radiance, _ = _object_radiance(reflection.points, reflection.normals, reflection.albedo, reflection.occlusion,
                                   light_position, lights, maps, bounds, nearest, block, floor_color)
    margin = math.ceil(REFLECTION_BLUR * BLUR_TRUNCATE) + 1
    (r0, c0), (r1, c1) = reflection.pixels.min(axis=0) - margin, reflection.pixels.max(axis=0) + 1 + margin
    change = np.zeros((r1 - r0, c1 - c0, 3), dtype=np.float32)
    change[reflection.pixels[:, 0] - r0, reflection.pixels[:, 1] - c0] = (
        reflection.weight[:, None] * (radiance - AMBIENT_RADIANCE))
    change = ndimage.gaussian_filter(change, (REFLECTION_BLUR, REFLECTION_BLUR, 0), mode="constant",
                                     truncate=BLUR_TRUNCATE)
    # Interpolated where it is added, over the image rows and columns the box reaches (its pixels' centres at
    # (i + 0.5) * step), clamped at the box's edges.
    step = surface.size / reflection.side
    top, left = round(r0 * step), round(c0 * step)
    bottom, right = round(r1 * step), round(c1 * step)
    rows = linear_weights((np.arange(r1 - r0) + 0.5) * ((bottom - top) / (r1 - r0)), bottom - top)
    cols = linear_weights((np.arange(c1 - c0) + 0.5) * ((right - left) / (c1 - c0)), right - left)
    first_row, first_col = max(top, 0), max(left, 0)
    rows = [w[first_row - top:min(bottom, surface.size) - top] for w in rows]
    cols = [w[first_col - left:min(right, surface.size) - left] for w in cols]
    kernels.add_upsampled(image, change, *rows, *cols, first_row, first_col, surface.floor, surface.coverage)


# --- what a network reads ---------------------------------------------------------------------

BUFFER_CHANNELS = ("image r", "image g", "image b", "albedo r", "albedo g", "albedo b", "normal x", "normal y",
                   "normal z", "depth", "visibility", "occlusion", "coverage")


def network_buffers(shaded: ShadedImage) -> np.ndarray:
    """(H, W, len(BUFFER_CHANNELS)) float32, each channel in about [-1, 1]: the shaded image (sRGB), the object's
    albedo (sRGB), its world normal, its depth (0 at the look-at distance, +-1 at the grid's faces), the
    share of the light and of the sky each point sees, and the object's coverage; 0 where there is no object."""
    out = np.empty(shaded.coverage.shape + (len(BUFFER_CHANNELS),), dtype=np.float32)
    kernels.pack_buffers(shaded.image, shaded.albedo_srgb, shaded.normal, shaded.depth, shaded.visibility,
                         shaded.occlusion, shaded.coverage, CAMERA_DISTANCE, 1.0 / (0.5 * GRID_EXTENT), out)
    return out


# --- all stages -------------------------------------------------------------------------------


def shade_scene(scene: Scene, object_rgba: np.ndarray, floor_color, size: int | None = None,
                grid_size: int = SHADER_GRID_SIZE, cover_behind: bool = True, reflection: bool = True,
                quality: ShaderQuality = FULL_QUALITY) -> ShadedImage:
    """All three stages at once: the shaded image of a scene whose (painted) object voxels are `object_rgba`, at `size`
    (default the scene's), from the object voxels merged as for a `grid_size`^3 grid (renderer.grid.shader_pool_factors;
    `cover_behind`: see visible_surface; `reflection`: False leaves out the floor's reflection of the object, as for a
    network's input; `quality`: ShaderQuality)."""
    resolution = object_rgba.shape[0]
    factors = shader_pool_factors(resolution, scene.object.scale, grid_size)
    merged = pool_voxels(object_rgba, factors)
    geometry = placed(object_geometry(merged, resolution, factors, quality.ambient_occlusion), scene.object,
                      scene.camera.elevation_deg)
    size = scene.image_size if size is None else size
    surface = visible_surface(geometry, size, cover_behind, quality=quality)
    mirrored = floor_reflection(geometry, surface) if reflection else None
    return shade(geometry, surface, scene.light.position, floor_color, reflection=mirrored, quality=quality)
