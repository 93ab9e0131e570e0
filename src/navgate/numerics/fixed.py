"""Bit-true signed two's complement fixed point (Q formats), as the gateware computes it.

Reference: seed 004 (2x2 fixed-point Kalman filter, parameters ``N`` = word width and
``FRAC`` = fraction bits, default N=20, FRAC=10): its adder, subtractor and multiplier
each give a full-precision and a truncated output; "the multiplier keeps the middle,
aligned bits; the adder drops the carry MSB, keeping the binary point" (seed 004,
"算法实现"). Those are :func:`fixed_mul_full` / :func:`fixed_mul_trunc` and
:func:`fixed_add_full` / :func:`fixed_add_trunc` here. docs/numerics.md is the spec.

Format: ``QFormat(width, frac)``: a ``width``-bit two's complement integer ``x`` (sign
bit included) representing ``x * 2**-frac``; range ``[-2**(width-1), 2**(width-1) - 1]``
in integer units. (Seed 004's Q(N, FRAC) is ``QFormat(N, FRAC)``; it has
``width - 1 - frac`` integer bits besides the sign.)

Values are Python ints or NumPy integer arrays holding the raw integers. Results are
int64 arrays when every intermediate fits in 62 bits, otherwise NumPy object arrays of
Python ints (any width works; wide formats are just slower). A scalar input gives a
scalar result. Operands outside their format's range raise ``ValueError``.

Conventions shared by every function:

* Any result that can leave its format is returned as ``(value, overflow)``, where
  ``overflow`` is a bool array set where the exact (rounded) result did not fit.
  ``mode="saturate"`` clamps to the format's range; ``mode="wrap"`` keeps the low
  ``width`` bits (two's complement wrap-around, what a register of that width holds).
* ``rounding="truncate"``: arithmetic shift right, i.e. floor (toward -infinity).
  ``rounding="nearest"``: add half an output LSB, then floor, i.e. round to nearest
  with ties toward +infinity (the cheap hardware rounding; not ties-to-even).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = [
    "QFormat",
    "quantize",
    "to_float",
    "saturate",
    "wrap",
    "fits",
    "rescale",
    "fixed_add",
    "fixed_sub",
    "fixed_add_full",
    "fixed_sub_full",
    "fixed_add_trunc",
    "fixed_sub_trunc",
    "fixed_neg",
    "fixed_abs",
    "fixed_mul",
    "fixed_mul_full",
    "fixed_mul_trunc",
    "mul_full_format",
]

_INT64_SAFE_BITS = 62


@dataclass(frozen=True)
class QFormat:
    """Signed fixed-point format: ``width`` bits in all (sign included), ``frac``
    fraction bits. ``QFormat(20, 10)`` is seed 004's default Q(N=20, FRAC=10)."""

    width: int
    frac: int

    def __post_init__(self):
        if not isinstance(self.width, (int, np.integer)) or self.width < 2:
            raise ValueError(f"QFormat width must be an integer >= 2, got {self.width!r}")
        if not isinstance(self.frac, (int, np.integer)):
            raise ValueError(f"QFormat frac must be an integer, got {self.frac!r}")

    @property
    def int_bits(self) -> int:
        """Integer bits besides the sign bit (may be negative when frac >= width)."""
        return self.width - 1 - self.frac

    @property
    def min_int(self) -> int:
        return -(1 << (self.width - 1))

    @property
    def max_int(self) -> int:
        return (1 << (self.width - 1)) - 1

    @property
    def lsb(self) -> float:
        return math.ldexp(1.0, -self.frac)

    @property
    def min_value(self) -> float:
        return math.ldexp(float(self.min_int), -self.frac)

    @property
    def max_value(self) -> float:
        return math.ldexp(float(self.max_int), -self.frac)

    def __str__(self) -> str:
        return f"Q(width={self.width}, frac={self.frac})"


# ----------------------------------------------------------------------------- helpers


def _scalar(*args) -> bool:
    return all(np.ndim(a) == 0 for a in args)


