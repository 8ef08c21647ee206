"""Files in and out: atomic writes, PNG images and JSON, each with one-line errors on bad input.

Every write goes to a temporary file in the target folder and is then renamed over the
target, so a crash or a kill never leaves a half-written file under the real name.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, ImageOps

from renderer.color import to_uint8
from renderer.errors import InputError

# Photos far larger than any use here are downscaled on load so they never exhaust memory.
MAX_IMAGE_SIDE = 4096
Image.MAX_IMAGE_PIXELS = 400_000_000  # refuse decompression bombs beyond this


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path next to `path`; rename it over `path` only if the block succeeds."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise InputError("output folder does not exist", folder)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp" + path.suffix, dir=folder)
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp_path, 0o666 & ~umask)  # mkstemp (and some writers) make 0600; use the usual mode
        os.replace(tmp_path, path)
    except PermissionError as exc:
        raise InputError(f"cannot write: {exc.strerror}", path) from None
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def check_writable(path: str | Path, overwrite: bool = True) -> Path:
    """Check up front that `path` can be written (folder exists and is writable; no clobbering if asked)."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise InputError("output folder does not exist", folder)
    if not os.access(folder, os.W_OK):
        raise InputError("output folder is not writable", folder)
    if path.exists() and not overwrite:
        raise InputError("file exists (pass --force to overwrite)", path)
    return path


def save_json(path: str | Path, data: Any) -> None:
    """Write `data` as indented JSON, atomically."""
    text = json.dumps(data, indent=2, sort_keys=False, allow_nan=False) + "\n"
    try:
        with atomic_path(path) as tmp:
            tmp.write_text(text)
    except OSError as exc:
        raise InputError(f"cannot write: {exc.strerror}", path) from None


def load_json(path: str | Path) -> Any:
    """Read a JSON file; missing, unreadable or malformed files raise InputError naming the line."""
    path = Path(path)
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise InputError("file not found", path) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read: {exc}", path) from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise InputError(f"broken JSON at line {exc.lineno} column {exc.colno}: {exc.msg}", path) from None


def save_png(path: str | Path, image: np.ndarray) -> None:
    """Write an sRGB image (H x W x 3 or 4, float in [0, 1] or uint8) as PNG, atomically."""
    arr = np.asarray(image)
    if arr.dtype != np.uint8:
        arr = to_uint8(arr)
    try:
        with atomic_path(path) as tmp:
            Image.fromarray(arr).save(tmp, format="PNG")
    except OSError as exc:
        raise InputError(f"cannot write: {exc.strerror or exc}", path) from None


def load_image(path: str | Path, max_side: int = MAX_IMAGE_SIDE) -> tuple[np.ndarray, np.ndarray | None]:
    """Load any still image as float32 sRGB (H x W x 3) in [0, 1] and its alpha (H x W) or None.

    Honours EXIF rotation; accepts grayscale, palette, 16-bit and RGBA images; images larger
    than `max_side` are downscaled (aspect kept) while decoding so memory stays bounded.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("file not found", path)
    try:
        with Image.open(path) as im:
            im.draft("RGB", (max_side, max_side))  # JPEG: decode at reduced size when huge
            im = ImageOps.exif_transpose(im)
            if max(im.size) > max_side:
                im.thumbnail((max_side, max_side), Image.Resampling.LANCZOS)
            alpha = None
            if im.mode in ("I;16", "I;16B", "I;16L", "I"):
                gray = np.asarray(im, dtype=np.float64)
                peak = 65535.0 if gray.max(initial=0) > 255 else 255.0
                rgb = np.repeat((gray / peak)[..., None], 3, axis=2)
            elif im.mode == "F":
                gray = np.clip(np.asarray(im, dtype=np.float64), 0.0, 1.0)
                rgb = np.repeat(gray[..., None], 3, axis=2)
            else:
                has_alpha = im.mode in ("RGBA", "LA", "PA") or (im.mode == "P" and "transparency" in im.info)
                im = im.convert("RGBA" if has_alpha else "RGB")
                arr = np.asarray(im, dtype=np.float64) / 255.0
                rgb = arr[..., :3]
                alpha = arr[..., 3].astype(np.float32) if has_alpha else None
    except InputError:
        raise
    except Image.DecompressionBombError:
        raise InputError("image is too large to decode safely", path) from None
    except (OSError, ValueError, SyntaxError) as exc:
        raise InputError(f"not a readable image ({exc})", path) from None
    if rgb.ndim != 3 or rgb.shape[0] < 1 or rgb.shape[1] < 1:
        raise InputError("image has no pixels", path)
    return np.ascontiguousarray(rgb, dtype=np.float32), alpha
