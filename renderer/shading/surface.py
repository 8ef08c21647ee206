"""Stage 2 of the voxel shader: what the camera sees, for an image size.

Per pixel, the first surface point a camera ray meets (sphere tracing the distance), anti-aliased at silhouettes by
2 x 2 rays (ShaderQuality), its normal (averaged over the surface around it where the surface is flat), albedo (the
voxels' colors averaged over the pixel's footprint) and ambient occlusion; the floor points, and how much of their sky
the object blocks; these as images too (SurfaceImages), shared by every light's shaded image. floor_reflection: the
same, coarser, of the object mirrored in the floor, where the floor shows (for the shader's own image).
Its compiled loops (numba) follow the Python that calls them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache

import numba
import numpy as np
from numba import njit, prange
from scipy import ndimage, special

from renderer.camera import Camera
from renderer.color import srgb_to_linear
from renderer.floor_light import coarse_floor_grid, coat_reflectance
from renderer.resample import downscaled_mask, upsampled
from renderer.shading.fields import FAR, HIT_GAP, blend_fields, cell_corners, sample, sample_pair, surface_gap
from renderer.shading.geometry import ObjectGeometry, points_box
from renderer.shading.quality import (
    BLOCKED_SKY_LIGHT,
    BROAD_SCALE,
    BROAD_SIGMA,
    COLOR_LEAST,
    COVERAGE_FULL,
    COVERAGE_PROBE,
    FAR_BLOCKS,
    FAR_CONE_HALF_ANGLE,
    FAR_FULL_SKY,
    FAR_RING_CONES,
    FAR_RING_TILT,
    FAR_SHARE_COSINE,
    FAR_SHARE_DISTANCE,
    FAR_SHARE_PIXELS,
    FAR_START,
    FLOOR_OCCLUSION_DISTANCES,
    FLOOR_OCCLUSION_WEIGHTS,
    FLOOR_SKY_PIXELS,
    FLOOR_SKY_START,
    FULL_QUALITY,
    NORMAL_AGREE,
    NORMAL_DISC,
    OCCLUSION_DISTANCES,
    OCCLUSION_WEIGHTS,
    REFLECTION_SCALE,
    REFLECTION_SUBSAMPLING,
    SPECK_PIXELS,
    SUBPIXELS,
    SURFACE_LEVEL,
    THIN_LEVEL,
    ShaderQuality,
)
from renderer.splat import cached_floor_mask


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
                                                          quality.ambient_occlusion, (pixels, size))
    points_world, normals_world, depth = _in_world(geometry, camera, points_crop, normals_crop)
    color_spread = quality.color_spread * np.maximum(depth, 0.0) / camera.focal_px  # pixel sides at its depth

    floor, floor_points, floor_extent = camera_floor_points(camera)
    floor_occlusion = (_floor_occlusion(geometry, floor_points, np.linalg.inv(geometry.voxel_to_world))
                       if quality.ambient_occlusion else np.ones(len(floor_points), dtype=np.float32))
    lookup = color_voxels if colors else np.full_like(color_voxels, -1)  # -1: no voxel, grey
    srgb, albedo = _surface_colors(geometry, lookup, points_crop, color_spread)
    images = surface_images(size, pixels, srgb, albedo, normals_world, depth, occlusion, floor, floor_occlusion)
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
    hit = centre_t < FAR
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
            sub_hit = sub_t < FAR
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


def _point_normals(geometry: ObjectGeometry, points_crop: np.ndarray, rings: int, occluded: bool = True,
                   pixels: tuple[np.ndarray, int] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each crop point's normal (in crop coordinates, averaged over `rings` rings of the tangent plane's disc), the
    crop index of the voxel its color is centred on (-1: none), and the sky light reaching it (all of it unless
    `occluded`; `pixels`: the points' pixels and the image's side, see _surface_occlusion)."""
    normals = np.zeros((len(points_crop), 3))
    color_voxels = np.full((len(points_crop), 3), -1, dtype=np.int64)
    if not len(points_crop):
        return normals, color_voxels, np.ones(0, dtype=np.float32)
    surface_normals_and_voxels(geometry.gradient, geometry.coarse_gradient, geometry.occupied, points_crop,
                                       normals, color_voxels, NORMAL_DISC, rings, NORMAL_AGREE)
    sky = (_surface_occlusion(geometry, points_crop, normals, pixels) if occluded
           else np.ones(len(points_crop), np.float32))
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
                                                          occluded=geometry.broad is not None, pixels=(pixels, side))
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
    least COLOR_LEAST voxel sides; filtered_colors; grey where -1)."""
    colors = np.empty(color_voxels.shape, dtype=np.float32)
    sides = np.linalg.norm(geometry.voxel_to_world[:3, :3], axis=0)  # a voxel's side along each crop axis
    filtered_colors(geometry.rgb, np.asarray(geometry.rgb_offset, dtype=np.int64), geometry.occupied,
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


def surface_images(size: int, pixels: np.ndarray, colors: np.ndarray, albedo: np.ndarray, normals: np.ndarray,
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
    t, points, cover = np.full(shape, FAR, dtype=np.float64), np.zeros(shape + (3,)), np.zeros(shape, np.float32)
    r, c = np.nonzero(candidates)
    t[r, c], points[r, c], cover[r, c] = _trace(geometry, camera, world_to_voxel, origin, rows[r] + 0.5, cols[c] + 0.5,
                                                nearest[r, c], farthest[r, c], cover_behind)
    return t, points, cover


def _ray_candidates(geometry: ObjectGeometry, camera: Camera, rows: np.ndarray, cols: np.ndarray,
                    cells: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For the pixel window (rows, cols): which pixels' centre rays may stop on the surface (bool), and the camera
    depths nearer and farther than which no ray through the pixel can stop (mark_surface_pixels of `cells`,
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
    mark_surface_pixels(cells, np.asarray(geometry.occupied.shape), image @ crop_to_camera,
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
    trace_surface(geometry.distance_and_core, SURFACE_LEVEL, THIN_LEVEL, COVERAGE_PROBE, COVERAGE_FULL,
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


def _surface_occlusion(geometry: ObjectGeometry, points: np.ndarray, normals: np.ndarray,
                       pixels: tuple[np.ndarray, int] | None = None) -> np.ndarray:
    """Sky light reaching each surface point: 1 minus the broad occupancy found along its normal, less
    what an open flat surface itself puts there, times the far sky a hollow hides (far_sky_seen). `pixels`: the
    points' pixels (N, 2) and the image's side, if they are an image's: the far sky, which changes slowly over a
    surface, is then traced at one point of each block of pixels (FAR_SHARE_PIXELS on a side at 256^2, as many
    voxels across at any size) and taken by the others of the block that lie on the same surface
    (FAR_SHARE_DISTANCE, FAR_SHARE_COSINE)."""
    found = np.empty(len(points))
    occlusion_along(geometry.broad, BROAD_SCALE, points, normals, OCCLUSION_DISTANCES, OCCLUSION_WEIGHTS, found)
    flat = float(np.sum(OCCLUSION_WEIGHTS * _half_space_blur(OCCLUSION_DISTANCES + SURFACE_LEVEL, BROAD_SIGMA)))
    blocked = np.clip((found - flat) / max(1.0 - flat, 1e-6), 0.0, 1.0)
    far = np.ones(len(points))
    if geometry.far_occupancy:
        source = np.full(len(points), -1, dtype=np.int64)
        block = round(FAR_SHARE_PIXELS * pixels[1] / 256) if pixels is not None else 1  # the same voxels at any size
        if block > 1:
            block_sources(pixels[0], points, normals, pixels[1], block, FAR_SHARE_DISTANCE, FAR_SHARE_COSINE, source)
        traced = np.flatnonzero(source < 0)
        seen = np.empty(len(traced))
        far_sky_seen(geometry.far_occupancy, _FAR_BLOCKS, _FAR_CONES, _FAR_TANGENT, FAR_START,
                     np.array(geometry.distance_and_core.shape[:3], dtype=np.float64), FAR_FULL_SKY, points[traced],
                     normals[traced], seen)
        far[traced] = seen
        shared = np.flatnonzero(source >= 0)
        far[shared] = far[source[shared]]
    far = np.minimum(far / FAR_FULL_SKY, 1.0)
    blocked = 1.0 - (1.0 - blocked) * far  # the sky seen is what both leave
    return (1.0 - blocked * (1.0 - BLOCKED_SKY_LIGHT)).astype(np.float32)


def _cone_directions() -> np.ndarray:
    """(1 + FAR_RING_CONES, 4): the far occlusion's cone axes in a normal's frame (tangent, bitangent, normal) and
    their weights (the cosine to the normal, summing to 1)."""
    tilt = math.radians(FAR_RING_TILT)
    angles = 2.0 * math.pi * np.arange(FAR_RING_CONES) / FAR_RING_CONES
    ring = np.column_stack([math.sin(tilt) * np.cos(angles), math.sin(tilt) * np.sin(angles),
                            np.full(FAR_RING_CONES, math.cos(tilt)), np.full(FAR_RING_CONES, math.cos(tilt))])
    cones = np.vstack([[0.0, 0.0, 1.0, 1.0], ring])
    cones[:, 3] /= cones[:, 3].sum()
    return cones


_FAR_CONES = _cone_directions()
_FAR_BLOCKS = np.array(FAR_BLOCKS, dtype=np.float64)
_FAR_TANGENT = math.tan(math.radians(FAR_CONE_HALF_ANGLE))


def _half_space_blur(distance: np.ndarray, sigma: float) -> np.ndarray:
    """Gaussian-blurred occupancy of a filled half space, `distance` voxels outside its boundary."""
    return 0.5 * special.erfc(distance / (sigma * math.sqrt(2.0)))


@lru_cache(maxsize=8)
def camera_floor_points(camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The floor mask, the world points (F, 3) where the floor pixels' centre rays meet y = 0, and their least and
    greatest x and z ((2, 2): [[x, z] least, [x, z] greatest]; zeros if there are none) (cached, read-only: an
    object move keeps the camera)."""
    floor = cached_floor_mask(camera)
    rows, cols = np.nonzero(floor)
    origin, dirs = camera.pixel_rays(cols + 0.5, rows + 0.5)
    t = -origin[1] / dirs[:, 1]
    points = origin + t[:, None] * dirs
    extent = points_box(points)[:, [0, 2]]
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
    mark_within_xz(floor_points, x0, z0, x1, z1, near)
    if not near.any():
        return occlusion
    crop = floor_points[near] @ world_to_voxel[:3, :3].T + world_to_voxel[:3, 3] - geometry.offset
    up = world_to_voxel[:3, :3] @ np.array([0.0, 1.0, 0.0])
    up /= np.linalg.norm(up)
    found = np.empty(int(near.sum()))
    occlusion_along(geometry.broad, BROAD_SCALE, np.ascontiguousarray(crop),
                            np.broadcast_to(up, (int(near.sum()), 3)).copy(),
                            FLOOR_OCCLUSION_DISTANCES, FLOOR_OCCLUSION_WEIGHTS, found)
    blocked = np.clip(found, 0.0, 1.0)
    occlusion[near] = 1.0 - blocked * (1.0 - BLOCKED_SKY_LIGHT)
    return occlusion


