"""Capture an object's appearance from a photo: find (or read) the photo's pose, then color the
object's voxels from the pixels they project to (renderer/photo.py).

The pose comes from a camera file, from the automatic search (renderer/capture/align.py) on the
object's mask in the photo (renderer/capture/segment.py), or from both: the file's pose refined
by the search. When the pose knows the photo's light and its camera is the scene camera (a square photo
on the scene camera's orbit, as the data generator and the editor take them), the light is divided out of
the colors (renderer.photo.unmixed_albedo with the object's mesh, photo_albedo without), as the training data's are.
When the light is unknown (every real photo), it is fitted from the photo's shading of the mesh
(renderer/capture/light_fit.py) and divided out, unless the caller turns that off; the colors then keep the shading.
What stands in front of the object or under it (a rod, a saucer) gives no colors (`foreign_pixels`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import trimesh
from PIL import Image
from scipy import ndimage

from renderer.capture.align import (
    Alignment,
    align_pose,
    in_box_score,
    refine_by_colors,
    refine_placement,
    search_in_box,
    silhouette_iou,
)
from renderer.capture.color_fit import LEVELS, quantised_colors
from renderer.capture.grabcut import Hints, context_window
from renderer.capture.light_fit import FittedLight, fit_light, light_divided
from renderer.capture.pose import PhotoPose, lit_photo_scene
from renderer.capture.segment import OPAQUE, object_mask
from renderer.capture.silhouette import SilhouetteRenderer
from renderer.errors import InputError
from renderer.limits import DEFAULT_RESOLUTION
from renderer.photo import (
    color_voxels_from_photo,
    is_mirror_symmetric,
    mirror_symmetry_score,
    photo_albedo,
    unmixed_albedo,
)
from renderer.resample import downscaled, downscaled_mask
from renderer.scene import CameraSpec, ObjectSpec, Scene, validate
from renderer.voxels import ProgressCallback

ASPECT_TOLERANCE = 0.01  # a photo resized from its camera's size keeps the aspect ratio within this
TRUST_MARGIN = 0.01  # colors come from pixels at least this share of the photo's shorter side inside the mask
SEGMENT_SIDE = 320  # long side at which the photo is segmented and aligned (the colors use the full photo)
LOOSE_FIT_IOU = 0.9  # a found pose whose silhouette overlaps the photo's mask less than this was fitted to a poor
# mask (0.80-0.88 on four cluttered photos searched without a box; 0.94 on a path-traced floor photo aligned right)
SEGMENT_ROUNDS = 2  # segmentations restarted from the found pose's silhouette, each followed by a pose refinement
ROUND_FIT_DROP = 0.1  # a segmentation round whose best fit is this much looser than the last round's broke the mask
# (docs/results.md, "Measurements behind the code")
SEARCH_SHARE, LIGHT_SHARE = 0.75, 0.85  # the progress a capture reports: the search's share of it, then the light
# fit's share of what follows (docs/results.md, "Measurements behind the code")
DISK_GAIN = 0.03  # a search with a disk under the object (a saucer) replaces a loose fit when its IoU is this much higher
FOREIGN_ODDS = 2.0  # a color this many times likelier on what stands beside the object than on it is not the object's
MIN_FOREIGN_PIXELS = 20  # fewer pixels than this beside the silhouette say nothing


@dataclass(frozen=True)
class Capture:
    pose: PhotoPose  # at the photo's size
    rgba: np.ndarray  # (N, N, N, 4) object voxels with the photo's colors
    visible: np.ndarray  # (N, N, N) bool: voxels the photo shows
    mirror_score: float  # IoU of the occupancy with its mirror across x = 0
    mirror_used: bool  # hidden voxels copied their mirror voxel's color
    alignment: Alignment | None  # the search's result; None when the camera file alone gave the pose
    light_note: str  # whether the photo's light was divided out of the colors, and if not why
    fitted_light: FittedLight | None = None  # the light fitted from the photo, when it was


def find_pose(mesh: trimesh.Trimesh, photo_rgb: np.ndarray, alpha: np.ndarray | None = None,
              initial: PhotoPose | None = None, path: str | Path | None = None, free_focal: bool = False,
              box: tuple[int, int, int, int] | None = None, object_strokes: np.ndarray | None = None,
              background_strokes: np.ndarray | None = None, focal_35mm: float | None = None,
              progress: ProgressCallback | None = None, silhouettes: SilhouetteRenderer | None = None) -> Alignment:
    """Search the pose of `mesh` (object coordinates) in the photo; `initial` narrows the search around a rough
    pose; `box` (x0, y0, x1, y1 photo pixels) says where the object is; `focal_35mm`, the lens the photo's EXIF
    states (35 mm equivalent), replaces the scene camera's 40 mm when there is no `initial` pose.

    Without an alpha channel, segmentation and pose search alternate: the first pose's silhouette starts
    the next segmentation (GrabCut with it as prior), whose mask refines the pose, SEGMENT_ROUNDS times. With a
    box, each search is followed by a refinement on the colors the silhouette separates around the box (a mask
    cut from clutter is wrong where object and background share colors; the mesh's shape is not). Then a search on those
    colors alone, placed by the box (align.search_in_box), replaces the pose where it scores higher: it finds
    objects whose mask GrabCut got wrong in shape; from
    an `initial` pose it searches only the window around it, on align_pose's 5-degree grid (searching every
    rotation had turned some photos started near the truth far off: docs/results.md, "Measurements behind the code").
    Last, elevation, position and scale are refined on the colors and the last mask together, the rotation kept.
    Without a box the mask alone decides: on floor photos the colors changed little, and a photo's floor and sky are what GrabCut separates well; a cluttered photo
    without a box or strokes is refused before the search (segment.object_mask: GrabCut from the frame's middle cuts
    out whatever stands there). The result's mask is the last segmentation, at the photo's size.
    `progress` gets the share done, in [0, 1]. `silhouettes`: the mesh's, when the caller has built them already.
    """
    report = progress or (lambda _share: None)
    h, w = photo_rgb.shape[:2]
    small_rgb, small_alpha = _downscale(photo_rgb, alpha, SEGMENT_SIDE)
    sh, sw = small_rgb.shape[:2]
    hints = photo_hints((sw, sh), (w, h), box, object_strokes, background_strokes)
    mask = object_mask(small_rgb, small_alpha, path, hints)
    report(0.1)
    start = None if initial is None else initial.at_size(sw, sh)
    silhouettes = silhouettes or SilhouetteRenderer(mesh)
    alignment = align_pose(silhouettes, mask, start, free_focal, focal_35mm)
    rays, seconds = alignment.rays, alignment.seconds
    # A loose fit may be a saucer or a plate under the object in the mask: from here on the searches model a disk there
    # (only then: searching with one every time doubled a floor photo's search; docs/results.md, "Measurements behind
    # the code")
    disk = small_alpha is None and alignment.iou < LOOSE_FIT_IOU
    if disk:
        on_disk = align_pose(silhouettes, mask, start, free_focal, focal_35mm, disk=True)
        rays, seconds = rays + on_disk.rays, seconds + on_disk.seconds
        if on_disk.floor_disk > 0.0 and on_disk.iou >= alignment.iou + DISK_GAIN:
            alignment = on_disk
    by_colors = small_alpha is None and hints.box is not None
    rounds = SEGMENT_ROUNDS if small_alpha is None else 0
    searched_share = 0.7 if by_colors else 1.0  # with a box, the search on the colors takes the rest
    report(0.1 + (searched_share - 0.1) / (1 + rounds))
    if by_colors:
        region = np.zeros((sh, sw), dtype=bool)
        region[context_window(hints.box, sh, sw)] = True  # the colors are compared where GrabCut modelled them
    for round_ in range(rounds + 1 if small_alpha is None else 0):
        if round_ > 0:
            try:
                new_mask = object_mask(small_rgb, None, path, replace(hints, prior=_found_shape(silhouettes, alignment)))
            except InputError:
                break  # the pose's silhouette gave nothing better: keep the pose found
            found = align_pose(silhouettes, new_mask, alignment.pose, free_focal, disk=disk)
            rays, seconds = rays + found.rays, seconds + found.seconds
            if not by_colors and found.iou < alignment.iou - ROUND_FIT_DROP:
                break  # no pose fits the new mask as well as the last pose fitted its mask: keep those
            mask, alignment = new_mask, found
        if by_colors:
            alignment = refine_by_colors(silhouettes, small_rgb, alignment.pose, mask, region, free_focal)
            rays, seconds = rays + alignment.rays, seconds + alignment.seconds
        report(0.1 + (searched_share - 0.1) * (round_ + 1) / (1 + rounds))
    if by_colors:  # the search that needs no mask: it wins where its pose separates the colors in the box better
        found = search_in_box(silhouettes, small_rgb, hints.box, region, mask, free_focal, start, focal_35mm)
        rays, seconds = rays + found.rays, seconds + found.seconds
        scores = [in_box_score(silhouettes, small_rgb, hints.box, region, a.pose) for a in (alignment, found)]
        if scores[1] > scores[0]:
            silhouette = silhouettes.mask(found.pose)
            try:
                mask = object_mask(small_rgb, None, path, replace(hints, prior=silhouette))
            except InputError:
                mask = silhouette
            alignment = replace(found, iou=silhouette_iou(silhouette, mask))
        # The colors alone leave elevation and size loose; the last mask (cut with the pose's silhouette as prior)
        # pins them. Letting it move the rotation too pulled the rotation towards the mask's errors (the capture
        # bench's 60 boxed photographs from no pose: rotation 2.2 deg that way, 1.7 this way; elevation 1.5 and 1.8).
        alignment = refine_placement(silhouettes, small_rgb, alignment.pose, mask, region, free_focal)
        rays, seconds = rays + alignment.rays, seconds + alignment.seconds
    report(1.0)
    return Alignment(alignment.pose.at_size(w, h), alignment.iou, rays, seconds, mask_at_size(mask, (w, h)),
                     alignment.floor_disk)


def _found_shape(silhouettes: SilhouetteRenderer, alignment: Alignment) -> np.ndarray:
    """The found pose's silhouette joined by the disk under the object the search found with it (a saucer)."""
    silhouette = silhouettes.mask(alignment.pose)
    if alignment.floor_disk > 0.0:
        silhouette |= silhouettes.floor_radii(alignment.pose, alignment.floor_disk) <= alignment.floor_disk
    return silhouette


