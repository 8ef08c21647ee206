"""Training and test sets after the paper's protocol (section 4.1), made here from procedural objects.

For every object: generate it from its seed, give it an appearance (single color, per-part
"default" materials, or a procedural texture), render an appearance source image A from another
view and light, color its voxels from A (or directly, for single color), then render V target
images T with the path tracer and the matching splatted images S.

Folder layout (all paths in the manifest are relative to the folder):
    config.json                 the DataConfig and renderer that made the set (written first)
    objects/oNNNNN.npz          object voxels (key "rgba", uint8, N^3 x 4) as the network sees them
    objects/oNNNNN_source.png   appearance source image A, with oNNNNN_source_camera.json beside it
    images/oNNNNN_vVV.png       target T (path traced, sRGB)
    splats/oNNNNN_vVV.png       splatted image S of the same scene
    records/oNNNNN.json         written last, atomically: the object is complete
    manifest.json               every sample's full scene and file names, from the records

Resuming: an object counts as done only when its record exists; every file is written
atomically, so a killed run leaves no half-written file under a real name and a rerun redoes
only unfinished objects. Sharding: `--shard I/N` takes objects with index % N == I; the shards'
folders merge into one set with `merge_datasets`.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from renderer.dataset_config import (  # noqa: F401  (the data set names, re-exported)
    DELIGHT_SHADERS,
    MADE_DELIGHT_SHADERS,
    MAX_OBJECTS,
    MAX_SPP,
    MAX_VIEWS,
    MAX_WORKERS,
    SETTINGS,
    SPLITS,
    DataConfig,
)
from renderer.errors import InputError
from renderer.io import atomic_path, load_image, load_json, remove_stale_temporaries, save_json, save_png
from renderer.scene import (
    ELEVATION_RANGE,
    GROUP_AXIS_SPREAD,
    GROUP_SCALE_RANGE,
    GROUP_VIEW_X,
    GROUP_VIEW_Z,
    LIGHT_XZ_RANGE,
    LIGHT_Y_RANGE,
    SCALE_RANGE,
    TRANSLATION_RANGE,
    CameraSpec,
    EnvironmentSpec,
    FloorSpec,
    LightSpec,
    MaterialSpec,
    ObjectSpec,
    Scene,
    SkySpec,
    scene_from_dict,
)

DATA_FORMAT = 1
TEST_ELEVATION_RANGE = (15.0, 45.0)
TEST_ROTATION_STEP_DEG = 10.0
FACING_ROTATION_RANGE = (-90.0, 90.0)  # the half of all rotations that faces the camera
# --- the sampling protocol ----------------------------------------------------------------


@dataclass(frozen=True)
class View:
    """The editable scene parameters of one sample."""

    elevation_deg: float
    rotation_deg: float
    translation: tuple[float, float]
    scale: tuple[float, float, float]
    light: tuple[float, float, float]


def sample_light(rng: np.random.Generator) -> tuple[float, float, float]:
    """A light position drawn uniformly over the box lights are sampled from (renderer.scene)."""
    return (
        float(rng.uniform(*LIGHT_XZ_RANGE)),
        float(rng.uniform(*LIGHT_Y_RANGE)),
        float(rng.uniform(*LIGHT_XZ_RANGE)),
    )


def sample_train_views(rng: np.random.Generator, count: int) -> list[View]:
    """Training views: every parameter uniform and independent over its training range."""
    views = []
    for _ in range(count):
        views.append(
            View(
                elevation_deg=float(rng.uniform(*ELEVATION_RANGE)),
                rotation_deg=float(rng.uniform(*FACING_ROTATION_RANGE)),
                translation=(float(rng.uniform(*TRANSLATION_RANGE)), float(rng.uniform(*TRANSLATION_RANGE))),
                scale=tuple(float(s) for s in rng.uniform(*SCALE_RANGE, size=3)),
                light=sample_light(rng),
            )
        )
    return views


def sample_test_sequence(rng: np.random.Generator, count: int) -> list[View]:
    """A test sequence: one elevation, rotation in 10-degree steps, translation and light interpolated."""
    elevation = float(rng.uniform(*TEST_ELEVATION_RANGE))
    span = TEST_ROTATION_STEP_DEG * (count - 1)
    lo, hi = FACING_ROTATION_RANGE
    start = float(rng.uniform(lo, max(lo, hi - span))) if span < hi - lo else lo
    direction = 1.0 if rng.uniform() < 0.5 else -1.0
    if direction < 0:
        start = lo + hi - start  # walk the same span downwards from the mirrored start
    t0, t1 = rng.uniform(*TRANSLATION_RANGE, size=2), rng.uniform(*TRANSLATION_RANGE, size=2)
    l0, l1 = np.array(sample_light(rng)), np.array(sample_light(rng))
    scale = tuple(float(s) for s in rng.uniform(*SCALE_RANGE, size=3))
    views = []
    for k in range(count):
        f = k / (count - 1) if count > 1 else 0.0
        views.append(
            View(
                elevation_deg=elevation,
                rotation_deg=start + direction * TEST_ROTATION_STEP_DEG * k,
                translation=tuple(float(v) for v in (1 - f) * t0 + f * t1),
                scale=scale,
                light=tuple(float(v) for v in (1 - f) * l0 + f * l1),
            )
        )
    return views


def sample_source_view(rng: np.random.Generator) -> View:
    """The view and light of the appearance source image A: centred object, random everything else."""
    return View(
        elevation_deg=float(rng.uniform(*ELEVATION_RANGE)),
        rotation_deg=float(rng.uniform(*FACING_ROTATION_RANGE)),
        translation=(0.0, 0.0),
        scale=(1.0, 1.0, 1.0),
        light=sample_light(rng),
    )


# Scenes of several objects: each object of a size in GROUP_SCALE_RANGE (renderer/scene.py), beside one placed before
# with a gap between the circles that hold their footprints (never touching, close enough to shadow and reflect each
# other), every centre in the part of the floor every camera elevation shows (GROUP_VIEW_X, GROUP_VIEW_Z).
GROUP_GAP_RANGE = (0.02, 0.3)
SHADOWED_SHARE = 0.5  # of objects past the first, the share placed on the far side of a neighbour from the light
SHADOWED_GAP_RANGE = (0.01, 0.1)  # and their gap: inside its shadow
SHADOWED_SPREAD = 0.5  # radians either side of the line away from the light
LAYOUT_TRIES = 400  # draws per object before the layout starts again at smaller sizes


def footprint_points(rgba: np.ndarray) -> np.ndarray:
    """(M, 2) object-unit (x, z) corners of the floor cells under an object's voxels: what its footprint holds."""
    from renderer.transform import OBJECT_BOX_MAX, OBJECT_BOX_MIN

    n = rgba.shape[0]
    i, k = np.nonzero((rgba[..., 3] > 0.5).any(axis=1))
    corners = [(i + a, k + b) for a in (0, 1) for b in (0, 1)]
    cells = np.concatenate([np.column_stack(c) for c in corners]).astype(np.float64)
    cells = np.unique(cells, axis=0) if len(cells) else np.zeros((1, 2))
    return OBJECT_BOX_MIN[[0, 2]] + cells * ((OBJECT_BOX_MAX[0] - OBJECT_BOX_MIN[0]) / n)


