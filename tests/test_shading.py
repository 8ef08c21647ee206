"""The voxel shader on scenes with a known answer: shadow geometry, Lambert's law, the empty floor,
and hard cases; its compiled kernels against plain numpy and scipy."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy import ndimage

from renderer.camera import Camera
from renderer.color import srgb_to_linear
from renderer.errors import InputError
from renderer.floor_light import lit_floor_image
from renderer.grid import pool_object, shader_pool_factors
from renderer.scene import (
    AMBIENT_RADIANCE,
    FLOOR_HALF_SIZE,
    GRID_SIZE,
    LIGHT_RADIANCE,
    LIGHT_SIZE,
    CameraSpec,
    LightSpec,
    ObjectSpec,
    Scene,
)
from renderer.shading import (
    FAST_QUALITY,
    FULL_QUALITY,
    ShaderQuality,
    filters,
    object_geometry,
    placed,
    repaint_surface,
    shade,
    shade_scene,
    visible_surface,
)
from renderer.shading import fields as field_kernels
from renderer.shading import geometry as geometry_stage
from renderer.shading import lighting as lighting_stage
from renderer.shading import surface as surface_stage
from renderer.shading.lighting import light_points
from renderer.shading.quality import (
    COARSE_CELLS,
    COLOR_LEAST,
    COLOR_SPREAD,
    COVERAGE_FULL,
    COVERAGE_PROBE,
    FAR_BLOCKS,
    FAR_CONE_HALF_ANGLE,
    FAR_START,
    FLOOR_SHADOW_STEP,
    REFLECTION_BLUR,
    REFLECTION_SCALE,
    REFLECTION_SUBSAMPLING,
    SURFACE_LEVEL,
    THIN_LEVEL,
)
from renderer.shading.staged import StagedShader
from renderer.shading.surface import (
    _any_in_3x3,
    _differs_from_a_neighbour,
    _pixel_window,
    _ray_candidates,
    _trace,
    _trace_candidates,
)

FLOOR = (0.6, 0.6, 0.6)
SIZE = 96


def cube(n: int = 16, color=(0.8, 0.8, 0.8)) -> np.ndarray:
    rgba = np.zeros((n, n, n, 4), dtype=np.float32)
    rgba[..., :3], rgba[..., 3] = color, 1.0
    return rgba


def ball(n: int = 40, color=(0.8, 0.8, 0.8)) -> np.ndarray:
    centre = (np.arange(n) + 0.5) / n - 0.5
    x, y, z = np.meshgrid(centre, centre, centre, indexing="ij")
    rgba = np.zeros((n, n, n, 4), dtype=np.float32)
    inside = x**2 + y**2 + z**2 <= 0.25
    rgba[inside, :3], rgba[inside, 3] = color, 1.0
    return rgba


def scene_of(spec: ObjectSpec, light, elevation=30.0, size=SIZE) -> Scene:
    return Scene.single(object=spec, light=LightSpec(tuple(float(v) for v in light)), camera=CameraSpec(elevation),
                 image_size=size)


def shaded(rgba, spec: ObjectSpec, light, elevation=30.0, size=SIZE, cover_behind=True, grid_size=GRID_SIZE,
           quality=FULL_QUALITY):
    return shade_scene(scene_of(spec, light, elevation, size), rgba, FLOOR, size, grid_size, cover_behind,
                       quality=quality)


def geometry_of(rgba, spec: ObjectSpec, elevation: float, grid_size: int = GRID_SIZE):
    """The shader's geometry of `rgba` merged as for a `grid_size`^3 grid, placed by `spec`."""
    factors = shader_pool_factors(rgba.shape[0], spec.scale, grid_size)
    return placed(object_geometry(pool_object(rgba, factors)[0], rgba.shape[0], factors), spec, elevation)


def pixel_of(point, elevation=30.0, size=SIZE) -> tuple[int, int]:
    u, v, _ = Camera(elevation, width=size, height=size).project(np.asarray(point, dtype=np.float64))
    return int(v), int(u)


@pytest.mark.parametrize("grid_size", [GRID_SIZE, 2 * GRID_SIZE])
def test_placing_the_geometry_is_placing_the_voxels(grid_size):
    """The shader draws the object's voxels in their own frame and places the result (how it keeps its voxel work
    through every turn and move): an object turned by 90 degrees and moved must shade as its voxels turned by hand
    (x to -z, z to x about the vertical), moved, and placed unturned."""
    rgba = ball(24, color=(0.7, 0.3, 0.2))
    rgba[:6, ..., :3] = (0.1, 0.5, 0.9)  # one side painted, so the turn shows
    rgba[:, :5] = 0.0  # and cut flat below, so it stands on the floor
    by_hand = np.ascontiguousarray(np.transpose(rgba, (2, 1, 0, 3))[:, :, ::-1])  # new[k, j, N-1-i] = old[i, j, k]
    light = (0.6, 2.7, 0.4)
    turned = shaded(rgba, ObjectSpec(voxels="v.npz", translation=(0.2, -0.1), rotation_deg=90.0, scale=(0.5, 0.5, 0.5)),
                    light)
    turned_voxels = shaded(by_hand, ObjectSpec(voxels="v.npz", translation=(0.2, -0.1), scale=(0.5, 0.5, 0.5)), light)
    # Equal but at a few silhouette pixels, within the rays' stopping tolerance: each ray starts at a depth found from
    # runs of voxels along the crop's last axis, which the turn by hand lays out along another, so the two trace
    # different steps to the same surface. The normals, averaged over a disc of the surface 16 voxels across, move
    # most: 0.5 % of their values differ, by at most 0.024.
    for part in ("image", "coverage", "albedo", "normal", "visibility", "occlusion"):
        difference = np.abs(getattr(turned, part) - getattr(turned_voxels, part))
        largest, share = (0.03, 0.007) if part == "normal" else (0.015, 0.005)
        assert difference.max() < largest and (difference > 1e-4).mean() < share, part
    unturned = shaded(rgba, ObjectSpec(voxels="v.npz", translation=(0.2, -0.1), scale=(0.5, 0.5, 0.5)), light)
    assert np.abs(turned.albedo - unturned.albedo).max() > 0.5  # the turn shows


@pytest.mark.parametrize("quality", [FULL_QUALITY, FAST_QUALITY], ids=["full", "fast"])
@pytest.mark.parametrize("light_x", [1.2, -1.2])
def test_a_cubes_shadow_lies_where_geometry_puts_it(light_x, quality):
    # A cube of side 0.3 at the origin, the light to one side: the shadow of its top's centre falls on
    # the line from the light through it, on the side away from the light; the other side is lit.
    spec = ObjectSpec(voxels="v.npz", scale=(0.3, 0.3, 0.3))
    light = np.array([light_x, 2.0, 0.0])
    out = shaded(cube(), spec, light, quality=quality)
    top = np.array([0.0, 0.3, 0.0])
    shadow = light + (top - light) * light[1] / (light[1] - top[1])  # where that line meets y = 0
    assert np.sign(shadow[0]) == -np.sign(light_x)
    row, col = pixel_of(shadow)
    assert out.coverage[row, col] == 0.0 and out.visibility[row, col] < 0.5
    mirror = np.array([-shadow[0], 0.0, shadow[2]])  # as far from the cube, on the light's side
    row, col = pixel_of(mirror)
    assert out.coverage[row, col] == 0.0 and out.visibility[row, col] > 0.95


def test_a_spheres_shading_follows_lambert():
    # A sphere of radius 0.25 lit from the side and above: on its lit, unshadowed points the linear
    # radiance grows with the direct irradiance computed here from the analytic sphere normal and a
    # fine grid on the light (cosine at the surface and at the light over r^2), with slope albedo / pi.
    spec = ObjectSpec(voxels="v.npz", scale=(0.5, 0.5, 0.5))
    light = np.array([1.5, 2.0, 0.5])
    albedo = float(srgb_to_linear(0.8))
    out = shaded(ball(), spec, light, elevation=20.0, size=128)
    camera = Camera(20.0, width=128, height=128)
    rows, cols = np.nonzero((out.coverage == 1.0) & (out.visibility > 0.99))
    origin, dirs = camera.pixel_rays(cols + 0.5, rows + 0.5)
    centre = np.array([0.0, 0.25, 0.0])
    # Ray-sphere intersection gives each pixel's true point and normal.
    oc = origin - centre
    b = dirs @ oc
    disc = b**2 - (oc @ oc - 0.25**2)
    keep = disc > 0.0
    t = -b[keep] - np.sqrt(disc[keep])
    points = origin + t[:, None] * dirs[keep]
    normals = (points - centre) / 0.25
    # The drawn normals agree with the sphere's (within 12 degrees nearly everywhere).
    drawn = out.normal[rows[keep], cols[keep]]
    assert np.quantile(np.sum(drawn * normals, axis=1), 0.1) > np.cos(np.radians(12.0))
    n = 24
    offsets = ((np.arange(n) + 0.5) / n - 0.5) * LIGHT_SIZE
    samples = np.stack(np.meshgrid(light[0] + offsets, [light[1]], light[2] + offsets, indexing="ij"), -1).reshape(-1, 3)
    to_light = samples[None] - points[:, None]
    r2 = np.sum(to_light**2, axis=-1)
    cos_surface = np.maximum(np.einsum("pkc,pc->pk", to_light, normals), 0.0) / np.sqrt(r2)
    cos_light = to_light[..., 1] / np.sqrt(r2)
    direct = LIGHT_RADIANCE * np.mean(cos_surface * cos_light / r2, axis=1) * LIGHT_SIZE**2
    radiance = srgb_to_linear(out.image[rows[keep], cols[keep]]).mean(axis=1)
    lit = direct > 0.3 * direct.max()
    slope, intercept = np.polyfit(direct[lit], radiance[lit], 1)
    assert slope == pytest.approx(albedo / np.pi, rel=0.15)
    assert np.corrcoef(direct[lit], radiance[lit])[0, 1] > 0.95


