"""Training samples from a data folder made by `nvr data generate` (see renderer/dataset.py).

Each sample gives the network's three inputs and its target, in the convention of models/networks/nvr.py:
voxels (4, D, H, W) in [0, 1], light (3,) in camera coordinates (scaled; with the environment, its switch and the
material after it for a network that reads them: models.networks.nvr.lighting_input), splat (3, S, S) and
target (3, S, S) in sRGB [0, 1]. Object voxels are read once per object and kept (their non-empty voxels); the
scene grid and the shader's buffers are made anew per sample. A scene may hold several objects (sets made with
--scene-objects): their voxels are read alike and meet in one grid (renderer.pipeline.scene_grid_for).
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
from torch.utils.data import Dataset

from models.networks.config import IMAGE_CHANNELS, LIGHT_DIMS, PROBE_DIMS
from renderer.errors import InputError
from renderer.io import load_image, load_json
from renderer.scene import Scene, needs_environment_shading, scene_from_dict


def read_manifest(folder: str | Path) -> dict:
    """The manifest of a data folder, with a clear error when the folder is not a data set."""
    folder = Path(folder)
    path = folder / "manifest.json"
    if not path.is_file():
        raise InputError("no manifest.json: not a data folder made by `nvr data generate`", folder)
    manifest = load_json(path)
    if not isinstance(manifest, dict) or "samples" not in manifest:
        raise InputError("manifest.json has no sample list", folder)
    return manifest


def image_tensor(path: Path) -> torch.Tensor:
    """An sRGB PNG as a (3, H, W) float tensor in [0, 1]."""
    image, _ = load_image(path)
    return torch.from_numpy(np.ascontiguousarray(image.transpose(2, 0, 1)))


def network_inputs(scene: Scene, painted: Sequence[np.ndarray], floor_color, grid_size: int,
                   environment: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
    """The voxel grid (4, D, H, W) (a view of channels-last memory) of a scene whose objects' painted voxels are
    `painted` (one array per object, in order), and the light input (lighting_input: with `environment`, for a
    network that reads the environment and the material) the network reads."""
    from models.networks.nvr import lighting_input
    from renderer.pipeline import scene_grid_for

    grid = scene_grid_for(scene, painted, floor_color, grid_size)
    # A channels-first view of the channels-last grid, not a copy: stacking a batch copies it anyway, several
    # times quicker than numpy's transposing copy per sample.
    voxels = torch.from_numpy(np.asarray(grid, dtype=np.float32)).permute(3, 0, 1, 2)
    return voxels, torch.from_numpy(lighting_input(scene, environment))


# Object voxels a data set keeps in memory per process, as their non-empty voxels (the latest object always): at
# 200^3 an object is 128 MB dense but 4-10 MB stored so, and the 126 objects of three 42-object sets fit; kept dense,
# only 16 did, and a training sample mostly waited for its object's file.
VOXEL_CACHE_BYTES = 2 * 2**30


class _StoredVoxels:
    """Object voxels (N, N, N, 4) kept as the flat indices and rows of their non-empty voxels; `dense()` rebuilds them."""

    def __init__(self, rgba: np.ndarray):
        rows = rgba.reshape(-1, 4)
        self.shape = rgba.shape
        self.flat = np.flatnonzero(rows.any(axis=1)).astype(np.int64)
        self.rows = rows[self.flat]
        self.nbytes = self.flat.nbytes + self.rows.nbytes

    def dense(self) -> np.ndarray:
        rgba = np.zeros(self.shape, dtype=self.rows.dtype)
        rgba.reshape(-1, 4)[self.flat] = self.rows
        return rgba


class VoxelRenderSet(Dataset):
    """Samples of one or several data folders, as network-ready tensors."""

    def __init__(self, folders: list[str | Path] | str | Path, grid_size: int = 128,
                 voxel_cache_bytes: int = VOXEL_CACHE_BYTES,
                 object_resolution: int | None = None, floor_light: bool = False, shading: bool = False,
                 shading_grid_factor: int = 1, shader_quality: str = "full", environment: bool = False):
        folders = [folders] if isinstance(folders, (str, Path)) else list(folders)
        self.items: list[tuple[Path, dict]] = []
        self.settings: list[str] = []
        for folder in map(Path, folders):
            manifest = read_manifest(folder)
            setting = manifest.get("config", {}).get("setting", "unknown")
            samples = manifest["samples"]
            if not isinstance(samples, list):
                raise InputError("manifest.json: samples must be a list", folder)
            for index, sample in enumerate(samples):
                if not (isinstance(sample, dict) and isinstance(sample.get("scene"), dict)
                        and all(isinstance(sample.get(key), str) for key in ("target", "splat"))):
                    raise InputError(f"manifest.json: sample {index} needs a scene and target and splat file names", folder)
                self.items.append((folder, sample))
                self.settings.append(setting)
        if not self.items:
            raise InputError(f"no samples in {', '.join(map(str, folders))}")
        self.grid_size = grid_size
        self.object_resolution = object_resolution  # coarser object voxels, for the resolution study
        self.floor_light = floor_light  # add the lit empty floor (NVR+ with config.floor_light_input)
        self.shading = shading  # add the voxel shader's buffers (NVR+ with config.shading_input)
        self.shading_grid_size = grid_size * shading_grid_factor  # the grid the shader draws from
        self.shader_quality = shader_quality  # 'full' (as trained on) or 'fast': renderer.shading.QUALITIES
        self.environment = environment  # the light input holds the environment and material (config.environment_input)
        self._voxel_cache_bytes = voxel_cache_bytes
        self._voxels: OrderedDict[str, _StoredVoxels] = OrderedDict()  # the objects read last, by voxel file
        self._dense: tuple[tuple[str, ...], list[np.ndarray]] | None = None  # the latest scene's voxels, dense
        # (views come in runs)
        self._shaders = None  # SceneShaders, made on first use (each loader process its own)

    def __getstate__(self) -> dict:
        """For a loader worker process: everything but the voxel cache (each process keeps its own)."""
        state = dict(self.__dict__)
        state["_voxels"], state["_dense"], state["_shaders"] = OrderedDict(), None, None
        return state

    def check_samples(self, image_size: int) -> None:
        """Refuse the set before training when a sample's files are missing or unreadable, or its images
        are not `image_size` pixels square (the network's output size). Reads image headers only."""
        from PIL import Image

        voxel_files = set()
        for index, (folder, sample) in enumerate(self.items):
            scene = self.scene(index)
            if needs_environment_shading(scene) and not self.environment:
                raise InputError(f"sample {sample.get('id', index)} is lit by an environment or has a glossy "
                                 "material, which this network does not read (train --config environment_refiner)",
                                 folder / "manifest.json")
            if self.environment and len(scene.objects) > 1:
                raise InputError(f"sample {sample.get('id', index)} holds several objects; a network that reads "
                                 "the environment reads one object's material", folder / "manifest.json")
            voxel_files.update(scene.file(o.voxels) for o in scene.objects)
            for key in ("target", "splat"):
                path = folder / str(sample.get(key))
                try:
                    with Image.open(path) as image:
                        size = image.size
                except (OSError, ValueError, SyntaxError):
                    raise InputError(f"sample {sample.get('id', index)}: its {key} image is missing or unreadable", path) from None
                if size != (image_size, image_size):
                    raise InputError(f"sample {sample.get('id', index)}: its {key} image is {size[0]}x{size[1]}; "
                                     f"the network renders {image_size}x{image_size}", path)
        for path in voxel_files:
            if path is None or not path.is_file():
                raise InputError("object voxels of a sample are missing", path)

    def _load_voxels(self, path: str) -> np.ndarray:
        from renderer.voxels import downsample_voxels, load_voxels

        rgba = load_voxels(path)
        if self.object_resolution is not None and self.object_resolution < rgba.shape[0]:
            rgba = downsample_voxels(rgba, self.object_resolution)
        return rgba

    def object_voxels(self, index: int) -> list[np.ndarray]:
        """The object voxels (N, N, N, 4) of a sample's objects, in order (each read once while the cache holds it)."""
        scene = self.scene(index)
        paths = tuple(str(scene.file(o.voxels)) for o in scene.objects)
        if self._dense is not None and self._dense[0] == paths:
            return self._dense[1]
        painted = []
        for path in paths:
            if path in self._voxels:
                self._voxels.move_to_end(path)
                rgba = self._voxels[path].dense()
            else:
                rgba = self._load_voxels(path)
                self._voxels[path] = _StoredVoxels(rgba)
                while (len(self._voxels) > len(paths)
                       and sum(v.nbytes for v in self._voxels.values()) > self._voxel_cache_bytes):
                    self._voxels.popitem(last=False)
            painted.append(rgba)
        self._dense = (paths, painted)
        return painted

    def __len__(self) -> int:
        return len(self.items)

    def scene(self, index: int) -> Scene:
        folder, sample = self.items[index]
        return scene_from_dict(sample["scene"], folder / "manifest.json")

    def __getitem__(self, index: int) -> dict[str, torch.Tensor]:
        folder, sample = self.items[index]
        scene = self.scene(index)
        painted = self.object_voxels(index)
        voxels, light = network_inputs(scene, painted, scene.floor.color, self.grid_size, self.environment)
        if self.object_resolution is None:
            splat = image_tensor(folder / sample["splat"])
        else:  # the stored splat shows the full-resolution voxels: splat the coarse ones instead
            from renderer.splat import splat_objects

            splat = torch.from_numpy(np.ascontiguousarray(
                splat_objects(scene, painted, scene.floor.color).transpose(2, 0, 1)))
        item = {
            "voxels": voxels,
            "light": light,
            "splat": splat,
            "target": image_tensor(folder / sample["target"]),
            "index": torch.tensor(index),
        }
        if self.floor_light:
            item["floor_light"] = floor_light_tensor(scene, scene.floor.color, splat.shape[-1])
        if self.shading:
            item["shading"] = shading_tensor(self.shaded(scene, painted, splat.shape[-1]))
        return item

    def shaded(self, scene: Scene, painted: Sequence[np.ndarray], size: int, reflection: bool = False):
        """The voxel shader's ShadedImage (renderer/shading/) of a sample's scene at `size`^2, its objects' voxels
        `painted` merged as for the shader's grid (the network's own, or a finer one: renderer.grid.shader_pool_factors).
        `reflection`: with the floor's reflection of the objects, as the shader draws its own image (a network's input
        has none)."""
        return self.shaders.shade(scene, painted, self.voxel_keys(scene), size, reflection=reflection)

    @property
    def shaders(self):
        """The set's staged shaders (renderer.shading.staged.SceneShaders): views of the same objects one after
        another, as a test sequence's are, reuse each object's geometry."""
        if self._shaders is None:
            from renderer.shading import quality_named
            from renderer.shading.staged import SceneShaders

            self._shaders = SceneShaders(self.shading_grid_size, quality_named(self.shader_quality))
        return self._shaders

    def voxel_keys(self, scene: Scene) -> tuple[str, ...]:
        """What names each object's voxels for the shaders: its file (and the resolution they are read at)."""
        return tuple(f"{scene.file(o.voxels)}@{self.object_resolution}" for o in scene.objects)


def floor_light_tensor(scene: Scene, floor_color, size: int) -> torch.Tensor:
    """The lit empty floor of a scene (renderer/floor_light.py) as the network's (3, size, size) input."""
    from renderer.camera import Camera
    from renderer.floor_light import lit_floor_image

    image = lit_floor_image(Camera.from_scene(scene, size), scene.light.position, floor_color)
    return torch.from_numpy(np.ascontiguousarray(image.transpose(2, 0, 1)))


def shading_tensor(shaded) -> torch.Tensor:
    """A ShadedImage's image and buffers as the network's (SHADING_CHANNELS, S, S) input."""
    from renderer.shading import network_buffers

    buffers = network_buffers(shaded)
    return torch.from_numpy(np.ascontiguousarray(buffers.transpose(2, 0, 1)))


def _color_channel_groups() -> dict[str, list[list[int]]]:
    """Per input that holds colors, its groups of (r, g, b) channels: a color permutation reorders each group and
    leaves every other channel (the voxels' occupancy, the shader's normals, depth, visibility, coverage)."""
    from renderer.shading import BUFFER_CHANNELS

    rgb = [[0, 1, 2]]
    shading = [[BUFFER_CHANNELS.index(f"{group} {c}") for c in "rgb"] for group in ("image", "albedo")]
    return {"voxels": rgb, "splat": rgb, "target": rgb, "floor_light": rgb, "shading": shading}


def color_orders(seed: int, step: int, batch: int) -> torch.Tensor:
    """(batch, 3) channel orders, one of the six at random per sample of the step's global batch, fixed by
    (seed, step) like the batch itself (a resumed run permutes as an uninterrupted one)."""
    generator = torch.Generator().manual_seed(seed * 104_729 + step + 1)
    return torch.stack([torch.randperm(3, generator=generator) for _ in range(batch)])


def permute_colors(batch: dict[str, torch.Tensor], orders: torch.Tensor) -> dict[str, torch.Tensor]:
    """The batch with each sample's RGB channels reordered by its row of `orders` ((B, 3): new channel c is old
    channel orders[b, c]) in every input that holds colors and in the target.

    Why this is a training sample: every renderer here treats the three channels alike (the path tracer, the
    shader, the splat), so reordering the channels of every color of a scene, its environment's included (the
    probe in the light input), reorders the channels of its images.
    """
    count = orders.shape[0]
    rows = torch.arange(count)[:, None]
    out = dict(batch)
    if "light" in batch and batch["light"].shape[1] > LIGHT_DIMS:  # the environment probe's channels come along
        light = batch["light"]
        head, probe = light[:, :-PROBE_DIMS], light[:, -PROBE_DIMS:].reshape(count, IMAGE_CHANNELS, -1)
        out["light"] = torch.cat([head, probe[rows, orders].reshape(count, -1)], dim=1)
    for key, channel_groups in _color_channel_groups().items():
        if key not in batch:
            continue
        index = torch.arange(batch[key].shape[1]).repeat(count, 1)
        for channels in channel_groups:
            index[:, channels] = torch.as_tensor(channels)[orders]
        out[key] = batch[key][rows, index.to(batch[key].device)]
    return out