def disk_note(alignment: Alignment) -> str:
    """What the user should know of a saucer or plate the search found under the object ('' when none)."""
    if alignment.floor_disk <= 0.0:
        return ""
    return "the object stands on a saucer or a plate, whose pixels give no colors"


def fit_advice(alignment: Alignment, hinted: bool) -> str | None:
    """What to do when the found pose fits the photo's mask loosely (None when it fits well)."""
    if alignment.iou >= LOOSE_FIT_IOU:
        return None
    if hinted:
        return (f"the silhouette fits the photo's mask loosely (IoU {alignment.iou:.2f}): look at the mask and mark "
                "what it gets wrong with object or background strokes (editor: Photo tab)")
    return (f"the silhouette fits the photo's mask loosely (IoU {alignment.iou:.2f}): the mask may miss part of the "
            "object (a grey part on a grey floor) or take in background; check the pose, and if it is off, draw a box "
            "around the object (Photo tab, or nvr capture --box x0,y0,x1,y1) or mark the mask's errors with strokes")


def photo_hints(small: tuple[int, int], full: tuple[int, int], box=None, object_strokes=None,
                background_strokes=None) -> Hints:
    """The user's box and strokes (photo pixels) at the segmentation's size `small` (width, height)."""
    (sw, sh), (w, _) = small, full

    def shrunk(strokes: np.ndarray | None) -> np.ndarray | None:
        if strokes is None:
            return None
        pooled = Image.fromarray(np.asarray(strokes, dtype=np.float32)).resize((sw, sh), Image.Resampling.BOX)
        return np.asarray(pooled) > 0.25  # a pixel mostly stroked keeps the stroke

    return Hints(box=None if box is None else tuple(round(v * sw / w) for v in box),
                 object_strokes=shrunk(object_strokes), background_strokes=shrunk(background_strokes))


