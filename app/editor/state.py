"""Files the editor keeps between runs, under $XDG_STATE_HOME/nvr-studio (default ~/.local/state/nvr-studio).

- recovery/scene.json and recovery/origin.json: the last autosaved scene and the file it was
  opened from, offered back on the next start when the editor ended with unsaved changes.
  Headless runs (`nvr-editor --frames`, scripted) keep theirs in recovery-headless/ instead, so a
  script never replaces, nor is offered, what the interactive editor left.
- captures/<hash>.npz: object voxels colored from a photo, named by their content, so a scene
  can point at them before it is saved anywhere.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from renderer.color import to_uint8
from renderer.errors import InputError
from renderer.io import atomic_path, load_json, save_json
from renderer.scene import Scene, load_scene, save_scene
from renderer.voxels import save_voxels


def state_dir() -> Path:
    base = os.environ.get("XDG_STATE_HOME") or str(Path.home() / ".local" / "state")
    return Path(base) / "nvr-studio"


MAX_RECENT = 8


def recent_scenes() -> list[Path]:
    """The scene files opened or saved last, newest first (those that still exist)."""
    try:
        entries = load_json(state_dir() / "recent.json")
    except InputError:
        return []
    if not isinstance(entries, list):
        return []
    return [Path(e) for e in entries if isinstance(e, str) and Path(e).is_file()][:MAX_RECENT]


def remember_scene(path: str | Path) -> None:
    """Put `path` first in the recent scene files (a failure to write the list is not the user's problem)."""
    path = str(Path(path).resolve())
    entries = [path] + [str(p) for p in recent_scenes() if str(p) != path]
    try:
        state_dir().mkdir(parents=True, exist_ok=True)
        save_json(state_dir() / "recent.json", entries[:MAX_RECENT])
    except (InputError, OSError):
        pass


RECOVERY = "recovery"  # the interactive editor's autosave
HEADLESS_RECOVERY = "recovery-headless"  # a headless run's


def _recovery_dir(slot: str) -> Path:
    return state_dir() / slot


@dataclass(frozen=True)
class Recovery:
    scene: Scene
    origin: Path | None  # the scene file the unsaved changes belong to
    saved_at: float  # seconds since the epoch


def write_recovery(scene: Scene, origin: Path | None, slot: str = RECOVERY) -> None:
    """Autosave `scene` (atomically) with the path of the file it came from."""
    folder = _recovery_dir(slot)
    folder.mkdir(parents=True, exist_ok=True)
    save_json(folder / "origin.json", {"origin": None if origin is None else str(Path(origin).resolve())})
    save_scene(scene, folder / "scene.json")


def read_recovery(slot: str = RECOVERY) -> Recovery | None:
    """The autosaved scene, or None when there is none or it no longer loads (e.g. its mesh is gone)."""
    scene_file = _recovery_dir(slot) / "scene.json"
    if not scene_file.is_file():
        return None
    try:
        scene = load_scene(scene_file)
        origin = load_json(_recovery_dir(slot) / "origin.json").get("origin")
    except (InputError, AttributeError):
        return None
    return Recovery(scene, None if origin is None else Path(origin), scene_file.stat().st_mtime)


def clear_recovery(slot: str = RECOVERY) -> None:
    for name in ("scene.json", "origin.json"):
        (_recovery_dir(slot) / name).unlink(missing_ok=True)


def save_capture(rgba: np.ndarray) -> Path:
    """Store captured object voxels under a name made from their content; returns the file."""
    data = to_uint8(np.asarray(rgba))
    digest = hashlib.sha256(data.tobytes()).hexdigest()[:16]
    folder = state_dir() / "captures"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{digest}.npz"
    if not path.is_file():
        save_voxels(path, rgba)
    return path


def age_text(saved_at: float) -> str:
    """'3 min ago' style age of an autosave."""
    minutes = max(0, int((time.time() - saved_at) // 60))
    return "just now" if minutes == 0 else f"{minutes} min ago" if minutes < 120 else f"{minutes // 60} h ago"


def adopt_capture(scene: Scene, scene_file: str | Path) -> Scene:
    """The scene to write to `scene_file`: captured voxels kept in the state folder are copied beside it first (the
    first object's as SCENE.voxels.npz, as before there were several; the others' as SCENE.voxels2.npz and on)."""
    captures = (state_dir() / "captures").resolve()
    objects = []
    for index, o in enumerate(scene.objects):
        voxels = scene.file(o.voxels)
        if voxels is None or voxels.resolve().parent != captures:
            objects.append(o)
            continue
        copy = Path(scene_file).with_name(f"{Path(scene_file).stem}.voxels{index + 1 if index else ''}.npz")
        with atomic_path(copy) as tmp:
            shutil.copyfile(voxels, tmp)
        objects.append(replace(o, voxels=str(copy.resolve())))
    return scene if tuple(objects) == scene.objects else replace(scene, objects=tuple(objects))