def _reach(points: np.ndarray | None, scale: tuple[float, float, float]) -> float:
    """Radius of the circle about the object's axis that holds its footprint `points` at `scale`, whatever its turn
    (None: the whole unit box's)."""
    from renderer.transform import footprint_radius

    if points is None:
        return footprint_radius(ObjectSpec(scale=scale))
    return float(np.hypot(points[:, 0] * scale[0], points[:, 1] * scale[2]).max())


def sample_layout(rng: np.random.Generator, objects: Sequence[ObjectSpec],
                  light: tuple[float, float, float] | None = None,
                  footprints: Sequence[np.ndarray | None] | None = None) -> tuple[ObjectSpec, ...]:
    """`objects` placed, turned and sized on the floor as GROUP_* says (their other fields kept), the gaps between
    the circles that hold their `footprints` (footprint_points; default their whole boxes'). With the `light`, some
    stand in a neighbour's shadow (SHADOWED_*): a scene's objects shadow each other where its light allows."""
    footprints = footprints or [None] * len(objects)
    shrink = 1.0
    while True:
        placed: list[ObjectSpec] = []
        reach: list[float] = []
        for o, points in zip(objects, footprints):
            base = float(rng.uniform(*GROUP_SCALE_RANGE)) * shrink
            scale = tuple(float(v) for v in base * rng.uniform(1.0 - GROUP_AXIS_SPREAD, 1.0 + GROUP_AXIS_SPREAD, size=3))
            one = replace(o, scale=scale, rotation_deg=float(rng.uniform(-180.0, 180.0)))
            radius = _reach(points, scale)
            for _ in range(LAYOUT_TRIES):
                if placed:
                    n = int(rng.integers(len(placed)))
                    neighbour = placed[n]
                    angle, gap = float(rng.uniform(0.0, 2.0 * np.pi)), float(rng.uniform(*GROUP_GAP_RANGE))
                    if light is not None and rng.random() < SHADOWED_SHARE:
                        away = np.arctan2(neighbour.translation[1] - light[2], neighbour.translation[0] - light[0])
                        angle = float(away + rng.uniform(-SHADOWED_SPREAD, SHADOWED_SPREAD))
                        gap = float(rng.uniform(*SHADOWED_GAP_RANGE))
                    distance = radius + reach[n] + gap
                    place = (neighbour.translation[0] + distance * np.cos(angle),
                             neighbour.translation[1] + distance * np.sin(angle))
                else:
                    place = (rng.uniform(-0.4, 0.4), rng.uniform(-0.5, 0.2))
                one = replace(one, translation=(float(place[0]), float(place[1])))
                inside = abs(one.translation[0]) <= GROUP_VIEW_X and GROUP_VIEW_Z[0] <= one.translation[1] <= GROUP_VIEW_Z[1]
                apart = all(np.hypot(one.translation[0] - p.translation[0], one.translation[1] - p.translation[1])
                            > radius + r for p, r in zip(placed, reach))
                if inside and apart:
                    placed.append(one)
                    reach.append(radius)
                    break
            else:
                break
        if len(placed) == len(objects):
            return tuple(placed)
        shrink *= 0.9