def segment_photo(photo_rgb: np.ndarray, alpha: np.ndarray | None = None, path: str | Path | None = None,
                  silhouette: np.ndarray | None = None, **hints) -> np.ndarray:
    """The object's mask at the photo's size, segmented at SEGMENT_SIDE with the user's hints (box, strokes) and
    the object's `silhouette` at a known pose (photo size) as prior."""
    h, w = photo_rgb.shape[:2]
    small_rgb, small_alpha = _downscale(photo_rgb, alpha, SEGMENT_SIDE)
    sh, sw = small_rgb.shape[:2]
    small_hints = photo_hints((sw, sh), (w, h), **hints)
    if silhouette is not None:  # thin parts kept (a metal chair base lost from a 1024^2 photo's prior was colored wood)
        small_hints = replace(small_hints, prior=downscaled_mask(silhouette, SEGMENT_SIDE))
    return mask_at_size(object_mask(small_rgb, small_alpha, path, small_hints), (w, h))


def mask_at_size(mask: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """A (H, W) bool mask resized to `size` (width, height), nearest pixel."""
    return np.asarray(Image.fromarray(mask.astype(np.uint8) * 255).resize(size, Image.Resampling.NEAREST)) > 127


def capture_appearance(object_rgba: np.ndarray, mesh: trimesh.Trimesh | None, photo_rgb: np.ndarray,
                       alpha: np.ndarray | None = None, pose: PhotoPose | None = None, search: bool = True,
                       path: str | Path | None = None, free_focal: bool = False, mask: np.ndarray | None = None,
                       light: tuple[float, float, float] | None = None, fit_photo_light: bool = True,
                       focal_35mm: float | None = None, progress: ProgressCallback | None = None,
                       **hints) -> Capture:
    """Color `object_rgba` (voxels of `mesh`) from the photo.

    `pose` alone (search False) is used as given; with `search` it is the start of the search;
    without a pose the search covers every rotation and elevation. A pose made for another size
    of the same photo is scaled to it; another aspect ratio is an error. Colors come from pixels well
    inside the object's mask: `mask` when given, else the search's last segmentation, else the photo
    segmented with the user's `hints` (box, strokes: see find_pose) and the pose's silhouette (when `mesh`
    is given). `light` (world), when given, is the photo's light; else the pose's, if it knows one; else, with
    `fit_photo_light` and a mesh, the light is fitted from the photo and divided out. `focal_35mm`: see find_pose.
    `progress` gets the share done, in [0, 1].
    """
    report = progress or (lambda _share: None)
    if pose is None and not search:
        raise InputError("a photo needs a camera file or the automatic alignment", path)
    h, w = photo_rgb.shape[:2]
    if pose is not None and abs(pose.camera.width * h - pose.camera.height * w) > ASPECT_TOLERANCE * pose.camera.width * h:
        raise InputError(f"the photo is {w}x{h} pixels but its camera is {pose.camera.width}x{pose.camera.height}", path)
    alignment = None
    silhouettes = None if mesh is None else SilhouetteRenderer(mesh)  # built once: search, segmentation, occluders, light
    if search:
        alignment = find_pose(mesh, photo_rgb, alpha, pose, path, free_focal, focal_35mm=focal_35mm,
                              progress=lambda share: report(SEARCH_SHARE * share), silhouettes=silhouettes, **hints)
        pose = replace(alignment.pose, light=None if pose is None else pose.light)
        mask = alignment.mask if mask is None else mask
    if light is not None:
        pose = replace(pose, light=tuple(float(v) for v in light))
    pose = pose.at_size(w, h)
    silhouette = None if silhouettes is None else silhouettes.mask(pose)
    if mask is None:
        try:
            mask = segment_photo(photo_rgb, alpha, path, silhouette=silhouette, **hints)
        except InputError:
            mask = None  # nothing separates: every pixel the object projects to counts
    occupied = object_rgba[..., 3] > 0.5
    score = mirror_symmetry_score(occupied)
    mirror = is_mirror_symmetric(occupied)
    trusted = trusted_pixels(mask)
    if trusted is not None and silhouette is not None and (alpha is None or not np.any(alpha < OPAQUE)):  # a cut
        trusted &= ~foreign_pixels(photo_rgb, mask, silhouette)
    fitted = None
    done = SEARCH_SHARE if search else 0.0
    report(done)
    try:
        light_scene = lit_photo_scene(pose)
        light_note = f"the photo's light at {list(pose.light)} divided out"
    except InputError as exc:
        light_scene, light_note = None, f"{exc.problem}: colors keep its shading"
    if pose.light is None and fit_photo_light and mesh is not None:
        cut = mask is not None and (alpha is None or not np.any(alpha < OPAQUE))
        background = ~ndimage.binary_dilation(mask, iterations=2) if cut else None  # what a cut says is not the object
        try:
            fitted = fit_light(silhouettes, photo_rgb, pose, trusted, background)
        except InputError as exc:
            light_note = f"{exc.problem}: colors keep its shading"
        if fitted is not None and not fitted.explains_photo:
            fitted, light_note = None, "no light explains the photo's shading: colors keep it"
        if fitted is not None:
            photo_rgb, known = light_divided(photo_rgb, fitted)
            trusted = known if trusted is None else trusted & known
            light_note = (f"the photo's light fitted at [{', '.join(f'{v:.2f}' for v in fitted.position)}], ambient "
                          f"x{fitted.ambient:.2f}, and divided out")
        report(done + LIGHT_SHARE * (1.0 - done))
    try:
        if light_scene is not None:  # the mesh's path-traced light where there is a mesh (renderer/photo.py)
            photo_rgb, known = (photo_albedo(photo_rgb, light_scene, object_rgba) if mesh is None
                                else unmixed_albedo(photo_rgb, light_scene, mesh))
            trusted = known if trusted is None else trusted & known
        colors = color_voxels_from_photo(object_rgba, pose.object_to_world(), photo_rgb, pose.camera, mirror=mirror,
                                         trusted=trusted)
    except InputError as exc:
        raise InputError(exc.problem, path) from None
    report(1.0)
    return Capture(pose, colors.rgba, colors.visible, score, mirror, alignment, light_note, fitted)


def foreign_pixels(photo_rgb: np.ndarray, mask: np.ndarray, silhouette: np.ndarray) -> np.ndarray:
    """Pixels inside the object's `silhouette` at its pose that show something else: a rod in front of it, the
    saucer under it. What the segmented `mask` holds beyond the silhouette (by more than a margin) is such a thing,
    not the object; inside the silhouette, a pixel whose color (quantised as color_fit's) is FOREIGN_ODDS times
    likelier among those pixels than among the silhouette's is taken for it. (H, W) bool."""
    h, w = mask.shape
    margin = max(1, round(TRUST_MARGIN * min(h, w)))
    beyond = mask & ~ndimage.binary_dilation(silhouette, iterations=margin)
    if beyond.sum() < MIN_FOREIGN_PIXELS:
        return np.zeros((h, w), dtype=bool)
    bins = quantised_colors(photo_rgb, (h, w))
    counts = [np.bincount(bins[where], minlength=LEVELS**3).astype(np.float64) for where in (beyond, silhouette & mask)]
    pooled = (counts[0] + counts[1]) / max(1.0, counts[0].sum() + counts[1].sum())
    # Each side's color frequencies, drawn towards the pooled ones by MIN_FOREIGN_PIXELS pixels' worth: a color
    # seen a few times on one side only is not yet that side's.
    foreign, own = ((c + MIN_FOREIGN_PIXELS * pooled) / (c.sum() + MIN_FOREIGN_PIXELS) for c in counts)
    return silhouette & (foreign[bins] > FOREIGN_ODDS * own[bins])


def trusted_pixels(mask: np.ndarray | None) -> np.ndarray | None:
    """The pixels surely on the object: its mask farther than TRUST_MARGIN of the photo's shorter side from the
    mask's edge, where a pose a pixel off or a soft edge would mix in the background. A part too thin for that
    (a chair's arm or leg) keeps its middle, the pixels within a pixel of its deepest, so it gets colors of its
    own instead of its neighbours' (the demo chair's metal arms and base were wood-colored). None without a mask:
    then every pixel counts."""
    if mask is None:
        return None
    h, w = mask.shape
    margin = max(1.0, TRUST_MARGIN * min(h, w))
    depth = ndimage.distance_transform_edt(mask)
    deepest_near = ndimage.maximum_filter(depth, size=2 * math.ceil(margin) + 1)
    thin_middle = mask & (deepest_near <= margin) & (depth >= deepest_near - 1.0)
    return (depth > margin) | thin_middle


def _downscale(rgb: np.ndarray, alpha: np.ndarray | None, long_side: int) -> tuple[np.ndarray, np.ndarray | None]:
    """The photo (and alpha) with its long side at most `long_side`, by area averaging."""
    return downscaled(rgb, long_side), None if alpha is None else downscaled(alpha, long_side)


def captured_scene(mesh_path: str | Path, voxels_path: str | Path, pose: PhotoPose, up: str = "y",
                   resolution: int = DEFAULT_RESOLUTION, image_size: int = 256) -> Scene:
    """A scene that shows the object as the photo did: the pose's placement and elevation, the captured voxels.

    Paths are taken relative to the working directory; save_scene rewrites them relative to the scene file.
    """
    obj = ObjectSpec(mesh=str(mesh_path), up=up, resolution=resolution, voxels=str(voxels_path),
                     rotation_deg=pose.rotation_deg, translation=pose.translation, scale=pose.scale)
    scene = Scene.single(object=obj, camera=CameraSpec(elevation_deg=pose.camera.elevation_deg), image_size=image_size,
                  base_dir=Path.cwd())
    validate(scene)
    return scene