def floor_sky_axes() -> np.ndarray:
    """(K, 3) world unit axes of the cones floor_sky_cones traces: the far occlusion's cones about the floor's normal."""
    cones = _cone_directions()
    axes = cones[:, [0, 2, 1]]  # tangent x, bitangent z, normal y
    return axes / np.linalg.norm(axes, axis=1, keepdims=True)


def floor_sky_cones(geometry: ObjectGeometry, surface: VisibleSurface) -> np.ndarray | None:
    """(F, K): per floor point of `surface`, the share of each cone about floor_sky_axes() that the object leaves
    open, so that a sky whose light comes from one side puts the object's shadow on the other (a table's top shades
    the ground under it from the zenith). Traced at floor points FLOOR_SKY_PIXELS apart (at 256^2) and interpolated
    bilinearly; None where the geometry has no far occupancy (fast quality)."""
    if not geometry.far_occupancy:
        return None
    axes = floor_sky_axes()
    if geometry.empty or not surface.floor.any():
        return np.ones((len(surface.floor_points), len(axes)), dtype=np.float32)
    points, row_weights, col_weights = _floor_sky_grid(geometry.elevation_deg, surface.size)
    world_to_voxel = np.linalg.inv(geometry.voxel_to_world)
    crop = points.reshape(-1, 3) @ world_to_voxel[:3, :3].T + world_to_voxel[:3, 3] - geometry.offset
    crop_axes = axes @ world_to_voxel[:3, :3].T
    crop_axes /= np.linalg.norm(crop_axes, axis=1, keepdims=True)
    coarse = np.empty((len(crop), len(axes)))
    cones_through(geometry.far_occupancy, _FAR_BLOCKS, np.ascontiguousarray(crop_axes), _FAR_TANGENT,
                  FLOOR_SKY_START, np.array(geometry.distance_and_core.shape[:3], dtype=np.float64),
                  np.ascontiguousarray(crop), coarse)
    return upsampled(coarse.reshape(*points.shape[:2], len(axes)), row_weights, col_weights)[surface.floor]


