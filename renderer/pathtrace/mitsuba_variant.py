"""Which Mitsuba variant the path tracer runs: the vectorised LLVM one when a libLLVM >= 16 exists, else scalar.

drjit's LLVM backend compiles the whole path tracer into one vectorised kernel but needs a
shared libLLVM of version 16 or newer (DRJIT_LIBLLVM_PATH); without one the scalar variant
gives the same images, only slower. The variant is chosen and set once per process.
"""

from __future__ import annotations

import functools
import glob
import os
import re
from collections.abc import Iterable
from pathlib import Path

LLVM_VARIANT = "llvm_ad_rgb"
SCALAR_VARIANT = "scalar_rgb"
MIN_LLVM_VERSION = 16
LIBLLVM_ENV = "DRJIT_LIBLLVM_PATH"
LIBLLVM_PATTERNS = (
    "/usr/lib/x86_64-linux-gnu/libLLVM*.so*",
    "/usr/lib/aarch64-linux-gnu/libLLVM*.so*",
    "/usr/lib/llvm-*/lib/libLLVM*.so*",
    "/usr/lib64/libLLVM*.so*",
    "/usr/local/lib/libLLVM*.so*",
)

# libLLVM-19.so, libLLVM-14.0.6.so.1, libLLVM.so.19.1; a bare libLLVM.so takes its folder's llvm-NN.
_NAME_VERSION = re.compile(r"^libLLVM(?:-(\d+)[\d.]*\.so|\.so\.(\d+))")
_FOLDER_VERSION = re.compile(r"^llvm-(\d+)$")


def libllvm_version(path: str) -> int | None:
    """Major LLVM version read from a libLLVM file name (or an enclosing llvm-NN folder); None if unknown."""
    p = Path(path)
    match = _NAME_VERSION.match(p.name)
    if match:
        return int(match.group(1) or match.group(2))
    for folder in p.parents:
        match = _FOLDER_VERSION.match(folder.name)
        if match:
            return int(match.group(1))
    return None


def choose_variant(libllvm_paths: Iterable[str]) -> tuple[str, str | None]:
    """The variant for these candidate libLLVM files and the library to load: the newest version >= 16, else scalar."""
    usable = [(libllvm_version(p), p) for p in libllvm_paths]
    usable = [(v, p) for v, p in usable if v is not None and v >= MIN_LLVM_VERSION]
    if not usable:
        return SCALAR_VARIANT, None
    best = max(usable, key=lambda vp: vp[0])
    return LLVM_VARIANT, best[1]


def libllvm_candidates() -> list[str]:
    """The user's DRJIT_LIBLLVM_PATH if set, else the libLLVM files found in the usual system folders."""
    explicit = os.environ.get(LIBLLVM_ENV)
    if explicit:
        return [explicit]
    return sorted({path for pattern in LIBLLVM_PATTERNS for path in glob.glob(pattern)})


@functools.cache
def active_variant() -> str:
    """Choose, set and return the process-wide Mitsuba variant (LLVM if it initialises, else scalar)."""
    import drjit as dr
    import mitsuba as mi

    variant, library = choose_variant(libllvm_candidates())
    if variant == LLVM_VARIANT:
        os.environ.setdefault(LIBLLVM_ENV, library)
        try:
            mi.set_variant(LLVM_VARIANT)  # raises ImportError when the library does not load
            if dr.has_backend(dr.JitBackend.LLVM):
                return LLVM_VARIANT
        except ImportError:
            pass
    mi.set_variant(SCALAR_VARIANT)
    return SCALAR_VARIANT