SceneView = tuple[float, tuple[float, float, float], tuple[ObjectSpec, ...]]  # elevation, light, placed objects


def sample_train_layouts(rng: np.random.Generator, count: int, objects: Sequence[ObjectSpec],
                         footprints: Sequence[np.ndarray] | None = None) -> list[SceneView]:
    """Training views of a scene of several objects: a layout, elevation and light drawn anew per view."""
    views = []
    for _ in range(count):
        elevation, light = float(rng.uniform(*ELEVATION_RANGE)), sample_light(rng)
        views.append((elevation, light, sample_layout(rng, objects, light, footprints)))
    return views


def sample_test_layouts(rng: np.random.Generator, count: int, objects: Sequence[ObjectSpec],
                        footprints: Sequence[np.ndarray] | None = None) -> list[SceneView]:
    """A test sequence of a scene of several objects: one layout and elevation, each object turning about its own
    axis in 10-degree steps (either way), the light moving between two positions (the layout made for their mean)."""
    elevation = float(rng.uniform(*TEST_ELEVATION_RANGE))
    l0, l1 = np.array(sample_light(rng)), np.array(sample_light(rng))
    layout = sample_layout(rng, objects, tuple((l0 + l1) / 2.0), footprints)
    directions = np.where(rng.uniform(size=len(layout)) < 0.5, -1.0, 1.0)
    views = []
    for k in range(count):
        f = k / (count - 1) if count > 1 else 0.0
        turned = tuple(replace(o, rotation_deg=float((o.rotation_deg + d * TEST_ROTATION_STEP_DEG * k + 180.0) % 360.0
                                                     - 180.0)) for o, d in zip(layout, directions))
        views.append((elevation, tuple(float(v) for v in (1 - f) * l0 + f * l1), turned))
    return views


def view_scene(view: View, voxels: str, floor_color: tuple, size: int, color: tuple | None = None,
               lighting: Lighting | None = None, material: MaterialSpec | None = None) -> Scene:
    """The scene of one sample, its object given by a voxel file relative to the data folder."""
    lighting = lighting or Lighting()
    return Scene.single(
        object=ObjectSpec(voxels=voxels, color=color, translation=view.translation, rotation_deg=view.rotation_deg,
                          scale=view.scale, material=material or MaterialSpec()),
        floor=FloorSpec(tuple(float(c) for c in floor_color)),
        light=LightSpec(view.light, enabled=lighting.area_light),
        camera=CameraSpec(view.elevation_deg),
        image_size=size,
        environment=lighting.environment,
    )


@dataclass(frozen=True)
class Lighting:
    """How one view is lit: the area light (or not) and an environment (or the uniform ambient light)."""

    area_light: bool = True
    environment: EnvironmentSpec | None = None


MAPS_PER_SPLIT = {"train": 300, "test": 60}  # made maps per kind a split draws from (disjoint seeds: map_seed)
SKY_ELEVATION_RANGE = (5.0, 70.0)
SKY_TURBIDITY_RANGE = (2.0, 8.0)


def sample_lighting(rng: np.random.Generator, lighting: str, split: str) -> tuple[Lighting, tuple[str, int] | None]:
    """A view's lighting for the set's `lighting` (DataConfig.lighting), and the made map it uses ((kind, seed) or
    None): an environment is a sky (random sun and haze) or one of the split's made maps, turned at random."""
    from renderer.environment_maps import KINDS, map_seed

    if lighting == "area":
        return Lighting(), None
    mode = "environment" if lighting == "environment" else ("area", "environment", "both")[int(rng.integers(3))]
    if mode == "area":
        return Lighting(), None
    kind = ("sky", *KINDS)[int(rng.integers(len(KINDS) + 1))]
    rotation = float(rng.uniform(-180.0, 180.0))
    if kind == "sky":
        sky = SkySpec(float(rng.uniform(*SKY_ELEVATION_RANGE)), float(rng.uniform(-180.0, 180.0)),
                      float(rng.uniform(*SKY_TURBIDITY_RANGE)))
        return Lighting(mode == "both", EnvironmentSpec(sky=sky, rotation_deg=rotation)), None
    seed = map_seed(split, int(rng.integers(MAPS_PER_SPLIT[split])))
    environment = EnvironmentSpec(image=environment_file(kind, seed), rotation_deg=rotation)
    return Lighting(mode == "both", environment), (kind, seed)


GROUND_SCALE_RANGE = (1.0, 3.0)  # world units a textured ground repeats over
GROUND_TILE_PIXELS = 512  # a ground image's side: 2 to 5 millimetres of ground a pixel, finer than the images see
DISK_SHARE = 0.5  # of textured grounds, the share that are disks (the paper's), the rest squares
MIXED_TEXTURED_SHARE = 0.5  # with grounds "mixed", the share of views on a textured ground (the rest plain)


def sample_ground(rng: np.random.Generator, split: str) -> tuple[np.ndarray, float, str, str]:
    """A textured ground: its image (sRGB uint8, GROUND_TILE_PIXELS square), the world units it repeats over, the
    floor's shape and the texture's family (the split's own: renderer/objects/textures.py)."""
    from renderer.objects.textures import draw_texture

    family, texture = draw_texture(rng, split)
    scale = float(rng.uniform(*GROUND_SCALE_RANGE))
    shape = "disk" if rng.random() < DISK_SHARE else "square"
    return ground_tile(texture, scale, GROUND_TILE_PIXELS), scale, shape, family