@lru_cache(maxsize=8)
def _floor_sky_grid(elevation_deg: float, size: int) -> tuple[np.ndarray, tuple, tuple]:
    """floor_sky_cones' floor points (floor_light.coarse_floor_grid, FLOOR_SKY_PIXELS apart at 256^2; past the
    horizon far points, whose cones see no object) and their weights, per camera (read-only)."""
    camera = Camera(elevation_deg, width=size, height=size)
    points, row_weights, col_weights = coarse_floor_grid(camera, max(1, round(FLOOR_SKY_PIXELS * size / 256)))
    points.flags.writeable = False
    return points, row_weights, col_weights


def _view_axis(camera: Camera) -> np.ndarray:
    return -camera.camera_to_world()[:3, 2]


# --- compiled loops (numba, cached on disk) ---------------------------------------------------------

STEP_MIN = 0.3  # voxels: the least step a sphere-traced ray takes (near a surface its gap is tiny)
EXIT_GAP = 0.5  # voxels outside the surface a ray must get past a grazed part before a part behind it counts


@njit(cache=True, parallel=True)
def mark_within_xz(points, x0, z0, x1, z1, out):
    """out[i] = whether point i's x and z lie in [x0, x1] x [z0, z1], in one pass instead of numpy's four comparisons."""
    for i in prange(points.shape[0]):
        x, z = points[i, 0], points[i, 2]
        out[i] = (x >= x0) & (x <= x1) & (z >= z0) & (z <= z1)


@njit(cache=True, inline="always")
def _box_interval(ox, oy, oz, dx, dy, dz, n0, n1, n2):
    """Ray parameters [t0, t1] inside the box [0, n0] x [0, n1] x [0, n2] (t0 > t1: the ray misses it)."""
    t0, t1 = 0.0, 1.0e30
    for o, d, n in ((ox, dx, n0), (oy, dy, n1), (oz, dz, n2)):
        if abs(d) < 1e-12:
            if o < 0.0 or o > n:
                return 1.0, 0.0
        else:
            a, b = (0.0 - o) / d, (n - o) / d
            if a > b:
                a, b = b, a
            t0, t1 = max(t0, a), min(t1, b)
    return t0, t1


# A thread traces RAY_GROUP rays in step, one sample of each in turn. A ray's next sample waits on its last (where to
# step depends on the gap found), so one ray at a time leaves the core idle while memory answers; the samples of
# several rays overlap. On the bench chairs' rays the trace took 0.8 of the time of one ray at a time (the march
# alone 0.6; two or eight in step did less well).
RAY_GROUP = 4
_MARCH, _BISECT, _BEHIND, _DONE = 0, 1, 2, 3  # what a ray's next sample is for
BISECTIONS = 6  # halvings of the last step that passed the surface
FULL_MARGIN = 1e-6  # voxels: how far past full coverage a ray's probe must reach to stop early (rounding)


