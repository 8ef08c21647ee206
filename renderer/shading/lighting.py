"""Stage 3 of the voxel shader: the light and the floor color on what the camera sees.

Soft shadows from shadow maps seen from LIGHT_POINTS^2 (ShaderQuality) points on the square light (the floor reads
each as its square of the light: one smooth penumbra), direct light (Lambert), ambient light with occlusion, light
bounced up from the floor, the lit floor (renderer/floor_light.py, which a caller may keep while the object moves)
times the object's shadow, and the object's reflection in the floor's glossy coat, if given; composited over the
background, in sRGB. Its compiled loops (numba) follow the Python that calls them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit, prange
from scipy import ndimage

from renderer.camera import Camera
from renderer.color import linear_to_srgb, srgb_to_linear
from renderer.floor_light import FloorTerms, lit_floor_terms
from renderer.resample import bilinear_at, linear_weights
from renderer.scene import (
    AMBIENT_RADIANCE,
    LIGHT_RADIANCE,
    LIGHT_SIZE,
)
from renderer.shading.fields import FAR
from renderer.shading.geometry import ObjectGeometry
from renderer.shading.quality import (
    BLUR_TRUNCATE,
    FLOOR_BELOW_LIT,
    FLOOR_BOUNCE,
    FLOOR_SHADOW_BIAS,
    FLOOR_SHADOW_STEP,
    FULL_QUALITY,
    LIGHT_POINTS,
    OCCLUDER_RADIUS,
    REFLECTION_BLUR,
    SHADOW_BIAS,
    SHADOW_GRAZING_OFFSET,
    SHADOW_MAP_SIZE,
    SHADOW_NORMAL_OFFSET,
    ShaderQuality,
)
from renderer.shading.surface import FloorReflection, VisibleSurface


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


class ObjectShadowMaps:
    """One object's shadow maps of the light points (build_shadow_maps), its occluders' box, and the visibility past
    it on the floor, sampled once per floor view and kept (a move of another object does not read them again)."""

    def __init__(self, occluders: np.ndarray, width: float, box: np.ndarray, points: np.ndarray):
        self.maps = np.empty((len(points), SHADOW_MAP_SIZE, SHADOW_MAP_SIZE), dtype=np.float32)
        self.bounds = np.zeros((len(points), 3))
        build_shadow_maps(occluders, OCCLUDER_RADIUS * width, width / math.sqrt(2.0), points, SHADOW_MAP_SIZE,
                          self.maps, self.bounds)
        self.nearest = self.maps.reshape(len(points), -1).min(axis=1).astype(np.float64)
        self.box = box
        self._floor: dict[tuple, tuple | str | None] = {}  # floor_grid's results, by what they read

    def visibility(self, points: np.ndarray, receivers: np.ndarray, bias: float, spread: float,
                   out: np.ndarray) -> None:
        """out[i]: the share of the light (its `points`) receiver i sees past this object (light_visibility)."""
        light_visibility(receivers, bias, points, self.maps, self.bounds, self.nearest, spread, out)

    def floor_grid(self, points: np.ndarray, bias: float, spacing: float, extent: tuple) -> tuple | str | None:
        """The visibility past this object on a grid of floor points FLOOR_SHADOW_STEP apart over the box its shadow
        can reach (its occluders' box cast from the light's corner points onto y = 0, within the floor `extent` the
        camera sees): (grid, x0, z0, x1, z1); None where no shadow reaches the floor seen; "exact" where the object
        reaches the light's height (every floor point is read off the maps instead)."""
        key = (bias, spacing, tuple(np.asarray(extent, dtype=np.float64).ravel()))
        if key not in self._floor:
            self._floor[key] = self._floor_grid(points, bias, spacing, extent)
        return self._floor[key]

    def _floor_grid(self, lights: np.ndarray, bias: float, spacing: float, extent: tuple) -> tuple | str | None:
        lo, hi = self.box
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        if corners[:, 1].max() >= lights[:, 1].min() - 1e-6:  # part of the object reaches the light's height
            return "exact"
        # Opposite corners of the light's square: of the grid of light points, widened by the square each stands for
        # (a wide light's soft shadow reaches past what its points alone cast).
        half = 0.5 * spacing * np.array([1.0, 0.0, 1.0])
        ends = np.stack([lights.min(axis=0) - half, lights.max(axis=0) + half])[:, None, :]
        cast = ends + (corners[None] - ends) * (ends[..., 1:2] / (ends[..., 1:2] - corners[None, :, 1:2]))
        cast = np.concatenate([cast.reshape(-1, 3), corners * np.array([1.0, 0.0, 1.0])])
        (x0, z0) = cast[:, [0, 2]].min(axis=0) - FLOOR_SHADOW_STEP
        (x1, z1) = cast[:, [0, 2]].max(axis=0) + FLOOR_SHADOW_STEP
        (x_min, z_min), (x_max, z_max) = extent
        # No wider than the floor the camera sees (on the same grid of samples): an object whose top comes near the
        # light's height casts a box that grows without bound, and nothing clips a large object to a grid.
        x0 += max(math.floor((float(x_min) - x0) / FLOOR_SHADOW_STEP), 0) * FLOOR_SHADOW_STEP
        z0 += max(math.floor((float(z_min) - z0) / FLOOR_SHADOW_STEP), 0) * FLOOR_SHADOW_STEP
        x1, z1 = min(x1, float(x_max) + FLOOR_SHADOW_STEP), min(z1, float(z_max) + FLOOR_SHADOW_STEP)
        if x0 > x1 or z0 > z1:
            return None
        xs = np.arange(x0, x1 + FLOOR_SHADOW_STEP, FLOOR_SHADOW_STEP)
        zs = np.arange(z0, z1 + FLOOR_SHADOW_STEP, FLOOR_SHADOW_STEP)
        gx, gz = np.meshgrid(xs, zs, indexing="ij")
        samples = np.stack([gx.ravel(), np.zeros(gx.size), gz.ravel()], axis=1)
        on_grid = np.empty(len(samples))
        self.visibility(lights, samples, bias, spacing, on_grid)
        return on_grid.reshape(gx.shape), x0, z0, x1, z1


