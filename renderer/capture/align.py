"""Find the pose of a photo: the object rotation, camera elevation, floor position and scale whose
rendered silhouette best overlaps the object's mask in the photo (intersection over union).

1. Coarse: every rotation and elevation on a grid (or a window around a given pose), each
   silhouette compared with the photo's mask after matching their centroids and sizes, so the
   grid need not cover position and scale.
2. The best few distinct candidates get a position and scale that put their silhouette's
   centroid and area where the photo's are (a few Gauss-Newton steps).
3. Local refinement of all five numbers by compass search on the IoU: try a step up and
   down in each, keep what improves, halve the steps when nothing does.
All of it at a reduced photo size; the result is the pose at the photo's own size.

A photo without an alpha channel has only a segmented mask, wrong where object and background share
colors; `refine_by_colors` then refines a pose by the same compass search on how well its silhouette
separates the photo's colors (renderer/capture/color_fit.py), the mesh's shape deciding the boundary.
With `disk`, each silhouette is joined by the disk on the floor under the object that best fits the mask (a
saucer or a plate segmented with the object), and the coarse search proposes poses scored with one too.
With a box, `search_in_box` needs no mask at all: every rotation and elevation of a coarse grid is
placed by the box and scored by the colors, and the best few are refined on that score.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from renderer.camera import Camera
from renderer.capture.color_fit import color_separation, quantised_colors
from renderer.capture.pose import PhotoPose, photo_camera
from renderer.capture.silhouette import SilhouetteRenderer

COARSE_SIDE = 64  # long side of the masks compared in the coarse search, pixels
EARLY_SIDE = 96  # ... in the first refinement of every candidate
REFINE_SIDE = 160  # ... and in the final refinement
CANONICAL_SIDE = 48  # side of the centroid-and-size normalised frame of the coarse comparison
CANONICAL_REACH = 3.0  # the normalised frame spans +-3 square roots of the mask's area
FULL_ROTATIONS = np.arange(-180.0, 180.0, 10.0)
FULL_ELEVATIONS = np.arange(0.0, 81.0, 5.0)
WINDOW_ROTATION_DEG = 40.0  # coarse window around a given pose
WINDOW_ELEVATION_DEG = 30.0
WINDOW_STEP_DEG = 5.0
MAX_ELEVATION_DEG = 85.0
CANDIDATES = 6  # distinct coarse poses refined
FINALISTS = 2  # candidates refined to the end
DISTINCT_ROTATION_DEG = 25.0
DISTINCT_ELEVATION_DEG = 15.0
# Parameters: rotation (deg), elevation (deg), translation x, z (object units), log of the scale factor
# (and, with a free focal length, the log of its factor).
INITIAL_STEPS = np.array([6.0, 4.0, 0.03, 0.05, 0.05])
FINAL_STEPS = np.array([0.25, 0.25, 0.002, 0.003, 0.003])
FOCAL_STEP, FOCAL_FINAL_STEP = 0.05, 0.003  # log of the focal length factor, when it is free
LENSES_MM = (24.0, 32.0, 40.0, 55.0, 80.0)  # focal lengths tried first when it is free
EARLY_HALVINGS = 2  # compass halvings every candidate gets before the finalists are chosen
DISK_RADII = (1.0, 2.0)  # a disk under the object (a saucer, a plate), when modelled, spans this many footprint radii
DISK_COARSE_RADII = (1.25, 1.6, 2.0)  # ... of which these are tried in the coarse search
DISK_CANDIDATES = 3  # coarse poses with a disk refined beside the CANDIDATES without one
BOX_ROTATIONS = np.arange(-180.0, 180.0, 20.0)  # the grid of the search in a box, every pose placed and scored
BOX_ELEVATIONS = np.arange(0.0, 81.0, 10.0)
BOX_CANDIDATES = 4  # distinct poses of that grid refined
BOX_MARGIN = 1.1  # a user's box is about this much larger than the object (the bench's boxes: 1.04-1.16)
PLACEMENT_MASK_WEIGHT = 3.0  # refine_placement scores the colors plus this times the IoU with the mask
OUTSIDE_BOX_WEIGHT = 2.0  # the score loses this times the silhouette's share outside the box: the object is
# inside it, and over a whole window a silhouette drifted onto a distinct background patch can separate colors better


@dataclass(frozen=True)
class Alignment:
    pose: PhotoPose  # at the photo's size
    iou: float  # silhouette overlap at the refinement size
    rays: int  # silhouette rays cast
    seconds: float
    mask: np.ndarray | None = None  # the photo's object mask the pose was fitted to
    floor_disk: float = 0.0  # radius (object units) of a disk under the object that the mask holds too (a saucer)


def align_pose(silhouettes: SilhouetteRenderer, photo_mask: np.ndarray, initial: PhotoPose | None = None,
               free_focal: bool = False, focal_35mm: float | None = None, disk: bool = False) -> Alignment:
    """The pose whose silhouette best overlaps `photo_mask` ((H, W) bool).

    `initial`: a rough pose to start from (searches a window around it); None searches all
    rotations and elevations with the scene camera, or with the lens `focal_35mm` (35 mm equivalent, from the photo's
    EXIF). `free_focal`: the last refinement also fits the focal length (for photos not taken with that lens).
    `disk`: the mask may hold a disk the object stands on (a saucer, a plate), so each silhouette is scored joined by
    the disk that fits best (`disk_iou`), and the result says its radius.
    """
    start = time.perf_counter()
    rays_before = silhouettes.rays_cast
    h, w = photo_mask.shape
    base = initial if initial is not None else PhotoPose(photo_camera(w, h, focal_35mm))
    base = base.at_size(w, h)
    coarse, early, fine = (_Problem(silhouettes, _resize_mask(photo_mask, min(side, max(h, w))), base, disk)
                           for side in (COARSE_SIDE, EARLY_SIDE, REFINE_SIDE))

    candidates = _coarse_candidates(coarse, initial)
    refined = []
    for candidate in candidates:
        params = early.place(candidate[:5], disk_ratio=candidate[5])
        refined.append(early.compass(params, INITIAL_STEPS, INITIAL_STEPS / 2**EARLY_HALVINGS))
    refined.sort(key=lambda item: -item[1])
    steps, final_steps = INITIAL_STEPS / 2**EARLY_HALVINGS, FINAL_STEPS
    starts = [params for params, _ in refined[:FINALISTS]]
    if free_focal:
        # The lens changes only the perspective, which a local search follows poorly: try a few
        # lenses on the best pose, each placed again, and let the last search fine-tune the lens.
        lenses = [math.log(focal / base.camera.focal_mm) for focal in LENSES_MM]
        starts = [fine.place(np.append(refined[0][0], lens)) for lens in lenses]
        steps, final_steps = np.append(steps, FOCAL_STEP), np.append(final_steps, FOCAL_FINAL_STEP)
    finals = [fine.compass(params, steps, final_steps, coupled=True) for params in starts]
    best_params, best_iou = max(finals, key=lambda item: item[1])
    pose = fine.pose(best_params).at_size(w, h)
    return Alignment(pose, float(best_iou), silhouettes.rays_cast - rays_before, time.perf_counter() - start, photo_mask,
                     fine.disk_radius(best_params))


def refine_by_colors(silhouettes: SilhouetteRenderer, photo_rgb: np.ndarray, pose: PhotoPose, photo_mask: np.ndarray,
                     region: np.ndarray | None = None, free_focal: bool = False) -> Alignment:
    """`pose` refined by the colors its silhouette separates in `photo_rgb` ((H, W, 3)) within `region` ((H, W) bool;
    None: the whole photo). `photo_mask`, the photo's segmented object, only gives the reported IoU (and is kept
    as the alignment's mask). `free_focal`: the focal length is refined too."""
    return _refine(silhouettes, photo_rgb, pose, photo_mask, region, free_focal, mask_weight=0.0, first_steps=0.5,
                   rotation=True)