def _out(x, scalar: bool):
    return np.asarray(x)[()] if scalar else x


def _ints(x, fmt: QFormat | None, bits: int, name: str = "operand"):
    """Integer array in int64 (bits <= 62) or object dtype; range-checked against fmt."""
    arr = np.asarray(x)
    if arr.dtype.kind == "f":
        raise TypeError(f"{name}: fixed-point values are raw integers; use quantize()")
    if arr.dtype == bool or arr.dtype.kind not in "iuO":
        raise TypeError(f"{name}: integer values expected, got dtype {arr.dtype}")
    if bits <= _INT64_SAFE_BITS:
        if arr.dtype.kind == "O":
            arr = np.array([int(v) for v in arr.ravel()], dtype=np.int64).reshape(arr.shape)
        elif arr.dtype == np.uint64 and arr.size and arr.max() > np.iinfo(np.int64).max:
            raise ValueError(f"{name} out of range")
        arr = arr.astype(np.int64)
    else:
        arr = np.array([int(v) for v in arr.ravel()], dtype=object).reshape(arr.shape)
    if fmt is not None and arr.size:
        if arr.min() < fmt.min_int or arr.max() > fmt.max_int:
            raise ValueError(f"{name} out of range for {fmt}")
    return arr


def _clamp(v, fmt: QFormat, mode: str):
    """Saturate or wrap ``v`` to ``fmt``; returns (value, overflow)."""
    if fmt.width > _INT64_SAFE_BITS and v.dtype.kind != "O":
        v = np.array([int(t) for t in v.ravel()], dtype=object).reshape(v.shape)
    over = (v < fmt.min_int) | (v > fmt.max_int)
    if mode == "saturate":
        out = np.where(v > fmt.max_int, fmt.max_int, np.where(v < fmt.min_int, fmt.min_int, v))
    elif mode == "wrap":
        low = v & ((1 << fmt.width) - 1)
        out = np.where(low > fmt.max_int, low - (1 << fmt.width), low)
    else:
        raise ValueError(f"mode must be 'saturate' or 'wrap', got {mode!r}")
    if fmt.width <= _INT64_SAFE_BITS:
        out = np.asarray(out).astype(np.int64)
    else:
        out = np.asarray(out, dtype=object)
    return out, np.asarray(over, dtype=bool)


def _shift_round(v, shift: int, rounding: str):
    """Multiply by 2**-shift with the given rounding (shift may be <= 0: exact)."""
    if rounding not in ("truncate", "nearest"):
        raise ValueError(f"rounding must be 'truncate' or 'nearest', got {rounding!r}")
    if shift <= 0:
        return v << (-shift)
    if rounding == "nearest":
        v = v + (1 << (shift - 1))
    return v >> shift


# ----------------------------------------------------------------------------- formats


def _raw(x):
    """Any raw integers: int64 when the dtype allows it, else an object array."""
    arr = np.asarray(x)
    if arr.dtype.kind in "iu" and arr.dtype != np.uint64:
        return arr.astype(np.int64)
    return _ints(x, None, _INT64_SAFE_BITS + 1)


def fits(x, fmt: QFormat):
    """Bool array: raw integers ``x`` lie in the range of ``fmt``."""
    scalar = _scalar(x)
    v = _raw(x)
    return _out(np.asarray((v >= fmt.min_int) & (v <= fmt.max_int), dtype=bool), scalar)


def saturate(x, fmt: QFormat):
    """Clamp raw integers to ``fmt``'s range -> ``(value, overflow)``."""
    scalar = _scalar(x)
    out, over = _clamp(_raw(x), fmt, "saturate")
    return _out(out, scalar), _out(over, scalar)


def wrap(x, fmt: QFormat):
    """Keep the low ``fmt.width`` bits (two's complement) -> ``(value, overflow)``."""
    scalar = _scalar(x)
    out, over = _clamp(_raw(x), fmt, "wrap")
    return _out(out, scalar), _out(over, scalar)