def ground_tile(texture, span: float, pixels: int) -> np.ndarray:
    """`texture` (object-unit coordinates -> sRGB) over half of `span` world units, mirrored into a 2 x 2 tile of
    `pixels` a side: the tile repeats without seams (the textures themselves do not repeat)."""
    half = pixels // 2
    centres = (np.arange(half) + 0.5) * (span / pixels)
    u, v = np.meshgrid(centres, centres)
    quarter = np.clip(texture(np.column_stack([u.ravel(), v.ravel()])), 0.0, 1.0).reshape(half, half, 3)
    top = np.concatenate([quarter, quarter[:, ::-1]], axis=1)
    return np.round(np.concatenate([top, top[::-1]], axis=0) * 255.0).astype(np.uint8)


def sample_material(rng: np.random.Generator) -> MaterialSpec:
    """An object's material: matte (a third), plastic or ceramic of any gloss, or metal (a fifth)."""
    pick = rng.random()
    if pick < 1.0 / 3.0:
        return MaterialSpec()
    roughness = float(rng.uniform(0.05, 0.9))
    if pick < 0.8:
        return MaterialSpec(roughness, float(rng.uniform(0.2, 0.9)), 0.0)
    return MaterialSpec(roughness, 0.5, float(rng.uniform(0.8, 1.0)))


def environment_file(kind: str, seed: int) -> str:
    """Where a made map lies in a data folder (relative)."""
    return f"environments/{kind}_{seed:07d}.hdr"


def write_environment_map(out: Path, kind: str, seed: int) -> None:
    """Make the map once per data folder (atomically: workers may race to it)."""
    from renderer.environment_maps import make_map

    path = out / environment_file(kind, seed)
    if path.exists():
        return
    import mitsuba as mi

    from renderer.pathtrace.mitsuba_variant import active_variant

    active_variant()
    with atomic_path(path) as tmp:
        mi.Bitmap(make_map(kind, seed)).write(str(tmp))


def object_rng(config: DataConfig, index: int, purpose: int, part: int = 0) -> np.random.Generator:
    """Independent, reproducible random stream per (data seed, split, setting, scene, purpose, and object of the
    scene past its first)."""
    key = [config.seed, SPLITS.index(config.split), SETTINGS.index(config.setting), index, purpose]
    key += [part] if part else []
    return np.random.default_rng(np.random.SeedSequence(key))


# --- generation -----------------------------------------------------------------------------


def _object_name(index: int) -> str:
    return f"o{index:05d}"


def _renderer_info(config: DataConfig) -> dict[str, Any]:
    import mitsuba

    from renderer.pathtrace.path_tracer import active_variant

    return {"name": "mitsuba", "version": mitsuba.__version__, "variant": active_variant(),
            "spp": config.spp, "denoise": config.denoise}


def prepare_folder(out: Path, config: DataConfig) -> None:
    """Create the folder tree and config.json, or check that an existing one was made by the same config."""
    config.check()
    if out.exists() and not out.is_dir():
        raise InputError("not a folder", out)
    try:
        for sub in ("objects", "images", "splats", "records", "environments", "grounds"):
            (out / sub).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the output folder: {exc.strerror}", out) from None
    for folder in (out, *(out / sub for sub in ("objects", "images", "splats", "records"))):
        remove_stale_temporaries(folder)  # half-written files of a killed run
    config_file = out / "config.json"
    if config_file.exists():
        stored = load_json(config_file).get("config")
        if not isinstance(stored, dict) or _config_or_none(stored) != config:
            raise InputError("holds a data set made with other arguments; use another --out folder", out)
    else:
        save_json(config_file, {"format": DATA_FORMAT, "config": config.to_dict()})


def _config_or_none(stored: dict[str, Any]) -> DataConfig | None:
    try:
        return DataConfig.from_dict(stored)
    except TypeError:  # keys this version does not know
        return None


@dataclass
class _MadeObject:
    """One object of a scene as generation made it: its painted voxels, mesh, colors and record entry."""

    rgba: np.ndarray
    mesh: Any
    floor_color: tuple[float, float, float]
    single_color: tuple[float, float, float] | None
    voxels: str
    record: dict[str, Any]