def refine_placement(silhouettes: SilhouetteRenderer, photo_rgb: np.ndarray, pose: PhotoPose, photo_mask: np.ndarray,
                     region: np.ndarray | None = None, free_focal: bool = False) -> Alignment:
    """`pose`'s elevation, position and scale (and lens, with `free_focal`) refined, its rotation kept, on the colors its
    silhouette separates within `region` plus PLACEMENT_MASK_WEIGHT times its IoU with `photo_mask`; a short search
    from `pose`. The colors settle the rotation where a mask cut from clutter is wrong, but leave elevation and size
    loose, which a mask pins; letting the mask move the rotation too pulled it towards the mask's errors (docs/results.md, "Measurements behind the code")."""
    return _refine(silhouettes, photo_rgb, pose, photo_mask, region, free_focal, mask_weight=PLACEMENT_MASK_WEIGHT,
                   first_steps=0.25, rotation=False)


def _refine(silhouettes: SilhouetteRenderer, photo_rgb: np.ndarray, pose: PhotoPose, photo_mask: np.ndarray,
            region: np.ndarray | None, free_focal: bool, mask_weight: float, first_steps: float,
            rotation: bool) -> Alignment:
    """Compass search from `pose` on the colors plus `mask_weight` times the IoU with `photo_mask`, its first steps
    `first_steps` times INITIAL_STEPS; the rotation stays unless `rotation`. Scale and lens are relative to `pose`."""
    start = time.perf_counter()
    rays_before = silhouettes.rays_cast
    h, w = photo_mask.shape
    side = min(REFINE_SIDE, max(h, w))
    problem = _ColorProblem(silhouettes, _resize_mask(photo_mask, side), pose.at_size(w, h), photo_rgb,
                            None if region is None else _resize_mask(region, side), mask_weight)
    params = np.array([pose.rotation_deg, pose.camera.elevation_deg, *pose.translation, 0.0])
    steps, final_steps = INITIAL_STEPS * first_steps, FINAL_STEPS
    if not rotation:
        steps[0] = 0.0  # a zero step leaves the parameter where it is
    if free_focal:
        params, steps, final_steps = (np.append(params, 0.0), np.append(steps, FOCAL_STEP * first_steps),
                                      np.append(final_steps, FOCAL_FINAL_STEP))
    params, _ = problem.compass(params, steps, final_steps)
    found = problem.pose(params)
    iou = silhouette_iou(silhouettes.mask(found), problem.target)
    return Alignment(found.at_size(w, h), float(iou), silhouettes.rays_cast - rays_before, time.perf_counter() - start,
                     photo_mask)


