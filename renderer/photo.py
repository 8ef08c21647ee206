"""Colors from a photo (paper section 3.2): voxels take the colors of the pixels they project to.

The photo is aligned with the object through a Camera of the photo's size (its azimuth and
principal offset place the object in the picture). Visibility comes from ray marching through
the occupancy (renderer/raymarch.py): a surface voxel is visible when the camera sees the
centre of one of its exposed faces and its centre projects inside the photo.

Visible voxels take the photo color at their centre's projection (bilinear); with `mirror`, a
hidden voxel whose mirror voxel across the object's plane x = 0 (i -> N-1-i) is visible copies
that voxel's color. Every other voxel (hidden, or visible only where the photo is not trusted)
takes one of two rules:
- "blend" (the default): a blend of the well-seen voxels' colors around it, a normalized convolution
  whose Gaussian widens (HIDDEN_SIGMAS) until some well-seen voxel is near. Unknown parts get the
  local mean color rather than a guess: on textured objects the paper's rule smears the colors of
  the silhouette's pixels into streaks across faces the photo sees edge-on or not at all.
- "ray" (the paper's section 3.2): the color of the first occupied voxel that the ray from the
  camera through its centre meets; a visible voxel on an untrusted pixel takes the nearest well-seen
  voxel's. Kept for data sets made with it.

A photo shows color times light. When the photo's light is known (the data generator's source images,
a capture with the light given), the light is divided out, so that the voxels carry albedo, as mesh colors and
paint do, rather than a shading the renderers would apply a second time:
- `unmixed_albedo`, with the object's mesh: a pixel of a diffuse object's photo is, to first order, linear in the
  object's albedo, photo = base + albedo * slope. Two path-traced renders of the mesh, black and grey, give the
  base (the floor's share of a silhouette pixel, its reflection) and the slope (the light the object receives, its
  shadows and the light between its parts, exactly as the target images have them).
- `photo_albedo`, from the voxels alone: the light the voxel shader computes for the object under it (its shadows
  and bounce light are approximate, and pixels it does not cover fully are not used).
On the generalisation set's textured photos the first takes the color error on the voxels the photo shows from 708
to 476 (0-255 squared; docs/results.md).
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np
from PIL import Image

from renderer.camera import Camera
from renderer.color import linear_to_srgb, srgb_to_linear
from renderer.dataset_config import check_hidden_rule
from renderer.errors import InputError
from renderer.raymarch import OccupancyMarcher
from renderer.resample import downscaled, resized
from renderer.scene import Scene, replaced
from renderer.surface import check_object_voxels, grid_from_world, occupancy, surface_mask, voxel_centers_at
from renderer.transform import apply_transform

# A symmetric mesh voxelised on the x-symmetric object grid scores about 1; the threshold
# tolerates a few percent of voxels that differ through rounding on thin parts, and rejects
# shapes whose halves differ in a tenth of their volume (one armrest, an off-centre lever).
MIRROR_IOU_THRESHOLD = 0.9
# Dividing out the light: the shading is drawn for a grey object of this linear albedo (headroom to twice the
# light an albedo of 1 would reflect before the sRGB image clips); pixels whose shading is below MIN_SHADING
# (deep shadow, where the photo holds little but noise) or that are not fully covered keep no color of their own.
SHADING_GREY = 0.5
MIN_SHADING = 0.02
# Unmixing with path-traced renders: samples per pixel of each (denoised, as the data's photos are), and the least
# slope (the light a white object would send back) at which a pixel's albedo is trusted.
UNMIX_SPP = 16
MIN_SLOPE = 0.05
# A larger photo is unmixed at this many pixels a side (area averaged) and its albedo scaled back up, since the two
# renders' cost grows with the pixels. (Scaling the renders' light up to the photo instead mixed the floor's light into
# the silhouette's pixels and blurred thin parts' shadows: on 3 of 4 novel objects it colored the seen voxels worse
# than a photo of half the side did.)
UNMIX_MAX_SIDE = 512
# The blend's Gaussians, in voxels: the narrowest whose weight of well-seen voxels reaches HIDDEN_MIN_WEIGHT
# colors a voxel (a plane of well-seen voxels reaches it from 3.3 voxels away at 1.5, 6 at 3, ...); the widest
# colors whatever is left.
HIDDEN_SIGMAS = (1.5, 3.0, 6.0, 12.0, 24.0)
HIDDEN_MIN_WEIGHT = 0.02
HIDDEN_TRUNCATE = 3.0  # the Gaussians reach this many sigmas


class PhotoColors(NamedTuple):
    rgba: np.ndarray  # (N, N, N, 4) float32: the input voxels recolored from the photo
    visible: np.ndarray  # (N, N, N) bool: voxels the photo shows (where color errors can be measured)


def color_voxels_from_photo(object_rgba: np.ndarray, object_to_world_matrix: np.ndarray, photo_rgb: np.ndarray,
                            camera: Camera, mirror: bool = False, trusted: np.ndarray | None = None,
                            hidden_rule: str = "blend") -> PhotoColors:
    """Color every occupied voxel from `photo_rgb` ((H, W, 3) sRGB) seen by `camera`; occupancy is unchanged.

    `trusted` ((H, W) bool): the pixels surely on the object (the mask away from its edge). A visible voxel
    that lands elsewhere is colored like a hidden one, by `hidden_rule` (HIDDEN_RULES), so the background
    around the silhouette never colors the object.
    """
    check_hidden_rule(hidden_rule)
    rgba = check_object_voxels(object_rgba).copy()
    photo = _check_photo(photo_rgb, camera)
    if hidden_rule == "blend":
        return _blended_colors(rgba, np.asarray(object_to_world_matrix, dtype=np.float64), photo, camera, mirror, trusted)
    occupied = occupancy(rgba)
    n = occupied.shape[0]
    matrix = np.asarray(object_to_world_matrix, dtype=np.float64)
    marcher = OccupancyMarcher(occupied)
    camera_grid = apply_transform(grid_from_world(matrix, n), camera.position)

    visible = marcher.visible_from(camera_grid) & _in_frame(occupied, matrix, camera)
    source = np.arange(n**3, dtype=np.int32).reshape(n, n, n)  # flat index of the voxel whose photo color each voxel takes
    hidden = occupied & ~visible
    if mirror:
        mirrored = hidden & visible[::-1]
        source[mirrored] = source[::-1][mirrored]
        hidden &= ~mirrored
    hidden_flat = np.flatnonzero(hidden)
    source.reshape(-1)[hidden_flat] = marcher.first_occupied_towards(camera_grid, hidden_flat)

    if trusted is not None:
        source = _trusted_sources(source, visible, occupied, matrix, camera, np.asarray(trusted, dtype=bool))
    rgba[occupied, :3] = _photo_at_voxels(photo, matrix, camera, source[occupied], n)
    return PhotoColors(rgba, visible)


def _blended_colors(rgba: np.ndarray, matrix: np.ndarray, photo: np.ndarray, camera: Camera, mirror: bool,
                    trusted: np.ndarray | None) -> PhotoColors:
    """The "blend" rule: well-seen voxels (visible, on a trusted pixel) take their pixel's color, their hidden
    mirror voxels copy it (with `mirror`), every other voxel the blend of well-seen colors around it."""
    occupied = occupancy(rgba)
    n = occupied.shape[0]
    camera_grid = apply_transform(grid_from_world(matrix, n), camera.position)
    visible = OccupancyMarcher(occupied).visible_from(camera_grid) & _in_frame(occupied, matrix, camera)
    well_seen = visible.copy()
    if trusted is not None:
        flat = np.flatnonzero(visible)
        col, row = _pixel_of_voxels(matrix, camera, flat, n)
        well_seen.reshape(-1)[flat] = np.asarray(trusted, dtype=bool)[row, col]
    if not well_seen.any():
        well_seen = visible  # nothing is sure: keep what the photo shows rather than nothing
    colors = np.zeros((n, n, n, 3), dtype=np.float32)
    colors[well_seen] = _photo_at_voxels(photo, matrix, camera, np.flatnonzero(well_seen), n)
    known = well_seen.copy()
    if mirror:
        mirrored = occupied & ~known & known[::-1]
        colors[mirrored] = colors[::-1][mirrored]
        known |= mirrored
    todo = occupied & ~known
    # (weight, weight * color) of the well-seen voxels; the mirror copies add no information of their own
    sums = np.concatenate([well_seen[..., None], colors * well_seen[..., None]], axis=3).astype(np.float32)
    pooled: dict[int, np.ndarray] = {}
    for sigma in HIDDEN_SIGMAS:
        if not todo.any() or not well_seen.any():
            break
        index = np.nonzero(todo)
        blurred = _pooled_blur(sums, sigma, index, pooled)
        total = blurred[:, 0]
        take = (total >= HIDDEN_MIN_WEIGHT) if sigma < HIDDEN_SIGMAS[-1] else (total > 0)
        where = tuple(i[take] for i in index)
        colors[where] = blurred[take, 1:] / total[take, None]
        todo[where] = False
    if todo.any():  # beyond the widest blend's reach: the mean of every well-seen color
        colors[todo] = colors[well_seen].mean(axis=0) if well_seen.any() else 0.0
    rgba[occupied, :3] = np.clip(colors[occupied], 0.0, 1.0)
    return PhotoColors(rgba, visible)


def _pooled_blur(sums: np.ndarray, sigma: float, index: tuple[np.ndarray, ...],
                 pooled: dict[int, np.ndarray]) -> np.ndarray:
    """The Gaussian blur (sigma in voxels) of the (N, N, N, C) `sums`, read at the voxels `index` (as np.nonzero
    gives them; (M, C)). Wide blurs run on sums pooled in blocks of about sigma / 3 voxels (the same weights, a
    coarser grid): the blend needs their smooth trend only, and the full-size blur would cost 20 times more at sigma
    24. `pooled` keeps the pooled grids by block size between calls. Only the box around the voxels read, grown by
    the kernel's reach, is blurred: the values read are the whole grid's blur, bit for bit."""
    from scipy import ndimage

    block = max(1, int(sigma // 3))
    grid = _block_means(sums, block, pooled)
    width = sigma / block
    reach = int(HIDDEN_TRUNCATE * width + 0.5)  # scipy's kernel radius
    at = [i // block for i in index]
    low = [max(0, int(a.min()) - reach) for a in at]
    high = [min(n, int(a.max()) + reach + 1) for a, n in zip(at, grid.shape)]
    box = grid[low[0]:high[0], low[1]:high[1], low[2]:high[2]]
    blurred = ndimage.gaussian_filter(box, (width,) * 3 + (0,), truncate=HIDDEN_TRUNCATE)
    return blurred[at[0] - low[0], at[1] - low[1], at[2] - low[2]]


def _block_means(sums: np.ndarray, block: int, pooled: dict[int, np.ndarray]) -> np.ndarray:
    """`sums` (N, N, N, C) averaged over blocks of `block`^3 voxels (zero past the grid's end), from the coarsest
    grid in `pooled` whose block divides `block` (a mean of equal blocks' means is the mean)."""
    if block == 1:
        return sums
    if block not in pooled:
        base = max((b for b in pooled if block % b == 0), default=1)
        grid = sums if base == 1 else pooled[base]
        factor = block // base
        for axis in range(3):
            n = grid.shape[axis]
            padded = -(-n // factor) * factor
            if padded != n:
                pad = [(0, 0)] * grid.ndim
                pad[axis] = (0, padded - n)
                grid = np.pad(grid, pad)
            shape = grid.shape[:axis] + (padded // factor, factor) + grid.shape[axis + 1:]
            grid = grid.reshape(shape).mean(axis=axis + 1, dtype=np.float32)
        pooled[block] = grid
    return pooled[block]


def photo_albedo(photo_rgb: np.ndarray, scene: Scene, object_rgba: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A photo taken by `scene`'s camera of the object voxels `object_rgba`, placed and lit as in `scene`, with the
    light divided out: the albedo (H, W, 3) sRGB in [0, 1], and (H, W) bool where it is known (the object covers
    the pixel fully, the light there is strong enough to divide, the shading did not clip). Elsewhere the albedo
    is that of the nearest pixel where it is known (0 if none is); pass the mask to color_voxels_from_photo as
    `trusted`."""
    from renderer.shading.shader import shade_scene  # numba kernels: loaded only when a light is divided out

    camera = Camera.from_scene(scene)
    photo = _check_photo(photo_rgb, camera)
    grey = check_object_voxels(object_rgba).copy()
    occupied = occupancy(grey)
    grey[..., :3] = np.where(occupied[..., None], np.float32(linear_to_srgb(SHADING_GREY)), np.float32(0.0))
    # A pixel where one part is drawn over another mixes both in the photo: it must not count as covered.
    shaded = shade_scene(scene, grey, scene.floor.color, cover_behind=False, reflection=False)
    shading = srgb_to_linear(shaded.image.astype(np.float64)) / SHADING_GREY
    known = (shaded.coverage >= 1.0) & (shading.min(axis=2) >= MIN_SHADING) & (shaded.image.max(axis=2) < 1.0)
    return albedo_image(srgb_to_linear(photo) / np.maximum(shading, MIN_SHADING), known), known


def unmixed_albedo(photo_rgb: np.ndarray, scene: Scene, mesh, spp: int = UNMIX_SPP, seed: int = 0,
                   max_side: int = UNMIX_MAX_SIDE) -> tuple[np.ndarray, np.ndarray]:
    """A photo taken by `scene`'s camera of `mesh` (object coordinates, a trimesh.Trimesh), placed and lit as in
    `scene`, with the light unmixed: the albedo (H, W, 3) sRGB in [0, 1], and (H, W) bool where it is known (the
    object sends back at least MIN_SLOPE of the light and the photo did not clip in every channel), solving
    photo = base + albedo * slope per pixel from two path-traced renders of the mesh, black and grey. A photo over
    `max_side` pixels a side is unmixed at that side and its results scaled back up. Elsewhere as photo_albedo."""
    from renderer.pathtrace.path_tracer import PathTracer, denoise_layers  # Mitsuba: loaded only when used

    camera = Camera.from_scene(scene)
    photo = _check_photo(photo_rgb, camera)
    if camera.width > max_side:
        albedo, known = unmixed_albedo(downscaled(photo, max_side), replace(scene, image_size=max_side), mesh, spp,
                                       seed, max_side)
        size = (camera.width, camera.height)
        return (np.clip(resized(albedo, size, Image.Resampling.BILINEAR), 0.0, 1.0),
                resized(known.astype(np.float32), size, Image.Resampling.NEAREST) > 0.5)

    def render(albedo_linear: float) -> np.ndarray:
        srgb = float(linear_to_srgb(albedo_linear))
        colored = replaced(scene, object=replace(scene.object, color=(srgb, srgb, srgb)))
        return denoise_layers(PathTracer(colored, mesh).render_layers(spp, seed)).astype(np.float64)

    base = render(0.0)
    slope = (render(SHADING_GREY) - base) / SHADING_GREY
    # A channel that clipped still bounds its albedo from below, far closer than a neighbour's color (a bright
    # orange's red clips under a strong light); a pixel that clipped in all three says nothing.
    known = (slope.min(axis=2) >= MIN_SLOPE) & (photo.min(axis=2) < 1.0)
    return albedo_image((srgb_to_linear(photo) - base) / np.maximum(slope, MIN_SLOPE), known), known


def albedo_image(albedo_linear: np.ndarray, known: np.ndarray) -> np.ndarray:
    """sRGB float32 albedo in [0, 1] where `known`; elsewhere the nearest known pixel's (bilinear reads beside a
    known pixel then mix no unknown one), 0 if none is known."""
    albedo = albedo_linear
    if known.any() and not known.all():
        from scipy import ndimage

        nearest = ndimage.distance_transform_edt(~known, return_distances=False, return_indices=True)
        albedo = albedo[nearest[0], nearest[1]]
    elif not known.any():
        albedo = np.zeros_like(albedo)
    return np.clip(linear_to_srgb(np.clip(albedo, 0.0, 1.0)), 0.0, 1.0).astype(np.float32)


def _trusted_sources(source: np.ndarray, visible: np.ndarray, occupied: np.ndarray, matrix: np.ndarray, camera: Camera,
                     trusted: np.ndarray) -> np.ndarray:
    """`source` with every voxel whose source projects outside `trusted` sent to the nearest trusted visible voxel."""
    from scipy import ndimage

    n = occupied.shape[0]
    flat = np.flatnonzero(visible)
    col, row = _pixel_of_voxels(matrix, camera, flat, n)
    good = np.zeros(occupied.size, dtype=bool)
    good[flat[trusted[row, col]]] = True
    if not good.any():
        return source  # nothing is sure: keep what the photo shows rather than nothing
    _, nearest = ndimage.distance_transform_edt(~good.reshape(occupied.shape), return_indices=True)
    nearest_flat = np.ravel_multi_index(tuple(nearest), occupied.shape).reshape(-1)
    out = source.reshape(-1).copy()
    bad = occupied.reshape(-1) & ~good[out]
    out[bad] = nearest_flat[out[bad]]
    return out.reshape(source.shape)


def mirror_symmetry_score(occupied: np.ndarray) -> float:
    """Intersection over union of the occupancy and its mirror image i -> N-1-i (1 for an empty grid)."""
    occ = np.asarray(occupied, dtype=bool)
    union = np.count_nonzero(occ | occ[::-1])
    return 1.0 if union == 0 else np.count_nonzero(occ & occ[::-1]) / union


def is_mirror_symmetric(occupied: np.ndarray, threshold: float = MIRROR_IOU_THRESHOLD) -> bool:
    """Whether copying colors across the plane x = 0 fits this shape (mirror IoU at least `threshold`)."""
    return mirror_symmetry_score(occupied) >= threshold


def _in_frame(occupied: np.ndarray, matrix: np.ndarray, camera: Camera) -> np.ndarray:
    """(N, N, N) bool: surface voxels whose centre projects inside the photo, in front of the camera."""
    n = occupied.shape[0]
    flat = np.flatnonzero(surface_mask(occupied))
    u, v, depth = _project_voxels(matrix, camera, flat, n)
    inside = (depth > 0) & (u >= 0) & (u < camera.width) & (v >= 0) & (v < camera.height)
    frame = np.zeros(occupied.size, dtype=bool)
    frame[flat[inside]] = True
    return frame.reshape(occupied.shape)


def _pixel_of_voxels(matrix: np.ndarray, camera: Camera, flat: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Column and row of the pixel each given voxel's centre projects into (clamped to the photo)."""
    u, v, _ = _project_voxels(matrix, camera, flat, n)
    col = np.clip(np.floor(u).astype(np.int64), 0, camera.width - 1)
    row = np.clip(np.floor(v).astype(np.int64), 0, camera.height - 1)
    return col, row


def _project_voxels(matrix: np.ndarray, camera: Camera, flat: np.ndarray, n: int):
    """Pixel coordinates u, v and depth of the centres of the voxels with the given flat indices."""
    centres = voxel_centers_at(np.stack(np.unravel_index(flat, (n, n, n)), axis=1), n)
    return camera.project(apply_transform(matrix, centres))


def _photo_at_voxels(photo: np.ndarray, matrix: np.ndarray, camera: Camera, flat: np.ndarray, n: int) -> np.ndarray:
    """Bilinear photo colors at the projections of the given voxels' centres (clamped at the border)."""
    unique, inverse = np.unique(flat, return_inverse=True)
    u, v, _ = _project_voxels(matrix, camera, unique, n)
    return _bilinear(photo, u, v)[inverse]


def _bilinear(image: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear samples of `image` at pixel coordinates (u, v); pixel centres sit at half-integers."""
    h, w = image.shape[:2]
    x = np.clip(u - 0.5, 0.0, w - 1.0)
    y = np.clip(v - 0.5, 0.0, h - 1.0)
    x0 = np.floor(x).astype(np.int64)
    y0 = np.floor(y).astype(np.int64)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    top = image[y0, x0] * (1 - fx) + image[y0, x1] * fx
    bottom = image[y1, x0] * (1 - fx) + image[y1, x1] * fx
    return (top * (1 - fy) + bottom * fy).astype(np.float32)


def _check_photo(photo_rgb: np.ndarray, camera: Camera) -> np.ndarray:
    """The photo as float (H, W, 3) sRGB clipped to [0, 1]; InputError if it does not fit the camera."""
    photo = np.asarray(photo_rgb)
    if photo.ndim != 3 or photo.shape[2] != 3:
        raise InputError(f"the photo must be an RGB image of shape (H, W, 3), got shape {photo.shape}")
    if photo.shape[:2] != (camera.height, camera.width):
        raise InputError(f"the photo is {photo.shape[1]}x{photo.shape[0]} pixels but its camera is "
                         f"{camera.width}x{camera.height}")
    values = photo.astype(np.float64)
    if not np.all(np.isfinite(values)):
        raise InputError("the photo holds NaN or infinite values")
    return np.clip(values, 0.0, 1.0)