def _make_object(out: Path, config: DataConfig, index: int, part: int) -> _MadeObject:
    """Make one object's files: voxels colored from a source photo of another view and light (or its one color).
    Part 0 is the scene's own object (the only one of a one-object set); parts 1.. are the others in its scene,
    of random categories from the set's and seeds of the split drawn at random."""
    from renderer.camera import Camera
    from renderer.capture.pose import PhotoPose
    from renderer.objects import apply_appearance, generate_object, split_seed, split_seeds
    from renderer.objects.generate import SEEDS_PER_SPLIT
    from renderer.pathtrace.path_tracer import render_pathtraced
    from renderer.photo import color_voxels_from_photo, is_mirror_symmetric
    from renderer.transform import object_to_world
    from renderer.voxels import save_voxels, voxelize

    name = _object_name(index) + (f"_{part}" if part else "")
    if part == 0:
        category = config.categories[index % len(config.categories)]
        object_seed = int(split_seeds(config.split, config.objects)[index])
    else:
        pick = object_rng(config, index, 7, part)
        category = config.categories[int(pick.integers(len(config.categories)))]
        object_seed = split_seed(config.split, int(pick.integers(SEEDS_PER_SPLIT)))
    labeled = generate_object(category, object_seed)
    appearance_seed = int(object_rng(config, index, 0, part).integers(2**31))
    mesh, floor_color, appearance = apply_appearance(labeled, config.setting, appearance_seed, config.split)
    floor_color = tuple(float(c) for c in floor_color)
    single_color = appearance.get("color") if config.setting == "single" else None
    single_color = None if single_color is None else tuple(float(c) for c in single_color)

    rgba = voxelize(mesh, resolution=config.resolution)
    voxel_file = f"objects/{name}.npz"

    # Appearance source A: another view and light, the object alone; the voxels take their colors from it.
    source_view = sample_source_view(object_rng(config, index, 1, part))
    source_scene = view_scene(source_view, voxel_file, floor_color, config.source_size, single_color)
    seed = photo_seed(index, part)
    source = render_pathtraced(source_scene, mesh, spp=config.spp, seed=seed, denoise=config.denoise)
    source_camera = Camera.from_scene(source_scene)
    mirror = False
    if config.setting == "single":
        rgba[..., :3] = np.where(rgba[..., 3:] > 0.5, np.asarray(single_color, dtype=np.float32), 0.0)
    else:
        mirror = bool(is_mirror_symmetric(rgba[..., 3] > 0.5))
        photo, trusted = source.image, None
        if config.delight:
            photo, trusted = _divided_light(source.image, source_scene, rgba, mesh, config.delight_shader, seed)
        rgba = color_voxels_from_photo(
            rgba, object_to_world(source_scene.object), photo, source_camera, mirror=mirror, trusted=trusted,
            hidden_rule=config.hidden_rule).rgba
    save_voxels(out / voxel_file, rgba)
    save_png(out / f"objects/{name}_source.png", source.image)
    source_pose = PhotoPose(source_camera, source_view.rotation_deg, source_view.translation, source_view.scale)
    save_json(out / f"objects/{name}_source_camera.json", {**source_pose.to_dict(), "light": list(source_view.light)})
    record = {"id": name, "index": index, "category": category, "seed": object_seed,
              "setting": config.setting, "appearance": appearance, "floor_color": list(floor_color),
              "voxels": voxel_file, "mirror_symmetry_used": mirror,
              "source_image": f"objects/{name}_source.png", "source_camera": f"objects/{name}_source_camera.json",
              "params": labeled.params}
    if part:
        record["part"] = part
    return _MadeObject(rgba, mesh, floor_color, single_color, voxel_file, record)


def scene_object_count(config: DataConfig, index: int) -> int:
    """How many objects scene `index` of the set holds: 1 to config.scene_objects, uniformly."""
    if config.scene_objects == 1:
        return 1
    return 1 + int(object_rng(config, index, 6).integers(config.scene_objects))


def generate_object_samples(out: Path, config: DataConfig, index: int) -> dict[str, Any]:
    """Make every file of one scene's objects and views, and return its record (written by the caller, last)."""
    from renderer.pathtrace.path_tracer import render_pathtraced
    from renderer.splat import splat_objects

    made = [_make_object(out, config, index, part) for part in range(scene_object_count(config, index))]
    first = made[0]
    floor_color = first.floor_color
    name = _object_name(index)
    materials = [sample_material(object_rng(config, index, 3, part)) if config.materials else MaterialSpec()
                 for part in range(len(made))]
    light_rng = object_rng(config, index, 4)
    ground_rng = object_rng(config, index, 5)
    if len(made) == 1:
        sampler = sample_train_views if config.split == "train" else sample_test_sequence
        views = [(view.elevation_deg, view.light, view_scene(view, first.voxels, floor_color, config.size,
                                                             first.single_color, material=materials[0]).objects)
                 for view in sampler(object_rng(config, index, 2), config.views)]
    else:
        layouts = sample_train_layouts if config.split == "train" else sample_test_layouts
        views = layouts(object_rng(config, index, 2), config.views, [
            ObjectSpec(voxels=m.voxels, color=m.single_color, material=material, name=m.record["id"])
            for m, material in zip(made, materials)], [footprint_points(m.rgba) for m in made])
    meshes = [m.mesh for m in made] if len(made) > 1 else first.mesh
    samples = []
    for v, (elevation, light, objects) in enumerate(views):
        sample_id = f"{name}_v{v:02d}"
        lighting, made_map = sample_lighting(light_rng, config.lighting, config.split)
        if made_map is not None:
            write_environment_map(out, *made_map)
        scene = Scene(objects=objects, floor=FloorSpec(floor_color), light=LightSpec(light, enabled=lighting.area_light),
                      camera=CameraSpec(elevation), image_size=config.size, environment=lighting.environment,
                      base_dir=out)
        if config.grounds == "textured" or (config.grounds == "mixed" and ground_rng.random() < MIXED_TEXTURED_SHARE):
            tile, scale, shape, _ = sample_ground(ground_rng, config.split)
            save_png(out / f"grounds/{sample_id}.png", tile)
            scene = replace(scene, floor=FloorSpec(floor_color, f"grounds/{sample_id}.png", scale, shape))
        target = render_pathtraced(scene, meshes, spp=config.spp,
                                   seed=index * 1000 + v, denoise=config.denoise)
        save_png(out / f"images/{sample_id}.png", target.image)
        save_png(out / f"splats/{sample_id}.png", splat_objects(scene, [m.rgba for m in made], floor_color))
        samples.append({"id": sample_id, "object": name, "scene": replace(scene, base_dir=Path(".")).to_dict(),
                        "target": f"images/{sample_id}.png", "splat": f"splats/{sample_id}.png"})
    record = {"object": first.record, "samples": samples}
    if len(made) > 1:
        record["companions"] = [m.record for m in made[1:]]
    return record


