"""Turntables and light sweeps: a scene rendered frame by frame with the object turning or the light circling,
written as a PNG sequence or an animated GIF (`nvr turntable`, the editor's File menu).

Each renderer keeps its caches across the frames: in a light sweep the voxel shader reruns only its
shading stage and the network only its light-dependent layers, so those frames cost a fraction of the first.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from models.renderers import RENDERERS, RendererOptions, fixed_size, make_renderer
from renderer.errors import InputError
from renderer.limits import MAX_IMAGE_SIZE, MIN_IMAGE_SIZE
from renderer.transform import turned_on_platter

if TYPE_CHECKING:  # the command line reads TurntableConfig at start-up: the image and scene modules load when used
    import numpy as np

    from renderer.scene import Scene

SWEEPS = ("rotation", "light")
MAX_FRAMES = 3600
GIF_SECONDS = 4.0  # one turn lasts this long in the GIF, whatever the frame count
MIN_LIGHT_RADIUS = 1.0  # a light straight above the object circles at this distance instead


@dataclass(frozen=True)
class TurntableConfig:
    """What `nvr turntable` and the editor's Export turntable render; a field with help is a command-line option."""

    frames: int = field(default=36, metadata={"help": "frames in one full turn"})
    sweep: str = field(default="rotation", metadata={
        "help": "rotation: the object turns; light: the light circles at its height", "choices": SWEEPS})
    renderer: str = field(default="shaded", metadata={"help": "what draws each frame", "choices": list(RENDERERS)})
    size: int | None = field(default=None, metadata={
        "help": "image side in pixels (default: the scene's; nvr, which draws the image itself: 256)"})
    spp: int = field(default=64, metadata={"help": "path tracing: samples per pixel (denoised)"})
    model: str | None = field(default=None, metadata={
        "help": "network weights (.safetensors); default: the shipped model"})

    def check(self) -> None:
        if isinstance(self.frames, bool) or not isinstance(self.frames, int) or not 1 <= self.frames <= MAX_FRAMES:
            raise InputError(f"--frames must be from 1 to {MAX_FRAMES}, got {self.frames!r}")
        if self.sweep not in SWEEPS:
            raise InputError(f"--sweep must be one of {', '.join(SWEEPS)}, got {self.sweep!r}")
        if self.renderer not in RENDERERS:
            raise InputError(f"--renderer must be one of {', '.join(RENDERERS)}, got {self.renderer!r}")
        if self.size is not None and not MIN_IMAGE_SIZE <= self.size <= MAX_IMAGE_SIZE:
            raise InputError(f"--size must be from {MIN_IMAGE_SIZE} to {MAX_IMAGE_SIZE} pixels, got {self.size}")


def frame_scenes(scene: Scene, frames: int, sweep: str) -> Iterator[Scene]:
    """The scene of each frame: the object turned by 360 / frames degrees a frame in place (several objects: each
    about its own axis, and their places about the vertical axis through the scene centre, as on a turntable's
    platter), or the light moved as far around that axis, at its height and distance (the environment turned when it
    lights the scene alone)."""
    x, y, z = scene.light.position
    radius, start = max(math.hypot(x, z), MIN_LIGHT_RADIUS), math.atan2(z, x)
    for f in range(frames):
        turn = 2.0 * math.pi * f / frames
        if sweep == "rotation":
            yield replace(scene, objects=turned_on_platter(scene.objects, math.degrees(turn)))
        elif not scene.light.enabled and scene.environment is not None:  # the environment alone lights it: turn that
            env = scene.environment
            yield replace(scene, environment=replace(env, rotation_deg=env.rotation_deg + math.degrees(turn)))
        else:
            position = (radius * math.cos(start + turn), y, radius * math.sin(start + turn))
            yield replace(scene, light=replace(scene.light, position=position))


def frame_renderer(scene: Scene, config: TurntableConfig) -> tuple[Callable[[Scene], np.ndarray], str]:
    """A function rendering a frame's scene with the chosen renderer (caches kept between calls), and its name."""
    renderer = make_renderer(config.renderer, RendererOptions(model=config.model, spp=config.spp, denoise=True))
    own = fixed_size(renderer)
    if own is not None and config.size is not None and config.size != own:
        raise InputError(f"the model renders {own}x{own}; --size {config.size} is not supported")
    size = own or config.size or scene.image_size
    # Every frame at the scene's image size, so the renderers keep their size-dependent stages between frames (a
    # network's render_sized at its own size is its live render).
    return (lambda s: renderer.render_sized(replace(s, image_size=size), size)), \
        f"{config.renderer}, {renderer.description}"


def render_turntable(scene: Scene, config: TurntableConfig, progress: bool = True,
                     on_frame: Callable[[float], None] | None = None) -> tuple[list[np.ndarray], list[float], str]:
    """All frames (uint8 images), each frame's seconds, and what rendered them. `progress`: a progress bar on
    the terminal; `on_frame` gets the fraction done after each frame (the editor's progress bar)."""
    from tqdm import tqdm

    from renderer.color import to_uint8

    config.check()
    render, name = frame_renderer(scene, config)
    images, seconds = [], []
    for frame_scene in tqdm(frame_scenes(scene, config.frames, config.sweep), total=config.frames, unit="frame",
                            disable=not progress, desc=f"{config.sweep} sweep"):
        start = time.perf_counter()
        images.append(to_uint8(render(frame_scene)))
        seconds.append(time.perf_counter() - start)
        if on_frame is not None:
            on_frame(len(images) / config.frames)
    return images, seconds, name


def write_frames(out: Path, images: list[np.ndarray]) -> list[Path]:
    """An animated GIF when `out` ends in .gif (one turn in GIF_SECONDS, looping), else a folder of
    frame_0000.png ...; each file written atomically."""
    from PIL import Image

    from renderer.io import atomic_path, save_png

    if out.suffix.lower() == ".gif":
        frames = [Image.fromarray(image) for image in images]
        duration = max(20, round(1000.0 * GIF_SECONDS / len(frames)))
        with atomic_path(out) as tmp:
            frames[0].save(tmp, format="GIF", save_all=True, append_images=frames[1:], duration=duration, loop=0)
        return [out]
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / f"frame_{i:04d}.png" for i in range(len(images))]
    for path, image in zip(paths, images):
        save_png(path, image)
    return paths