class ShadowMaps:
    """Shadow maps of one light, seen from its `points`: one ObjectShadowMaps per object whose occluders the
    geometry holds (its own bounds, so its texels stay as fine as the object alone makes them). A receiver sees the
    light past every object: the product of its visibility past each."""

    def __init__(self, geometry: ObjectGeometry, points: np.ndarray, block: float):
        self.points = points
        self.sets = [ObjectShadowMaps(occluders, width, box, points)
                     for occluders, width, box in occluder_groups(geometry, block)]

    @classmethod
    def joined(cls, parts: Sequence[ShadowMaps]) -> ShadowMaps:
        """Several objects' shadow maps of the same light points as one (each object's kept by the caller, so an
        edit of one object builds its maps alone)."""
        joined = cls.__new__(cls)
        joined.points = parts[0].points
        joined.sets = [one for part in parts for one in part.sets]
        return joined

    def visibility(self, receivers: np.ndarray, bias: float, spread: float, out: np.ndarray) -> None:
        """out[i]: the share of the light receiver i sees (light_visibility, multiplied over the sets)."""
        out[:] = 1.0
        part = np.empty(len(receivers))
        for one in self.sets:
            one.visibility(self.points, receivers, bias, spread, part)
            out *= part


def occluder_groups(geometry: ObjectGeometry, block: float) -> list[tuple[np.ndarray, float, np.ndarray]]:
    """The geometry's shadow occluders per object, each with its block's width in the world (`block` for a
    geometry of one object; renderer/shading/compose.py joins several) and its occluders' box."""
    if not geometry.occluder_parts:
        return [(geometry.occluders, block, geometry.occluder_box)]
    starts = [0, *(end for end, _, _ in geometry.occluder_parts[:-1])]
    return [(geometry.occluders[start:end], width, box)
            for start, (end, width, box) in zip(starts, geometry.occluder_parts)]