def photo_seed(index: int, part: int) -> int:
    """The seed of the source photo (and of its light's unmixing) of object `part` of scene `index`."""
    return index if part == 0 else index * 1000 + 900 + part


def _divided_light(photo: np.ndarray, scene: Scene, rgba: np.ndarray, mesh, delight_shader: str,
                   seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The photo's albedo and where it is known, the light divided out as `delight_shader` (one of
    MADE_DELIGHT_SHADERS) says: with the mesh's path-traced light, or the voxel shader's for the voxels `rgba`."""
    from renderer.photo import photo_albedo, unmixed_albedo

    if delight_shader == "path traced":
        return unmixed_albedo(photo, scene, mesh, seed=seed)
    return photo_albedo(photo, scene, rgba)


def parse_shard(text: str | None) -> tuple[int, int]:
    """'I/N' -> (I, N) with 0 <= I < N; None -> (0, 1)."""
    if text is None:
        return 0, 1
    try:
        i, n = (int(p) for p in text.split("/"))
    except ValueError:
        raise InputError(f"--shard must look like I/N (e.g. 0/4), got {text!r}") from None
    if not 0 <= i < n:
        raise InputError(f"--shard I/N needs 0 <= I < N, got {text!r}")
    return i, n


def pending_objects(out: Path, config: DataConfig, shard: tuple[int, int]) -> list[int]:
    """Indices of this shard's objects that have no record yet."""
    i, n = shard
    return [k for k in range(config.objects) if k % n == i and not (out / f"records/{_object_name(k)}.json").exists()]


def _generate_one(args: tuple[str, dict, int]) -> int:
    out, config_dict, index = args
    out_path, config = Path(out), DataConfig.from_dict(config_dict)
    record = generate_object_samples(out_path, config, index)
    save_json(out_path / f"records/{_object_name(index)}.json", record)
    return index


def generate_dataset(out: str | Path, config: DataConfig, shard: tuple[int, int] = (0, 1), workers: int = 1,
                     progress: bool = True, on_object_done: Callable[[int], None] | None = None) -> Path:
    """Generate (or resume) a data set; returns the manifest path. `on_object_done` is called after each object."""
    from tqdm import tqdm

    out = Path(out)
    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= MAX_WORKERS:
        raise InputError(f"--workers must be a whole number from 1 to {MAX_WORKERS}, got {workers!r}")
    prepare_folder(out, config)
    todo = pending_objects(out, config, shard)
    bar = tqdm(total=len(todo), unit="object", disable=not progress, desc=f"{config.split}/{config.setting}")
    jobs = [(str(out), config.to_dict(), k) for k in todo]
    for index in _run_jobs(jobs, workers):
        bar.update(1)
        if on_object_done is not None:
            on_object_done(index)
    bar.close()
    return write_manifest(out, config)


def _run_jobs(jobs: list, workers: int, work: Callable[[Any], int] = _generate_one) -> Iterator[int]:
    if workers <= 1:
        for job in jobs:
            yield work(job)
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        yield from pool.map(work, jobs)