def search_in_box(silhouettes: SilhouetteRenderer, photo_rgb: np.ndarray, box: tuple[float, float, float, float],
                  region: np.ndarray, photo_mask: np.ndarray, free_focal: bool = False,
                  initial: PhotoPose | None = None, focal_35mm: float | None = None) -> Alignment:
    """The pose whose silhouette best separates `photo_rgb`'s colors within `region` ((H, W) bool) while staying
    inside `box` (x0, y0, x1, y1 pixels of the photo), found without a mask: each pose of a coarse grid of
    rotations and elevations is placed so its bounding box fills the box, scored by `in_box_score`, and the best
    distinct ones are refined on it. A mask cut from clutter can miss the object's shape entirely (a thin chair
    over a busy photo); this search only needs the box to hold the object. `photo_mask` only gives the reported
    IoU (and is kept as the alignment's mask), as in `refine_by_colors`. `initial`: a rough pose, whose window of
    rotations and elevations (as in `align_pose`) is searched instead of all of them; `focal_35mm` as in `align_pose`."""
    start = time.perf_counter()
    rays_before = silhouettes.rays_cast
    h, w = photo_rgb.shape[:2]
    base = PhotoPose(photo_camera(w, h, focal_35mm))
    coarse, early, fine = (_BoxProblem(silhouettes, photo_rgb, box, region, base, side)
                           for side in (COARSE_SIDE, EARLY_SIDE, REFINE_SIDE))
    rotations, elevations = BOX_ROTATIONS, BOX_ELEVATIONS
    if initial is not None:
        rotations, elevations = _window(initial, WINDOW_STEP_DEG)
    scored = []
    for rotation in rotations:
        for elevation in elevations:
            params = coarse.place(np.array([rotation, elevation, 0.0, 0.0, 0.0]), iterations=2)
            scored.append((coarse.score(params), params))
    scored.sort(key=lambda item: -item[0])
    chosen = _distinct([params for _, params in scored], BOX_CANDIDATES)
    refined = sorted((early.compass(early.place(params, iterations=2), INITIAL_STEPS, INITIAL_STEPS / 2**EARLY_HALVINGS)
                      for params in chosen), key=lambda item: -item[1])
    steps, final_steps = INITIAL_STEPS / 2**EARLY_HALVINGS, FINAL_STEPS
    starts = [params for params, _ in refined[:FINALISTS]]
    if free_focal:
        starts = [np.append(params, 0.0) for params in starts]
        steps, final_steps = np.append(steps, FOCAL_STEP), np.append(final_steps, FOCAL_FINAL_STEP)
    best_params, _ = max((fine.compass(params, steps, final_steps) for params in starts), key=lambda item: item[1])
    iou = silhouette_iou(fine.mask(best_params), _resize_mask(photo_mask, max(fine.target.shape)))
    return Alignment(fine.pose(best_params).at_size(w, h), float(iou), silhouettes.rays_cast - rays_before,
                     time.perf_counter() - start, photo_mask)


