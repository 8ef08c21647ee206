"""The one sRGB <-> linear conversion of the project (IEC 61966-2-1 transfer curve).

Scene files and voxels hold sRGB values in [0, 1] as a color picker shows them;
the path tracer works in linear light; PNGs are written in sRGB.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange


def srgb_to_linear(srgb: np.ndarray | float) -> np.ndarray:
    """sRGB-encoded values in [0, 1] to linear light (values are clipped to [0, 1] first)."""
    c = np.clip(np.asarray(srgb, dtype=np.float64), 0.0, 1.0)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(linear: np.ndarray | float) -> np.ndarray:
    """Linear light to sRGB-encoded values in [0, 1] (negative and NaN become 0, above 1 clips).

    float32 input is converted in float32 (within 1e-6 of float64; every shaded frame's last step), anything else in
    float64. Compiled loops: numpy's power has no vectorised path on CPUs without AVX512 (docs/results.md, "Measurements behind the code")."""
    c = np.asarray(linear)
    c = np.asarray(c, dtype=np.float32 if c.dtype == np.float32 else np.float64)
    c = c if c.flags.c_contiguous else c.copy()  # (np.ascontiguousarray would make a scalar 1-D)
    out = np.empty_like(c)
    if c.dtype == np.float32:
        _linear_to_srgb_float32(c.reshape(-1), c.reshape(-1).view(np.uint32), out.reshape(-1), _SRGB_TABLE,
                                _SRGB_TABLE_FIRST)
    else:
        _linear_to_srgb(c.reshape(-1), out.reshape(-1))
    return out


def _srgb_table() -> tuple[np.ndarray, int]:
    """The curve's power segment at the float32 values whose last _SRGB_TABLE_SHIFT bits are 0 (512 per octave),
    from the curve's knee to 1 and one past, and the first one's bits >> _SRGB_TABLE_SHIFT. Between two of them the
    curve is interpolated linearly: within 1.4e-7 of float64 over [0, 1], and far quicker than float32's power."""
    first = int(np.float32(_SRGB_KNEE).view(np.uint32)) >> _SRGB_TABLE_SHIFT
    last = (int(np.float32(1.0).view(np.uint32)) >> _SRGB_TABLE_SHIFT) + 1
    starts = (np.arange(first, last + 1, dtype=np.uint32) << _SRGB_TABLE_SHIFT).view(np.float32).astype(np.float64)
    return (1.055 * starts ** (1.0 / 2.4) - 0.055).astype(np.float32), first


_SRGB_KNEE = 0.0031308  # linear values up to this are encoded by a straight line
_SRGB_TABLE_SHIFT = 14
_ONE_BITS = int(np.float32(1.0).view(np.uint32))
_SRGB_TABLE, _SRGB_TABLE_FIRST = _srgb_table()


@njit(cache=True, parallel=True)
def _linear_to_srgb_float32(linear, bits, out, table, first):
    """`_linear_to_srgb` of float32 values from _srgb_table's segments; `bits`: `linear` viewed as uint32."""
    one, zero = np.float32(1.0), np.float32(0.0)
    fraction = np.float32(1.0 / (1 << _SRGB_TABLE_SHIFT))
    low = np.uint32((1 << _SRGB_TABLE_SHIFT) - 1)
    for i in prange(linear.size):
        c = linear[i]
        c = min(max(c, zero), one) if c == c else zero  # NaN compares unequal to itself
        if c <= _SRGB_KNEE:
            out[i] = c * np.float32(12.92)
        else:
            b = bits[i] if c == linear[i] else np.uint32(_ONE_BITS)  # above 1: 1's bits
            k = (b >> _SRGB_TABLE_SHIFT) - first
            t = np.float32(b & low) * fraction
            out[i] = table[k] + t * (table[k + 1] - table[k])


@njit(cache=True, parallel=True)
def _linear_to_srgb(linear, out):
    one, zero = linear.dtype.type(1.0), linear.dtype.type(0.0)
    for i in prange(linear.size):
        c = linear[i]
        c = min(max(c, zero), one) if c == c else zero  # NaN compares unequal to itself
        if c <= _SRGB_KNEE:
            out[i] = c * linear.dtype.type(12.92)
        else:
            out[i] = linear.dtype.type(1.055) * c ** linear.dtype.type(1.0 / 2.4) - linear.dtype.type(0.055)


def to_uint8(values: np.ndarray) -> np.ndarray:
    """Values in [0, 1] to 8-bit with rounding (NaN becomes 0)."""
    v = np.nan_to_num(np.asarray(values, dtype=np.float64), nan=0.0)
    return np.clip(np.round(v * 255.0), 0, 255).astype(np.uint8)
