"""The scene as data: up to MAX_OBJECTS objects on a ground plane, one rectangular area light, an optional
environment, one camera.

A `Scene` mirrors the JSON scene file (version 2) key for key; a version 1 file (one "object", its paint strokes at
the top level) reads as a one-object scene, its floor strokes folded into the floor's color. It is immutable: an edit
makes a new scene with `dataclasses.replace`, which lets undo keep old scenes and lets the
live engine see exactly which part changed.

Fixed set-up (paper section 3.1): white area light, ambient light, focal length 40 mm on a
36 mm sensor, camera at a fixed distance looking at the scene centre, diffuse object,
slightly specular floor. World axes: y up, the floor is the plane y = 0, the camera sits
on the +z side of the scene at azimuth 0.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from renderer.errors import InputError
from renderer.io import check_path_text, load_json, save_json
from renderer.limits import (
    DEFAULT_RESOLUTION,
    MAX_IMAGE_SIZE,
    MAX_OBJECTS,
    MAX_PAINT_STROKES,
    MAX_RESOLUTION,
    MIN_IMAGE_SIZE,
    MIN_RESOLUTION,
)

SCENE_VERSION = 2  # what save_scene writes; load_scene reads 1 and 2

# Fixed set-up, in world units (the object is normalised to a unit box).
OBJECT_SIZE = 1.0  # longest side of a normalised object's bounding box
CAMERA_DISTANCE = 2.8  # from the look-at point
LOOK_AT = (0.0, 0.5, 0.0)  # scene centre the camera looks at
FOCAL_MM = 40.0
SENSOR_MM = 36.0  # sensor width (and height: images are square)
LIGHT_SIZE = 1.0  # side of the square area light, facing down
LIGHT_RADIANCE = 14.0  # white, linear; renderer/pathtrace/path_tracer.py explains the exposure
AMBIENT_RADIANCE = 0.2  # uniform white environment light (linear), also the background seen past the floor
FLOOR_ROUGHNESS = 0.1  # GGX alpha of the floor's clear coat: blurred but visible reflections
FLOOR_IOR = 1.5  # coat index of refraction: 4 % reflectance head on, more at grazing angles
FLOOR_HALF_SIZE = 10.0  # the floor is a square of side 20 centred under the scene
FLOOR_DISK_RADIUS = 3.0  # or a disk (the paper's textured ground), its edge in view behind the object
FLOOR_SHAPES = ("square", "disk")
GRID_SIZE = 128  # voxels per side of the camera-aligned scene grid
# The grid the voxel shader stands in for unless told otherwise: it merges no object voxels at scales above a half
# (renderer.grid.shader_pool_factors), where the network's grid merges them in pairs; sharper, and on the test split
# about 40 % lower in MSE (docs/results.md), for a slower light edit (more occluders cast shadows).
SHADER_GRID_SIZE = 2 * GRID_SIZE
GRID_EXTENT = 2.56  # world units per side of that grid (one voxel = 0.02)

# Training ranges (paper section 4.1); values outside are accepted with a warning.
ELEVATION_RANGE = (5.0, 50.0)
TRANSLATION_RANGE = (-0.5, 0.5)
LIGHT_XZ_RANGE = (-1.5, 1.5)
LIGHT_Y_RANGE = (2.5, 3.0)
SCALE_RANGE = (0.75, 1.25)
# Scenes of 1 to 4 objects (renderer/dataset.py sample_layout), which the shipped NVR+ trained on too: each object's
# size (its box's side, each axis within GROUP_AXIS_SPREAD of it) and where its centre stands.
GROUP_SCALE_RANGE = (0.45, 0.85)
GROUP_AXIS_SPREAD = 0.1
GROUP_VIEW_X = 0.9  # |x| at most
GROUP_VIEW_Z = (-0.9, 0.5)  # +z faces the camera

# Hard limits; values outside them are impossible and rejected (sizes: renderer/limits.py).
SIMILARITIES = ("rgb", "perceptual")  # a region fill's color comparisons (renderer/paint.py)
MAX_ABS_POSITION = 100.0
MAX_ABS_ANGLE = 36000.0  # degrees: a hundred turns, far beyond what a drag makes, far from float32's limits
MAX_STRENGTH = 1000.0  # environment strength
TURBIDITY_RANGE = (1.0, 10.0)  # the sky model's range (Hosek-Wilkie, as Mitsuba's sunsky)
MAX_TEXTURE_SCALE = 100.0  # world units a floor texture's one repeat may span (the floor is 20 across)


@dataclass(frozen=True)
class PaintOp:
    """One bucket-fill stroke, replayed in order on the object's voxels.

    target "region": fill the 6-connected region of similar color around `seed` (an index
    into the object's own N^3 grid, so the stroke survives moves); "object": the whole
    object; "floor": the floor color.
    """

    target: str
    color: tuple[float, float, float]
    seed: tuple[int, int, int] | None = None
    tolerance: float = 0.1
    similarity: str = "rgb"  # how a region fill compares colors: one of SIMILARITIES (renderer/paint.py)


@dataclass(frozen=True)
class MaterialSpec:
    """The object's surface, as Disney's principled BSDF: GGX `roughness` (alpha = roughness^2); `specular`, the
    dielectric reflectance head on over 0.08 (0.5: index 1.5, a plastic or ceramic); `metallic`, the share that
    reflects like a metal tinted by the albedo. Specular and metallic 0 is Lambertian (today's object)."""

    roughness: float = 1.0
    specular: float = 0.0
    metallic: float = 0.0

    @property
    def diffuse_only(self) -> bool:
        return self.specular == 0.0 and self.metallic == 0.0


@dataclass(frozen=True)
class ObjectSpec:
    mesh: str | None = None  # path relative to the scene file
    up: str = "y"
    resolution: int = DEFAULT_RESOLUTION
    color: tuple[float, float, float] | None = None  # None: the mesh's own colors
    translation: tuple[float, float] = (0.0, 0.0)  # world x and z
    rotation_deg: float = 0.0  # about the vertical axis
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    voxels: str | None = None  # optional .npz of RGBA object voxels (e.g. captured colors)
    material: MaterialSpec = field(default_factory=MaterialSpec)
    paint: tuple[PaintOp, ...] = ()  # region and whole-object fills, replayed in order on this object's voxels
    name: str | None = None  # shown in the editor's object list; unique within a scene


@dataclass(frozen=True)
class FloorSpec:
    """The ground: a diffuse `color` (sRGB) under a glossy coat, or with `texture` (an image, path relative to the
    scene file) the image's albedo instead, repeated every `texture_scale` world units (renderers take the image's
    mean where they need one color; the editor sets `color` to it when a texture is loaded)."""

    color: tuple[float, float, float] = (0.53, 0.64, 0.78)
    texture: str | None = None
    texture_scale: float = 1.0
    shape: str = "square"  # one of FLOOR_SHAPES: the square FLOOR_HALF_SIZE wide, or a disk of FLOOR_DISK_RADIUS

    def holds(self, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """Whether the floor holds the points at world (x, z) (bool array)."""
        if self.shape == "disk":
            return x * x + z * z <= FLOOR_DISK_RADIUS**2
        return (np.abs(x) <= FLOOR_HALF_SIZE) & (np.abs(z) <= FLOOR_HALF_SIZE)


@dataclass(frozen=True)
class LightSpec:
    position: tuple[float, float, float] = (1.0, 2.75, 0.5)
    enabled: bool = True  # False: the environment alone lights the scene


@dataclass(frozen=True)
class SkySpec:
    """A physical sun and sky (renderer/environment.py); azimuth from the camera's side (+z) towards +x."""

    sun_elevation_deg: float = 35.0
    sun_azimuth_deg: float = 120.0
    turbidity: float = 3.0


@dataclass(frozen=True)
class EnvironmentSpec:
    """Light from all around the scene, instead of the uniform ambient light: an equirectangular image (path relative
    to the scene file) or a sky, turned by `rotation_deg` about the vertical axis and scaled by `strength`."""

    image: str | None = None
    sky: SkySpec | None = None
    rotation_deg: float = 0.0
    strength: float = 1.0


@dataclass(frozen=True)
class CameraSpec:
    elevation_deg: float = 30.0


@dataclass(frozen=True)
class Scene:
    objects: tuple[ObjectSpec, ...] = (ObjectSpec(),)  # 1 to MAX_OBJECTS; where their voxels meet the later one wins
    floor: FloorSpec = field(default_factory=FloorSpec)
    light: LightSpec = field(default_factory=LightSpec)
    camera: CameraSpec = field(default_factory=CameraSpec)
    image_size: int = 256
    environment: EnvironmentSpec | None = None  # None: the uniform ambient light
    base_dir: Path = field(default=Path("."), compare=False)  # where relative paths start

    @classmethod
    def single(cls, object: ObjectSpec | None = None, paint: tuple[PaintOp, ...] = (), **parts: Any) -> Scene:
        """A one-object scene (unvalidated, like the constructor); `paint`: the object's strokes."""
        obj = ObjectSpec() if object is None else object
        return cls(objects=(replace(obj, paint=tuple(paint)) if paint else obj,), **parts)

    @property
    def object(self) -> ObjectSpec:
        """The scene's only object, for the tools that draw or edit one (InputError when it holds several)."""
        if len(self.objects) != 1:
            raise InputError(f"this tool draws and edits one object; the scene holds {len(self.objects)}")
        return self.objects[0]

    @property
    def paint(self) -> tuple[PaintOp, ...]:
        """The only object's paint strokes (see `object`)."""
        return self.object.paint

    def alone(self, index: int) -> Scene:
        """The scene holding object `index` alone: what the one-object tools and each object's own stages read."""
        return replace(self, objects=(self.objects[index],))

    def file(self, relative: str | None) -> Path | None:
        """A path from the scene file (relative to its folder) as a path to open, or None."""
        return None if relative is None else self.base_dir / relative

    def mesh_path(self) -> Path | None:
        """Path of the only object's mesh, or None."""
        return self.file(self.object.mesh)

    def voxels_path(self) -> Path | None:
        return self.file(self.object.voxels)

    def floor_texture_path(self) -> Path | None:
        """Absolute path of the floor's texture image, or None."""
        return None if self.floor.texture is None else (self.base_dir / self.floor.texture)

    def environment_path(self) -> Path | None:
        """Absolute path of the environment image, or None."""
        env = self.environment
        return None if env is None or env.image is None else (self.base_dir / env.image)

    def with_changes(self, **parts: Any) -> Scene:
        """A copy with whole parts replaced, validated (e.g. `light=LightSpec((0, 3, 0))`); `object` and `paint`
        replace the only object and its strokes."""
        scene = replaced(self, **parts)
        validate(scene)
        return scene

    def to_dict(self) -> dict[str, Any]:
        """The JSON form (version 2); keys that are None, and optional parts left at their defaults, are left out."""
        light: dict[str, Any] = {"position": list(self.light.position)}
        if not self.light.enabled:
            light["enabled"] = False
        data: dict[str, Any] = {
            "version": SCENE_VERSION,
            "objects": [_object_to_dict(o) for o in self.objects],
            "floor": _floor_to_dict(self.floor),
            "light": light,
            "camera": {"elevation_deg": self.camera.elevation_deg},
            "image_size": self.image_size,
        }
        if self.environment is not None:
            data["environment"] = {k: v for k, v in asdict(self.environment).items() if v is not None}
        return data


def replaced(scene: Scene, **parts: Any) -> Scene:
    """dataclasses.replace, where `object` (and `paint`, its strokes) replace a one-object scene's object; unvalidated."""
    obj, paint = parts.pop("object", None), parts.pop("paint", None)
    if obj is not None or paint is not None:
        obj = scene.object if obj is None else obj
        parts["objects"] = (obj if paint is None else replace(obj, paint=tuple(paint)),)
    return replace(scene, **parts)


def _object_to_dict(o: ObjectSpec) -> dict[str, Any]:
    data = {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(o).items()
            if v is not None and k not in ("material", "paint", "name")}
    if o.name is not None:
        data = {"name": o.name, **data}
    if o.material != MaterialSpec():
        data["material"] = asdict(o.material)
    if o.paint:
        data["paint"] = [_paint_to_dict(op) for op in o.paint]
    return data


def _floor_to_dict(floor: FloorSpec) -> dict[str, Any]:
    """The floor's JSON form: its color, and its texture and scale only when it has one (older files stay as they
    were)."""
    data: dict[str, Any] = {"color": list(floor.color)}
    if floor.texture is not None:
        data["texture"] = floor.texture
        data["texture_scale"] = floor.texture_scale
    if floor.shape != "square":
        data["shape"] = floor.shape
    return data


def _paint_to_dict(op: PaintOp) -> dict[str, Any]:
    d: dict[str, Any] = {"target": op.target, "color": list(op.color)}
    if op.seed is not None:
        d["seed"] = list(op.seed)
    if op.target == "region":
        d["tolerance"] = op.tolerance
        if op.similarity != "rgb":  # files from before the perceptual fill stay as they were
            d["similarity"] = op.similarity
    return d


# --- parsing -------------------------------------------------------------------------------


class _Reader:
    """Typed access to a JSON dict that reports problems as 'file: key: problem'."""

    def __init__(self, path: Path | None):
        self.path = path

    def fail(self, key: str, problem: str) -> InputError:
        return InputError(f"{key}: {problem}", self.path)

    def section(self, data: dict, key: str, required: bool = False, name: str | None = None) -> dict:
        name = key if name is None else name
        if key not in data:
            if required:
                raise self.fail(name, "missing")
            return {}
        value = data[key]
        if not isinstance(value, dict):
            raise self.fail(name, f"must be an object, got {json_type(value)}")
        return value

    def known_keys(self, data: dict, keys: Iterable[str], where: str = "") -> None:
        """Refuse a key the format does not have (a misspelt key would otherwise be ignored), naming the nearest."""
        keys = list(keys)
        for key in data:
            if key not in keys:
                near = difflib.get_close_matches(str(key), keys, n=1)
                hint = f' (did you mean "{near[0]}"?)' if near else f" (known: {', '.join(keys)})"
                raise self.fail(f"{where}{key}", f"unknown key{hint}")

    def boolean(self, data: dict, key: str, name: str, default: bool) -> bool:
        value = data.get(key, default)
        if not isinstance(value, bool):
            raise self.fail(name, f"must be true or false, got {json_type(value)}")
        return value

    def number(self, data: dict, key: str, name: str, default: float) -> float:
        value = data.get(key, default)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(name, f"must be a number, got {json_type(value)}")
        value = float(value)
        if not math.isfinite(value):
            raise self.fail(name, "must be finite")
        return value

    def vector(self, data: dict, key: str, name: str, length: int, default: tuple) -> tuple:
        value = data.get(key, default)
        if not isinstance(value, (list, tuple)) or len(value) != length:
            raise self.fail(name, f"must be a list of {length} numbers")
        out = []
        for i, v in enumerate(value):
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise self.fail(f"{name}[{i}]", f"must be a number, got {json_type(v)}")
            if not math.isfinite(float(v)):
                raise self.fail(f"{name}[{i}]", "must be finite")
            out.append(float(v))
        return tuple(out)

    def string(self, data: dict, key: str, name: str, default: str | None) -> str | None:
        value = data.get(key, default)
        if value is not None and not isinstance(value, str):
            raise self.fail(name, f"must be a string, got {json_type(value)}")
        return value

    def file_path(self, data: dict, key: str, name: str) -> str | None:
        """A file path: a string the file system can hold (length, characters), or None."""
        value = self.string(data, key, name, None)
        if value is not None:
            problem = check_path_text(value)
            if problem:
                raise self.fail(name, problem)
        return value


def json_type(value: Any) -> str:
    return {dict: "object", list: "list", str: "string", bool: "boolean", type(None): "null"}.get(
        type(value), type(value).__name__
    )


def scene_from_dict(data: Any, path: str | Path | None = None) -> Scene:
    """Build and validate a Scene from its JSON form (version 1 or 2); problems raise InputError naming `path`."""
    path = None if path is None else Path(path)
    r = _Reader(path)
    if not isinstance(data, dict):
        raise InputError("a scene file must hold a JSON object", path)
    version = data.get("version")
    if version not in (1, SCENE_VERSION):
        raise r.fail("version", f"unsupported scene version {version!r} (expected 1 or {SCENE_VERSION})")
    r.known_keys(data, SCENE_KEYS_V1 if version == 1 else SCENE_KEYS)
    f = r.section(data, "floor")
    r.known_keys(f, FLOOR_KEYS, "floor.")
    floor = FloorSpec(r.vector(f, "color", "floor.color", 3, FloorSpec().color), r.file_path(f, "texture", "floor.texture"),
                      r.number(f, "texture_scale", "floor.texture_scale", FloorSpec().texture_scale),
                      r.string(f, "shape", "floor.shape", "square"))
    if version == 1:  # one object; its strokes and the floor's at the top level
        strokes = _paint_from_list(r, data.get("paint", []), "paint", _paint_side(data.get("object")))
        floor_strokes = [op for op in strokes if op.target == "floor"]
        if floor_strokes:  # a floor fill sets the floor's color (renderer.paint.apply_paint)
            floor = replace(floor, color=tuple(floor_strokes[-1].color))
        o = r.section(data, "object", required=True)
        objects = (_object_from_dict(r, o, "object", tuple(op for op in strokes if op.target != "floor")),)
    else:
        entries = data.get("objects")
        if not isinstance(entries, list):
            raise r.fail("objects", "missing" if entries is None else f"must be a list of objects, got {json_type(entries)}")
        if not 1 <= len(entries) <= MAX_OBJECTS:
            raise r.fail("objects", f"{len(entries)} objects; a scene holds 1 to {MAX_OBJECTS}")
        objects = []
        for i, o in enumerate(entries):
            name = f"objects[{i}]"
            if not isinstance(o, dict):
                raise r.fail(name, f"must be an object, got {json_type(o)}")
            paint = _paint_from_list(r, o.get("paint", []), f"{name}.paint", _paint_side(o))
            if any(op.target == "floor" for op in paint):
                raise r.fail(f"{name}.paint", 'an object\'s fills are "region" or "object"; the floor\'s color is floor.color')
            objects.append(_object_from_dict(r, o, name, paint))
        objects = tuple(objects)
    li = r.section(data, "light")
    r.known_keys(li, ("position", "enabled"), "light.")
    light = LightSpec(r.vector(li, "position", "light.position", 3, LightSpec().position),
                      r.boolean(li, "enabled", "light.enabled", True))
    c = r.section(data, "camera")
    r.known_keys(c, ("elevation_deg",), "camera.")
    camera = CameraSpec(r.number(c, "elevation_deg", "camera.elevation_deg", 30.0))
    environment = _environment_from_dict(r, data) if "environment" in data else None
    image_size = data.get("image_size", 256)
    if isinstance(image_size, bool) or not isinstance(image_size, int):
        raise r.fail("image_size", f"must be an integer, got {json_type(image_size)}")
    base_dir = path.parent if path is not None else Path(".")
    scene = Scene(objects, floor, light, camera, image_size, environment, base_dir)
    validate(scene, path, object_key=(lambda i: "object") if version == 1 else (lambda i: f"objects[{i}]"))
    return scene


def _object_from_dict(r: _Reader, o: dict, name: str, paint: tuple[PaintOp, ...]) -> ObjectSpec:
    """One object's entry (`name`: how messages name it, "object" or "objects[i]")."""
    r.known_keys(o, OBJECT_KEYS if name != "object" else OBJECT_KEYS_V1, f"{name}.")
    resolution = o.get("resolution", DEFAULT_RESOLUTION)
    if isinstance(resolution, bool) or not isinstance(resolution, int):
        raise r.fail(f"{name}.resolution", f"must be an integer, got {json_type(resolution)}")
    color = None if o.get("color") is None else r.vector(o, "color", f"{name}.color", 3, (0, 0, 0))
    m = r.section(o, "material", name=f"{name}.material")
    r.known_keys(m, MATERIAL_KEYS, f"{name}.material.")
    material = MaterialSpec(**{key: r.number(m, key, f"{name}.material.{key}", getattr(MaterialSpec(), key))
                               for key in MATERIAL_KEYS})
    return ObjectSpec(
        mesh=r.file_path(o, "mesh", f"{name}.mesh"),
        up=r.string(o, "up", f"{name}.up", "y"),
        resolution=resolution,
        color=color,
        translation=r.vector(o, "translation", f"{name}.translation", 2, (0.0, 0.0)),
        rotation_deg=r.number(o, "rotation_deg", f"{name}.rotation_deg", 0.0),
        scale=r.vector(o, "scale", f"{name}.scale", 3, (1.0, 1.0, 1.0)),
        voxels=r.file_path(o, "voxels", f"{name}.voxels"),
        material=material,
        paint=paint,
        name=r.string(o, "name", f"{name}.name", None),
    )


def _paint_side(o: Any) -> int:
    """The voxels per side a stroke's seed indexes: the object's resolution, or the largest for a voxel file."""
    if not isinstance(o, dict) or o.get("voxels") is not None:
        return MAX_RESOLUTION
    resolution = o.get("resolution", DEFAULT_RESOLUTION)
    return resolution if isinstance(resolution, int) and not isinstance(resolution, bool) else MAX_RESOLUTION


def _paint_from_list(r: _Reader, paint_data: Any, where: str, side: int) -> tuple[PaintOp, ...]:
    """Fill strokes from their JSON list (`where`: its key in messages; `side`: the seeds' bound)."""
    if not isinstance(paint_data, list):
        raise r.fail(where, "must be a list of fill operations")
    if len(paint_data) > MAX_PAINT_STROKES:
        raise r.fail(where, f"{len(paint_data)} operations; a scene holds at most {MAX_PAINT_STROKES}")
    paint = []
    for i, p in enumerate(paint_data):
        name = f"{where}[{i}]"
        if not isinstance(p, dict):
            raise r.fail(name, "must be an object")
        r.known_keys(p, ("target", "color", "seed", "tolerance", "similarity"), f"{name}.")
        seed = p.get("seed")
        if seed is not None:
            if not isinstance(seed, list) or len(seed) != 3 or not all(isinstance(s, int) and not isinstance(s, bool) for s in seed):
                raise r.fail(f"{name}.seed", "must be a list of 3 integers")
            if not all(0 <= s < side for s in seed):
                raise r.fail(f"{name}.seed", f"must be voxel indices from 0 to {side - 1}, got {seed}")
            seed = tuple(seed)
        paint.append(
            PaintOp(
                target=r.string(p, "target", f"{name}.target", "region"),
                color=r.vector(p, "color", f"{name}.color", 3, (0, 0, 0)),
                seed=seed,
                tolerance=r.number(p, "tolerance", f"{name}.tolerance", 0.1),
                similarity=r.string(p, "similarity", f"{name}.similarity", "rgb"),
            )
        )
    return tuple(paint)


FLOOR_KEYS = ("color", "texture", "texture_scale", "shape")
SCENE_KEYS = ("version", "objects", "floor", "light", "camera", "image_size", "environment")
SCENE_KEYS_V1 = ("version", "object", "floor", "light", "camera", "image_size", "paint", "environment")
OBJECT_KEYS_V1 = ("mesh", "up", "resolution", "color", "translation", "rotation_deg", "scale", "voxels", "material")
OBJECT_KEYS = ("name", *OBJECT_KEYS_V1, "paint")
MATERIAL_KEYS = ("roughness", "specular", "metallic")
SKY_KEYS = ("sun_elevation_deg", "sun_azimuth_deg", "turbidity")


def _environment_from_dict(r: _Reader, data: dict) -> EnvironmentSpec:
    e = r.section(data, "environment")
    r.known_keys(e, ("image", "sky", "rotation_deg", "strength"), "environment.")
    sky = None
    if "sky" in e:
        s = r.section(e, "sky", name="environment.sky")
        r.known_keys(s, SKY_KEYS, "environment.sky.")
        sky = SkySpec(**{key: r.number(s, key, f"environment.sky.{key}", getattr(SkySpec(), key)) for key in SKY_KEYS})
    return EnvironmentSpec(image=r.file_path(e, "image", "environment.image"), sky=sky,
                           rotation_deg=r.number(e, "rotation_deg", "environment.rotation_deg", 0.0),
                           strength=r.number(e, "strength", "environment.strength", 1.0))


def validate(scene: Scene, path: str | Path | None = None,
             object_key: Callable[[int], str] | None = None) -> None:
    """Raise InputError for impossible values (NaN, scale <= 0, light at or below the floor, ...). `object_key`: how
    messages name object i (default "object" in a one-object scene, else "objects[i]")."""

    def fail(key: str, problem: str) -> InputError:
        return InputError(f"{key}: {problem}", path)

    if not 1 <= len(scene.objects) <= MAX_OBJECTS:
        raise fail("objects", f"{len(scene.objects)} objects; a scene holds 1 to {MAX_OBJECTS}")
    if object_key is None:
        object_key = (lambda i: "object") if len(scene.objects) == 1 else (lambda i: f"objects[{i}]")
    values = [*scene.light.position, scene.camera.elevation_deg]
    if not all(math.isfinite(v) for v in values):
        raise InputError("scene holds a NaN or infinite value", path)
    names: dict[str, int] = {}
    for i, o in enumerate(scene.objects):
        _validate_object(o, object_key(i), fail)
        if o.name is not None:
            if o.name in names:
                raise fail(f"{object_key(i)}.name", f"{o.name!r} is the name of {object_key(names[o.name])} too; "
                                                    "names are unique")
            names[o.name] = i
    if scene.floor.color is not None and not all(0.0 <= c <= 1.0 for c in scene.floor.color):
        raise fail("floor.color", f"sRGB values must be in [0, 1], got {list(scene.floor.color)}")
    if scene.floor.shape not in FLOOR_SHAPES:
        raise fail("floor.shape", f'must be "square" or "disk", got {scene.floor.shape!r}')
    if not 0.0 < scene.floor.texture_scale <= MAX_TEXTURE_SCALE:
        raise fail("floor.texture_scale", f"must be in (0, {MAX_TEXTURE_SCALE:g}] world units, got {scene.floor.texture_scale}")
    lx, ly, lz = scene.light.position
    if ly <= 0.0:
        raise fail("light.position", f"the light must be above the floor (y > 0), got y = {ly}")
    if max(abs(lx), abs(ly), abs(lz)) > MAX_ABS_POSITION:
        raise fail("light.position", f"must be within +-{MAX_ABS_POSITION}")
    if not 0.0 <= scene.camera.elevation_deg < 90.0:
        raise fail("camera.elevation_deg", f"must be in [0, 90), got {scene.camera.elevation_deg}")
    env = scene.environment
    if env is not None:
        if (env.image is None) == (env.sky is None):
            raise fail("environment", 'needs either "image" or "sky", not both or neither')
        if not math.isfinite(env.rotation_deg) or abs(env.rotation_deg) > MAX_ABS_ANGLE:
            raise fail("environment.rotation_deg", f"must be within +-{MAX_ABS_ANGLE:g}, got {env.rotation_deg}")
        if not math.isfinite(env.strength) or not 0.0 <= env.strength <= MAX_STRENGTH:
            raise fail("environment.strength", f"must be in [0, {MAX_STRENGTH:g}], got {env.strength}")
        if env.sky is not None:
            sky = env.sky
            if not math.isfinite(sky.sun_elevation_deg) or not 0.0 <= sky.sun_elevation_deg <= 90.0:
                raise fail("environment.sky.sun_elevation_deg", f"must be in [0, 90], got {sky.sun_elevation_deg}")
            if not math.isfinite(sky.sun_azimuth_deg) or abs(sky.sun_azimuth_deg) > MAX_ABS_ANGLE:
                raise fail("environment.sky.sun_azimuth_deg", f"must be within +-{MAX_ABS_ANGLE:g}, got {sky.sun_azimuth_deg}")
            if not math.isfinite(sky.turbidity) or not TURBIDITY_RANGE[0] <= sky.turbidity <= TURBIDITY_RANGE[1]:
                raise fail("environment.sky.turbidity", f"must be in [{TURBIDITY_RANGE[0]:g}, {TURBIDITY_RANGE[1]:g}], "
                                                        f"got {sky.turbidity}")
    if not scene.light.enabled and env is None:
        raise fail("light.enabled", "the area light can be off only when an environment lights the scene")
    if not MIN_IMAGE_SIZE <= scene.image_size <= MAX_IMAGE_SIZE:
        raise fail("image_size", f"must be in [{MIN_IMAGE_SIZE}, {MAX_IMAGE_SIZE}], got {scene.image_size}")


def _validate_object(o: ObjectSpec, key: str, fail: Callable[[str, str], InputError]) -> None:
    """One object's values (`key`: how messages name it); the paint strokes' keys are "paint[j]" in a version 1
    file's one-object scene, as they are written there."""
    values = [*o.translation, o.rotation_deg, *o.scale]
    if not all(math.isfinite(v) for v in values):
        raise fail(key, "holds a NaN or infinite value")
    if o.up not in ("y", "z"):
        raise fail(f"{key}.up", f'must be "y" or "z", got {o.up!r}')
    if not MIN_RESOLUTION <= o.resolution <= MAX_RESOLUTION:
        raise fail(f"{key}.resolution", f"must be in [{MIN_RESOLUTION}, {MAX_RESOLUTION}], got {o.resolution}")
    if o.mesh is None and o.voxels is None:
        raise fail(key, "needs a mesh or a voxels file")
    if any(s <= 0 for s in o.scale):
        raise fail(f"{key}.scale", f"must be positive, got {list(o.scale)}")
    if any(abs(t) > MAX_ABS_POSITION for t in o.translation):
        raise fail(f"{key}.translation", f"must be within +-{MAX_ABS_POSITION}")
    if o.color is not None and not all(0.0 <= c <= 1.0 for c in o.color):
        raise fail(f"{key}.color", f"sRGB values must be in [0, 1], got {list(o.color)}")
    for name, value in asdict(o.material).items():
        if not math.isfinite(value) or not 0.0 <= value <= 1.0:
            raise fail(f"{key}.material.{name}", f"must be in [0, 1], got {value}")
    if o.name is not None and not o.name.strip():
        raise fail(f"{key}.name", "must not be empty")
    where = "paint" if key == "object" else f"{key}.paint"
    if len(o.paint) > MAX_PAINT_STROKES:
        raise fail(where, f"{len(o.paint)} operations; an object holds at most {MAX_PAINT_STROKES}")
    for i, op in enumerate(o.paint):
        if op.target not in ("region", "object"):
            raise fail(f"{where}[{i}].target", f'must be "region" or "object", got {op.target!r}')
        if op.target == "region" and op.seed is None:
            raise fail(f"{where}[{i}].seed", "a region fill needs a seed voxel")
        if not all(0.0 <= c <= 1.0 for c in op.color):
            raise fail(f"{where}[{i}].color", "sRGB values must be in [0, 1]")
        if not 0.0 <= op.tolerance <= 1.0:
            raise fail(f"{where}[{i}].tolerance", "must be in [0, 1]")
        if op.similarity not in SIMILARITIES:
            raise fail(f"{where}[{i}].similarity", f"must be one of {', '.join(SIMILARITIES)}, got {op.similarity!r}")


def needs_environment_shading(scene: Scene) -> bool:
    """Whether the scene holds more than the area-light set-up (an environment, the area light off, an object that is
    not diffuse, a textured or round floor): the shader's environment path draws it, and only a network that reads the
    environment (config.environment_input) corrects it."""
    return (scene.environment is not None or not scene.light.enabled
            or any(not o.material.diffuse_only for o in scene.objects)
            or scene.floor.texture is not None or scene.floor.shape != "square")


def range_warnings(scene: Scene) -> list[str]:
    """One message per value outside the paper's training range (accepted, but the network extrapolates)."""
    out = []

    def check(name: str, value: float, lo: float, hi: float) -> None:
        if not lo <= value <= hi:
            out.append(f"{name} = {value:g} is outside the training range [{lo:g}, {hi:g}]")

    check("camera.elevation_deg", scene.camera.elevation_deg, *ELEVATION_RANGE)
    # The paper's one object and the layouts of several: the shipped network trained on both.
    x_range = (min(TRANSLATION_RANGE[0], -GROUP_VIEW_X), max(TRANSLATION_RANGE[1], GROUP_VIEW_X))
    z_range = (min(TRANSLATION_RANGE[0], GROUP_VIEW_Z[0]), max(TRANSLATION_RANGE[1], GROUP_VIEW_Z[1]))
    scale_range = (min(SCALE_RANGE[0], round(GROUP_SCALE_RANGE[0] * (1.0 - GROUP_AXIS_SPREAD), 6)),
                   max(SCALE_RANGE[1], round(GROUP_SCALE_RANGE[1] * (1.0 + GROUP_AXIS_SPREAD), 6)))
    for i, o in enumerate(scene.objects):
        key = "object" if len(scene.objects) == 1 else f"objects[{i}]"
        for name, v, span in zip(("x", "z"), o.translation, (x_range, z_range)):
            check(f"{key}.translation.{name}", v, *span)
        for name, v in zip("xyz", o.scale):
            check(f"{key}.scale.{name}", v, *scale_range)
    lx, ly, lz = scene.light.position
    check("light.position.x", lx, *LIGHT_XZ_RANGE)
    check("light.position.y", ly, *LIGHT_Y_RANGE)
    check("light.position.z", lz, *LIGHT_XZ_RANGE)
    return out


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file (format version 1 or 2)."""
    return scene_from_dict(load_json(path), path)


def save_scene(scene: Scene, path: str | Path) -> None:
    """Write a scene file (version 2) atomically; mesh, voxel, environment and floor texture paths are rewritten
    relative to its folder."""
    import os

    folder = Path(path).resolve().parent

    def rebase(value: str | None) -> str | None:
        return None if value is None else os.path.relpath((scene.base_dir / value).resolve(), folder)

    env = scene.environment
    objects = tuple(replace(o, mesh=rebase(o.mesh), voxels=rebase(o.voxels)) for o in scene.objects)
    rebased = replace(scene, objects=objects,
                      environment=None if env is None else replace(env, image=rebase(env.image)),
                      floor=replace(scene.floor, texture=rebase(scene.floor.texture)))
    save_json(path, rebased.to_dict())