def recolor_dataset(source: str | Path, out: str | Path, workers: int = 1, progress: bool = True,
                    hidden_rule: str = "blend", resolution: int | None = None,
                    delight_shader: str = DELIGHT_SHADERS[0], photo_size: int | None = None) -> Path:
    """A copy in `out` of a data set whose photo colors were made by other rules (config delight false, another
    hidden_rule or delight_shader), as generation makes them with `hidden_rule` and `delight_shader`: photo-colored
    voxels recolored from their source photos with the light divided out, splats redrawn from them. `resolution`:
    voxelise every object anew at that many voxels per side (its mesh remade from the record's category and seeds, as
    generation made it), so a set moves to finer voxels without rendering its targets again. `photo_size`: path trace
    every source photo again at that side (0: the images'), as generation does. Targets and kept source photos are hard
    links where the file system allows (else copies); rerun to resume. Returns the manifest path."""
    from tqdm import tqdm

    source, out = Path(source), Path(out)
    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= MAX_WORKERS:
        raise InputError(f"--workers must be a whole number from 1 to {MAX_WORKERS}, got {workers!r}")
    stored = load_json(source / "config.json").get("config")
    config = _config_or_none(stored) if isinstance(stored, dict) else None
    if config is None:
        raise InputError("config.json does not describe a data set", source)
    stored_resolution = config.resolution
    recolored = dataclasses.replace(config, delight=True, hidden_rule=hidden_rule, delight_shader=delight_shader,
                                    resolution=config.resolution if resolution is None else resolution,
                                    photo_size=config.photo_size if photo_size is None else photo_size)
    recolored.check()
    if recolored == config:
        raise InputError(f"its photo colors are already made by these rules (light divided out: {delight_shader}, "
                         f"hidden voxels {hidden_rule}, {config.resolution}^3 voxels, photos "
                         f"{config.source_size}^2)", source)
    if source.resolve() == out.resolve():
        raise InputError("give another --out folder: the data set is copied, not changed in place", out)
    new_photos = recolored.source_size != config.source_size
    config = recolored
    todo = [f.stem for f in sorted((source / "records").glob("o*.json")) if not (out / "records" / f.name).exists()]
    remake_mesh = (config.resolution != stored_resolution or new_photos
                   or (config.setting != "single" and delight_shader == "path traced"))
    for name in todo:  # every record readable before anything is written
        _check_record(load_json(source / "records" / f"{name}.json"), source / "records" / f"{name}.json", remake_mesh)
    prepare_folder(out, config)
    bar = tqdm(total=len(todo), unit="object", disable=not progress, desc=f"recolor {source.name}")
    photos = (config.source_size, config.spp, config.denoise) if new_photos else None
    jobs = [(str(source), str(out), name, config.hidden_rule, config.resolution, delight_shader, photos)
            for name in todo]
    for _ in _run_jobs(jobs, workers, _recolor_one):
        bar.update(1)
    bar.close()
    return write_manifest(out, config)


def _remade_mesh(obj: dict[str, Any]):
    """A record's object mesh (trimesh.Trimesh), remade as generation made it (category, seed, appearance seed and
    split)."""
    from renderer.objects import apply_appearance, generate_object

    appearance = obj["appearance"]
    labeled = generate_object(obj["category"], int(obj["seed"]))
    return apply_appearance(labeled, obj["setting"], int(appearance["seed"]), appearance["split"])[0]


def _voxelised_again(obj: dict[str, Any], resolution: int, mesh=None) -> np.ndarray:
    """A record's object voxelised at `resolution` (its mesh remade unless given), single-colored voxels painted its
    color (photo-colored ones are colored by the caller)."""
    from renderer.voxels import voxelize

    rgba = voxelize(_remade_mesh(obj) if mesh is None else mesh, resolution=resolution)
    if obj["setting"] == "single":
        color = np.asarray(obj["appearance"]["color"], dtype=np.float32)
        rgba[..., :3] = np.where(rgba[..., 3:] > 0.5, color, 0.0)
    return rgba


RECORD_OBJECT_KEYS = ("index", "setting", "floor_color", "voxels", "source_image", "source_camera",
                      "mirror_symmetry_used")


def _check_record(record: Any, path: Path, remake_mesh: bool = False) -> None:
    """InputError naming `path` unless the record holds what recoloring its objects reads (and, with `remake_mesh`,
    what remaking their meshes reads)."""
    objects = [record.get("object"), *record.get("companions", [])] if isinstance(record, dict) else [None]
    samples = record.get("samples") if isinstance(record, dict) else None
    keys = RECORD_OBJECT_KEYS + (("category", "seed", "appearance") if remake_mesh else ())
    missing = sorted({key for obj in objects for key in keys if not isinstance(obj, dict) or key not in obj},
                     key=keys.index)
    if missing or not isinstance(samples, list) or not all(
            isinstance(s, dict) and all(k in s for k in ("scene", "target", "splat")) for s in samples):
        what = f"object keys {', '.join(missing)}" if missing else "samples with a scene, target and splat each"
        raise InputError(f"not a data set record: it lacks {what}", path)


def _recolor_one(args: tuple[str, str, str, str, int, str, tuple[int, int, bool] | None]) -> int:
    """Recolor one object of a data set into `out` (see recolor_dataset); its record is written last."""
    source, out, name, hidden_rule, resolution, delight_shader, photos = Path(args[0]), Path(args[1]), *args[2:]
    try:
        return _recolor_object(source, out, name, hidden_rule, resolution, delight_shader, photos)
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise InputError(f"a malformed record or camera file ({type(exc).__name__}: {exc})",
                         source / "records" / f"{name}.json") from None


def _recolor_object(source: Path, out: Path, name: str, hidden_rule: str, resolution: int, delight_shader: str,
                    photos: tuple[int, int, bool] | None) -> int:
    """Recolor every object of one scene (its record's object and companions) and redraw its splats.
    `photos`: (side, spp, denoise) to path trace the source photos again with, or None to keep them."""
    from renderer.splat import splat_objects
    from renderer.voxels import save_voxels

    record = load_json(source / "records" / f"{name}.json")
    objects = [record["object"], *record.get("companions", [])]
    voxels = [_recolored_voxels(source, out, obj, hidden_rule, resolution, delight_shader, photos) for obj in objects]
    redrawn = any(changed for _, changed in voxels)
    links = [s["target"] for s in record["samples"]]
    links += sorted(set(_scene_files(record["samples"])))  # environment maps and ground images the scenes name
    for obj, (rgba, _) in zip(objects, voxels):
        links += [] if photos is not None else [obj["source_image"], obj["source_camera"]]
        if redrawn:
            save_voxels(out / obj["voxels"], rgba)
        else:
            links.append(obj["voxels"])
    links += [] if redrawn else [s["splat"] for s in record["samples"]]
    for rel in links:
        _link_or_copy(source / rel, out / rel)
    if redrawn:
        floor_color = tuple(float(c) for c in objects[0]["floor_color"])
        for sample in record["samples"]:
            scene = scene_from_dict(sample["scene"])
            save_png(out / sample["splat"], splat_objects(scene, [rgba for rgba, _ in voxels], floor_color))
    save_json(out / "records" / f"{name}.json", record)
    return int(objects[0]["index"])