def quantize(x, fmt: QFormat, rounding: str = "nearest", mode: str = "saturate"):
    """Real value(s) -> raw integers of ``fmt`` -> ``(value, overflow)``.

    ``nearest`` = floor(x * 2**frac + 1/2) (ties toward +inf), ``truncate`` = floor.
    The scaling by 2**frac is exact in float64; the rounding is done without forming
    ``x + 1/2`` in floating point (which could itself round). +-inf saturate (flagged);
    NaN raises ValueError.
    """
    if rounding not in ("truncate", "nearest"):
        raise ValueError(f"rounding must be 'truncate' or 'nearest', got {rounding!r}")
    scalar = _scalar(x)
    xf = np.asarray(x, dtype=np.float64)
    if np.isnan(xf).any():
        raise ValueError("quantize: NaN input")
    scaled = np.ldexp(xf, fmt.frac)
    fl = np.floor(scaled)
    if rounding == "nearest":
        finite = np.isfinite(fl)
        rest = np.where(finite, scaled, 0.0) - np.where(finite, fl, 0.0)  # exact
        fl = fl + (rest >= 0.5)
    lim = float(2 ** (fmt.width + 1))
    inrange = np.abs(fl) < lim
    clipped = np.where(inrange, fl, np.sign(fl) * lim)
    if fmt.width + 2 <= _INT64_SAFE_BITS:
        v = clipped.astype(np.int64)
    else:
        v = np.array([int(t) for t in clipped.ravel()], dtype=object).reshape(clipped.shape)
    out, over = _clamp(v, fmt, mode)
    return _out(out, scalar), _out(over, scalar)


def to_float(x, fmt: QFormat):
    """Raw integers -> float64 values ``x * 2**-frac`` (exact while |x| < 2**53)."""
    scalar = _scalar(x)
    out = np.ldexp(np.asarray(_raw(x), dtype=np.float64), -fmt.frac)
    return _out(out, scalar)


def rescale(x, fmt_in: QFormat, fmt_out: QFormat, rounding: str = "truncate",
            mode: str = "saturate"):
    """Convert raw integers between Q formats -> ``(value, overflow)``."""
    scalar = _scalar(x)
    bits = max(fmt_in.width + max(0, fmt_out.frac - fmt_in.frac), fmt_out.width) + 1
    v = _ints(x, fmt_in, bits)
    out, over = _clamp(_shift_round(v, fmt_in.frac - fmt_out.frac, rounding), fmt_out, mode)
    return _out(out, scalar), _out(over, scalar)


# ----------------------------------------------------------------------------- add / sub


def fixed_add_full(a, b, fmt: QFormat):
    """Exact sum of two ``fmt`` values: a ``fmt.width + 1``-bit result, same ``frac``."""
    scalar = _scalar(a, b)
    va = _ints(a, fmt, fmt.width + 1, "a")
    vb = _ints(b, fmt, fmt.width + 1, "b")
    return _out(va + vb, scalar)


def fixed_sub_full(a, b, fmt: QFormat):
    """Exact difference ``a - b``: a ``fmt.width + 1``-bit result, same ``frac``."""
    scalar = _scalar(a, b)
    va = _ints(a, fmt, fmt.width + 1, "a")
    vb = _ints(b, fmt, fmt.width + 1, "b")
    return _out(va - vb, scalar)


def fixed_add(a, b, fmt: QFormat, mode: str = "saturate"):
    """``a + b`` in ``fmt`` -> ``(value, overflow)``; saturating by default."""
    scalar = _scalar(a, b)
    va = _ints(a, fmt, fmt.width + 1, "a")
    vb = _ints(b, fmt, fmt.width + 1, "b")
    out, over = _clamp(va + vb, fmt, mode)
    return _out(out, scalar), _out(over, scalar)


def fixed_sub(a, b, fmt: QFormat, mode: str = "saturate"):
    """``a - b`` in ``fmt`` -> ``(value, overflow)``; saturating by default."""
    scalar = _scalar(a, b)
    va = _ints(a, fmt, fmt.width + 1, "a")
    vb = _ints(b, fmt, fmt.width + 1, "b")
    out, over = _clamp(va - vb, fmt, mode)
    return _out(out, scalar), _out(over, scalar)


