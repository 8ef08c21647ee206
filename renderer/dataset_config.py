"""The configuration of `nvr data generate`: everything that determines a data set, checked before anything is made.

Plain dataclasses and names, cheap to import, so the command line reads the options (app/options.py) without the
renderers. A field with help in its metadata is a command-line option.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from renderer.errors import InputError
from renderer.limits import DEFAULT_RESOLUTION, MAX_IMAGE_SIZE, MAX_RESOLUTION, MIN_IMAGE_SIZE, MIN_RESOLUTION

HIDDEN_RULES = ("blend", "ray")  # how voxels the photo does not show well are colored (renderer/photo.py)
# Option limits: far above any use (the paper's set is 2,000 objects x 20 views), low enough to catch a typo.
MAX_OBJECTS = 1_000_000
MAX_VIEWS = 1000
MAX_SPP = 65536
MAX_WORKERS = 256
MAX_SCENE_OBJECTS = 4  # objects a data set's scene holds at most: more leave no room apart in view at its scales
SETTINGS = ("single", "default", "textured")
# How the target views are lit: the paper's area light; an environment alone; or each view one of area light,
# environment, or both (renderer/dataset.py, sample_lighting).
LIGHTINGS = ("area", "environment", "mixed")
GROUNDS = ("plain", "textured", "mixed")
SPLITS = ("train", "test")
DELIGHT_SHADERS = ("path traced", "object voxels", "camera grid")  # DataConfig.delight_shader: today's first
MADE_DELIGHT_SHADERS = DELIGHT_SHADERS[:2]  # those a set can still be made with



@dataclass(frozen=True)
class DataConfig:
    """Everything that determines a data set; stored in its config.json."""

    setting: str = field(default="single", metadata={"help": "appearance: single color, default (colors from a photo), textured", "choices": SETTINGS})
    split: str = field(default="train", metadata={"help": "train or test (test: seeds never trained on, sequences of views)", "choices": SPLITS})
    objects: int = field(default=10, metadata={"help": "number of objects (of scenes, with --scene-objects)", "required": True})
    views: int = field(default=20, metadata={"help": "views per object (test: frames per sequence)"})
    size: int = field(default=256, metadata={"help": "image side in pixels"})
    spp: int = field(default=16, metadata={"help": "path tracing samples per pixel"})
    denoise: bool = field(default=True, metadata={"help": "keep the raw path-traced targets", "flag": "--no-denoise"})
    seed: int = field(default=0, metadata={"help": "random seed of the first object"})
    categories: tuple[str, ...] = field(default=("chair",), metadata={"help": "comma-separated object categories: chair, table, sofa, stool, solids (random assemblies, for training), novel (the generalisation shapes, for testing)", "comma": True})
    resolution: int = field(default=DEFAULT_RESOLUTION, metadata={"help": "object voxels per side", "flag": "--res"})
    delight: bool = field(default=True, metadata={"help": "photo-colored voxels keep the source photo's light (the paper's inputs)", "flag": "--no-delight"})
    hidden_rule: str = field(default="blend", metadata={"help": "voxels the source photo does not show: a blend of the colors seen around them, or the paper's first voxel on the camera ray", "flag": "--hidden-voxels", "choices": HIDDEN_RULES})
    # What the light divided out was computed with (a set's colors follow it): "path traced", renders of the mesh
    # (renderer.photo.unmixed_albedo); "object voxels", the voxel shader (photo_albedo); "camera grid", the voxel
    # shader before it drew the object's own voxels (no longer made).
    delight_shader: str = field(default="path traced", metadata={"help": "how the source photo's light is divided out: two path-traced renders of the mesh (default), or the voxel shader's light (the shipped models' training sets)", "choices": MADE_DELIGHT_SHADERS})
    photo_size: int = field(default=0, metadata={"help": "side in pixels of the source photo that colors the voxels (0: --size)"})
    lighting: str = field(default="area", metadata={"help": "how target views are lit: the area light, an environment (sky or a made map), or mixed (area, environment or both per view)", "choices": LIGHTINGS})
    materials: bool = field(default=False, metadata={"help": "give each object a random material (matte to mirror-like, plastic or metal)"})
    grounds: str = field(default="plain", metadata={"help": "the ground of each view: plain (a color), textured (an image of the split's texture families, on a square or a disk), or mixed (either, half and half)", "choices": GROUNDS})
    scene_objects: int = field(default=1, metadata={"help": f"objects per scene: each scene holds 1 to this many (at most {MAX_SCENE_OBJECTS}), placed apart on the floor, so that they shadow and reflect each other"})

    def __post_init__(self) -> None:
        if self.photo_size == self.size:  # one config per set: a photo of the images' size is written 0
            object.__setattr__(self, "photo_size", 0)

    @property
    def source_size(self) -> int:
        """The source photo's side in pixels."""
        return self.photo_size or self.size

    def check(self) -> None:
        """Refuse values no data set can be made with, naming the option and its limits (before anything is written)."""
        if self.setting not in SETTINGS:
            raise InputError(f"unknown setting {self.setting!r} (choose from {', '.join(SETTINGS)})")
        if self.split not in SPLITS:
            raise InputError(f"unknown split {self.split!r} (choose from {', '.join(SPLITS)})")
        for name, low, high in (("objects", 1, MAX_OBJECTS), ("views", 1, MAX_VIEWS), ("spp", 1, MAX_SPP),
                                ("size", MIN_IMAGE_SIZE, MAX_IMAGE_SIZE), ("seed", 0, 2**32 - 1),
                                ("res", MIN_RESOLUTION, MAX_RESOLUTION)):
            value = getattr(self, "resolution" if name == "res" else name)
            if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
                raise InputError(f"--{name} must be a whole number from {low} to {high}, got {value!r}")
        size = self.photo_size
        if isinstance(size, bool) or not isinstance(size, int) or not (size == 0 or MIN_IMAGE_SIZE <= size <= MAX_IMAGE_SIZE):
            raise InputError(f"--photo-size must be 0 (the images' size) or a whole number from {MIN_IMAGE_SIZE} to "
                             f"{MAX_IMAGE_SIZE}, got {self.photo_size!r}")
        value = self.scene_objects
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_SCENE_OBJECTS:
            raise InputError(f"--scene-objects must be a whole number from 1 to {MAX_SCENE_OBJECTS}, got {value!r}")
        if self.lighting not in LIGHTINGS:
            raise InputError(f"unknown lighting {self.lighting!r} (choose from {', '.join(LIGHTINGS)})")
        if self.grounds not in GROUNDS:
            raise InputError(f"unknown grounds {self.grounds!r} (choose from {', '.join(GROUNDS)})")
        if not self.categories:
            raise InputError("at least one object category is needed")
        from renderer.objects.generate import CATEGORIES  # the generators: imported only when a set is to be made

        for name in self.categories:
            if name not in CATEGORIES:
                raise InputError(f"--categories: unknown category {name!r} (choose from {', '.join(CATEGORIES)})")
        check_hidden_rule(self.hidden_rule)
        if self.delight_shader not in MADE_DELIGHT_SHADERS:
            raise InputError(f"delight shader {self.delight_shader!r} is unknown or no longer made "
                             f"(choose from {', '.join(MADE_DELIGHT_SHADERS)})")

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["categories"] = list(self.categories)
        return d

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> DataConfig:
        data = dict(data)
        data["categories"] = tuple(data.get("categories", ("chair",)))
        data.setdefault("delight", False)  # data sets made before the light was divided out
        data.setdefault("hidden_rule", "ray")  # and before hidden voxels took a blend of the colors around them
        data.setdefault("delight_shader", "camera grid")  # and before the shader drew the object's own voxels
        data.setdefault("photo_size", 0)  # and before the source photo had a size of its own
        data.setdefault("lighting", "area")  # and before environments and materials
        data.setdefault("materials", False)
        data.setdefault("scene_objects", 1)  # and before scenes of several objects
        return cls(**data)


def check_hidden_rule(hidden_rule: str) -> None:
    """InputError unless `hidden_rule` is one of HIDDEN_RULES."""
    if hidden_rule not in HIDDEN_RULES:
        raise InputError(f"unknown rule for hidden voxels {hidden_rule!r} (choose from {', '.join(HIDDEN_RULES)})")