@pytest.mark.parametrize("elevation", [10.0, 40.0])
def test_the_floor_mirrors_the_object_by_the_coats_fresnel_reflectance(elevation):
    # A cube lit from the front, standing on the floor: past the floor, a pixel's ray meets the cube mirrored below it
    # (its front face, found here by intersecting the ray with that face's plane). There the floor gains, in linear
    # light, Schlick's reflectance (F0 = 0.04, 1.5 the coat's index) along the ray times the reflection's scale times
    # the radiance of the real point it mirrors (read off the image where the camera sees that point) less the sky's
    # the coat mirrored instead, where the cube leaves the floor uncovered. The reflection is blurred, which keeps its
    # sum: the image gains that sum, and nothing off the mirrored cube's outline (less its blur) or on the cube.
    size, light, floor, half = 128, (0.0, 0.9, 1.6), (0.5, 0.5, 0.5), 0.2
    scene = scene_of(ObjectSpec(voxels="v.npz", scale=(2 * half,) * 3), light, elevation, size)
    plain, mirrored = (shade_scene(scene, cube(48), floor, size, reflection=r) for r in (False, True))
    camera = Camera(elevation, width=size, height=size)
    rows, cols = np.mgrid[0:size, 0:size]
    origin, rays = camera.pixel_rays(cols.ravel() + 0.5, rows.ravel() + 0.5)
    t = (half - origin[2]) / rays[:, 2]
    meets = origin + t[:, None] * rays
    on_face = (t > 0.0) & (np.abs(meets[:, 0]) < half) & (meets[:, 1] < 0.0) & (meets[:, 1] > -2.0 * half)
    u, v, _ = camera.project(meets[on_face] * np.array([1.0, -1.0, 1.0]))
    radiance = srgb_to_linear(plain.image[v.astype(int), u.astype(int)].astype(np.float64))
    fresnel = 0.04 + 0.96 * (1.0 + rays[on_face, 1]) ** 5  # the cosine to the floor's normal is -rays[:, 1]
    shown = 1.0 - plain.coverage.ravel()[on_face]
    expected = np.sum((REFLECTION_SCALE * fresnel * shown)[:, None] * (radiance - AMBIENT_RADIANCE), axis=0)
    gained = srgb_to_linear(mirrored.image.astype(np.float64)) - srgb_to_linear(plain.image.astype(np.float64))
    assert expected.min() > 0.1
    np.testing.assert_allclose(gained.sum(axis=(0, 1)), expected, rtol=0.2)  # measured: within 8 % at 10 degrees, 12 % at 40
    rows, cols = np.nonzero(np.abs(mirrored.image - plain.image).max(axis=2) > 0.5 / 255.0)
    corners = np.array([[x, y, z] for x in (-half, half) for y in (0.0, -2 * half) for z in (-half, half)])
    corner_u, corner_v, _ = camera.project(corners)
    reach = REFLECTION_SUBSAMPLING * (2 + REFLECTION_BLUR * 2.5)  # pixels: the coarse reflection's blur and fade
    assert corner_v.min() - reach <= rows.min() and rows.max() <= corner_v.max() + reach
    assert corner_u.min() - reach <= cols.min() and cols.max() <= corner_u.max() + reach
    assert np.all(plain.coverage[rows, cols] < 1.0)


def test_an_empty_object_is_the_lit_floor():
    light = (0.7, 2.7, -0.4)
    empty = np.zeros((8, 8, 8, 4), dtype=np.float32)
    for elevation in (5.0, 30.0, 60.0):
        out = shaded(empty, ObjectSpec(voxels="v.npz"), light, elevation)
        floor = lit_floor_image(Camera(elevation, width=SIZE, height=SIZE), light, FLOOR)
        # The same shading, interpolated from the same coarse points in linear rather than sRGB values.
        assert np.abs(out.image - floor).max() < 3.0 / 255.0
        assert np.all(out.coverage == 0.0) and np.all(out.visibility == 1.0)


@pytest.mark.parametrize("quality", [FULL_QUALITY, FAST_QUALITY, ShaderQuality(8, 1)], ids=["full", "fast", "extremes"])
@pytest.mark.parametrize("case", ["light at a corner", "light outside its box", "light low and far", "elevation 0",
                                  "elevation 89", "object at the grid border", "object larger than the grid"])
def test_hard_cases_give_finite_images(case, quality):
    spec, light, elevation = ObjectSpec(voxels="v.npz", scale=(0.5, 0.5, 0.5)), (1.0, 2.75, 0.5), 30.0
    if case == "light at a corner":
        light = (1.5, 2.5, -1.5)
    elif case == "light outside its box":
        light = (6.0, 0.05, 6.0)
    elif case == "light low and far":
        light = (-40.0, 0.3, 25.0)
    elif case == "elevation 0":
        elevation = 0.0
    elif case == "elevation 89":
        elevation = 89.0
    elif case == "object at the grid border":
        spec = ObjectSpec(voxels="v.npz", translation=(1.1, 0.2), scale=(0.6, 0.6, 0.6))
    elif case == "object larger than the grid":
        spec = ObjectSpec(voxels="v.npz", scale=(4.0, 4.0, 4.0))
    out = shaded(cube(12), spec, light, elevation, size=48, quality=quality)
    for name in ("image", "coverage", "albedo", "normal", "depth", "visibility", "occlusion"):
        values = getattr(out, name)
        assert np.all(np.isfinite(values)), name
    assert out.image.min() >= 0.0 and out.image.max() <= 1.0
    assert 0.0 <= out.visibility.min() and out.visibility.max() <= 1.0


def test_trilinear_sample_matches_scipy():
    rng = np.random.default_rng(0)
    field = rng.random((7, 9, 5)).astype(np.float32)
    points = rng.uniform(0.5, [6.5, 8.5, 4.5], size=(200, 3))  # voxel centres at i + 0.5
    expected = ndimage.map_coordinates(field, (points - 0.5).T, order=1)
    got = np.array([field_kernels.sample(field, *p) for p in points])
    np.testing.assert_allclose(got, expected, atol=1e-5)


@pytest.mark.parametrize("shape", [(7, 9), (1, 5), (4, 1)])
def test_grid_interpolation_matches_scipy_beyond_the_edges_too(shape):
    rng = np.random.default_rng(1)
    values = rng.random(shape)
    a, b = rng.uniform(-2.0, shape[0] + 1.0, 300), rng.uniform(-2.0, shape[1] + 1.0, 300)
    # Samples 0.5 apart from (1, -3) at points (x, 0, z); only those in the box from (1, -3) to a sample past the
    # grid's far edges are interpolated.
    x0, z0, step = 1.0, -3.0, 0.5
    x1, z1 = x0 + shape[0] * step, z0 + shape[1] * step
    points = np.stack([x0 + a * step, np.zeros(300), z0 + b * step], axis=1)
    got = np.full(300, -1.0)
    lighting_stage.interpolate_grid(values, x0, z0, step, points, x1, z1, got)
    inside = (points[:, 0] >= x0) & (points[:, 0] <= x1) & (points[:, 2] >= z0) & (points[:, 2] <= z1)
    expected = np.where(inside, ndimage.map_coordinates(values, [a, b], order=1, mode="nearest"), -1.0)
    assert inside.sum() > 20 and (~inside).sum() > 20  # both kinds of point are there
    np.testing.assert_allclose(got, expected, atol=1e-12)


@pytest.mark.parametrize("shape", [(30, 41), (1, 7), (6, 1)])
def test_mask_neighbourhoods_match_scipy(shape):
    rng = np.random.default_rng(2)
    for density in (0.1, 0.5, 0.9):
        mask = rng.random(shape) < density
        edge = (mask ^ ndimage.binary_erosion(mask, border_value=0)) | (ndimage.binary_dilation(mask) & ~mask)
        np.testing.assert_array_equal(_differs_from_a_neighbour(mask), edge)
        near = ndimage.maximum_filter(mask, size=3, mode="constant", cval=True)
        np.testing.assert_array_equal(_any_in_3x3(mask), near)


def test_shadow_maps_block_what_lies_between():
    # One occluder at height 1 straight below a light point at height 3: a receiver on the floor under it
    # is in shadow, one a metre aside is lit, and with no occluders everything is lit.
    lights = np.array([[0.0, 3.0, 0.0]])
    occluders = np.array([[0.0, 1.0, 0.0]])
    maps = np.empty((1, 16, 16), dtype=np.float32)
    bounds = np.zeros((1, 3))
    lighting_stage.build_shadow_maps(occluders, 0.05, 0.0, lights, 16, maps, bounds)
    receivers = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    seen = np.empty(3)
    lighting_stage.light_visibility(receivers, 0.01, lights, maps, bounds, np.full(1, 2.0), 0.0, seen)
    assert seen[0] < 0.01 and seen[1] == 1.0 and seen[2] == 1.0  # the last lies between occluder and light
    lighting_stage.build_shadow_maps(np.zeros((0, 3)), 0.05, 0.0, lights, 16, maps, bounds)
    lighting_stage.light_visibility(receivers, 0.01, lights, maps, bounds, np.full(1, 2.0), 0.0, seen)
    assert np.all(seen == 1.0)