def _recolored_voxels(source: Path, out: Path, obj: dict[str, Any], hidden_rule: str, resolution: int,
                      delight_shader: str, photos: tuple[int, int, bool] | None) -> tuple[np.ndarray, bool]:
    """One object's voxels recolored (see _recolor_object; new source photos are written to `out`), and whether
    they differ from the stored ones."""
    from renderer.capture.pose import lit_photo_scene, load_pose
    from renderer.pathtrace.path_tracer import render_pathtraced
    from renderer.photo import color_voxels_from_photo
    from renderer.voxels import load_voxels

    floor_color = tuple(float(c) for c in obj["floor_color"])  # the floor of the object's own source photo
    rgba = load_voxels(source / obj["voxels"])
    recolor = obj["setting"] != "single"
    revoxelise = rgba.shape[0] != resolution
    mesh = (_remade_mesh(obj) if revoxelise or photos is not None or (recolor and delight_shader == "path traced")
            else None)
    if revoxelise:
        rgba = _voxelised_again(obj, resolution, mesh)
    seed = photo_seed(int(obj["index"]), int(obj.get("part", 0)))
    if recolor or photos is not None:
        camera_file = source / obj["source_camera"]
        pose = load_pose(camera_file)
        if photos is not None:
            pose = pose.at_size(photos[0], photos[0])
        try:
            source_scene = lit_photo_scene(pose, floor_color)
        except InputError as exc:
            raise InputError(exc.problem, camera_file) from None
        if photos is None:
            photo = load_image(source / obj["source_image"])[0]
        else:  # with the seed generation rendered it with
            photo = render_pathtraced(source_scene, mesh, spp=photos[1], seed=seed, denoise=photos[2]).image
            save_png(out / obj["source_image"], photo)
            save_json(out / obj["source_camera"], pose.to_dict())
    if recolor:
        albedo, known = _divided_light(photo, source_scene, rgba, mesh, delight_shader, seed)
        rgba = color_voxels_from_photo(rgba, pose.object_to_world(), albedo, pose.camera,
                                       mirror=bool(obj["mirror_symmetry_used"]), trusted=known,
                                       hidden_rule=hidden_rule).rgba
    return rgba, recolor or revoxelise


def _scene_files(samples: list[dict]) -> list[str]:
    """The data folder's files (relative) that the samples' scenes name besides the object: environment images
    and ground textures."""
    found = []
    for sample in samples:
        scene = sample["scene"]
        found += [part[key] for part, key in ((scene.get("environment") or {}, "image"), (scene.get("floor") or {}, "texture"))
                  if part.get(key)]
    return found


def _link_or_copy(source: Path, target: Path) -> None:
    if not source.is_file():
        raise InputError("file not found", source)
    with atomic_path(target) as tmp:
        tmp.unlink()
        try:
            os.link(source, tmp)
        except OSError:
            shutil.copyfile(source, tmp)


def write_manifest(out: Path, config: DataConfig) -> Path:
    """Assemble manifest.json from the records present, in object order."""
    records = [load_json(p) for p in sorted((out / "records").glob("o*.json"))]
    manifest = {
        "format": DATA_FORMAT,
        "config": config.to_dict(),
        "renderer": _renderer_info(config),
        "complete": len(records) == config.objects,
        "objects": [o for r in records for o in (r["object"], *r.get("companions", []))],
        "samples": [s for r in records for s in r["samples"]],
    }
    path = out / "manifest.json"
    save_json(path, manifest)
    return path


def merge_datasets(out: str | Path, parts: list[str | Path]) -> Path:
    """Merge shard folders made with the same config into one folder, as if made by one run."""
    out = Path(out)
    if not parts:
        raise InputError("nothing to merge: give at least one data folder")
    configs = []
    for part in parts:
        stored = load_json(Path(part) / "config.json")
        configs.append(stored.get("config"))
    if any(c != configs[0] for c in configs):
        raise InputError("the folders were made with different arguments and cannot be merged")
    config = DataConfig.from_dict(configs[0])
    prepare_folder(out, config)
    for part in map(Path, parts):
        for record_file in sorted((part / "records").glob("o*.json")):
            record = json.loads(record_file.read_text())
            files = [o[key] for o in (record["object"], *record.get("companions", []))
                     for key in ("voxels", "source_image", "source_camera")]
            files += [f for s in record["samples"] for f in (s["target"], s["splat"])]
            files += sorted(set(_scene_files(record["samples"])))
            for rel in files:
                if not (out / rel).exists():
                    with atomic_path(out / rel) as tmp:
                        shutil.copyfile(part / rel, tmp)
            save_json(out / "records" / record_file.name, record)
    return write_manifest(out, config)