def in_box_score(silhouettes: SilhouetteRenderer, photo_rgb: np.ndarray, box: tuple[float, float, float, float],
                 region: np.ndarray, pose: PhotoPose) -> float:
    """What `search_in_box` maximises, for one pose: the color separation of its silhouette within `region`, less
    OUTSIDE_BOX_WEIGHT times its share outside `box`; at REFINE_SIDE, so poses found in different ways compare."""
    h, w = photo_rgb.shape[:2]
    problem = _BoxProblem(silhouettes, photo_rgb, box, region, PhotoPose(Camera(elevation_deg=0.0, width=w, height=h)),
                          REFINE_SIDE)
    height, width = problem.target.shape
    return problem.score_mask(silhouettes.mask(pose.at_size(width, height)))


def disk_iou(mask: np.ndarray, target: np.ndarray, radii: np.ndarray, min_radius: float,
             max_radius: float) -> tuple[float, float]:
    """The best IoU of `mask` joined by a disk on the floor with `target`, and the disk's radius (0: no disk).
    `radii` ((H, W)): where each pixel's ray meets the floor, as SilhouetteRenderer.floor_radii gives it; the disk's
    radius is 0 or in [min_radius, max_radius]."""
    inter0, union0 = np.count_nonzero(mask & target), np.count_nonzero(mask | target)
    best = (1.0 if union0 == 0 else inter0 / union0, 0.0)
    free = ~mask & (radii <= max_radius)
    r, inside = radii[free], target[free]
    if len(r) == 0:
        return best
    order = np.argsort(r, kind="stable")
    r, inside = r[order], inside[order]
    ious = (inter0 + np.cumsum(inside)) / (union0 + np.cumsum(~inside))
    ious = np.where(r >= min_radius, ious, -1.0)
    k = int(np.argmax(ious))
    if ious[k] > best[0]:
        best = (float(ious[k]), float(r[k]))
    return best


def silhouette_iou(a: np.ndarray, b: np.ndarray) -> float:
    """Intersection over union of two boolean masks (1 when both are empty)."""
    union = np.count_nonzero(a | b)
    return 1.0 if union == 0 else np.count_nonzero(a & b) / union


def rotation_error_deg(a: float, b: float) -> float:
    """Smallest angle between two rotations about the vertical axis, in [0, 180]."""
    return abs((a - b + 180.0) % 360.0 - 180.0)