@njit(cache=True, parallel=True, fastmath=True, error_model="numpy")
def trace_surface(fields, level, thin, probe, full, look_behind, origin, pixel_to_ray, depth_axis, pixels, nearest,
                  farthest, hits, points, deepest, cores, behind):
    """Sphere-trace the rays through `pixels` (N, 2: u, v) from `origin` to where `distance` (voxels to the
    nearest occupied voxel, fields[..., 0]) falls to the surface level: `level`, or `thin` above the part's core where that
    is more (a part thinner than a voxel or two never reaches `level`, and would break up). A pixel's ray
    direction is pixel_to_ray @ (u, v, 1), made unit. A ray starts a voxel before camera depth nearest[i] (or where it
    enters the crop, if later; the depth of a crop point p is depth_axis . p, the origin's 0): nearer, it cannot stop
    (mark_surface_pixels), so it skips the empty space there without sampling it (the demo chair's rays took 43
    steps each from the crop's face, 36 of them more than 6 voxels before their hit). It ends a voxel past camera
    depth farthest[i] (or where it leaves the crop, if sooner): further, it cannot stop either, so a ray that misses
    stops marching there. A ray takes at most 256 steps; one that steps past the surface bisects its last step
    BISECTIONS times.
    hits[i] = ray parameter (FAR if none),
    points[i] = the crop point, deepest[i] = the least distance within `probe` voxels past the hit (how far inside
    the ray goes, sought until it covers its pixel fully: a ray that only grazes a part stays near the level),
    cores[i] = `core` at the hit (the least distance of the part around it, fields[..., 1]: 0 inside a thick part,
    more in a thin one).
    behind[i] (if `look_behind`, else False) = whether a ray that only grazes the part it hit (its coverage,
    (surface level - deepest) / ((surface level - core) * `full`), under 1) leaves it by EXIT_GAP and goes on to
    reach a surface behind it (within HIT_GAP, or stepping inside) in 256 steps, or goes on as deep as a covering
    ray without leaving it (a concave wall or a crease seen at a slant): that ray is covered by the object, not by
    the floor (else a bright floor fringe outlines a part in front of another, and seams of floor show in creases
    and inside hollows). The rays are traced RAY_GROUP at a time in step."""
    n0, n1, n2 = fields.shape[0], fields.shape[1], fields.shape[2]
    count = pixels.shape[0]
    # Each ray's state between its samples: direction, where it is (t), its last point outside the surface
    # (previous) and, while bisecting, inside it, where it ends, samples taken in its current phase, and the phase.
    direction = np.empty((count, 3))
    t, previous, inside, t_end = np.empty(count), np.empty(count), np.empty(count), np.empty(count)
    steps, phase, left = np.zeros(count, np.int64), np.empty(count, np.int64), np.zeros(count, np.bool_)
    for group in prange((count + RAY_GROUP - 1) // RAY_GROUP):
        first, stop = group * RAY_GROUP, min(group * RAY_GROUP + RAY_GROUP, count)
        for i in range(first, stop):
            u, v = pixels[i, 0], pixels[i, 1]
            dx = pixel_to_ray[0, 0] * u + pixel_to_ray[0, 1] * v + pixel_to_ray[0, 2]
            dy = pixel_to_ray[1, 0] * u + pixel_to_ray[1, 1] * v + pixel_to_ray[1, 2]
            dz = pixel_to_ray[2, 0] * u + pixel_to_ray[2, 1] * v + pixel_to_ray[2, 2]
            norm = math.sqrt(dx * dx + dy * dy + dz * dz)
            direction[i, 0], direction[i, 1], direction[i, 2] = dx / norm, dy / norm, dz / norm
            hits[i] = FAR
            deepest[i] = FAR
            behind[i] = False
            start, end = _box_interval(origin[0], origin[1], origin[2], direction[i, 0], direction[i, 1],
                                       direction[i, 2], n0, n1, n2)
            rate = depth_axis[0] * direction[i, 0] + depth_axis[1] * direction[i, 1] + depth_axis[2] * direction[i, 2]
            if rate > 1e-12:  # depth per unit of t
                start = max(start, nearest[i] / rate - 1.0)
                end = min(end, farthest[i] / rate + 1.0)
            t[i], previous[i], t_end[i], phase[i] = start, start, end, _MARCH
        running = True
        while running:
            running = False
            for i in range(first, stop):
                state = phase[i]
                if state == _DONE:
                    continue
                running = True
                dx, dy, dz = direction[i, 0], direction[i, 1], direction[i, 2]
                at = t[i]
                hit = False
                if state == _MARCH:
                    if steps[i] == 256 or at > t_end[i]:
                        phase[i] = _DONE  # a miss
                        continue
                    steps[i] += 1
                    gap = surface_gap(fields, level, thin, origin[0] + at * dx, origin[1] + at * dy, origin[2] + at * dz)
                    if gap < 0.0 and at > previous[i]:  # stepped past the surface: bisect the step
                        inside[i], steps[i], phase[i] = at, 0, _BISECT
                        continue
                    if gap < HIT_GAP:
                        hit = True
                    else:
                        previous[i] = at
                        t[i] = at + max(gap, STEP_MIN)
                elif state == _BISECT:
                    middle = 0.5 * (previous[i] + inside[i])
                    if surface_gap(fields, level, thin, origin[0] + middle * dx, origin[1] + middle * dy,
                            origin[2] + middle * dz) < 0.0:
                        inside[i] = middle
                    else:
                        previous[i] = middle
                    steps[i] += 1
                    if steps[i] == BISECTIONS:  # inside the surface: a hit
                        at = inside[i]
                        hit = True
                else:  # _BEHIND: after a grazing hit, whether the ray goes on to reach a surface behind the part
                    if steps[i] == 256 or at > t_end[i]:
                        phase[i] = _DONE
                        continue
                    steps[i] += 1
                    distance, core = sample_pair(fields, origin[0] + at * dx, origin[1] + at * dy, origin[2] + at * dz)
                    gap = distance - max(level, core + thin)
                    surface = max(level, cores[i] + thin)
                    # Reaching a surface after leaving the part, or going as deep as a covering ray without leaving
                    # it (a concave wall or a crease seen at a slant): either way no floor shows through.
                    if (left[i] and gap < HIT_GAP) or distance <= surface - (surface - cores[i]) * full:
                        behind[i] = True
                        phase[i] = _DONE
                        continue
                    left[i] = left[i] or gap > EXIT_GAP
                    t[i] = at + max(gap, STEP_MIN)
                if hit:
                    x, y, z = origin[0] + at * dx, origin[1] + at * dy, origin[2] + at * dz
                    hits[i] = at
                    points[i, 0], points[i, 1], points[i, 2] = x, y, z
                    least, cores[i] = sample_pair(fields, x, y, z)
                    surface = max(level, cores[i] + thin)
                    # A ray this deep covers its pixel fully (coverage clipped at 1, no look behind): the probe's
                    # remaining samples could change nothing (most rays inside a part's outline stop after two).
                    enough = surface - (surface - cores[i]) * full - FULL_MARGIN
                    for k in range(1, 9):
                        if least <= enough:
                            break
                        s = at + probe * k / 8.0
                        least = min(least, sample_pair(fields, origin[0] + s * dx, origin[1] + s * dy,
                                                       origin[2] + s * dz)[0])
                    deepest[i] = least
                    if look_behind and surface - least < (surface - cores[i]) * full:
                        t[i], steps[i], left[i], phase[i] = at + probe, 0, False, _BEHIND
                    else:
                        phase[i] = _DONE


@njit(cache=True, parallel=True)
def mark_surface_pixels(cells, shape, projection, row0, col0, mask, nearest, farthest):
    """mask[r, c] = True (image pixel row0 + r, col0 + c) where the pixel's centre falls in the image rectangle of
    one of `cells` (boxes i_first, i_last, j_first, j_last, k_first, k_last of near_surface_cell_mask's cells, (K, 6)
    indices into a crop of `shape` voxels; the cells at the crop's faces reach to its faces, where samples are
    clamped): a superset of the pixels whose centre ray may stop in `trace_surface` (a box covers its cells').
    nearest[p, r, c] = the least camera depth of the boxes of part p of `cells` whose rectangle reaches within half a
    pixel of the pixel's centre (left as it was where none does); the least over the parts is a depth nearer the
    camera than which no ray through any point of the pixel can stop. farthest[p, r, c] likewise the greatest depth:
    beyond it no such ray can stop. One part per thread, so no two threads write the same depth (the mask they may
    both set, to the same True). `projection`: 3x4, crop point -> (u * depth, v * depth, depth)."""
    n0, n1, n2 = shape[0], shape[1], shape[2]
    rows, cols = mask.shape
    parts = nearest.shape[0]
    for p in prange(parts):
        for q in range(p * cells.shape[0] // parts, (p + 1) * cells.shape[0] // parts):
            i, i_last, j, j_last, k, k_last = cells[q, 0], cells[q, 1], cells[q, 2], cells[q, 3], cells[q, 4], cells[q, 5]
            u0, u1, v0, v1, d0, d1 = 1e30, -1e30, 1e30, -1e30, 1e30, -1e30
            for x in (0.0 if i == 0 else i + 0.5, n0 if i_last == n0 - 2 else i_last + 1.5):
                for y in (0.0 if j == 0 else j + 0.5, n1 if j_last == n1 - 2 else j_last + 1.5):
                    for z in (0.0 if k == 0 else k + 0.5, n2 if k_last == n2 - 2 else k_last + 1.5):
                        pu = projection[0, 0] * x + projection[0, 1] * y + projection[0, 2] * z + projection[0, 3]
                        pv = projection[1, 0] * x + projection[1, 1] * y + projection[1, 2] * z + projection[1, 3]
                        pd = projection[2, 0] * x + projection[2, 1] * y + projection[2, 2] * z + projection[2, 3]
                        d0, d1 = min(d0, pd), max(d1, pd)  # depth is linear: a box's least and most are at corners
                        if pd <= 1e-9:  # behind the camera: keep every pixel
                            u0, u1, v0, v1 = -1e30, 1e30, -1e30, 1e30
                        else:
                            u0, u1 = min(u0, pu / pd), max(u1, pu / pd)
                            v0, v1 = min(v0, pv / pd), max(v1, pv / pd)
            u0, u1, v0, v1 = max(u0, -1e9), min(u1, 1e9), max(v0, -1e9), min(v1, 1e9)
            # Pixels any point of which (within half a pixel of the centre) is inside, with a hundredth to spare;
            # of those, the ones whose centre is inside are marked.
            c0, c1 = max(int(math.ceil(u0 - 1.01)) - col0, 0), min(int(math.floor(u1 + 0.01)) - col0, cols - 1)
            r0, r1 = max(int(math.ceil(v0 - 1.01)) - row0, 0), min(int(math.floor(v1 + 0.01)) - row0, rows - 1)
            for r in range(r0, r1 + 1):
                centre_v = r + row0 + 0.5
                inside_v = centre_v >= v0 - 0.01 and centre_v <= v1 + 0.01
                for c in range(c0, c1 + 1):
                    nearest[p, r, c] = min(nearest[p, r, c], d0)
                    farthest[p, r, c] = max(farthest[p, r, c], d1)
                    centre_u = c + col0 + 0.5
                    if inside_v and centre_u >= u0 - 0.01 and centre_u <= u1 + 0.01:
                        mask[r, c] = True


@njit(cache=True, inline="always")
def _field_normal(gradient, x, y, z):
    """The unit vector of the (n0, n1, n2, 3) `gradient` field read trilinearly at (x, y, z) (zeros where it is 0)."""
    i, j, k, i1, j1, k1, fx, fy, fz = cell_corners(gradient.shape[0], gradient.shape[1], gradient.shape[2], x, y, z)
    gx = blend_fields(gradient, 0, i, j, k, i1, j1, k1, fx, fy, fz)
    gy = blend_fields(gradient, 1, i, j, k, i1, j1, k1, fx, fy, fz)
    gz = blend_fields(gradient, 2, i, j, k, i1, j1, k1, fx, fy, fz)
    norm = math.sqrt(gx * gx + gy * gy + gz * gz)
    if norm <= 1e-9:
        return 0.0, 0.0, 0.0
    return gx / norm, gy / norm, gz / norm


@njit(cache=True, parallel=True)
def surface_normals_and_voxels(gradient, coarse, occupied, points, normals, voxels, radius, rings, agree):
    """Per surface point: the unit normal and the crop index of the nearest occupied voxel within two voxels, whose
    color it takes (-1s if none: it is drawn grey). The normal is the smoothed distance field's `gradient`
    averaged over a disc of `radius` voxels in the point's tangent plane (`rings` rings of 8 samples), each sample
    weighted by how far its normal agrees with the centre's beyond cosine `agree`: a slanted flat face's voxel steps
    average out, an edge between faces stays sharp."""
    disc = np.empty((max(rings, 0) * 8, 2))  # the samples' offsets along t and b, the same for every point
    for ring in range(1, rings + 1):
        r = radius * ring / rings
        for k in range(8):
            angle = (k + 0.5 * ring) * (math.pi / 4.0)
            disc[(ring - 1) * 8 + k, 0], disc[(ring - 1) * 8 + k, 1] = math.cos(angle) * r, math.sin(angle) * r
    for i in prange(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        ax, ay, az = _field_normal(gradient, x, y, z)
        sx, sy, sz = ax, ay, az
        if rings > 0 and (ax != 0.0 or ay != 0.0 or az != 0.0):
            # A tangent basis (t, b) of the plane normal to (ax, ay, az): t the object's up axis (y) projected onto
            # it, or x where the face is nearly level, so the samples turn with the object about the vertical.
            if abs(ay) < 0.9:
                tx, ty, tz = -ay * ax, 1.0 - ay * ay, -ay * az
            else:
                tx, ty, tz = 1.0 - ax * ax, -ax * ay, -ax * az
            tn = math.sqrt(tx * tx + ty * ty + tz * tz)
            tx, ty, tz = tx / tn, ty / tn, tz / tn
            bx, by, bz = ay * tz - az * ty, az * tx - ax * tz, ax * ty - ay * tx
            for sample in range(disc.shape[0]):
                ca, sa = disc[sample, 0], disc[sample, 1]
                qx, qy, qz = _field_normal(coarse, 0.5 * (x + ca * tx + sa * bx), 0.5 * (y + ca * ty + sa * by),
                                           0.5 * (z + ca * tz + sa * bz))
                w = (qx * ax + qy * ay + qz * az - agree) / (1.0 - agree)
                if w > 0.0:
                    w = w * w
                    sx, sy, sz = sx + w * qx, sy + w * qy, sz + w * qz
        norm = math.sqrt(sx * sx + sy * sy + sz * sz)
        if norm > 1e-9:
            normals[i, 0], normals[i, 1], normals[i, 2] = sx / norm, sy / norm, sz / norm
        else:
            normals[i, 0], normals[i, 1], normals[i, 2] = 0.0, 0.0, 0.0
        voxels[i, 0], voxels[i, 1], voxels[i, 2] = -1, -1, -1
        ci, cj, ck = int(x), int(y), int(z)
        # The 3^3 voxels around the point's cell first: any voxel beyond them is at least 1.5 voxels away along an
        # axis, so a voxel found nearer than that is the nearest of the 5^3 (the same one, as ties cannot arise).
        best = _nearest_occupied(occupied, x, y, z, ci, cj, ck, 1, voxels[i])
        if best >= 2.25:
            _nearest_occupied(occupied, x, y, z, ci, cj, ck, 2, voxels[i])


@njit(cache=True, inline="always")
def _nearest_occupied(occupied, x, y, z, ci, cj, ck, reach, out):
    """Writes to `out` the index of the occupied voxel nearest (x, y, z) among those within `reach` voxels of voxel
    (ci, cj, ck) along each axis, the first in index order among equals (left as it was if none); returns its
    squared distance (1e30 if none)."""
    n0, n1, n2 = occupied.shape
    best = 1e30
    for a in range(max(ci - reach, 0), min(ci + reach + 1, n0)):
        for b in range(max(cj - reach, 0), min(cj + reach + 1, n1)):
            for c in range(max(ck - reach, 0), min(ck + reach + 1, n2)):
                if occupied[a, b, c]:
                    d2 = (a + 0.5 - x) ** 2 + (b + 0.5 - y) ** 2 + (c + 0.5 - z) ** 2
                    if d2 < best:
                        best = d2
                        out[0], out[1], out[2] = a, b, c
    return best


@njit(cache=True, inline="always")
def _axis_range(centre, voxel, sigma, count):
    """The voxel indices along an axis whose centres lie within 2.8 `sigma` of `centre` (index units: voxel a's centre
    at a; weights above 0.02), within 2 of `voxel` and inside [0, count), `voxel` always: first, stop."""
    if sigma <= 0.0:
        return voxel, voxel + 1
    first = max(min(int(math.ceil(centre - 2.8 * sigma)), voxel), voxel - 2, 0)
    last = min(max(int(math.floor(centre + 2.8 * sigma)), voxel), voxel + 2, count - 1)
    return first, last + 1


@njit(cache=True, inline="always")
def _gauss(offset, sigma):
    """The Gaussian weight of a voxel centre `offset` voxel sides from the point (`sigma` in voxel sides; 1 if 0)."""
    return 1.0 if sigma <= 0.0 else math.exp(-0.5 * (offset / sigma) ** 2)


@njit(cache=True, inline="always")
def _axis_weights(first, stop, centre, sigma):
    """_gauss of the voxel indices first..stop - 1 (at most 5: _axis_range) from `centre`, as a 5-tuple (0 past stop):
    computed once per axis, not once per voxel of the 3D neighbourhood."""
    w0 = _gauss(first - centre, sigma)
    w1 = _gauss(first + 1 - centre, sigma) if first + 1 < stop else 0.0
    w2 = _gauss(first + 2 - centre, sigma) if first + 2 < stop else 0.0
    w3 = _gauss(first + 3 - centre, sigma) if first + 3 < stop else 0.0
    w4 = _gauss(first + 4 - centre, sigma) if first + 4 < stop else 0.0
    return (w0, w1, w2, w3, w4)


@njit(cache=True, parallel=True, error_model="numpy")
def filtered_colors(rgb, rgb_offset, occupied, voxels, points, sides, spread, least, out):
    """out[i] = the colors of the occupied voxels around crop index voxels[i] averaged with Gaussian weights centred
    on the crop point points[i], of standard deviation spread[i] (world units; `sides`: a voxel's side along each crop
    axis) but at least `least` voxel sides, out to 2.8 of them and at most 2 voxels from voxels[i]; 0.5 grey where
    voxels[i] is -1. Spread 0 takes the voxel's own color. `rgb` holds the colors at crop index + `rgb_offset`.
    Centred on the point, not on its voxel, the color varies smoothly across a voxel instead of in blocks (seen at
    a few pixels a voxel)."""
    n0, n1, n2 = occupied.shape
    m0, m1, m2 = rgb.shape[0], rgb.shape[1], rgb.shape[2]
    for i in prange(voxels.shape[0]):
        ci, cj, ck = voxels[i, 0], voxels[i, 1], voxels[i, 2]
        if ci < 0:
            out[i, 0], out[i, 1], out[i, 2] = 0.5, 0.5, 0.5
            continue
        s0 = 0.0 if spread[i] <= 0.0 else max(spread[i] / sides[0], least)  # in voxel sides
        s1 = 0.0 if spread[i] <= 0.0 else max(spread[i] / sides[1], least)
        s2 = 0.0 if spread[i] <= 0.0 else max(spread[i] / sides[2], least)
        px, py, pz = points[i, 0] - 0.5, points[i, 1] - 0.5, points[i, 2] - 0.5  # voxel a's centre is at a + 0.5
        a0, a1 = _axis_range(px, ci, s0, n0)
        e0, e1 = _axis_range(py, cj, s1, n1)
        c0, c1 = _axis_range(pz, ck, s2, n2)
        wx, wy, wz = _axis_weights(a0, a1, px, s0), _axis_weights(e0, e1, py, s1), _axis_weights(c0, c1, pz, s2)
        r, g, b, total = 0.0, 0.0, 0.0, 0.0
        for a in range(a0, a1):
            wa = wx[a - a0]
            x = a + rgb_offset[0]
            for e in range(e0, e1):
                wae = wa * wy[e - e0]
                y = e + rgb_offset[1]
                for c in range(c0, c1):
                    z = c + rgb_offset[2]
                    if occupied[a, e, c] and 0 <= x < m0 and 0 <= y < m1 and 0 <= z < m2:
                        w = wae * wz[c - c0]
                        r, g, b, total = r + w * rgb[x, y, z, 0], g + w * rgb[x, y, z, 1], b + w * rgb[x, y, z, 2], total + w
        if total > 0.0:
            out[i, 0], out[i, 1], out[i, 2] = r / total, g / total, b / total
        else:
            out[i, 0], out[i, 1], out[i, 2] = 0.5, 0.5, 0.5


@njit(cache=True, parallel=True)
def occlusion_along(field, scale, points, directions, distances, weights, out):
    """out[i] = sum_k weights[k] * field(scale * (points[i] + distances[k] * directions[i])): how much
    occupied space lies along each direction (a cheap ambient-occlusion estimate from smoothed occupancy
    stored at `scale` times the points' resolution)."""
    for i in prange(points.shape[0]):
        total = 0.0
        for k in range(distances.shape[0]):
            s = distances[k]
            total += weights[k] * sample(field, scale * (points[i, 0] + s * directions[i, 0]),
                                         scale * (points[i, 1] + s * directions[i, 1]),
                                         scale * (points[i, 2] + s * directions[i, 2]))
        out[i] = total


@njit(cache=True, inline="always")
def _blocked_along(level, x, y, z, wx, wy, wz):
    """A far occupancy level's coverage at crop coordinates (x, y, z) (in its cells) along a unit direction whose
    squared components are (wx, wy, wz)."""
    i, j, k, i1, j1, k1, fx, fy, fz = cell_corners(level.shape[0], level.shape[1], level.shape[2], x, y, z)
    return (wx * blend_fields(level, 0, i, j, k, i1, j1, k1, fx, fy, fz)
            + wy * blend_fields(level, 1, i, j, k, i1, j1, k1, fx, fy, fz)
            + wz * blend_fields(level, 2, i, j, k, i1, j1, k1, fx, fy, fz))


@njit(cache=True, inline="always")
def _flat_blocked(shape, block, x, y, z, px, py, pz, nx, ny, nz, wx, wy, wz):
    """What `_blocked_along` reads at (x, y, z) (in cells of `block` voxels, `shape` the level's) from the solid half
    space below the plane through crop point (px, py, pz) with unit normal (nx, ny, nz) alone: per cell and axis, the
    share of its face's columns whose lowest point lies under the plane (their heights taken as spread evenly)."""
    i, j, k, i1, j1, k1, fx, fy, fz = cell_corners(shape[0], shape[1], shape[2], x, y, z)
    ax, ay, az = abs(nx), abs(ny), abs(nz)
    total = 0.0
    for corner in range(8):
        ci, wi = (i1, fx) if corner & 4 else (i, 1.0 - fx)
        cj, wj = (j1, fy) if corner & 2 else (j, 1.0 - fy)
        ck, wk = (k1, fz) if corner & 1 else (k, 1.0 - fz)
        height = ((ci + 0.5) * block - px) * nx + ((cj + 0.5) * block - py) * ny + ((ck + 0.5) * block - pz) * nz
        cover_x = min(max(0.5 + (0.5 * ax * block - height) / max((ay + az) * block, 1e-6), 0.0), 1.0)
        cover_y = min(max(0.5 + (0.5 * ay * block - height) / max((ax + az) * block, 1e-6), 0.0), 1.0)
        cover_z = min(max(0.5 + (0.5 * az * block - height) / max((ax + ay) * block, 1e-6), 0.0), 1.0)
        total += wi * wj * wk * (wx * cover_x + wy * cover_y + wz * cover_z)
    return total


@njit(cache=True, inline="always")
def _level_shape(levels, level):
    """The shape of the far occupancy's level `level`."""
    if level == 0:
        return levels[0].shape
    if level == 1:
        return levels[1].shape
    if level == 2:
        return levels[2].shape
    return levels[3].shape


@njit(cache=True, inline="always")
def _level_blocked(levels, level, x, y, z, wx, wy, wz):
    """`_blocked_along` of the far occupancy's level `level` (a tuple of arrays: numba indexes it by a constant only)."""
    if level == 0:
        return _blocked_along(levels[0], x, y, z, wx, wy, wz)
    if level == 1:
        return _blocked_along(levels[1], x, y, z, wx, wy, wz)
    if level == 2:
        return _blocked_along(levels[2], x, y, z, wx, wy, wz)
    return _blocked_along(levels[3], x, y, z, wx, wy, wz)


@njit(cache=True, parallel=True, fastmath=True)
def far_sky_seen(levels, blocks, cones, tangent, start, shape, enough, points, normals, out):
    """out[i] = the share of the sky seen past `start` voxels from crop point i along its unit normal: the
    cosine-weighted transmittance of `cones` (K, 4: axis in the normal's frame, weight) of half-angle tangent = tan,
    each marched from `start` in steps of half its width (at most a block) through the occupancy level whose blocks
    (`blocks` voxels) match that width (interpolated between two), less what the surface's own tangent plane would put
    there, until
    it leaves the crop (`shape`), beyond which nothing is occupied. Four levels at most (_level_blocked). Once the
    cones traced see `enough` of the sky the rest are left out (out[i] is then at least `enough`, not the share)."""
    count_levels = len(blocks)
    for i in prange(points.shape[0]):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        nx, ny, nz = normals[i, 0], normals[i, 1], normals[i, 2]
        # A tangent frame: any unit vector across the normal, and the third by the cross product.
        if abs(nx) < 0.9:
            tx, ty, tz = 0.0, -nz, ny
        else:
            tx, ty, tz = nz, 0.0, -nx
        norm = math.sqrt(tx * tx + ty * ty + tz * tz)
        tx, ty, tz = tx / norm, ty / norm, tz / norm
        bx, by, bz = ny * tz - nz * ty, nz * tx - nx * tz, nx * ty - ny * tx
        seen = 0.0
        for c in range(cones.shape[0]):
            if seen >= enough:
                break
            dx = cones[c, 0] * tx + cones[c, 1] * bx + cones[c, 2] * nx
            dy = cones[c, 0] * ty + cones[c, 1] * by + cones[c, 2] * ny
            dz = cones[c, 0] * tz + cones[c, 1] * bz + cones[c, 2] * nz
            wx, wy, wz = dx * dx, dy * dy, dz * dz
            s, through = start, 1.0
            while through > 0.02:
                x, y, z = px + s * dx, py + s * dy, pz + s * dz
                if x < 0.0 or y < 0.0 or z < 0.0 or x >= shape[0] or y >= shape[1] or z >= shape[2]:
                    break
                width = 2.0 * s * tangent
                # The level whose blocks match the cone's width, interpolated with the next (log2 of the sizes), but no
                # larger than the sample's height over the tangent plane: blocks that straddle the surface itself
                # cannot tell a wall from it.
                at = min(max(math.log2(min(width, s * cones[c, 2]) / blocks[0]), 0.0), count_levels - 1.0)
                low = min(int(at), count_levels - 2)
                f = at - low
                block0, block1 = blocks[low], blocks[low + 1]
                occupied = ((1.0 - f) * _level_blocked(levels, low, x / block0, y / block0, z / block0, wx, wy, wz)
                            + f * _level_blocked(levels, low + 1, x / block1, y / block1, z / block1, wx, wy, wz))
                # Less what the surface's own tangent plane puts in the same cells (the cells near the surface
                # straddle it); where that fills them, nothing can be told apart from it.
                flat = ((1.0 - f) * _flat_blocked(_level_shape(levels, low), block0, x / block0, y / block0,
                                                  z / block0, px, py, pz, nx, ny, nz, wx, wy, wz)
                        + f * _flat_blocked(_level_shape(levels, low + 1), block1, x / block1, y / block1, z / block1,
                                            px, py, pz, nx, ny, nz, wx, wy, wz))
                block = block0 * (1.0 - f) + block1 * f
                occupied = min(max((occupied - flat) / (1.0 - flat), 0.0), 1.0) if flat < 0.95 else 0.0
                step = min(0.5 * width, block)
                through *= (1.0 - occupied) ** (step / block)
                s += step
            seen += cones[c, 3] * through
        out[i] = seen


@njit(cache=True, parallel=True, fastmath=True)
def cones_through(levels, blocks, axes, tangent, start, shape, points, out):
    """out[i, c] = the transmittance of the cone of half-angle tangent = tan about the unit crop direction axes[c]
    from crop point i (a point of the floor, which has no surface of its own in the occupancy): marched as
    far_sky_seen's cones are, from `start` voxels or where it enters the crop, to where it leaves it."""
    count_levels = len(blocks)
    for i in prange(points.shape[0]):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        for c in range(axes.shape[0]):
            dx, dy, dz = axes[c, 0], axes[c, 1], axes[c, 2]
            enter, leave = _box_interval(px, py, pz, dx, dy, dz, shape[0], shape[1], shape[2])
            s, through = max(start, enter), 1.0
            wx, wy, wz = dx * dx, dy * dy, dz * dz
            while through > 0.02 and s < leave:
                width = 2.0 * s * tangent
                at = min(max(math.log2(width / blocks[0]), 0.0), count_levels - 1.0)
                low = min(int(at), count_levels - 2)
                f = at - low
                block0, block1 = blocks[low], blocks[low + 1]
                x, y, z = px + s * dx, py + s * dy, pz + s * dz
                occupied = ((1.0 - f) * _level_blocked(levels, low, x / block0, y / block0, z / block0, wx, wy, wz)
                            + f * _level_blocked(levels, low + 1, x / block1, y / block1, z / block1, wx, wy, wz))
                block = block0 * (1.0 - f) + block1 * f
                step = min(0.5 * width, block)
                through *= (1.0 - min(max(occupied, 0.0), 1.0)) ** (step / block)
                s += step
            out[i, c] = through


@njit(cache=True)
def block_sources(pixels, points, normals, side, block, distance, cosine, out):
    """out[i] = the index of the point at the first pixel of point i's `block` x `block` block of pixels when that
    point lies within `distance` of it with a normal within `cosine` of its own; else out[i] is left as it is (-1:
    trace its own). `pixels` (N, 2) are rows and columns of a `side`^2 image, each at most once."""
    at = np.full((side, side), -1, dtype=np.int64)
    for i in range(pixels.shape[0]):
        at[pixels[i, 0], pixels[i, 1]] = i
    for i in range(pixels.shape[0]):
        first = at[pixels[i, 0] - pixels[i, 0] % block, pixels[i, 1] - pixels[i, 1] % block]
        if first < 0 or first == i:
            continue
        d = 0.0
        for k in range(3):
            d += (points[i, k] - points[first, k]) ** 2
        agree = normals[i, 0] * normals[first, 0] + normals[i, 1] * normals[first, 1] + normals[i, 2] * normals[first, 2]
        if d <= distance * distance and agree >= cosine:
            out[i] = first

