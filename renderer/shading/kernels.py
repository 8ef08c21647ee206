"""Compiled loops of the voxel shader (numba, cached on disk): rays through fields, shadow maps, occlusion,
and the image's last passes (compositing, the network's buffers).

numpy would need every ray's steps as arrays of (rays x steps); these loops stop each ray where it
hits and skip empty space by the distance field, so their work follows the object, not the grid.
Coordinates are a crop's voxel coordinates: voxel (i, j, k) spans [i, i+1) x [j, j+1) x [k, k+1),
its centre at (i + 0.5, j + 0.5, k + 0.5).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from renderer.resample import bilinear_at

FAR = np.float32(3.0e38)
MAP_PARTS = 2  # shares of the occluders each shadow map is drawn from in parallel (build_shadow_maps)
SOFT_SHADOW_TAPS = 4  # per side: samples of a light point's square of the shadow map (light_visibility)
HIT_GAP = 0.02  # a ray stops where its gap (how far outside the surface) falls below this
STEP_MIN = 0.3  # voxels: the least step a sphere-traced ray takes (near a surface its gap is tiny)
EXIT_GAP = 0.5  # voxels outside the surface a ray must get past a grazed part before a part behind it counts
EMPTY_DISTANCE2 = np.float32(1e20)  # squared distance from a line with nothing occupied (any transform stays below)


@njit(cache=True, inline="always")
def _cell(n0, n1, n2, x, y, z):
    """The voxel centres around crop coordinates (x, y, z), clamped to the crop's edge voxels: the lower and upper
    indices per axis and the weights of the upper ones."""
    x = min(max(x - 0.5, 0.0), n0 - 1.000001)
    y = min(max(y - 0.5, 0.0), n1 - 1.000001)
    z = min(max(z - 0.5, 0.0), n2 - 1.000001)
    i, j, k = int(x), int(y), int(z)
    return i, j, k, min(i + 1, n0 - 1), min(j + 1, n1 - 1), min(k + 1, n2 - 1), x - i, y - j, z - k


@njit(cache=True, inline="always")
def sample(field, x, y, z):
    """Trilinear sample of `field` at crop coordinates (x, y, z); clamped to the crop's edge voxels."""
    i, j, k, i1, j1, k1, fx, fy, fz = _cell(field.shape[0], field.shape[1], field.shape[2], x, y, z)
    c00 = field[i, j, k] * (1 - fz) + field[i, j, k1] * fz
    c01 = field[i, j1, k] * (1 - fz) + field[i, j1, k1] * fz
    c10 = field[i1, j, k] * (1 - fz) + field[i1, j, k1] * fz
    c11 = field[i1, j1, k] * (1 - fz) + field[i1, j1, k1] * fz
    return (c00 * (1 - fy) + c01 * fy) * (1 - fx) + (c10 * (1 - fy) + c11 * fy) * fx


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


@njit(cache=True, inline="always")
def sample_pair(fields, x, y, z):
    """`sample` of both fields of (n0, n1, n2, 2) `fields` at once (the same weights, neighbouring memory)."""
    i, j, k, i1, j1, k1, fx, fy, fz = _cell(fields.shape[0], fields.shape[1], fields.shape[2], x, y, z)
    return (_blend(fields, 0, i, j, k, i1, j1, k1, fx, fy, fz), _blend(fields, 1, i, j, k, i1, j1, k1, fx, fy, fz))


@njit(cache=True, inline="always")
def _blend(fields, f, i, j, k, i1, j1, k1, fx, fy, fz):
    """Field `f` of `fields` interpolated between the eight voxel centres of a `_cell`."""
    c00 = fields[i, j, k, f] * (1 - fz) + fields[i, j, k1, f] * fz
    c01 = fields[i, j1, k, f] * (1 - fz) + fields[i, j1, k1, f] * fz
    c10 = fields[i1, j, k, f] * (1 - fz) + fields[i1, j, k1, f] * fz
    c11 = fields[i1, j1, k, f] * (1 - fz) + fields[i1, j1, k1, f] * fz
    return (c00 * (1 - fy) + c01 * fy) * (1 - fx) + (c10 * (1 - fy) + c11 * fy) * fx


@njit(cache=True, inline="always")
def _gap(fields, level, thin, x, y, z):
    """How far (in voxels of distance) a point lies outside the surface; negative inside. `fields`: distance, core."""
    distance, core = sample_pair(fields, x, y, z)
    return distance - max(level, core + thin)


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
    reach a surface behind it (within HIT_GAP, or stepping inside) in 256 steps:
    that ray is covered by the object, not by the floor (else a bright floor fringe outlines a part in front of
    another). The rays are traced RAY_GROUP at a time in step."""
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
                    gap = _gap(fields, level, thin, origin[0] + at * dx, origin[1] + at * dy, origin[2] + at * dz)
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
                    if _gap(fields, level, thin, origin[0] + middle * dx, origin[1] + middle * dy,
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
                    gap = _gap(fields, level, thin, origin[0] + at * dx, origin[1] + at * dy, origin[2] + at * dz)
                    if left[i] and gap < HIT_GAP:
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
def _field_normal(gradient, x, y, z):
    """The unit vector of the (n0, n1, n2, 3) `gradient` field read trilinearly at (x, y, z) (zeros where it is 0)."""
    i, j, k, i1, j1, k1, fx, fy, fz = _cell(gradient.shape[0], gradient.shape[1], gradient.shape[2], x, y, z)
    gx = _blend(gradient, 0, i, j, k, i1, j1, k1, fx, fy, fz)
    gy = _blend(gradient, 1, i, j, k, i1, j1, k1, fx, fy, fz)
    gz = _blend(gradient, 2, i, j, k, i1, j1, k1, fx, fy, fz)
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


@njit(cache=True, parallel=True)
def pack_buffers(image, albedo, normal, depth, visibility, occlusion, coverage, depth_offset, depth_scale, out):
    """out[r, c] = image, albedo, normal (3 each), (depth - depth_offset) * depth_scale (0 where nothing is covered),
    visibility, occlusion, coverage: a network's buffers side by side in one pass, instead of numpy's concatenation."""
    for r in prange(out.shape[0]):
        for c in range(out.shape[1]):
            for k in range(3):
                out[r, c, k] = image[r, c, k]
                out[r, c, 3 + k] = albedo[r, c, k]
                out[r, c, 6 + k] = normal[r, c, k]
            out[r, c, 9] = (depth[r, c] - depth_offset) * depth_scale if coverage[r, c] > 0.0 else 0.0
            out[r, c, 10] = visibility[r, c]
            out[r, c, 11] = occlusion[r, c]
            out[r, c, 12] = coverage[r, c]