class _Problem:
    """The photo's mask at one size and the silhouettes to compare with it, as a function of 5 numbers."""

    def __init__(self, silhouettes: SilhouetteRenderer, target: np.ndarray, base: PhotoPose, disk: bool = False):
        self.silhouettes = silhouettes
        self.target = target
        self.disk = disk  # the silhouette is joined by the disk under it that fits best
        h, w = target.shape
        self.base = base.at_size(w, h)
        self.target_moments = self.moments(target)
        self._scores: dict[bytes, float] = {}  # score by parameters: a compass search comes back to points it scored

    def pose(self, params: np.ndarray) -> PhotoPose:
        rotation, elevation, tx, tz, log_scale = params[:5]
        factor = math.exp(log_scale)
        # A free focal length moves the camera with it (a dolly zoom): the object keeps its size in
        # the image and only the perspective changes, so the lens is not a second scale parameter.
        lens = math.exp(params[5]) if len(params) > 5 else 1.0
        camera = replace(self.base.camera, elevation_deg=float(elevation), focal_mm=self.base.camera.focal_mm * lens,
                         distance=self.base.camera.distance * lens)
        return replace(self.base, camera=camera,
                       rotation_deg=float(rotation), translation=(float(tx), float(tz)),
                       scale=tuple(float(s * factor) for s in self.base.scale))

    def mask(self, params: np.ndarray) -> np.ndarray:
        return self.silhouettes.mask(self.pose(params))

    def moments(self, mask: np.ndarray) -> tuple[float, float, float] | None:
        """What `place` matches between a silhouette and the target: centroid and square root of the area."""
        return _moments(mask)

    def iou(self, params: np.ndarray) -> float:
        if not self.disk:
            return silhouette_iou(self.mask(params), self.target)
        return self._disk_iou(params)[0]

    def disk_radius(self, params: np.ndarray) -> float:
        """The radius of the disk that joins the silhouette (object units; 0: none)."""
        return self._disk_iou(params)[1] if self.disk else 0.0

    def _disk_iou(self, params: np.ndarray) -> tuple[float, float]:
        pose = self.pose(params)
        low, high = (ratio * self.silhouettes.footprint_radius for ratio in DISK_RADII)
        return disk_iou(self.silhouettes.mask(pose), self.target, self.silhouettes.floor_radii(pose, high), low, high)

    def score(self, params: np.ndarray) -> float:
        """What the compass search maximises: here the IoU with the photo's mask."""
        return self.iou(params)

    def _remembered_score(self, params: np.ndarray) -> float:
        key = params.tobytes()
        if key not in self._scores:
            self._scores[key] = self.score(params)
        return self._scores[key]

    def place(self, params: np.ndarray, iterations: int = 3, disk_ratio: float = 0.0) -> np.ndarray:
        """Translation and scale that put the silhouette's `moments` on the target's (Gauss-Newton); with
        `disk_ratio`, of the silhouette joined by a disk that many footprint radii wide under it."""
        params = np.array(params, dtype=np.float64)
        deltas = np.array([0.02, 0.02, 0.02])

        def moments(params):
            if disk_ratio <= 0.0:
                return self.moments(self.mask(params))
            pose = self.pose(params)
            radius = disk_ratio * self.silhouettes.footprint_radius
            disk = self.silhouettes.floor_radii(pose, radius) <= radius
            return self.moments(self.silhouettes.mask(pose) | disk)

        for _ in range(iterations):
            current = moments(params)
            if current is None or self.target_moments is None:
                return params
            jacobian = np.zeros((3, 3))
            for j in range(3):
                probe = params.copy()
                probe[2 + j] += deltas[j]
                moved = moments(probe)
                if moved is None:
                    return params
                jacobian[:, j] = (np.array(moved) - np.array(current)) / deltas[j]
            step, *_ = np.linalg.lstsq(jacobian, np.array(self.target_moments) - np.array(current), rcond=None)
            params[2:5] = _clip_placement(params[2:5] + np.clip(step, -0.5, 0.5))
        return params

    def compass(self, params: np.ndarray, steps: np.ndarray, final_steps: np.ndarray,
                coupled: bool = False) -> tuple[np.ndarray, float]:
        """Compass search on the score from `params` until every step is below `final_steps`. `coupled`: an
        elevation step that does not improve is tried again with the silhouette placed anew (`place`, one step):
        elevation, depth and scale move a silhouette together, and one at a time they stall a low view's search."""
        params = np.array(params, dtype=np.float64)
        best = self._remembered_score(params)
        steps = np.array(steps, dtype=np.float64)
        while np.any(steps >= final_steps):
            improved = False
            for j in range(len(params)):
                for sign in (1.0, -1.0):
                    probe = params.copy()
                    probe[j] += sign * steps[j]
                    probe = _clip_params(probe)
                    if np.array_equal(probe, params):
                        continue
                    value = self._remembered_score(probe)
                    if coupled and j == 1 and value <= best:
                        probe = self.place(probe, iterations=1)
                        value = self._remembered_score(probe)
                    if value > best:
                        params, best, improved = probe, value, True
                        break
            if not improved:
                steps = steps / 2.0
        return params, best


