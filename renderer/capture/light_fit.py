"""The light a photo was taken under, fitted from the photo itself, with the mesh and its pose known.

The model is the scene's: the square light (its centre free, facing down) plus the uniform ambient light, whose
strength relative to the square light is free too (a real photo's sky is not ours). Each object pixel's shading
is the light's irradiance (cosines over squared distance, shadowed by the mesh, at a few points of the square)
plus the ambient irradiance from the sky (visible where the mesh does not block the way), plus what the floor sends
back up of both lights, as the voxel shader models it (renderer/shading/lighting.py): the colors drawn by the shader
under the fitted light then look as bright as the photo (docs/results.md, "Measurements behind the code"). The light
that explains the photo best leaves the most uniform albedo (photo over shading): the smallest mean absolute
deviation of its log brightness. An object's colors do not follow the light, so shading left in them only adds
spread. (Retinex's sum of log-brightness steps between neighbours did worse: docs/results.md, "Tried and not
adopted".) Written here: no registry package fits a light to a photo of a known mesh; it is ray casting and sums.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from PIL import Image
from scipy import ndimage

from renderer.capture.pose import PhotoPose
from renderer.capture.silhouette import SilhouetteRenderer
from renderer.color import srgb_to_linear
from renderer.errors import InputError
from renderer.photo import albedo_image
from renderer.resample import downscaled, downscaled_mask, resized
from renderer.scene import AMBIENT_RADIANCE, LIGHT_RADIANCE, LIGHT_SIZE, FloorSpec
from renderer.shading.lighting import light_form_factors
from renderer.shading.quality import FLOOR_BELOW_LIT

FIT_SIDE = 128  # long side at which the light is fitted
AMBIENT_RAYS = 48  # cosine-weighted rays per pixel for the sky's visibility
FLOOR_ALBEDO = float(np.mean(srgb_to_linear(np.asarray(FloorSpec().color))))  # the scene's floor, which the captured
# colors are drawn over, and the photo's when its floor's shading does not tell
FLOOR_ALBEDO_RANGE = (0.02, 0.95)  # a photo's floor's estimated albedo is kept within this
FLOOR_ALBEDO_ROUNDS = 3  # the albedo and the gain depend on each other: this many alternations settle them
# The square light sampled at its centre and four points halfway to its corners (soft shadows), as offsets in x, z
LIGHT_POINTS = ((0.0, 0.0), (-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25))
X_RANGE, Y_RANGE, Z_RANGE = (-3.0, 3.0), (2.0, 4.5), (-3.0, 3.0)  # where the light is looked for (world units)
AMBIENT_RANGE = (0.125, 8.0)  # the ambient light's strength relative to the scene's
MIN_PIXELS = 64  # fewer trusted object pixels than this at FIT_SIDE: no fit (fewer floor pixels: no floor term)
FLOOR_REACH = 0.5  # floor pixels count within this many times the object's extent in the image around it
FLOOR_EXPLAINED = 0.6  # ... and only if the fitted light leaves at most this share of their spread: a floor's shading
# left 0.14-0.77 of it on the capture bench's floor photos, photographs behind the object 0.73-1.03, backdrops 50-180
DARK = 0.004  # linear brightness below which a pixel says nothing about its shading
MIN_SHADING_SHARE = 0.02  # the fitted shading is floored at this share of its mean before dividing
MIN_GAIN = 0.02  # the fit explains the photo's shading when it makes the albedo's spread this share smaller
# (a photo without shading, flat colors, has nothing to divide: any light would add spread)


@dataclass(frozen=True)
class FittedLight:
    position: tuple[float, float, float]  # the square light's centre, world units
    ambient: float  # the ambient light's strength relative to the scene's AMBIENT_RADIANCE
    spread: float  # the albedo's mean absolute deviation of log brightness at the fit (object's plus floor's)
    spread_kept: float  # the same for the photo itself (its shading kept), for comparison
    shading: np.ndarray = field(repr=False, compare=False)  # (h, w) irradiance at the fit size, 0 off the object,
    # scaled to the scene's lights' mean there
    floor_share_left: float = float("nan")  # the floor's spread at the fit over its own (nan: the floor not used)
    floor_albedo: float = FLOOR_ALBEDO  # the photo's floor's (mean linear) albedo: estimated when the floor was used,
    # else the scene's; it sets how much light the floor sends up to the object

    @property
    def used_floor(self) -> bool:
        """Whether the floor's shading around the object counted too."""
        return not math.isnan(self.floor_share_left)

    @property
    def explains_photo(self) -> bool:
        """Whether dividing this light out leaves more uniform colors than the photo's own (by MIN_GAIN)."""
        return self.spread <= (1.0 - MIN_GAIN) * self.spread_kept