def light_points(light_position, per_side: int = LIGHT_POINTS) -> np.ndarray:
    """(per_side^2, 3) world points at the centres of a regular grid over the square light."""
    offsets = ((np.arange(per_side) + 0.5) / per_side - 0.5) * LIGHT_SIZE
    x, z = np.meshgrid(offsets, offsets, indexing="ij")
    light = np.asarray(light_position, dtype=np.float64)
    return np.stack([light[0] + x.ravel(), np.full(x.size, light[1]), light[2] + z.ravel()], axis=1)


def shadow_maps(geometry: ObjectGeometry, light_position, quality: ShaderQuality = FULL_QUALITY) -> ShadowMaps:
    """The geometry's shadow maps of the area light at `light_position`, from quality.light_points per side."""
    return ShadowMaps(geometry, light_points(light_position, quality.light_points), geometry.occluder_width)


def shade(geometry: ObjectGeometry, surface: VisibleSurface, light_position, floor_color,
          floor_terms: FloorTerms | None = None,
          reflection: FloorReflection | None = None, quality: ShaderQuality = FULL_QUALITY,
          shadows: ShadowMaps | None = None) -> ShadedImage:
    """The shaded image of the visible surface under the light at `light_position` (world). `floor_terms`: the
    empty floor's lighting, lit_floor_terms(camera, light_position, floor_color), if the caller keeps it (it does
    not change when the object does). `reflection`: the floor's mirror image of the object (floor_reflection) to draw,
    if any (a network's input has none: it learned its own). `quality`: its light points per side. `shadows`: the
    geometry's shadow maps of the light (shadow_maps), if the caller keeps them."""
    if floor_terms is None:
        floor_terms = lit_floor_terms(Camera(geometry.elevation_deg, width=surface.size, height=surface.size),
                                      light_position, floor_color)
    floor = floor_terms.floor
    block = geometry.occluder_width  # the side of an occluder's block in the world
    shadows = shadows or shadow_maps(geometry, light_position, quality)

    size = surface.size
    visibility = np.ones((size, size), dtype=np.float32)
    visibility[floor] = (1.0 if geometry.empty else
                         _floor_visibility(surface, shadows, FLOOR_SHADOW_BIAS * block, LIGHT_SIZE / quality.light_points))
    image = np.empty((size, size, 3), dtype=np.float32)
    radiance, seen = np.zeros((0, 3), dtype=np.float32), np.zeros(0, dtype=np.float32)
    if len(surface.points):
        radiance, seen = _object_radiance(surface.points, surface.normals, surface.albedo, surface.occlusion,
                                          light_position, shadows, block, floor_color)
    r, c = surface.pixels[:, 0], surface.pixels[:, 1]
    composite(floor_terms.from_light, floor_terms.from_ambient, *floor_terms.row_weights,
                      *floor_terms.col_weights, floor, visibility, surface.images.floor_occlusion,
                      np.full(3, AMBIENT_RADIANCE, dtype=np.float32), r, c, radiance, surface.coverage[r, c], image)
    if reflection is not None and len(reflection.points):
        _add_reflection(image, surface, reflection, light_position, shadows, block, floor_color)
    visibility[r, c] = seen  # the floor's visibility lit the floor behind partly covered pixels; now the object's
    images = surface.images
    return ShadedImage(image=linear_to_srgb(image), coverage=surface.coverage,  # in [0, 1], NaN as 0: no clip needed
                       albedo=images.albedo, albedo_srgb=images.albedo_srgb, normal=images.normal, depth=images.depth,
                       visibility=visibility, occlusion=images.occlusion)