def fixed_add_trunc(a, b, fmt: QFormat, mode: str = "wrap"):
    """Seed 004's truncated adder output: the sum's carry MSB is dropped (``wrap``,
    the default, as the seed) or the sum is clamped (``saturate``) -> ``(value, overflow)``."""
    return fixed_add(a, b, fmt, mode)


def fixed_sub_trunc(a, b, fmt: QFormat, mode: str = "wrap"):
    """Seed 004's truncated subtractor output (see :func:`fixed_add_trunc`)."""
    return fixed_sub(a, b, fmt, mode)


def fixed_neg(a, fmt: QFormat, mode: str = "saturate"):
    """``-a`` -> ``(value, overflow)`` (only ``-min_int`` overflows)."""
    scalar = _scalar(a)
    va = _ints(a, fmt, fmt.width + 1, "a")
    out, over = _clamp(-va, fmt, mode)
    return _out(out, scalar), _out(over, scalar)


def fixed_abs(a, fmt: QFormat, mode: str = "saturate"):
    """``|a|`` (seed 004's fxp_abs) -> ``(value, overflow)``; ``|min_int|`` overflows."""
    scalar = _scalar(a)
    va = _ints(a, fmt, fmt.width + 1, "a")
    out, over = _clamp(np.where(va < 0, -va, va), fmt, mode)
    return _out(out, scalar), _out(over, scalar)


# ----------------------------------------------------------------------------- multiply


def mul_full_format(fmt_a: QFormat, fmt_b: QFormat) -> QFormat:
    """Format of the exact product: ``QFormat(wa + wb, fa + fb)`` (always fits)."""
    return QFormat(fmt_a.width + fmt_b.width, fmt_a.frac + fmt_b.frac)


def fixed_mul_full(a, b, fmt_a: QFormat, fmt_b: QFormat | None = None):
    """Exact product (seed 004's full-precision multiplier output), in
    :func:`mul_full_format` ``(fmt_a, fmt_b)``: 2N bits with 2*FRAC fraction bits."""
    fmt_b = fmt_a if fmt_b is None else fmt_b
    scalar = _scalar(a, b)
    bits = fmt_a.width + fmt_b.width
    va = _ints(a, fmt_a, bits, "a")
    vb = _ints(b, fmt_b, bits, "b")
    return _out(va * vb, scalar)


def fixed_mul_trunc(a, b, fmt: QFormat, mode: str = "wrap"):
    """Seed 004's truncated multiplier output: the 2N-bit product shifted right by FRAC
    (arithmetic shift = floor), then N bits kept: ``wrap`` (default, the seed's "middle
    aligned bits" slice ``p[N+FRAC-1:FRAC]``) or ``saturate`` -> ``(value, overflow)``."""
    return fixed_mul(a, b, fmt, fmt, fmt, rounding="truncate", mode=mode)


def fixed_mul(a, b, fmt_a: QFormat, fmt_b: QFormat, out_fmt: QFormat,
              rounding: str = "truncate", mode: str = "saturate"):
    """``a * b`` rounded into ``out_fmt`` -> ``(value, overflow)``.

    The exact product has ``fmt_a.frac + fmt_b.frac`` fraction bits; it is shifted by
    ``fa + fb - out_fmt.frac`` with ``rounding`` (exact when that is <= 0), then
    saturated or wrapped to ``out_fmt.width`` bits.
    """
    scalar = _scalar(a, b)
    shift = fmt_a.frac + fmt_b.frac - out_fmt.frac
    bits = fmt_a.width + fmt_b.width + max(0, -shift) + 1
    bits = max(bits, out_fmt.width + 1)
    va = _ints(a, fmt_a, bits, "a")
    vb = _ints(b, fmt_b, bits, "b")
    out, over = _clamp(_shift_round(va * vb, shift, rounding), out_fmt, mode)
    return _out(out, scalar), _out(over, scalar)