class _Surface:
    """Points seen in the photo at the fit size (world coordinates, unit normals): the object's, or the floor's
    around it; their ambient visibility, and how to shade them under a light."""

    def __init__(self, silhouettes: SilhouetteRenderer, pose: PhotoPose, points: np.ndarray, normals: np.ndarray):
        self.silhouettes = silhouettes
        self.points, self.normals = points, normals
        self.to_object = pose.world_to_object()
        self.offset = 1e-3  # rays leave the surface this far along its normal (world units)
        self.origins_obj = (points + self.offset * normals) @ self.to_object[:3, :3].T + self.to_object[:3, 3]
        self.sky = self._sky_visibility()
        self.faces_floor = 0.5 * (1.0 - normals[:, 1])  # the share of the floor a point faces, unblocked, as the
        # shader has it (lighting.py); times the floor's albedo, what the floor sends back up

    @classmethod
    def of_object(cls, silhouettes: SilhouetteRenderer, pose: PhotoPose) -> tuple[_Surface, np.ndarray]:
        """The object's pixels, and the (H, W) bool mask of them."""
        hit, points_obj, normals_obj = silhouettes.surface(pose)
        to_world, to_object = pose.object_to_world(), pose.world_to_object()
        normals = normals_obj @ to_object[:3, :3]  # the inverse transpose carries normals
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
        return cls(silhouettes, pose, points_obj @ to_world[:3, :3].T + to_world[:3, 3], normals), hit

    @classmethod
    def of_floor(cls, silhouettes: SilhouetteRenderer, pose: PhotoPose, pixels: np.ndarray) -> _Surface:
        """The floor (y = 0) seen at `pixels` ((H, W) bool; those whose ray does not meet it are left out, as the
        caller's mask must be)."""
        rows, cols = np.nonzero(pixels)
        origin, directions = pose.camera.pixel_rays(cols + 0.5, rows + 0.5)
        t = -origin[1] / np.minimum(directions[:, 1], -1e-9)
        points = origin + t[:, None] * directions
        return cls(silhouettes, pose, points, np.tile([0.0, 1.0, 0.0], (len(points), 1)))

    def _sky_visibility(self) -> np.ndarray:
        """Per pixel, the cosine-weighted share of directions that reach the sky unblocked. Every pixel uses the same
        directions about its normal (a spiral over the disk, projected up), so a flat face gets one value instead of
        noise."""
        sky = np.zeros(len(self.points))
        tangent = np.cross(self.normals, np.where(np.abs(self.normals[:, 1:2]) < 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]]))
        tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
        bitangent = np.cross(self.normals, tangent)
        golden = math.pi * (3.0 - math.sqrt(5.0))
        for k in range(AMBIENT_RAYS):
            r, phi = math.sqrt((k + 0.5) / AMBIENT_RAYS), k * golden
            x, y, z = r * math.cos(phi), r * math.sin(phi), math.sqrt(max(0.0, 1.0 - r * r))
            d = x * tangent + y * bitangent + z * self.normals
            up = d[:, 1] > 0.0
            sky[up] += ~self.silhouettes.occluded(self.origins_obj[up], d[up] @ self.to_object[:3, :3].T)
        return sky / AMBIENT_RAYS

    def direct(self, light: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Irradiance from the square light centred at `light` (world), facing down, per pixel: directly, with
        shadows, and off the floor below the point (FLOOR_BELOW_LIT of it lit, the object's shadow falling there)
        for a floor of albedo 1, to be scaled by the floor's."""
        lights = np.array([light + LIGHT_SIZE * np.array([dx, 0.0, dz]) for dx, dz in LIGHT_POINTS])
        unshadowed, below = np.empty(len(self.points)), np.empty(len(self.points))  # the shader's form factors
        light_form_factors(self.points, self.normals, lights, LIGHT_SIZE**2 / len(lights), unshadowed, below)
        bounced = LIGHT_RADIANCE * FLOOR_BELOW_LIT * below * self.faces_floor
        terms, origins, reaches = [], [], []  # per light point; the shadow rays of all of them cast in one call
        for light_point in lights:
            to_light = light_point - self.points
            distance = np.linalg.norm(to_light, axis=1)
            cos_surface = np.einsum("ij,ij->i", self.normals, to_light) / distance
            cos_light = to_light[:, 1] / distance
            lit = (cos_surface > 0.0) & (cos_light > 0.0)
            terms.append((lit, cos_surface * cos_light / np.maximum(distance, 1e-3) ** 2))
            origins.append(self.origins_obj[lit])
            reaches.append(to_light[lit] @ self.to_object[:3, :3].T)  # to the light point, in object coordinates
        counts = [len(reach) for reach in reaches]
        shadowed = (self.silhouettes.occluded(np.concatenate(origins), np.concatenate(reaches), far=1.0) if sum(counts)
                    else np.zeros(0, dtype=bool))
        total = np.zeros(len(self.points))
        for (lit, term), shadow in zip(terms, np.split(shadowed, np.cumsum(counts)[:-1])):
            lit[np.flatnonzero(lit)[shadow]] = False
            total += np.where(lit, term, 0.0)
        return total / len(LIGHT_POINTS) * LIGHT_RADIANCE * LIGHT_SIZE**2, bounced

    def ambient(self) -> tuple[np.ndarray, np.ndarray]:
        """Irradiance from the uniform ambient light at the scene's strength, per pixel: directly, and off a floor of
        albedo 1."""
        return math.pi * AMBIENT_RADIANCE * self.sky, math.pi * AMBIENT_RADIANCE * self.faces_floor


def fit_light(silhouettes: SilhouetteRenderer, photo_rgb: np.ndarray, pose: PhotoPose,
              trusted: np.ndarray | None = None, background: np.ndarray | None = None) -> FittedLight:
    """The square light (and the ambient light's strength) that best explains the shading of the object (the mesh
    of `silhouettes`) in `photo_rgb` ((H, W, 3) sRGB in [0, 1]) seen at `pose`; `trusted` ((H, W) bool): the pixels surely on the object.
    `background` ((H, W) bool): the pixels surely not on it; where they show the floor near the object, its shading
    (the object's shadow above all) counts too, as a second albedo that should come out uniform, when the fit
    explains it (FLOOR_EXPLAINED).
    InputError when the photo shows too little of the object to tell."""
    h, w = photo_rgb.shape[:2]
    factor = min(1.0, FIT_SIDE / max(h, w))
    size = (max(1, round(w * factor)), max(1, round(h * factor)))
    small_pose = pose.at_size(*size)
    surface, hit = _Surface.of_object(silhouettes, small_pose)
    photo = srgb_to_linear(downscaled(np.asarray(photo_rgb, dtype=np.float64), max(size)))
    brightness = photo.mean(axis=2)
    use = hit & (brightness > DARK)
    if trusted is not None:
        use &= downscaled_mask(np.asarray(trusted, dtype=bool), max(size), min_cover=0.75)
    if use.sum() < MIN_PIXELS:
        raise InputError("the photo shows too little of the object to fit its light")
    parts = [(surface, use[hit], np.log(brightness[use]))]  # (points, those used, their log brightness)
    floor_pixels = _floor_pixels(small_pose, hit, brightness, background, size)
    if floor_pixels.sum() >= MIN_PIXELS:
        parts.append((_Surface.of_floor(silhouettes, small_pose, floor_pixels), slice(None),
                      np.log(brightness[floor_pixels])))
    ambients = [part[0].ambient() for part in parts]
    directs: dict[tuple, tuple[np.ndarray, np.ndarray]] = {}  # a part's direct light by light position: the ambient
    # strength, a third of the start grid and a quarter of the search's probes, changes nothing in it

    def shading(index: int, params: np.ndarray, floor_albedo: float = FLOOR_ALBEDO,
                ambient: float | None = None) -> np.ndarray:
        """A part's irradiance under the light `params`, over a floor of `floor_albedo` (`ambient`: the ambient
        light's strength instead of the one in `params`)."""
        key = (index, *params[:3].tolist())
        if key not in directs:
            directs[key] = parts[index][0].direct(params[:3])
        (straight, bounced), (sky, sky_bounced) = directs[key], ambients[index]
        strength = math.exp(params[3]) if ambient is None else ambient
        return straight + floor_albedo * bounced + strength * (sky + floor_albedo * sky_bounced)

    def spread(params: np.ndarray, count: int) -> float:
        """The albedo's spread over the first `count` parts (the object, and the floor)."""
        return sum(_spread(log_photo - np.log(_floored(shading(i, params)))[used])
                   for i, (_, used, log_photo) in enumerate(parts[:count]))

    params, value = _searched(lambda p: spread(p, len(parts)))
    left = float("nan")  # the floor's spread at the fit over its own
    if len(parts) > 1:
        left = (spread(params, 2) - spread(params, 1)) / max(_spread(parts[1][2]), 1e-9)
        if left > FLOOR_EXPLAINED:  # not a floor this light shades (a backdrop, a photograph): the object alone
            parts, left = parts[:1], float("nan")
            params, value = _searched(lambda p: spread(p, 1))
    # The scene's ambient light is fixed: the shading is scaled by the gain that makes the albedo, drawn under the
    # fitted square light, the scene's ambient light and the scene's floor, as bright as the photo on the object.
    used, photo_used = parts[0][1], np.exp(parts[0][2])
    in_scene = shading(0, params, ambient=1.0)

    def gained(floor_albedo: float) -> tuple[np.ndarray, float]:
        fitted = _floored(shading(0, params, floor_albedo))
        return fitted, float(np.sum(photo_used * in_scene[used] / fitted[used]) / np.sum(photo_used))

    floor_albedo = FLOOR_ALBEDO
    if len(parts) > 1:  # the photo's own floor bounces its light: its albedo is what makes it as bright as its
        # pixels under the light scaled by that gain (the object's albedo and the floor's share the exposure)
        floor_radiance = math.pi * np.exp(parts[1][2]) / _floored(shading(1, params))  # times the floor's albedo
        for _ in range(FLOOR_ALBEDO_ROUNDS):
            floor_albedo = float(np.clip(np.median(floor_radiance) / gained(floor_albedo)[1], *FLOOR_ALBEDO_RANGE))
    fitted, gain = gained(floor_albedo)
    image = np.zeros(hit.shape)
    image[hit] = fitted * gain
    kept = sum(_spread(part_log) for _, _, part_log in parts)
    return FittedLight(tuple(float(v) for v in params[:3]), float(math.exp(params[3])), value, kept, image, left,
                       floor_albedo)


def _searched(spread) -> tuple[np.ndarray, float]:
    """The light and ambient strength (x, y, z, log ambient) of least `spread`: the best of a coarse grid, then a
    compass search (a step each way per number, halved when nothing improves)."""
    best = min(((spread(p), tuple(p)) for p in _start_grid()), key=lambda item: item[0])
    params, value = np.array(best[1]), best[0]
    step = np.array([0.5, 0.4, 0.5, 0.5])
    while step[0] > 0.03:
        improved = False
        for j in range(4):
            for sign in (1.0, -1.0):
                probe = _clipped(params + sign * step * (np.arange(4) == j))
                score = spread(probe)
                if score < value - 1e-9:
                    params, value, improved = probe, score, True
        if not improved:
            step = step / 2.0
    return params, value


def _floor_pixels(pose: PhotoPose, hit: np.ndarray, brightness: np.ndarray, background: np.ndarray | None,
                  size: tuple[int, int]) -> np.ndarray:
    """(H, W) bool at the fit size: background pixels that see the floor within FLOOR_REACH object boxes of the
    object in the image, lit enough to divide."""
    if background is None or not hit.any():
        return np.zeros(hit.shape, dtype=bool)
    pixels = downscaled_mask(np.asarray(background, dtype=bool), max(size), min_cover=1.0) & (brightness > DARK)
    rows, cols = np.nonzero(hit)
    reach_r, reach_c = FLOOR_REACH * (np.ptp(rows) + 1), FLOOR_REACH * (np.ptp(cols) + 1)
    near = np.zeros(hit.shape, dtype=bool)
    near[max(0, int(rows.min() - reach_r)):int(rows.max() + reach_r) + 1,
         max(0, int(cols.min() - reach_c)):int(cols.max() + reach_c) + 1] = True
    pixels &= near
    r, c = np.nonzero(pixels)
    _, directions = pose.camera.pixel_rays(c + 0.5, r + 0.5)
    below = directions[:, 1] < -1e-3  # the ray meets the floor in front of the camera
    keep = np.zeros(hit.shape, dtype=bool)
    keep[r[below], c[below]] = True
    return keep


def light_divided(photo_rgb: np.ndarray, fitted: FittedLight) -> tuple[np.ndarray, np.ndarray]:
    """The photo with the fitted light divided out: the albedo (H, W, 3) sRGB in [0, 1] that the scene's lights,
    the square one placed where it was fitted, would show as bright as the photo on average, and (H, W) bool where it
    is known (on the object, with enough light to divide)."""
    h, w = photo_rgb.shape[:2]
    on_object = fitted.shading > 0.0
    nearest = ndimage.distance_transform_edt(~on_object, return_distances=False, return_indices=True)
    filled = fitted.shading[nearest[0], nearest[1]]  # so that bilinear reads beside the edge mix no zero in
    shading = resized(filled, (w, h), Image.Resampling.BILINEAR).astype(np.float64)
    known = resized(on_object.astype(np.float32), (w, h), Image.Resampling.NEAREST) > 0.5
    known &= shading >= MIN_SHADING_SHARE * fitted.shading[on_object].mean()
    albedo = math.pi * srgb_to_linear(np.asarray(photo_rgb, dtype=np.float64)) / np.maximum(shading, 1e-9)[..., None]
    return albedo_image(albedo, known), known  # clipped to [0, 1] there


def _floored(shading: np.ndarray) -> np.ndarray:
    """Shading floored at MIN_SHADING_SHARE of its mean: a pixel in full shadow divides by a small, finite number."""
    return np.maximum(shading, MIN_SHADING_SHARE * shading.mean() + 1e-9)


def _spread(values: np.ndarray) -> float:
    """Mean absolute deviation from the median."""
    return float(np.mean(np.abs(values - np.median(values))))


def _start_grid() -> list[np.ndarray]:
    """Coarse starts: lights over a grid above the scene, and three ambient strengths."""
    return [np.array([x, y, z, math.log(a)]) for x in np.linspace(*X_RANGE, 5) for z in np.linspace(*Z_RANGE, 5)
            for y in (2.75,) for a in (0.5, 1.0, 2.0)]


def _clipped(params: np.ndarray) -> np.ndarray:
    low = np.array([X_RANGE[0], Y_RANGE[0], Z_RANGE[0], math.log(AMBIENT_RANGE[0])])
    high = np.array([X_RANGE[1], Y_RANGE[1], Z_RANGE[1], math.log(AMBIENT_RANGE[1])])
    return np.clip(params, low, high)