def _floor_visibility(surface: VisibleSurface, shadows: ShadowMaps, bias: float, spacing: float) -> np.ndarray:
    """Share of the light each of the surface's floor points sees, each light point reading as its square of the
    light (`spacing` on a side): past each object, its floor grid (ObjectShadowMaps.floor_grid) interpolated at
    the points inside it (the rest see all the light past it), the product over the objects."""
    floor_points, lights = surface.floor_points, shadows.points
    seen = np.ones(len(floor_points))
    if not len(floor_points):
        return seen
    part = np.empty(len(floor_points))
    for one in shadows.sets:
        grid = one.floor_grid(lights, bias, spacing, surface.floor_extent)
        if grid is None:
            continue
        if isinstance(grid, str):  # "exact": the object reaches the light's height
            one.visibility(lights, floor_points, bias, spacing, part)
        else:
            part[:] = 1.0
            values, x0, z0, x1, z1 = grid
            interpolate_grid(values, x0, z0, FLOOR_SHADOW_STEP, floor_points, x1, z1, part)
        seen *= part
    return seen


def _object_radiance(points: np.ndarray, normals: np.ndarray, albedo: np.ndarray, occlusion: np.ndarray, light_position,
                     shadows: ShadowMaps, block: float, floor_color) -> tuple[np.ndarray, np.ndarray]:
    """Linear radiance (N, 3) of object points (world points and unit normals, linear albedo, the sky light reaching
    each) and the share of the light each sees (`block`: the side of an occluder's block in the world)."""
    form = np.empty(len(points))
    form_below = np.empty(len(points))
    lights = shadows.points
    light_form_factors(points, normals, lights, LIGHT_SIZE**2 / len(lights), form, form_below)
    # Shadows matter only where the light reaches the surface at all (points facing away see none of it).
    seen = np.zeros(len(points))
    facing = np.flatnonzero(form > 0.0)
    seen_facing = np.empty(len(facing))
    # Each point is read off the shadow maps a little way out along its normal, further where the light grazes it
    # (there the depth the maps hold changes fastest across a texel).
    receivers = np.empty((len(facing), 3))
    shadow_receivers(points, normals, facing, np.asarray(light_position, dtype=np.float64),
                             block * SHADOW_NORMAL_OFFSET, block * SHADOW_GRAZING_OFFSET, receivers)
    shadows.visibility(receivers, SHADOW_BIAS * block, 0.0, seen_facing)
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
                    shadows: ShadowMaps, block: float, floor_color) -> None:
    """Adds to the linear `image` the floor's reflection of the object, where the object leaves the floor uncovered:
    the coat mirrors the lit object where it mirrored the sky (an object darker than the sky darkens the floor). The
    reflection's pixels are blurred (the coat's roughness) and upsampled bilinearly over the box they reach."""
    radiance, _ = _object_radiance(reflection.points, reflection.normals, reflection.albedo, reflection.occlusion,
                                   light_position, shadows, block, floor_color)
    add_reflection_change(image, surface, reflection, radiance - AMBIENT_RADIANCE)