class _ColorProblem(_Problem):
    """The same five numbers scored by the colors the silhouette separates in the photo, within a region, plus
    `mask_weight` times the silhouette's IoU with the target mask."""

    def __init__(self, silhouettes: SilhouetteRenderer, target: np.ndarray, base: PhotoPose, photo_rgb: np.ndarray,
                 region: np.ndarray | None, mask_weight: float = 0.0):
        super().__init__(silhouettes, target, base)
        self.bins = quantised_colors(photo_rgb, target.shape)
        self.region = region
        self.mask_weight = mask_weight

    def score(self, params: np.ndarray) -> float:
        mask = self.mask(params)
        return color_separation(mask, self.bins, self.region) + self.mask_weight * silhouette_iou(mask, self.target)


class _BoxProblem(_ColorProblem):
    """The colors' score within a box the object lies in, at `side` pixels on the photo's long side; `place`
    fits the silhouette's bounding box to the box (there is no mask to match)."""

    def __init__(self, silhouettes: SilhouetteRenderer, photo_rgb: np.ndarray, box: tuple[float, float, float, float],
                 region: np.ndarray, base: PhotoPose, side: int):
        h, w = photo_rgb.shape[:2]
        side = min(side, max(h, w))
        factor = side / max(h, w)
        shape = (max(1, round(h * factor)), max(1, round(w * factor)))
        x0, y0, x1, y1 = (v * factor for v in box)
        super().__init__(silhouettes, np.zeros(shape, dtype=bool), base, photo_rgb, _resize_mask(region, side))
        self.target_moments = ((x0 + x1) / 2.0, (y0 + y1) / 2.0,
                               math.sqrt(max(x1 - x0, 1.0) * max(y1 - y0, 1.0)) / BOX_MARGIN)
        self.in_box = np.zeros(shape, dtype=bool)
        self.in_box[max(0, math.floor(y0)):max(0, math.ceil(y1)), max(0, math.floor(x0)):max(0, math.ceil(x1))] = True

    def moments(self, mask: np.ndarray) -> tuple[float, float, float] | None:
        """The centre of the mask's bounding box and the square root of its area, in pixels; None when empty."""
        rows, cols = np.nonzero(mask.any(axis=1))[0], np.nonzero(mask.any(axis=0))[0]
        if len(rows) == 0:
            return None
        (r0, r1), (c0, c1) = (rows[0], rows[-1] + 1), (cols[0], cols[-1] + 1)
        return (c0 + c1) / 2.0, (r0 + r1) / 2.0, math.sqrt((c1 - c0) * (r1 - r0))

    def score(self, params: np.ndarray) -> float:
        return self.score_mask(self.mask(params))

    def score_mask(self, mask: np.ndarray) -> float:
        area = np.count_nonzero(mask)
        if area == 0:
            return -OUTSIDE_BOX_WEIGHT
        outside = np.count_nonzero(mask & ~self.in_box) / area
        return color_separation(mask, self.bins, self.region) - OUTSIDE_BOX_WEIGHT * outside


def _coarse_candidates(problem: _Problem, initial: PhotoPose | None) -> list[np.ndarray]:
    """The best distinct (rotation, elevation) of the coarse grid, as the five parameters and the radius (in footprint
    radii, 0: none) of the disk under the object they were scored with; with a disk, DISK_CANDIDATES more."""
    if initial is None:
        rotations, elevations = FULL_ROTATIONS, FULL_ELEVATIONS
        start_placement = np.zeros(3)
    else:
        rotations, elevations = _window(initial, WINDOW_STEP_DEG)
        start_placement = np.array([*initial.translation, 0.0])
    target = _canonical(problem.target)
    reach = max(DISK_COARSE_RADII) * problem.silhouettes.footprint_radius  # the widest disk tried
    scored, disked = [], []
    for rotation in rotations:
        for elevation in elevations:
            params = np.array([rotation, elevation, *start_placement])
            pose = problem.pose(params)
            mask = problem.silhouettes.mask(pose)
            value = silhouette_iou(_canonical(mask), target)
            if problem.disk:
                radii = problem.silhouettes.floor_radii(pose, reach) / problem.silhouettes.footprint_radius
                disked.append(max((silhouette_iou(_canonical(mask | (radii <= ratio)), target), ratio, tuple(params))
                                  for ratio in DISK_COARSE_RADII))
            scored.append((value, params))
    scored.sort(key=lambda item: -item[0])
    chosen = [np.append(params, 0.0) for params in _distinct([params for _, params in scored], CANDIDATES)]
    if problem.disk:
        disked.sort(key=lambda item: -item[0])
        chosen = _distinct(chosen + [np.array([*params, ratio]) for _, ratio, params in disked],
                           CANDIDATES + DISK_CANDIDATES)
    return chosen