def test_occluders_spaced_wider_than_texels_cover_their_footprint():
    # A layer of occluders 0.04 apart at 1 below a light point, on a map of texels about 0.01 across: as points
    # they leave texels between them uncovered (light would pass a solid layer); each covering its block's square
    # (footprint: half its diagonal) they cover every texel whose centre lies over the layer.
    grid = np.arange(-0.5, 0.5 + 1e-9, 0.04)
    x, z = np.meshgrid(grid, grid, indexing="ij")
    layer = np.stack([x.ravel(), np.full(x.size, 1.0), z.ravel()], axis=1)
    layer = np.vstack([layer, [[0.53, 1.0, 0.0]]])  # one beyond: the texels do not line up with the layer's cells
    lights = np.array([[0.0, 2.0, 0.0]])
    uncovered = []
    for footprint in (0.0, 0.04 / np.sqrt(2.0)):
        maps, bounds = np.empty((1, 96, 96), dtype=np.float32), np.zeros((1, 3))
        lighting_stage.build_shadow_maps(layer, 0.002, footprint, lights, 96, maps, bounds)
        a0, b0, texel = bounds[0]
        centres = (np.arange(96) + 0.5) * texel
        over = (np.abs(a0 + centres)[:, None] < 0.49) & (np.abs(b0 + centres)[None, :] < 0.49)  # height 1: a = x
        uncovered.append(int((maps[0][over] >= field_kernels.FAR).sum()))
    assert uncovered[0] > 1000 and uncovered[1] == 0


def _reference_shadow_map(occluders, radius, footprint, light, size):
    """The nearest occluder per texel by the rule build_shadow_maps states, texel by texel over the whole map: an
    occluder covers a texel whose centre lies within `footprint` of its projection, or within sqrt(r^2 + 1/2) of
    it (r its radius in texels) and in the box of texels its disc spans."""
    lx, ly, lz = light
    h = ly - occluders[:, 1]
    kept = h > radius
    occluders, inv_h = occluders[kept], 1.0 / h[kept]
    across = max(radius, footprint) * inv_h
    a, b = (occluders[:, 0] - lx) * inv_h, (occluders[:, 2] - lz) * inv_h
    a_min, b_min = (a - across).min(), (b - across).min()
    texel = max((a + across).max() - a_min, (b + across).max() - b_min) / (size - 1)
    scale = inv_h / texel
    a = (occluders[:, 0] - lx) * scale - a_min / texel
    b = (occluders[:, 2] - lz) * scale - b_min / texel
    r, f = radius * scale, footprint * scale
    centres = np.arange(size) + 0.5
    d2 = (centres[None, :, None] - a[:, None, None]) ** 2 + (centres[None, None, :] - b[:, None, None]) ** 2
    columns, rows = np.arange(size)[None, :, None], np.arange(size)[None, None, :]
    in_box = ((columns >= (a - r).astype(int)[:, None, None]) & (columns <= (a + r).astype(int)[:, None, None])
              & (rows >= (b - r).astype(int)[:, None, None]) & (rows <= (b + r).astype(int)[:, None, None]))
    covered = (in_box & (d2 <= (r * r + 0.5)[:, None, None])) | (d2 <= (f * f)[:, None, None])
    near = (ly - occluders[:, 1] - radius).astype(np.float32)
    return np.where(covered, near[:, None, None], field_kernels.FAR).min(axis=0), (a_min, b_min, texel)


@pytest.mark.parametrize("footprint", [0.0, 0.01, 0.05])  # none, under the discs' radius, over it
def test_shadow_maps_hold_the_nearest_covering_occluder_per_texel(footprint):
    occluders = np.random.default_rng(7).uniform([-0.5, 0.0, -0.5], [0.5, 1.5, 0.5], (400, 3))
    lights = np.array([[0.1, 3.0, -0.2], [-0.3, 3.0, 0.25]])
    maps, bounds = np.empty((2, 24, 24), dtype=np.float32), np.zeros((2, 3))
    lighting_stage.build_shadow_maps(occluders, 0.02, footprint, lights, 24, maps, bounds)
    for k in range(2):
        expected, expected_bounds = _reference_shadow_map(occluders, 0.02, footprint, lights[k], 24)
        np.testing.assert_allclose(bounds[k], expected_bounds, rtol=1e-12)
        np.testing.assert_array_equal(maps[k], expected)


def test_shadow_maps_of_light_points_at_other_heights_are_each_points_own():
    # The maps keep 1 / height per occluder for the first point's height; a point at another height (and an
    # occluder above it) must give the map it gives alone.
    occluders = np.random.default_rng(3).uniform([-0.5, 0.0, -0.5], [0.5, 2.5, 0.5], (500, 3))
    lights = np.array([[0.1, 3.0, -0.2], [0.3, 2.0, 0.1], [-0.2, 3.0, 0.0]])
    maps, bounds = np.empty((3, 32, 32), dtype=np.float32), np.zeros((3, 3))
    lighting_stage.build_shadow_maps(occluders, 0.02, 0.0, lights, 32, maps, bounds)
    for k in range(3):
        alone, alone_bounds = np.empty((1, 32, 32), dtype=np.float32), np.zeros((1, 3))
        lighting_stage.build_shadow_maps(occluders, 0.02, 0.0, lights[k:k + 1], 32, alone, alone_bounds)
        np.testing.assert_array_equal(maps[k], alone[0])
        np.testing.assert_array_equal(bounds[k], alone_bounds[0])


@pytest.mark.parametrize("points", [2, 3, 4])  # 3: the shader's LIGHT_POINTS, 2: its fast quality
def test_soft_shadow_of_a_plate_matches_the_area_light(points):
    # A square plate at height 1 under a square light at height 3 (points x points): a floor point at x sees the
    # light but for the part of it whose rays cross the plate, which is exact per axis (similar triangles).
    # Each light point read as a point (spread 0) steps by 1/points^2 and bands; read as its square of the light it
    # is closer everywhere.
    light_height, plate_height, light_side, plate_side = 3.0, 1.0, 1.0, 0.5
    offsets = ((np.arange(points) + 0.5) / points - 0.5) * light_side
    lx, lz = np.meshgrid(offsets, offsets, indexing="ij")
    lights = np.stack([lx.ravel(), np.full(lx.size, light_height), lz.ravel()], axis=1)
    grid = np.linspace(-plate_side / 2, plate_side / 2, 51)
    ox, oz = np.meshgrid(grid, grid, indexing="ij")
    plate = np.stack([ox.ravel(), np.full(ox.size, plate_height), oz.ravel()], axis=1)
    maps = np.empty((len(lights), 96, 96), dtype=np.float32)
    bounds = np.zeros((len(lights), 3))
    lighting_stage.build_shadow_maps(plate, 0.005, 0.0, lights, 96, maps, bounds)
    nearest = maps.reshape(len(lights), -1).min(axis=1).astype(np.float64)
    xs = np.linspace(-1.5, 1.5, 301)
    receivers = np.stack([xs, np.zeros_like(xs), np.zeros_like(xs)], axis=1)

    def blocked_share(x):  # of the light's side: light points l whose ray from x crosses the plate
        ends = [x - (x + side * plate_side / 2) * light_height / plate_height for side in (1, -1)]
        return max(0.0, min(max(ends), light_side / 2) - max(min(ends), -light_side / 2)) / light_side

    exact = np.array([1.0 - blocked_share(x) * blocked_share(0.0) for x in xs])
    errors = {}
    for spread in (0.0, light_side / points):
        seen = np.empty(len(xs))
        lighting_stage.light_visibility(receivers, 0.01, lights, maps, bounds, nearest, spread, seen)
        errors[spread] = np.abs(seen - exact)
    soft = errors[light_side / points]
    # 2 x 2 points (the fast quality) leave coarser steps: up to a fifth of the light off at the worst receiver.
    assert soft.max() < {2: 0.2, 3: 0.09, 4: 0.09}[points] and soft.mean() < 0.6 * errors[0.0].mean()
    assert errors[0.0].max() > 0.12  # the test can tell: points alone band


