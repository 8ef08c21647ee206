"""Files in and out: atomic writes, PNG images and JSON, each with one-line errors on bad input.

Every write goes to a temporary file in the target folder and is then renamed over the
target, so a crash or a kill never leaves a half-written file under the real name.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, ImageOps

from renderer.color import to_uint8
from renderer.errors import InputError
from renderer.limits import (
    MAX_JSON_BYTES,
    MAX_NAME_BYTES,
    MAX_NUMBER_DIGITS,
    MAX_PATH_CHARACTERS,
    MAX_PHOTO_PIXELS,
    MAX_PHOTO_SIDE,
)

Image.MAX_IMAGE_PIXELS = MAX_PHOTO_PIXELS  # PIL refuses decompression bombs beyond this
# The temporary names atomic_path makes: "." + target name + "." + mkstemp's 8 random characters + ".tmp".
_TEMPORARY_NAME = re.compile(r"^\..+\.[a-z0-9_]{8}\.tmp(\.[^.]*)?$")


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


def remove_stale_temporaries(folder: str | Path) -> int:
    """Delete the temporary files a killed writer left in `folder` (atomic_path's names); returns how many.

    Only for folders one process writes at a time (a data set, a run); never call it while a writer runs.
    """
    removed = 0
    for entry in Path(folder).iterdir() if Path(folder).is_dir() else ():
        if entry.is_file() and _TEMPORARY_NAME.match(entry.name):
            entry.unlink(missing_ok=True)
            removed += 1
    return removed


def load_json(path: str | Path, max_bytes: int = MAX_JSON_BYTES) -> Any:
    """Read a JSON file; missing, unreadable, malformed or oversized files raise InputError naming the problem.

    Sizes and number lengths are bounded (renderer/limits.py) and nesting by the interpreter's recursion
    limit (about 1000 levels), so that no file can exhaust memory or the stack; NaN and Infinity, which JSON does not have, are refused.
    """
    path = Path(path)
    try:
        size = path.stat().st_size
        if size > max_bytes:
            raise InputError(f"file is {size / 2**20:.0f} MB; JSON files are read up to {max_bytes // 2**20} MB", path)
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError("file not found", path) from None
    except UnicodeDecodeError:
        raise InputError("not a text file (it is not UTF-8)", path) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror or exc}", path) from None
    return parse_json(text, path)


def parse_json(text: str, path: str | Path | None = None) -> Any:
    """JSON text as Python values, with the bounds of load_json."""
    try:
        data = json.loads(text, parse_int=_bounded_int, parse_float=_bounded_float, parse_constant=_no_constant)
    except json.JSONDecodeError as exc:
        raise InputError(f"broken JSON at line {exc.lineno} column {exc.colno}: {exc.msg}", path) from None
    except RecursionError:
        raise InputError("JSON nested too deeply", path) from None
    except ValueError as exc:  # raised by the hooks below
        raise InputError(str(exc), path) from None
    return data


def _bounded_int(text: str) -> int:
    if len(text) > MAX_NUMBER_DIGITS:
        raise ValueError(f"a number with {len(text)} digits (at most {MAX_NUMBER_DIGITS})")
    return int(text)


def _bounded_float(text: str) -> float:
    if len(text) > MAX_NUMBER_DIGITS:
        raise ValueError(f"a number with {len(text)} characters (at most {MAX_NUMBER_DIGITS})")
    return float(text)


def _no_constant(name: str) -> float:
    raise ValueError(f"{name} is not a JSON number")


def check_path_text(text: str) -> str | None:
    """Why `text` cannot be a file path on this system (too long, a name too long, unencodable
    characters, a NUL), or None when it can."""
    if len(text) > MAX_PATH_CHARACTERS:
        return f"path is {len(text)} characters long (at most {MAX_PATH_CHARACTERS})"
    if "\0" in text:
        return "path holds a NUL character"
    try:
        encoded = os.fsencode(text)
    except UnicodeError:
        return "path holds characters no file name can have"
    longest = max((len(part) for part in encoded.split(b"/")), default=0)
    if longest > MAX_NAME_BYTES:
        return f"a file name in the path is {longest} bytes long (at most {MAX_NAME_BYTES})"
    return None


@contextlib.contextmanager
def quiet_native_output(captured: list[str]) -> Iterator[None]:
    """Silence everything written to the terminal inside the block, including by C and C++ libraries
    (mesh readers print their own errors to file descriptors 1 and 2); the text is appended to `captured`.
    """
    sys.stdout.flush()
    sys.stderr.flush()
    with tempfile.TemporaryFile(mode="w+b") as sink:
        saved = [os.dup(1), os.dup(2)]
        try:
            os.dup2(sink.fileno(), 1)
            os.dup2(sink.fileno(), 2)
            yield
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            sink.seek(0)
            text = sink.read(65536).decode("utf-8", "replace")
            captured.extend(line for line in (_strip_ansi(t).strip() for t in text.splitlines()) if line)


def _strip_ansi(text: str) -> str:
    return re.sub(r"\x1b\[[0-9;]*m", "", text)


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


EXIF_IFD, FOCAL_35MM_TAG = 0x8769, 0xA405  # the Exif sub-directory, and FocalLengthIn35mmFilm in it


def photo_focal_35mm(path: str | Path) -> float | None:
    """The photo's focal length as its camera states it in EXIF, 35 mm equivalent (FocalLengthIn35mmFilm); None
    when the file states none (or an impossible one, or cannot be read: the search then assumes the scene's lens)."""
    try:
        with Image.open(path) as im:
            value = im.getexif().get_ifd(EXIF_IFD).get(FOCAL_35MM_TAG)
    except (OSError, ValueError, SyntaxError):
        return None
    try:
        focal = float(value)
    except (TypeError, ValueError):
        return None
    return focal if 4.0 <= focal <= 2000.0 else None


def load_image(path: str | Path, max_side: int = MAX_PHOTO_SIDE) -> tuple[np.ndarray, np.ndarray | None]:
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