def _window(initial: PhotoPose, step: float) -> tuple[np.ndarray, np.ndarray]:
    """The rotations and elevations, `step` degrees apart, within the search window around a rough pose."""
    rotations = initial.rotation_deg + np.arange(-WINDOW_ROTATION_DEG, WINDOW_ROTATION_DEG + 1e-9, step)
    e = initial.camera.elevation_deg
    elevations = np.arange(max(0.0, e - WINDOW_ELEVATION_DEG), min(MAX_ELEVATION_DEG, e + WINDOW_ELEVATION_DEG) + 1e-9, step)
    return rotations, elevations


def _distinct(ranked: list[np.ndarray], count: int) -> list[np.ndarray]:
    """The first `count` of `ranked` parameter vectors that differ from every one taken before in rotation or elevation."""
    chosen: list[np.ndarray] = []
    for params in ranked:
        if all(rotation_error_deg(params[0], c[0]) >= DISTINCT_ROTATION_DEG or
               abs(params[1] - c[1]) >= DISTINCT_ELEVATION_DEG for c in chosen):
            chosen.append(params)
        if len(chosen) == count:
            break
    return chosen


def _moments(mask: np.ndarray) -> tuple[float, float, float] | None:
    """Centroid (u, v) and square root of the area of a mask, in pixels; None when empty."""
    area = np.count_nonzero(mask)
    if area == 0:
        return None
    v, u = np.nonzero(mask)
    return float(u.mean()), float(v.mean()), math.sqrt(area)


def _canonical(mask: np.ndarray) -> np.ndarray:
    """The mask resampled into a frame centred on its centroid and scaled by the square root of its area."""
    moments = _moments(mask)
    if moments is None:
        return np.zeros((CANONICAL_SIDE, CANONICAL_SIDE), dtype=bool)
    cu, cv, size = moments
    q = (np.arange(CANONICAL_SIDE) + 0.5) / CANONICAL_SIDE * 2.0 - 1.0
    u = np.floor(cu + q * CANONICAL_REACH * size).astype(np.int64)
    v = np.floor(cv + q * CANONICAL_REACH * size).astype(np.int64)
    h, w = mask.shape
    inside = (v[:, None] >= 0) & (v[:, None] < h) & (u[None, :] >= 0) & (u[None, :] < w)
    return inside & mask[np.clip(v, 0, h - 1)[:, None], np.clip(u, 0, w - 1)[None, :]]


def _resize_mask(mask: np.ndarray, long_side: int) -> np.ndarray:
    """A boolean mask resized so its long side is `long_side` (area average, then majority)."""
    from PIL import Image

    h, w = mask.shape
    if long_side == max(h, w):
        return np.asarray(mask, dtype=bool)
    factor = long_side / max(h, w)
    size = (max(1, round(w * factor)), max(1, round(h * factor)))
    image = Image.fromarray(np.asarray(mask, dtype=np.uint8) * 255)
    return np.asarray(image.resize(size, Image.Resampling.BOX)) >= 128


def _clip_placement(placement: np.ndarray) -> np.ndarray:
    return np.clip(placement, [-5.0, -5.0, -1.5], [5.0, 5.0, 1.5])


def _clip_params(params: np.ndarray) -> np.ndarray:
    out = params.copy()
    out[1] = np.clip(out[1], 0.0, MAX_ELEVATION_DEG)
    out[2:5] = _clip_placement(out[2:5])
    if len(out) > 5:  # log focal factor: lenses from about 15 to 180 mm around the 40 mm default
        out[5] = np.clip(out[5], -1.0, 1.5)
    return out