def test_shadow_occluders_stand_for_blocks_of_fine_voxels():
    # At 200^3 each occluder is the mean centre of the occupied voxels of a 2^3 block (OCCLUDER_CELLS); at 100^3
    # each voxel casts its own. A slanted plate's floor shadow must not change by more than a penumbra's rounding.
    def slanted_plate(n):
        rgba = np.zeros((n, n, n, 4), dtype=np.float32)
        i = np.arange(n // 5, 4 * n // 5)
        x, z = np.meshgrid(i, i, indexing="ij")
        y = n // 2 + (x - n // 2) // 3  # a plate leaning 18 degrees, one voxel thick
        rgba[x, y, z] = (0.7, 0.7, 0.7, 1.0)
        return rgba

    spec, light = ObjectSpec(), (0.3, 3.0, 0.2)
    coarse = geometry_of(slanted_plate(100), spec, 30.0, 2 * GRID_SIZE)
    assert len(coarse.occluders) == int((slanted_plate(100)[..., 3] > 0).sum())
    rgba = slanted_plate(200)
    geometry = geometry_of(rgba, spec, 30.0, 2 * GRID_SIZE)
    found = np.argwhere(rgba[..., 3] > 0)
    blocks: dict[tuple, list] = {}
    for index in found:
        blocks.setdefault(tuple(index // 2), []).append(index)
    means = np.array([np.mean(members, axis=0) for _, members in sorted(blocks.items())])
    to_world = geometry.voxel_to_world
    np.testing.assert_allclose(geometry.occluders, (means + 0.5) @ to_world[:3, :3].T + to_world[:3, 3], atol=1e-9)

    one_per_voxel = replace(geometry, occluders=(found + 0.5) @ to_world[:3, :3].T + to_world[:3, 3],
                            occluder_block=1.0)
    surface = visible_surface(geometry, SIZE)
    seen = [shade(g, surface, light, FLOOR).visibility[surface.floor] for g in (geometry, one_per_voxel)]
    shadowed = (seen[0] < 0.99) | (seen[1] < 0.99)
    assert shadowed.sum() > 200  # the plate casts a shadow in view
    assert np.abs(seen[0] - seen[1])[shadowed].mean() < 0.02


def test_distance_transform_matches_scipy():
    rng = np.random.default_rng(1)
    occupied = rng.random((13, 17, 11)) < 0.02
    occupied[0, 0, 0] = True
    np.testing.assert_allclose(geometry_stage.distance_to_occupied(occupied), ndimage.distance_transform_edt(~occupied),
                               rtol=1e-5, atol=1e-5)


def test_closing_and_filling_make_a_shell_solid():
    from renderer.grid import dilate_cube
    from renderer.shading.geometry import _erode_cube, _solid

    rng = np.random.default_rng(2)
    mask = rng.random((9, 10, 8)) < 0.3
    structure = ndimage.generate_binary_structure(3, 3)
    np.testing.assert_array_equal(dilate_cube(mask), ndimage.binary_dilation(mask, structure))
    np.testing.assert_array_equal(_erode_cube(mask), ndimage.binary_erosion(mask, structure, border_value=0))
    # A hollow box whose shell has diagonal gaps only: solid inside, empty outside.
    shell = np.zeros((12, 12, 12), dtype=bool)
    shell[3:9, 3:9, 3:9] = True
    shell[4:8, 4:8, 4:8] = False
    solid = _solid(shell)
    assert solid[3:9, 3:9, 3:9].all() and solid.sum() == 6**3


def block_coverage_reference(coverage: np.ndarray) -> np.ndarray:
    """filters.block_coverage2 in numpy: per 2^3 block and axis, the mean over its four columns along the axis of
    1 - the product of (1 - coverage) of the column's two cells (odd sides padded with empty cells)."""
    padded = np.pad(coverage, [(0, n % 2) for n in coverage.shape[:3]] + [(0, 0)])
    h0, h1, h2 = (n // 2 for n in padded.shape[:3])
    blocks = np.moveaxis(padded.reshape(h0, 2, h1, 2, h2, 2, 3), (1, 3, 5), (3, 4, 5))  # (h0, h1, h2, 2, 2, 2, 3)
    out = np.empty((h0, h1, h2, 3), dtype=np.float32)
    for axis in range(3):
        through = np.prod(1.0 - blocks[..., axis], axis=3 + axis)
        out[..., axis] = (1.0 - through).mean(axis=(3, 4))
    return out


@pytest.mark.parametrize("shape", [(12, 10, 8), (13, 9, 7)])
def test_block_coverage_matches_numpy(shape):
    rng = np.random.default_rng(4)
    coverage = rng.random(shape + (3,)).astype(np.float32) * (rng.random(shape + (3,)) < 0.4)
    np.testing.assert_allclose(filters.block_coverage2(coverage), block_coverage_reference(coverage), atol=1e-6)
    mask = rng.random(shape) < 0.2
    as_coverage = np.repeat(mask[..., None], 3, axis=3).astype(np.float32)
    np.testing.assert_allclose(filters.mask_coverage2(mask), block_coverage_reference(as_coverage), atol=1e-6)


def test_a_wall_blocks_the_lines_across_it_at_every_level_and_less_of_those_along_it():
    # A one-voxel wall across x: every line along x through its blocks is stopped at every level (a mean of the
    # occupancy would let 1 - 1 / block through). A line along y meets it only in the wall's own slice of the block,
    # 1 / block of the columns; the cells along y, taken as independent, count more than that, but never as much as
    # a line across and less at each coarser level.
    wall = np.zeros((64, 64, 64), dtype=bool)
    wall[5] = True
    level, block, before = filters.mask_coverage2(wall), 2, 1.0
    while block <= 32:
        cell = 5 // block
        np.testing.assert_allclose(level[cell, :, :, 0], 1.0)
        along = level[cell, :, :, 1]
        assert np.ptp(along) == 0.0 and 1.0 / block - 1e-6 <= along[0, 0] <= 0.5 and along[0, 0] < before
        assert np.all(np.delete(level, cell, axis=0) == 0.0)
        level, block, before = filters.block_coverage2(level), block * 2, along[0, 0]


def closed_cup(n: int, depth: int, radius: int, wall: int = 4, bottom: int = 4) -> np.ndarray:
    """Voxels of a cup along +z: a bottom `bottom` voxels thick and a round wall around an opening of `radius`,
    `depth` voxels deep."""
    centre = np.arange(n) + 0.5 - n / 2
    x, y = np.meshgrid(centre, centre, indexing="ij")
    r = np.hypot(x, y)[..., None]
    z = np.arange(n)[None, None, :]
    rgba = np.zeros((n, n, n, 4), dtype=np.float32)
    rgba[..., :3] = 0.8
    rgba[..., 3] = (r <= radius + wall) & (z < bottom + depth) & ((r > radius) | (z < bottom))
    return rgba


def test_the_far_sky_follows_a_hollows_opening():
    # From the centre of a cup's bottom, the sky seen (cosine-weighted) is sin^2 of the opening's half-angle, exactly;
    # the cones are coarse, so: in that order, within 0.3, a deep narrow cup well under half, an open floor all of it.
    spec = ObjectSpec(voxels="v.npz", scale=(1.0, 1.0, 1.0))
    n, found, exact = 96, [], []
    for depth, radius in [(80, 10), (60, 20), (40, 30), (20, 40), (0, 40)]:
        geometry = geometry_of(closed_cup(n, depth, radius), spec, 30.0, grid_size=256)
        point = np.array([[n / 2, n / 2, 4 + SURFACE_LEVEL - 0.5]]) - geometry.offset  # on the bottom's surface
        seen = surface_stage._surface_occlusion(geometry, point, np.array([[0.0, 0.0, 1.0]]))
        far = np.empty(1)
        surface_stage.far_sky_seen(geometry.far_occupancy, np.array(FAR_BLOCKS, dtype=np.float64),
                                   surface_stage._FAR_CONES, np.tan(np.radians(FAR_CONE_HALF_ANGLE)), FAR_START,
                                   np.array(geometry.distance_and_core.shape[:3], dtype=np.float64), 1.0 + 1e-9,
                                   point, np.array([[0.0, 0.0, 1.0]]), far)
        found.append(far[0])
        exact.append(np.sin(np.arctan2(radius, depth)) ** 2)
        assert 0.0 < seen[0] <= 1.0
    assert np.all(np.diff(found) > 0.0)
    np.testing.assert_allclose(found, exact, atol=0.3)
    assert found[0] < 0.2 and found[1] < 0.5 and found[-1] > 0.97


def test_a_tube_seen_into_its_opening_is_dark_inside_and_shows_no_floor():
    # A tube lying along z, open at both ends, seen through its opening: every pixel inside its outline is tube (the
    # rays that graze its inner wall go on into it; before, a seam of floor showed there),
    # and its inside sees little sky (before, as much as its outside).
    n = 64
    centre = np.arange(n) + 0.5 - n / 2
    x, y = np.meshgrid(centre, centre, indexing="ij")
    r = np.hypot(x, y)
    tube = np.zeros((n, n, n, 4), dtype=np.float32)
    tube[..., :3] = 0.8
    tube[..., 3] = ((r > 22) & (r <= 28))[..., None]
    spec = ObjectSpec(voxels="v.npz", scale=(1.0, 1.0, 1.0))
    image = shaded(tube, spec, np.array([1.0, 2.75, 0.5]), elevation=15.0, size=128)
    covered = image.coverage > 0.0
    near_empty = ndimage.binary_dilation(~covered, np.ones((3, 3), dtype=bool), iterations=2)  # anti-aliased edges
    partial = (image.coverage < 1.0) & covered & ~near_empty
    assert covered.sum() > 1500 and partial.sum() <= 20  # before: 264
    hole_rows = np.nonzero((ndimage.binary_fill_holes(covered) & ~covered).any(axis=1))[0]
    rows = np.arange(covered.shape[0])[:, None]
    facing_up = covered & ~near_empty & (image.normal[..., 1] > 0.8)
    inside_floor = facing_up & (rows > hole_rows.max())  # the tube's inside below the opening, under its roof
    outside_top = facing_up & (rows < hole_rows.min())  # the top of its outside, under the open sky
    assert inside_floor.sum() > 100 and outside_top.sum() > 50
    assert image.occlusion[inside_floor].mean() < 0.9 < image.occlusion[outside_top].mean()  # inside: 0.81, was 1.0


def duck(n: int = 80) -> np.ndarray:
    """A voxel shell (two voxels thick, as the voxeliser's surfaces) of a flattened body and a head sunk into it:
    a crease all around the neck."""
    c = np.arange(n) + 0.5
    x, y, z = np.meshgrid(c, c, c, indexing="ij")
    body = (x - 0.5 * n) ** 2 + 2.0 * (y - 0.275 * n) ** 2 + (z - 0.5 * n) ** 2 <= (0.325 * n) ** 2
    head = (x - 0.65 * n) ** 2 + (y - 0.575 * n) ** 2 + (z - 0.5 * n) ** 2 <= (0.1625 * n) ** 2
    solid = body | head
    rgba = np.zeros((n, n, n, 4), dtype=np.float32)
    rgba[..., :3] = 0.8
    rgba[..., 3] = solid & ~ndimage.binary_erosion(solid, iterations=2)
    return rgba


@pytest.mark.parametrize("elevation", [10.0, 25.0, 40.0])
def test_a_crease_between_two_parts_shows_no_floor_inside_the_outline(elevation):
    # Rays that graze the head and run into the body at the neck cover their pixels (before, 102 pixels of these
    # nine views, one-pixel seams of floor color through the object).
    partial = 0
    for rotation in (0.0, 60.0, 120.0):
        spec = ObjectSpec(voxels="v.npz", rotation_deg=rotation, scale=(1.0, 1.0, 1.0))
        image = shaded(duck(), spec, np.array([1.0, 2.75, 0.5]), elevation=elevation, size=192)
        covered = image.coverage > 0.0
        near_empty = ndimage.binary_dilation(~covered, np.ones((3, 3), dtype=bool), iterations=2)  # anti-aliased
        partial += ((image.coverage < 1.0) & covered & ~near_empty).sum()
    assert partial <= 8  # a few at the crease's ends on the outline, 0.85-0.95 covered


def test_specks_inside_a_covered_part_close_and_openings_stay():
    from renderer.shading.quality import SPECK_PIXELS
    from renderer.shading.surface import _close_specks

    cover = np.zeros((40, 40), dtype=np.float32)
    cover[5:35, 5:35] = 1.0
    cover[5, 5:35] = cover[34, 5:35] = 0.5  # a partly covered silhouette row at the part's edge: touches the empty
    cover[10:12, 10:13] = 0.3  # a speck of 6 pixels, all around it covered: a panel the rays went through too shallow
    cover[20:23, 20:23] = 0.4  # an opening: partly covered pixels around an empty one the rays passed through
    cover[21, 21] = 0.0
    side = int(np.ceil(np.sqrt(SPECK_PIXELS))) + 1  # a partly covered patch larger than a speck stays as it is
    cover[24:24 + side, 8:8 + side] = 0.6
    closed = _close_specks(cover, 256)
    assert np.all(closed[10:12, 10:13] == 1.0)
    np.testing.assert_array_equal(closed[20:23, 20:23], cover[20:23, 20:23])
    np.testing.assert_array_equal(closed[5], cover[5])
    np.testing.assert_array_equal(closed[24:24 + side, 8:8 + side], cover[24:24 + side, 8:8 + side])
    # The speck size follows the image's area: at twice the size the larger patch is a speck too.
    assert np.all(_close_specks(cover, 512)[24:24 + side, 8:8 + side] == 1.0)
    assert np.array_equal(_close_specks(np.zeros((4, 4), np.float32), 256), np.zeros((4, 4)))


def test_a_part_in_front_of_another_shows_no_floor_at_its_outline():
    # A wall, and a rod a few voxels in front of it across its middle. Seen from the front, every pixel inside the
    # wall's outline is object: the rays that graze the rod's edges go on to the wall, so no floor may show
    # through there (it drew a bright fringe around the part in front). Where the rod sticks out past the wall,
    # its edges against the floor stay partly covered (anti-aliased).
    n = 40
    wall, both = np.zeros((n, n, n, 4), np.float32), np.zeros((n, n, n, 4), np.float32)
    wall[8:32, 0:30, 0:6] = (0.3, 0.3, 0.3, 1.0)  # x, y (up), z (towards the camera)
    both[...] = wall
    both[0:40, 13:16, 24:27] = (0.8, 0.8, 0.8, 1.0)  # the rod, longer than the wall is wide
    spec = ObjectSpec(voxels="v.npz", scale=(1.0, 1.0, 1.0))
    alone, with_rod = (shaded(rgba, spec, np.array([0.0, 2.0, 1.0]), elevation=10.0, size=128) for rgba in (wall, both))
    inside = ndimage.binary_erosion(alone.coverage >= 1.0, iterations=2)
    rod = (with_rod.coverage > 0.0) & ~(alone.coverage > 0.0)  # the rod's pixels past the wall's sides
    assert inside.sum() > 300 and rod.sum() > 50
    assert with_rod.coverage[inside].min() == 1.0  # before grazing rays went on: 40 pixels at 0.73-1
    assert ((with_rod.coverage > 0.0) & (with_rod.coverage < 1.0) & rod).sum() > 0
    # Photo delighting asks for the rod's outline to stay partly covered: there a photo pixel mixes rod and wall.
    for_photo = shaded(both, spec, np.array([0.0, 2.0, 1.0]), elevation=10.0, size=128, cover_behind=False)
    assert ((for_photo.coverage < 1.0) & inside).sum() > 10


@pytest.mark.parametrize(("grid_size", "quality"), [(GRID_SIZE, FULL_QUALITY), (2 * GRID_SIZE, FULL_QUALITY),
                                                     (GRID_SIZE, FAST_QUALITY)], ids=["128", "256", "128 fast"])
def test_the_staged_shader_equals_shading_from_scratch_after_every_edit(grid_size, quality):
    """Cached stages give the very image the uncached shader gives, after a move and turn, a move along the floor, a
    light move, a camera tilt, a floor color and a paint; with the object voxels merged as for the network's grid and
    for the finer one a shader refiner reads. The voxel work (the geometry) reruns only for another shape, and a paint
    stroke reruns only the colors and what they light."""
    rgba = ball(24, color=(0.7, 0.3, 0.2))
    painted = rgba.copy()
    painted[:12, ..., :3] = (0.1, 0.5, 0.9)
    scene = Scene.single(object=ObjectSpec(voxels="v.npz", scale=(0.7, 0.7, 0.7)), light=LightSpec((0.6, 2.7, 0.4)),
                  image_size=SIZE)
    moved = scene.with_changes(object=ObjectSpec(voxels="v.npz", translation=(0.3, -0.2), rotation_deg=40.0,
                                                 scale=(0.7, 0.7, 0.7)))
    slid = moved.with_changes(object=ObjectSpec(voxels="v.npz", translation=(-0.25, 0.1), rotation_deg=40.0,
                                                scale=(0.7, 0.7, 0.7)))
    lit = slid.with_changes(light=LightSpec((-0.9, 2.6, 0.2)))
    tilted = lit.with_changes(camera=CameraSpec(elevation_deg=55.0))
    green = (0.3, 0.5, 0.3)
    edits = [  # each from the one before
        ("start", scene, rgba, FLOOR),
        ("move", moved, rgba, FLOOR),
        ("slide", slid, rgba, FLOOR),
        ("light", lit, rgba, FLOOR),
        ("camera", tilted, rgba, FLOOR),
        ("floor", tilted, rgba, green),
        ("paint", tilted, painted, green),
        ("outside the grid", tilted.with_changes(object=ObjectSpec(voxels="v.npz", translation=(3.0, 0.0))), painted, green),
    ]
    staged, reran = StagedShader(grid_size, quality), {}
    for name, edited, voxels, floor in edits:
        cached = staged.render(edited, id(voxels), voxels, floor, SIZE, shape_key="ball")  # paint keeps the shape
        reran[name] = set(staged.stage_ms)
        fresh = shade_scene(edited, voxels, floor, SIZE, grid_size, quality=quality)
        for part in ("image", "coverage", "albedo", "normal", "depth", "visibility", "occlusion"):
            np.testing.assert_array_equal(getattr(cached, part), getattr(fresh, part), err_msg=f"{name}: {part}")
    assert reran["light"] == {"floor", "lighting"}  # the light-dependent stages alone
    assert reran["floor"] == {"floor", "lighting"}  # the object's stages do not read the floor color
    # The geometry is placed: turns keep it.
    assert reran["move"] == reran["slide"] == {"placement", "surface", "colors", "reflection", "lighting"}
    assert reran["camera"] == {"placement", "surface", "colors", "reflection", "floor", "lighting"}
    # Paint keeps the shape: what the camera sees stays, its colors and what they light change.
    assert reran["paint"] == {"pool", "colors", "reflection", "lighting"}
    # Without a shape key the voxels' key names the shape too: other voxels are another object.
    other = StagedShader(grid_size, quality)
    other.render(tilted, "before", rgba, green, SIZE)
    other.render(tilted, "after", painted, green, SIZE)
    assert set(other.stage_ms) == {"pool", "geometry", "placement", "surface", "colors", "reflection", "lighting"}


def test_an_image_of_another_size_not_kept_leaves_the_live_stages():
    """`keep=False` (the editor's redraw of a settled image at its panel's size): the image at that size equals the
    shader's from scratch, and the stages kept for the live size stay, so the next live render reruns nothing."""
    rgba = ball(24, color=(0.7, 0.3, 0.2))
    scene = Scene.single(object=ObjectSpec(voxels="v.npz", scale=(0.7, 0.7, 0.7)), light=LightSpec((0.6, 2.7, 0.4)))
    staged = StagedShader()
    live = staged.render(scene, "ball", rgba, FLOOR, SIZE).image
    larger = staged.render(scene, "ball", rgba, FLOOR, 2 * SIZE, keep=False).image
    np.testing.assert_array_equal(larger, shade_scene(scene, rgba, FLOOR, 2 * SIZE).image)
    np.testing.assert_array_equal(staged.render(scene, "ball", rgba, FLOOR, SIZE).image, live)
    assert staged.stage_ms == {}


def lattice(n: int = 40, bars: int = 4) -> np.ndarray:
    """One-voxel bars along all three axes, `bars` per side: thin parts and many openings."""
    rgba = np.zeros((n, n, n, 4), dtype=np.float32)
    at = np.linspace(0, n - 1, bars).astype(int)
    for a in at:
        for b in at:
            rgba[a, b, :, 3] = rgba[a, :, b, 3] = rgba[:, a, b, 3] = 1.0
    rgba[..., :3] = 0.7
    return rgba


def test_ray_candidates_leave_out_the_inside_of_a_solid():
    # A ray stops on the surface, never deep inside a part, so no cell wholly inside the ball is a candidate
    # (geometry_stage.near_surface_cell_mask): every candidate cell lies near the sphere of its 20-voxel radius.
    geometry = geometry_of(ball(), ObjectSpec(voxels="v.npz"), 30.0)
    centre = np.argwhere(geometry.occupied).mean(axis=0) + 0.5
    cells = geometry.surface_cells  # boxes: first and last i, j, k; here runs along k
    assert len(cells) > 0 and np.all(cells[:, 0] == cells[:, 1]) and np.all(cells[:, 2] == cells[:, 3])
    for k in (4, 5):  # a run's first and last cell; a cell spans voxel centres i..i+1, its middle at i + 1
        middles = np.column_stack([cells[:, 0], cells[:, 2], cells[:, k]]) + 1.0
        radii = np.linalg.norm(middles - centre, axis=1)
        assert radii.min() > 20.0 - 3.0 and radii.max() < 20.0 + 3.0
    # The coarse boxes hold the same cells, each within one block.
    coarse = geometry.coarse_surface_cells
    assert len(coarse) < len(cells) / 2
    assert np.all(coarse[:, 1::2] - coarse[:, 0::2] < COARSE_CELLS)
    assert np.all(coarse[:, 0::2] // COARSE_CELLS == coarse[:, 1::2] // COARSE_CELLS)

    def marked(boxes):
        out = np.zeros(np.array(geometry.occupied.shape) - 1, dtype=bool)
        for i0, i1, j0, j1, k0, k1 in boxes:
            out[i0:i1 + 1, j0:j1 + 1, k0:k1 + 1] = True
        return out

    fine = marked(cells)
    assert np.all(marked(coarse) >= fine) and marked(coarse).sum() < 3 * fine.sum()



def test_candidate_cells_are_those_whose_corners_allow_a_hit():
    """near_surface_cell_mask against its definition over the eight corners of each cell, computed with numpy."""
    rng = np.random.default_rng(3)
    i, j, k = np.meshgrid(*(np.arange(n, dtype=np.float32) for n in (9, 12, 15)), indexing="ij")
    distance = np.abs(np.sqrt((i - 4) ** 2 + (j - 5) ** 2 + (k - 7) ** 2) - 4.0)  # from a shell of radius 4
    core = rng.uniform(0.0, 0.6, distance.shape)  # thin parts here and there
    fields = np.stack([distance + rng.uniform(0.0, 0.2, distance.shape), core], axis=-1).astype(np.float32)
    corners = [fields[a:a + 8, b:b + 11, c:c + 14] for a in (0, 1) for b in (0, 1) for c in (0, 1)]
    least, most = np.minimum.reduce(corners), np.maximum.reduce(corners)
    level, thin, slack, depth = 0.8, 0.35, 0.01, 0.25
    expected = ((least[..., 0] - np.maximum(level, most[..., 1] + thin) < field_kernels.HIT_GAP + slack)
                & (most[..., 0] - np.maximum(level, least[..., 1] + thin) >= -depth))
    mask = geometry_stage.near_surface_cell_mask(fields, level, thin, slack, depth)
    assert 0.2 < expected.mean() < 0.8  # both kinds of cell
    np.testing.assert_array_equal(mask, expected)

@pytest.mark.parametrize("shape, elevation, translation", [("ball", 30.0, (0.0, 0.0)), ("lattice", 30.0, (0.0, 0.0)),
                                                           ("lattice", 0.0, (0.0, 0.0)), ("lattice", 89.0, (0.0, 0.0)),
                                                           ("ball", 30.0, (1.1, 0.2))])
@pytest.mark.parametrize("coarse", [False, True])
def test_skipped_rays_and_skipped_depths_hold_no_surface(shape, elevation, translation, coarse):
    # The centre pass traces only the pixels whose ray may stop on the surface, each from the depth nearer than which
    # no ray through its pixel can stop to the depth past which none can. Tracing every pixel of the window from those
    # depths, with or without the far one, must give the same hits, points and coverage, and the skip must leave out
    # most of the window's misses; tracing every ray from the crop's face (anywhere in its pixel) must find no hit
    # nearer than its pixel's depth, and the same hits for nearly all; a far depth changes no ray anywhere in a pixel.
    spec = ObjectSpec(voxels="v.npz", translation=translation, scale=(0.6, 0.6, 0.45))  # a voxel step of two lengths
    geometry = geometry_of(ball() if shape == "ball" else lattice(), spec, elevation)
    camera = Camera(elevation, width=128, height=128)
    world_to_voxel = np.linalg.inv(geometry.voxel_to_world)
    origin = world_to_voxel[:3, :3] @ camera.position + world_to_voxel[:3, 3] - geometry.offset
    rows, cols = _pixel_window(geometry, camera)
    cells = geometry.coarse_surface_cells if coarse else geometry.surface_cells
    candidates, nearest, farthest = _ray_candidates(geometry, camera, rows, cols, cells)
    every = _trace(geometry, camera, world_to_voxel, origin, rows[:, None] + 0.5, cols[None, :] + 0.5, nearest)
    bounded = _trace(geometry, camera, world_to_voxel, origin, rows[:, None] + 0.5, cols[None, :] + 0.5, nearest,
                     farthest)
    skipping = _trace_candidates(geometry, camera, world_to_voxel, origin, rows, cols, candidates, nearest, farthest)
    for full, far, fast in zip(every, bounded, skipping):
        np.testing.assert_array_equal(far, full)
        np.testing.assert_array_equal(fast, full)
    hits = every[0] < field_kernels.FAR
    assert 0 < hits.sum() < hits.size
    assert np.all(candidates[hits]) and candidates[~hits].mean() < 0.6
    assert np.isfinite(nearest[hits]).all() and (nearest[~candidates] > nearest[hits].min()).mean() > 0.3
    assert np.all(farthest[hits] >= nearest[hits]) and np.isfinite(farthest[candidates & ~hits]).any()  # misses bounded

    axis = -(camera.world_to_camera()[2, :3] @ geometry.voxel_to_world[:3, :3])  # depth per crop voxel
    for dv, du in ((0.5, 0.5), (0.02, 0.98), (0.98, 0.3)):
        t_face, points_face, _ = _trace(geometry, camera, world_to_voxel, origin, rows[:, None] + dv,
                                        cols[None, :] + du)
        from_near = _trace(geometry, camera, world_to_voxel, origin, rows[:, None] + dv, cols[None, :] + du, nearest)
        for full, far in zip(from_near, _trace(geometry, camera, world_to_voxel, origin, rows[:, None] + dv,
                                               cols[None, :] + du, nearest, farthest)):
            np.testing.assert_array_equal(far, full)
        t_near = from_near[0]
        face, near = t_face < field_kernels.FAR, t_near < field_kernels.FAR
        depth = (points_face[face] - origin) @ axis
        assert np.all(depth >= nearest[face] - 1e-9) and np.all(depth <= farthest[face] + 1e-9)
        # Rays that graze a lattice's thin bars may step past a bar from one start and not the other (2.7 % of them
        # at most here; their coverage is near 0): no more.
        assert (face != near).sum() < 0.04 * face.sum() and face.sum() > 0.1 * face.size
        assert np.median(np.abs(t_face - t_near)[face & near]) < 0.05


@pytest.mark.parametrize("shape", ["ball", "lattice"])
def test_a_rays_coverage_is_that_of_its_whole_probe(shape):
    """trace_surface stops a hit's coverage probe once the ray lies deep enough to cover its pixel fully; the coverage
    must be the one its nine samples along the ray give (sampled here in Python), for thick parts and thin bars."""
    spec = ObjectSpec(voxels="v.npz", scale=(0.6, 0.6, 0.45))
    geometry = geometry_of(ball() if shape == "ball" else lattice(), spec, 30.0)
    camera = Camera(30.0, width=128, height=128)
    world_to_voxel = np.linalg.inv(geometry.voxel_to_world)
    origin = world_to_voxel[:3, :3] @ camera.position + world_to_voxel[:3, 3] - geometry.offset
    rows, cols = _pixel_window(geometry, camera)
    t, points, cover = _trace(geometry, camera, world_to_voxel, origin, rows[:, None] + 0.5, cols[None, :] + 0.5,
                              cover_behind=False)
    hits = t < field_kernels.FAR
    directions = points[hits] - origin
    directions /= np.linalg.norm(directions, axis=-1, keepdims=True)
    fields = geometry.distance_and_core
    expected = []
    for point, direction in zip(points[hits], directions):
        samples = [field_kernels.sample_pair(fields, *(point + COVERAGE_PROBE * k / 8.0 * direction)) for k in range(9)]
        core = samples[0][1]
        level = max(SURFACE_LEVEL, core + THIN_LEVEL)
        least = min(distance for distance, _ in samples)
        expected.append(np.clip((level - least) / ((level - core) * COVERAGE_FULL), 0.0, 1.0))
    expected = np.array(expected)
    assert (expected == 1.0).sum() > 20 and ((expected > 0.0) & (expected < 1.0)).sum() > 20  # both kinds of ray
    np.testing.assert_allclose(cover[hits], expected, atol=1e-5)


@pytest.mark.parametrize("light", [(0.0, 1.0, 2.5), (0.3, 1.0, 2.0), (-0.5, 1.2, 2.2)])
def test_a_face_with_nothing_before_it_sees_the_whole_light(light):
    # A low light in front of a cube: its front face (normal +z) sees all of the light, and read off the shadow
    # maps it must not shadow itself (shadow acne: the maps hold depths measured straight down from the light).
    out = shaded(cube(32), ObjectSpec(voxels="v.npz", scale=(0.4, 0.4, 0.4)), np.array(light), grid_size=2 * GRID_SIZE)
    face = ndimage.binary_erosion((out.normal[..., 2] > 0.95) & (out.coverage >= 1.0), iterations=2)
    assert face.sum() > 40
    assert out.visibility[face].min() > 0.95


def leaning_slab(n: int, lean_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Voxels of a slab a third of the box thick whose faces lean back by `lean_deg` from vertical, and the unit
    normal of its front face (towards +z, tilted up)."""
    normal = np.array([0.0, np.sin(np.radians(lean_deg)), np.cos(np.radians(lean_deg))])
    centre = (np.arange(n) + 0.5) / n - 0.5
    x, y, z = np.meshgrid(centre, centre, centre, indexing="ij")
    rgba = np.zeros((n, n, n, 4), dtype=np.float32)
    inside = np.abs(y * normal[1] + z * normal[2]) <= 1.0 / 6.0
    rgba[inside, :3], rgba[inside, 3] = 0.8, 1.0
    return rgba, normal


@pytest.mark.parametrize("lean", [5.0, 12.0])
def test_a_slanted_face_has_one_normal_across_its_voxel_steps(lean):
    # A face leaning a few degrees off a voxel axis is a staircase of voxels with long treads; its normals must be
    # the plane's everywhere, not tilt up at every step (bands of light across a leaning chair back).
    rgba, normal = leaning_slab(64, lean)
    out = shaded(rgba, ObjectSpec(voxels="v.npz", scale=(0.6, 0.6, 0.6)), np.array([0.0, 2.5, 1.5]), elevation=10.0,
                 size=128, grid_size=2 * GRID_SIZE)
    face = ndimage.binary_erosion((out.normal[..., 2] > 0.8) & (out.coverage >= 1.0), iterations=3)
    assert face.sum() > 500
    angles = np.degrees(np.arccos(np.clip(out.normal[face] @ normal, -1.0, 1.0)))
    assert np.quantile(angles, 0.95) < 3.0


def test_normals_stay_sharp_up_to_a_cubes_edges():
    # Averaging normals over the surface must not round an edge between faces: the front face's normals are +z up to
    # two pixels (about two voxels) from its top and side edges.
    out = shaded(cube(48), ObjectSpec(voxels="v.npz", scale=(0.5, 0.5, 0.5)), np.array([0.5, 2.5, 1.5]), elevation=10.0,
                 size=128, grid_size=2 * GRID_SIZE)
    front = (out.normal[..., 2] > 0.5) & (out.coverage >= 1.0)
    face = ndimage.binary_erosion(front, iterations=2)
    assert face.sum() > 300
    assert np.quantile(out.normal[face, 2], 0.02) > np.cos(np.radians(6.0))


def test_the_composite_lays_the_object_over_the_lit_floor_by_its_coverage():
    # The floor's two terms come on a coarse grid with, per image row and column, the coarse rows and columns around
    # it and the weights between them: the composite interpolates them bilinearly.
    rng = np.random.default_rng(4)
    size, coarse = 12, (4, 5)
    from_light, from_ambient = (rng.random(coarse + (3,), dtype=np.float32) for _ in range(2))
    top, left = rng.integers(0, coarse[0] - 1, size), rng.integers(0, coarse[1] - 1, size)
    down, across = (rng.random(size, dtype=np.float32) for _ in range(2))
    floor = rng.random((size, size)) < 0.7
    visibility, floor_occlusion = (rng.random((size, size), dtype=np.float32) for _ in range(2))
    background = np.array([0.1, 0.2, 0.3], dtype=np.float32)
    rows, cols = np.array([0, 3, 7]), np.array([5, 3, 11])
    radiance = rng.random((3, 3), dtype=np.float32)
    cover = np.array([1.0, 0.25, 0.0], dtype=np.float32)
    out = np.empty((size, size, 3), dtype=np.float32)
    lighting_stage.composite(from_light, from_ambient, top, top + 1, down, left, left + 1, across, floor, visibility,
                      floor_occlusion, background, rows, cols, radiance, cover, out)

    def full(term):
        d, a = down[:, None, None], across[None, :, None]
        upper = term[top][:, left] * (1 - a) + term[top][:, left + 1] * a
        lower = term[top + 1][:, left] * (1 - a) + term[top + 1][:, left + 1] * a
        return upper * (1 - d) + lower * d

    ground = np.where(floor[..., None],
                      full(from_light) * visibility[..., None] + full(from_ambient) * floor_occlusion[..., None],
                      background)
    expected = ground.copy()
    expected[rows, cols] = ground[rows, cols] * (1.0 - cover[:, None]) + radiance * cover[:, None]
    np.testing.assert_allclose(out, expected, rtol=1e-5, atol=1e-6)


def test_network_buffers_hold_the_shaded_image_and_its_buffers_in_order():
    from renderer.scene import CAMERA_DISTANCE, GRID_EXTENT
    from renderer.shading.buffers import BUFFER_CHANNELS, network_buffers

    image = shaded(cube(), ObjectSpec(voxels="v.npz", scale=(0.4, 0.4, 0.4)), (0.4, 2.7, 0.3), size=48)
    buffers = network_buffers(image)
    assert buffers.shape == (48, 48, len(BUFFER_CHANNELS)) and buffers.dtype == np.float32
    on = image.coverage > 0.0
    assert on.any() and (~on).any()
    for start, field in ((0, image.image), (3, image.albedo_srgb), (6, image.normal)):
        np.testing.assert_array_equal(buffers[..., start:start + 3], field)
    np.testing.assert_allclose(buffers[on, 9], (image.depth[on] - CAMERA_DISTANCE) / (0.5 * GRID_EXTENT), atol=1e-6)
    assert np.all(buffers[~on, 9] == 0.0)
    for channel, field in ((10, image.visibility), (11, image.occlusion), (12, image.coverage)):
        np.testing.assert_array_equal(buffers[..., channel], field)


def test_a_repainted_surface_is_the_surface_of_the_painted_object():
    """Paint keeps occupancy: the surface traced for one paint, given the other paint's colors, is the surface traced
    for that paint from scratch (and so is its shaded image); and its colors are the paint's, not the first's."""
    rgba = ball(24, color=(0.7, 0.3, 0.2))
    painted = rgba.copy()
    painted[:12, ..., :3] = (0.1, 0.5, 0.9)
    spec, elevation = ObjectSpec(voxels="v.npz", scale=(0.7, 0.7, 0.7), rotation_deg=30.0), 25.0
    first, second = (geometry_of(v, spec, elevation) for v in (rgba, painted))
    fresh = visible_surface(second, SIZE)
    repainted = repaint_surface(visible_surface(first, SIZE), second)
    for part in ("albedo", "color_voxels", "points", "normals", "coverage"):
        np.testing.assert_array_equal(getattr(repainted, part), getattr(fresh, part))
    for part in ("albedo", "albedo_srgb", "normal", "occlusion"):
        np.testing.assert_array_equal(getattr(repainted.images, part), getattr(fresh.images, part))
    light = (0.5, 2.7, 0.3)
    np.testing.assert_array_equal(shade(second, repainted, light, FLOOR).image, shade(second, fresh, light, FLOOR).image)
    blue = np.all(np.isclose(repainted.images.albedo_srgb, (0.1, 0.5, 0.9)), axis=-1)
    assert 0 < blue.sum() < repainted.pixels.shape[0]  # part of the ball was painted blue, and it shows


def gaussian_mean_colors(rgb, occupied, centre, sides, sigma):
    """The Gaussian-weighted mean color of the occupied voxels around `centre` (voxel index units), those further
    than 2.8 sigmas along an axis left out (the kernel's reach)."""
    cells = np.argwhere(occupied)
    offsets = (cells - np.asarray(centre)) * np.asarray(sides)
    weights = np.exp(-(offsets**2).sum(axis=1) / (2.0 * sigma**2)) * np.all(np.abs(offsets) <= 2.8 * sigma, axis=1)
    return (weights[:, None] * rgb[tuple(cells.T)]).sum(axis=0) / weights.sum()


def _plate():
    """A plate of voxels, half red, half blue (the seam between indices 5 and 6 along the first axis), and its colors
    as filtered_colors reads them (at crop index + (1, 1, 1))."""
    occupied = np.zeros((12, 12, 3), dtype=bool)
    occupied[:, :, 1] = True
    rgb = np.zeros((14, 14, 5, 3), dtype=np.float32)
    rgb[1:7, 1:13, 2] = (0.9, 0.1, 0.1)
    rgb[7:13, 1:13, 2] = (0.1, 0.2, 0.9)
    return occupied, rgb


@pytest.mark.parametrize("sides", [(1.0, 1.0, 1.0), (2.0, 1.0, 0.5)])
def test_filtered_colors_average_the_voxels_around_the_point_by_their_distance(sides):
    """On the plate, the color of a point near the seam is the Gaussian mean of the plate's voxels around the point
    (weights by world distance, anisotropic voxels too); far from the seam it stays pure; spread 0 takes the voxel's
    own color; no voxel gives grey."""
    occupied, rgb = _plate()
    sigma = 0.5  # world units
    voxels = np.array([[5, 6, 1], [6, 6, 1], [0, 6, 1], [11, 3, 1], [-1, -1, -1]], dtype=np.int64)
    points = voxels + np.array([[0.75, 0.5, 0.5], [0.3, 0.6, 0.5], [0.5, 0.5, 0.5], [0.9, 0.1, 0.5], [0.5, 0.5, 0.5]])
    spread = np.array([sigma, sigma, sigma, 0.0, sigma])
    out = np.empty((len(voxels), 3), dtype=np.float32)
    surface_stage.filtered_colors(rgb, np.array([1, 1, 1], dtype=np.int64), occupied, voxels, points, np.asarray(sides),
                            spread, 0.0, out)
    crop_rgb = rgb[1:13, 1:13, 1:4]
    for row in (0, 1):
        expected = gaussian_mean_colors(crop_rgb, occupied, points[row] - 0.5, sides, sigma)
        np.testing.assert_allclose(out[row], expected, atol=2e-3)
        if sides[0] == 1.0:
            assert 0.11 < out[row, 0] < 0.89  # a mix of the two halves
    far = gaussian_mean_colors(crop_rgb, occupied, points[2] - 0.5, sides, sigma)
    np.testing.assert_allclose(out[2], far, atol=2e-3)
    np.testing.assert_allclose(out[3], (0.1, 0.2, 0.9))
    np.testing.assert_array_equal(out[4], (0.5, 0.5, 0.5))


def test_filtered_colors_change_smoothly_across_a_voxel_at_a_small_spread():
    """A close-up spreads a point's color over much less than a voxel; with the least spread (COLOR_LEAST voxel sides)
    the color still goes from red to blue across the seam in small steps, as the point moves, not in one jump at the
    voxel's edge, and in order."""
    occupied, rgb = _plate()
    along = np.linspace(4.0, 8.0, 81)  # the point's first coordinate: across the seam at 6
    points = np.stack([along, np.full_like(along, 6.5), np.full_like(along, 1.5)], axis=1)
    voxels = np.stack([np.floor(along).astype(np.int64), np.full(len(along), 6), np.full(len(along), 1)], axis=1)
    out = np.empty((len(along), 3), dtype=np.float32)
    surface_stage.filtered_colors(rgb, np.array([1, 1, 1], dtype=np.int64), occupied, voxels, points,
                            np.ones(3), np.full(len(along), 0.05), COLOR_LEAST, out)
    red = out[:, 0]
    assert red[0] > 0.85 and red[-1] < 0.15
    assert np.all(np.diff(red) <= 1e-6)  # from red to blue, never back
    assert np.abs(np.diff(red)).max() < 0.08  # 0.05 voxels a step: no jump of the whole 0.8 at the seam


def test_a_points_color_is_averaged_over_its_pixels_footprint():
    """The spread of each visible point's color is COLOR_SPREAD times the side of a pixel at the point's depth: the
    world distance between two points that project one pixel apart there."""
    spec, elevation = ObjectSpec(voxels="v.npz", scale=(0.8, 0.8, 0.8)), 30.0
    surface = visible_surface(geometry_of(cube(24), spec, elevation), SIZE)
    camera = Camera(elevation, width=SIZE, height=SIZE)
    right = camera.camera_to_world()[:3, 0]
    step = 1e-3
    for i in np.linspace(0, len(surface.points) - 1, 5).astype(int):
        point = surface.points[i]
        u0, _, _ = camera.project(point)
        u1, _, _ = camera.project(point + step * right)
        pixel_side = step / float(u1 - u0)
        assert surface.color_spread[i] == pytest.approx(COLOR_SPREAD * pixel_side, rel=1e-3)


def test_an_object_reaching_up_to_the_light_reads_only_the_floor_in_view(monkeypatch):
    """A tall object whose top comes just under the light casts a shadow box that grows without bound (nothing
    clips an object to a grid): the floor's shadows are read only over the floor the camera sees."""
    read = []
    light_visibility = lighting_stage.light_visibility

    def counting(receivers, *args):
        read.append(len(receivers))
        return light_visibility(receivers, *args)

    monkeypatch.setattr(lighting_stage, "light_visibility", counting)
    out = shaded(cube(12), ObjectSpec(voxels="v.npz", scale=(0.3, 2.74, 0.3)), (1.0, 2.75, 0.5), size=48)
    assert np.all(np.isfinite(out.image)) and out.visibility.min() < 0.5  # it does cast a shadow
    floor_side = 2 * FLOOR_HALF_SIZE / FLOOR_SHADOW_STEP + 3
    assert max(read) <= floor_side**2  # unclipped: a box about 130 units wide, 27 million samples


def test_the_fast_quality_samples_less_and_shades_nearly_alike():
    """FAST_QUALITY: one ray per silhouette pixel (its coverage from how deep that ray goes, so edges stay soft),
    2 x 2 light points, normals without the tangent plane's disc and colors of one voxel; the image stays close to
    the full quality's, and differs where those terms act: along the silhouette, in the penumbra, in the shading."""
    spec, light = ObjectSpec(voxels="v.npz", scale=(0.6, 0.6, 0.6)), (0.9, 2.6, 0.4)
    full, fast = (shaded(ball(40), spec, light, quality=q) for q in (FULL_QUALITY, FAST_QUALITY))
    difference = np.abs(fast.image - full.image).max(axis=2)
    assert difference.mean() < 0.01 and difference.max() > 0.02  # close, yet really another sampling
    edge = (full.coverage > 0.0) & (full.coverage < 1.0)
    assert edge.sum() > 20 and ((fast.coverage > 0.0) & (fast.coverage < 1.0)).sum() > 0.5 * edge.sum()
    inside = ndimage.binary_erosion(full.coverage == 1.0, iterations=3)
    np.testing.assert_array_equal(fast.coverage[inside], 1.0)  # one ray or four, the inside is covered
    np.testing.assert_allclose(fast.depth[inside], full.depth[inside], atol=1e-6)  # the surface is the same
    cosine = np.sum(fast.normal[inside] * full.normal[inside], axis=-1)
    assert cosine.min() > np.cos(np.radians(10.0)) and cosine.min() < 1.0 - 1e-6  # a ball's normals, found otherwise
    assert len(light_points(light, FAST_QUALITY.light_points)) == 4
    assert len(light_points(light, FULL_QUALITY.light_points)) == 9


def test_the_fast_quality_lets_every_point_see_the_whole_sky():
    """FAST_QUALITY leaves out the ambient occlusion (through the NVR+ it moved the test split's error by under 2 %):
    every point's sky visibility is 1, so the image is nowhere darker than with the occlusion, and lighter where that
    saw a blocked sky (the floor along the box's foot, its faces near the floor)."""
    spec, light = ObjectSpec(voxels="v.npz", scale=(0.6, 0.6, 0.6)), (0.9, 2.6, 0.4)
    occluded, open_sky = (shaded(cube(16), spec, light, quality=q)
                          for q in (replace(FAST_QUALITY, ambient_occlusion=True), FAST_QUALITY))
    np.testing.assert_array_equal(open_sky.occlusion, 1.0)
    blocked = occluded.occlusion < 0.95
    assert blocked.sum() > 50
    assert np.all(np.isfinite(open_sky.image)) and np.all(open_sky.image >= occluded.image - 1e-6)
    assert (open_sky.image - occluded.image).max(axis=2)[blocked].mean() > 0.01
    np.testing.assert_array_equal(open_sky.coverage, occluded.coverage)  # the rest of the sampling is the same
    # Nothing reads the broad occupancy then, so a geometry for the fast quality leaves it out; asked for an occluded
    # sky, such a geometry says so rather than shading without it.
    factors = shader_pool_factors(16, spec.scale, GRID_SIZE)
    bare = placed(object_geometry(pool_object(cube(16), factors)[0], 16, factors, ambient_occlusion=False), spec, 30.0)
    assert bare.broad is None and geometry_of(cube(16), spec, 30.0).broad is not None
    np.testing.assert_array_equal(visible_surface(bare, SIZE, quality=FAST_QUALITY).images.occlusion, 1.0)
    with pytest.raises(ValueError, match="without occlusion"):
        visible_surface(bare, SIZE, quality=FULL_QUALITY)


def test_the_fast_quality_colors_each_point_by_one_voxel():
    """With no color spread every visible point takes exactly one voxel's color: on a cube of voxels colored at
    random, each albedo is one of the voxels' colors (at the full quality's spread, most are blends of several)."""
    spec, elevation = ObjectSpec(voxels="v.npz", scale=(0.8, 0.8, 0.8)), 30.0
    rgba = cube(24)
    rgba[..., :3] = np.random.default_rng(0).integers(0, 8, rgba.shape[:3] + (3,)) / 7.0
    geometry = geometry_of(rgba, spec, elevation)
    palette = np.arange(8) / 7.0

    def share_of_one_voxel_colors(quality) -> float:
        colors = visible_surface(geometry, SIZE, quality=quality).images.albedo_srgb
        shown = colors[np.any(colors > 0.0, axis=-1)]
        return float(np.all(np.abs(shown[..., None] - palette).min(axis=-1) < 1e-5, axis=-1).mean())

    assert share_of_one_voxel_colors(FAST_QUALITY) >= 1.0
    assert share_of_one_voxel_colors(FULL_QUALITY) < 0.2


@pytest.mark.parametrize("rays, points", [(0, 3), (2, 0), (9, 3), (2, 12)])
def test_a_quality_outside_its_range_is_refused(rays, points):
    with pytest.raises(InputError, match="silhouette rays and light points"):
        ShaderQuality(rays, points)


@pytest.mark.parametrize("rings, spread", [(-1, 0.6), (9, 0.6), (2, -0.1), (2, float("nan")), (2, float("inf"))])
def test_a_normal_disc_or_color_spread_outside_its_range_is_refused(rings, spread):
    with pytest.raises(InputError, match="normal rings .* color spread"):
        ShaderQuality(normal_rings=rings, color_spread=spread)