def add_reflection_change(image: np.ndarray, surface: VisibleSurface, reflection: FloorReflection,
                          change: np.ndarray, floor: np.ndarray | None = None) -> None:
    """Adds to the linear `image` the reflection's `change` (N, 3) of what the floor's coat mirrors, weighted by the
    coat, blurred (the coat's roughness) and upsampled bilinearly over the box the reflection's pixels reach, at the
    pixels that show the `floor` (default: the surface's)."""
    margin = math.ceil(REFLECTION_BLUR * BLUR_TRUNCATE) + 1
    (r0, c0), (r1, c1) = reflection.pixels.min(axis=0) - margin, reflection.pixels.max(axis=0) + 1 + margin
    box = np.zeros((r1 - r0, c1 - c0, 3), dtype=np.float32)
    box[reflection.pixels[:, 0] - r0, reflection.pixels[:, 1] - c0] = reflection.weight[:, None] * change
    box = ndimage.gaussian_filter(box, (REFLECTION_BLUR, REFLECTION_BLUR, 0), mode="constant",
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
    add_upsampled(image, box, *rows, *cols, first_row, first_col, surface.floor if floor is None else floor,
                  surface.coverage)


# --- compiled loops (numba, cached on disk) ---------------------------------------------------------

MAP_PARTS = 2  # shares of the occluders each shadow map is drawn from in parallel (build_shadow_maps)
SOFT_SHADOW_TAPS = 4  # per side: samples of a light point's square of the shadow map (light_visibility)


@njit(cache=True, parallel=True)
def interpolate_grid(values, x0, z0, step, points, x1, z1, out):
    """For each point (N, 3) whose x and z lie in [x0, x1] x [z0, z1]: out[i] = the 2D grid `values` of samples `step`
    apart from (x0, z0) interpolated linearly at the point, clamped to the grid's edges (as
    scipy.ndimage.map_coordinates with order 1 and mode "nearest"); the other points' out[i] is left as it is. One
    pass over the floor's points, quicker than numpy's mask, gather and scatter."""
    n0, n1 = values.shape
    for i in prange(points.shape[0]):
        x, z = points[i, 0], points[i, 2]
        if x < x0 or x > x1 or z < z0 or z > z1:
            continue
        a, b = min(max((x - x0) / step, 0.0), n0 - 1.0), min(max((z - z0) / step, 0.0), n1 - 1.0)
        i0, j0 = int(math.floor(a)), int(math.floor(b))
        i1, j1 = min(i0 + 1, n0 - 1), min(j0 + 1, n1 - 1)
        fa, fb = a - i0, b - j0
        out[i] = ((values[i0, j0] * (1.0 - fb) + values[i0, j1] * fb) * (1.0 - fa)
                  + (values[i1, j0] * (1.0 - fb) + values[i1, j1] * fb) * fa)


@njit(cache=True, parallel=True)
def build_shadow_maps(occluders, radius, footprint, lights, size, depth, bounds):
    """One depth map per point on the light, looking straight down: map coordinates
    a = (x - lx) / (ly - y), b = (z - lz) / (ly - y), depth = ly - y, the nearest occluder (a sphere of
    `radius` world units around each occluder) per texel, each occluder covering the texels within `footprint` world
    units across too (the block of voxels it stands for: a solid layer of blocks leaves no texel between them
    uncovered, however fine the texels). bounds[k] = a0, b0, texel size.
    1 / (ly - y) is found once per occluder for all the points at the first point's height (a square light's are),
    not once per map: 15 % of the maps' time on a chair (a texel at a disc's edge may round the other way).
    Each map is drawn in MAP_PARTS parts, each from its share of the occluders into a map of its own, and the parts
    are merged by their least depth (the same maps: a texel's depth is the least over every occluder): nine maps
    alone keep one of two threads busy for five maps and the other for four."""
    count = occluders.shape[0]
    height = lights[0, 1]
    inverse = np.empty(count)  # 1 / (height - y), 0 where the occluder is not below the light by more than its radius
    for m in prange(count):
        h = height - occluders[m, 1]
        inverse[m] = 1.0 / h if h > radius else 0.0
    across = max(radius, footprint)  # an occluder's reach across the map
    maps = lights.shape[0]
    for k in prange(maps):
        lx, ly, lz = lights[k, 0], lights[k, 1], lights[k, 2]
        a_min, a_max, b_min, b_max = 1e30, -1e30, 1e30, -1e30
        for m in range(count):
            inv_h = _inverse_height(inverse, m, ly, height, occluders[m, 1], radius)
            if inv_h == 0.0:
                continue
            a = (occluders[m, 0] - lx) * inv_h
            b = (occluders[m, 2] - lz) * inv_h
            r = across * inv_h
            a_min, a_max = min(a_min, a - r), max(a_max, a + r)
            b_min, b_max = min(b_min, b - r), max(b_max, b + r)
        if a_min > a_max:
            bounds[k, 0], bounds[k, 1], bounds[k, 2] = 0.0, 0.0, 0.0
        else:
            bounds[k, 0], bounds[k, 1], bounds[k, 2] = a_min, b_min, max(a_max - a_min, b_max - b_min) / (size - 1)
    parts = np.full((MAP_PARTS - 1, maps, size, size), FAR, dtype=depth.dtype)  # the parts after the first
    for task in prange(maps * MAP_PARTS):
        k, part = task // MAP_PARTS, task % MAP_PARTS
        out = depth[k] if part == 0 else parts[part - 1, k]
        if part == 0:
            out[:, :] = FAR
        texel = bounds[k, 2]
        if texel == 0.0:
            continue
        lx, ly, lz = lights[k, 0], lights[k, 1], lights[k, 2]
        a0, b0 = bounds[k, 0] / texel, bounds[k, 1] / texel
        inv_texel = 1.0 / texel
        for m in range(part * count // MAP_PARTS, (part + 1) * count // MAP_PARTS):
            inv_h = _inverse_height(inverse, m, ly, height, occluders[m, 1], radius)
            if inv_h == 0.0:
                continue
            scale = inv_h * inv_texel  # world units -> texels
            a = (occluders[m, 0] - lx) * scale - a0
            b = (occluders[m, 2] - lz) * scale - b0
            r = radius * scale
            f = footprint * scale
            reach, f2 = r * r + 0.5, f * f
            # The texels the sphere's disc overlaps (about: those of the box it spans whose centre is within
            # reach), and those whose centre lies within the footprint.
            u_lo, u_hi, v_lo, v_hi = int(a - r), int(a + r), int(b - r), int(b + r)
            near = np.float32(ly - occluders[m, 1] - radius)
            v0, v1 = max(min(v_lo, int(b - f - 0.5)), 0), min(max(v_hi, int(b + f - 0.5)) + 1, size)
            for u in range(max(min(u_lo, int(a - f - 0.5)), 0), min(max(u_hi, int(a + f - 0.5)) + 1, size)):
                du = u + 0.5 - a
                du2 = du * du
                # Covered: d2 <= reach inside the disc's box, or d2 <= f2 anywhere; as one bound on d2 per texel
                # (7-13 % faster than the two tests joined on the bench chairs, the same texels).
                in_box = max(reach, f2) if (u >= u_lo) & (u <= u_hi) else f2
                for v in range(v0, v1):  # without a branch: which texels a disc covers is unpredictable
                    dv = v + 0.5 - b
                    bound = in_box if (v >= v_lo) & (v <= v_hi) else f2
                    current = out[u, v]
                    out[u, v] = min(current, near) if du2 + dv * dv <= bound else current
    for row in prange(maps * size):
        k, u = row // size, row % size
        for part in range(MAP_PARTS - 1):
            for v in range(size):
                depth[k, u, v] = min(depth[k, u, v], parts[part, k, u, v])


@njit(cache=True, inline="always")
def _inverse_height(inverse, m, ly, height, y, radius):
    """1 / (ly - y) for occluder m (0 if it is not below the light by more than `radius`): the kept value when the
    light point is at the kept `height`."""
    if ly == height:
        return inverse[m]
    h = ly - y
    return 1.0 / h if h > radius else 0.0


@njit(cache=True, inline="always")
def _lit_bilinear(depth, k, a, b, limit):
    """Share of the four texels nearest map coordinates (a, b) (in texels, centres at .5) whose occluder lies
    beyond `limit` (or that lie off the map), weighted bilinearly."""
    size = depth.shape[1]
    a, b = a - 0.5, b - 0.5
    u, v = math.floor(a), math.floor(b)
    fu, fv = a - u, b - v
    lit = 0.0
    for du, wu in ((0, 1.0 - fu), (1, fu)):
        for dv, wv in ((0, 1.0 - fv), (1, fv)):
            uu, vv = int(u) + du, int(v) + dv
            if uu < 0 or vv < 0 or uu >= size or vv >= size or limit <= depth[k, uu, vv]:
                lit += wu * wv
    return lit


@njit(cache=True, inline="always")
def _tap(centre, half, p, taps):
    """The texel of tap p of `taps` spread evenly over [centre - half, centre + half] (map coordinates in texels)."""
    return int(math.floor(centre + half * ((p + 0.5) / taps * 2.0 - 1.0)))


@njit(cache=True, parallel=True)
def light_visibility(receivers, bias, lights, depth, bounds, nearest, spread, out):
    """Share of the light each receiver (world point) sees past the shadow maps.

    Each light point stands for a square of side `spread` of the light (0: a point). A receiver at depth h below
    the light sees that square through an occluder at depth d over a square of the map of side
    spread * (1/d - 1/h): the map is averaged over it (percentage-closer soft shadows, with d the mean depth of
    the occluders found over the widest such square, from the map's nearest occluder `nearest[k]`), so the
    shadows of the light points blend into one penumbra instead of LIGHT_POINTS^2 overlapping copies. Where
    that square is under a texel wide the four nearest texels are read bilinearly."""
    size = depth.shape[1]
    count = lights.shape[0]
    taps = SOFT_SHADOW_TAPS
    for i in prange(receivers.shape[0]):
        x, y, z = receivers[i, 0], receivers[i, 1], receivers[i, 2]
        seen = 0.0
        for k in range(count):
            texel = bounds[k, 2]
            h = lights[k, 1] - y
            if texel == 0.0 or h <= 0.0:
                seen += 1.0
                continue
            a = ((x - lights[k, 0]) / h - bounds[k, 0]) / texel
            b = ((z - lights[k, 2]) / h - bounds[k, 1]) / texel
            reach = 0.0 if spread == 0.0 or nearest[k] >= h else 0.5 * spread * (1.0 / nearest[k] - 1.0 / h) / texel
            if a < -1.0 - reach or b < -1.0 - reach or a > size + 1.0 + reach or b > size + 1.0 + reach:
                seen += 1.0
                continue
            limit = h - bias
            if reach < 0.5:
                seen += _lit_bilinear(depth, k, a, b, limit)
                continue
            # The occluders over the widest square the light's part can be seen through: their mean depth.
            found, total = 0, 0.0
            for p in range(taps):
                uu = _tap(a, reach, p, taps)
                for q in range(taps):
                    vv = _tap(b, reach, q, taps)
                    if uu >= 0 and vv >= 0 and uu < size and vv < size and depth[k, uu, vv] < limit:
                        found += 1
                        total += depth[k, uu, vv]
            half = 0.0 if found == 0 else 0.5 * spread * (found / total - 1.0 / h) / texel
            if half < 0.5:  # a sharp shadow, or a thin occluder the taps stepped over
                seen += _lit_bilinear(depth, k, a, b, limit)
                continue
            lit = 0
            for p in range(taps):
                uu = _tap(a, half, p, taps)
                for q in range(taps):
                    vv = _tap(b, half, q, taps)
                    if uu < 0 or vv < 0 or uu >= size or vv >= size or limit <= depth[k, uu, vv]:
                        lit += 1
            seen += lit / (taps * taps)
        out[i] = seen / count


@njit(cache=True)
def shadow_receivers(points, normals, facing, light, normal_offset, grazing_offset, out):
    """out[j]: where the point facing[j] reads the shadow maps, moved along its normal by `normal_offset` plus
    `grazing_offset` times the sine of the angle between its normal and the direction to `light` (world lengths;
    in one pass, instead of numpy's masked copies and row norms)."""
    for j in range(facing.shape[0]):  # a few thousand points: one thread is quicker than starting two
        i = facing[j]
        tx, ty, tz = light[0] - points[i, 0], light[1] - points[i, 1], light[2] - points[i, 2]
        length = max(math.sqrt(tx * tx + ty * ty + tz * tz), 1e-12)
        cosine = min(max((normals[i, 0] * tx + normals[i, 1] * ty + normals[i, 2] * tz) / length, 0.0), 1.0)
        offset = normal_offset + grazing_offset * math.sqrt(1.0 - cosine * cosine)
        for k in range(3):
            out[j, k] = points[i, k] + normals[i, k] * offset


@njit(cache=True, parallel=True)
def light_form_factors(points, normals, lights, area, surface, below):
    """Per point, summed over the light's points (each of `area`, facing down): surface[i] = the cosine at
    the surface times the cosine at the light over r^2 (Lambert's direct-light factor), below[i] = the
    same for the floor point straight below it (normal up)."""
    for i in prange(points.shape[0]):
        px, py, pz = points[i, 0], points[i, 1], points[i, 2]
        nx, ny, nz = normals[i, 0], normals[i, 1], normals[i, 2]
        at_surface, at_floor = 0.0, 0.0
        for k in range(lights.shape[0]):
            dx, dy, dz = lights[k, 0] - px, lights[k, 1] - py, lights[k, 2] - pz
            r2 = max(dx * dx + dy * dy + dz * dz, 1e-8)
            inv = 1.0 / math.sqrt(r2)
            cos_surface = max((dx * nx + dy * ny + dz * nz) * inv, 0.0)
            cos_light = max(dy * inv, 0.0)
            at_surface += cos_surface * cos_light / r2
            h = lights[k, 1]
            r2_floor = dx * dx + h * h + dz * dz
            at_floor += h * h / (r2_floor * r2_floor)
        surface[i] = at_surface * area
        below[i] = at_floor * area


@njit(cache=True, parallel=True)
def composite(from_light, from_ambient, top, bottom, down, left, right, across, floor, visibility, floor_occlusion,
              background, rows, cols, radiance, cover, out):
    """The shaded image in linear light, in one pass: the lit floor (its light times `visibility`, its ambient
    times `floor_occlusion`; both terms interpolated bilinearly from the coarse grid they are evaluated on, with the
    weights FloorTerms holds: between the coarse rows once per image row, then across) or the `background` where
    there is no floor, then the object's `radiance` over it at pixels (rows, cols) by their coverage."""
    one = np.float32(1.0)
    for r in prange(out.shape[0]):
        t, b, wd = top[r], bottom[r], down[r]
        light_row = np.empty((from_light.shape[1], 3), dtype=np.float32)
        ambient_row = np.empty((from_ambient.shape[1], 3), dtype=np.float32)
        for j in range(light_row.shape[0]):
            for k in range(3):
                light_row[j, k] = from_light[t, j, k] * (one - wd) + from_light[b, j, k] * wd
                ambient_row[j, k] = from_ambient[t, j, k] * (one - wd) + from_ambient[b, j, k] * wd
        for c in range(out.shape[1]):
            if floor[r, c]:
                lit, sky = visibility[r, c], floor_occlusion[r, c]
                lc, rc, wa = left[c], right[c], across[c]
                for k in range(3):
                    light = light_row[lc, k] * (one - wa) + light_row[rc, k] * wa
                    ambient = ambient_row[lc, k] * (one - wa) + ambient_row[rc, k] * wa
                    out[r, c, k] = light * lit + ambient * sky
            else:
                for k in range(3):
                    out[r, c, k] = background[k]
    for i in prange(rows.shape[0]):
        r, c, share = rows[i], cols[i], cover[i]
        for k in range(3):
            out[r, c, k] = out[r, c, k] * (1.0 - share) + radiance[i, k] * share


@njit(cache=True, parallel=True)
def add_upsampled(image, change, top, bottom, down, left, right, across, row0, col0, floor, coverage):
    """image[row0 + r, col0 + c] += the (h, w, 3) `change` interpolated bilinearly at that pixel (bilinear_at, with
    the weights of row r and column c) times the share of the pixel that shows the floor (0 where none), kept at
    0 or more: the floor's reflection of the object added from its coarse image where the floor shows."""
    for r in prange(top.shape[0]):
        y = row0 + r
        for c in range(left.shape[0]):
            x = col0 + c
            shown = np.float32(1.0) - coverage[y, x] if floor[y, x] else np.float32(0.0)
            for k in range(3):
                added = bilinear_at(change, top[r], bottom[r], down[r], left[c], right[c], across[c], k) * shown
                image[y, x, k] = max(image[y, x, k] + added, np.float32(0.0))
