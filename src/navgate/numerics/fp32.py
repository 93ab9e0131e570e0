"""Bit-true IEEE-754 binary32 arithmetic as the navgate gateware computes it.

Reference: IEEE Std 754-2019 (binary32 format, round to nearest ties to even, the
special-value rules of sections 6 and 7); seed 003 (a float32 attitude datapath with
adder, multiplier, divider and square-root cores and float32 <-> fix16 converters).
docs/numerics.md holds the full specification; the summary below is normative for the
gateware (which is checked bit for bit against these functions).

Every operand and result is a ``uint32`` bit pattern. Functions take NumPy arrays (any
shape, broadcast together) or Python/NumPy integer scalars and return ``np.uint32``
arrays (or scalars when every input was a scalar).

Semantics
---------
* Rounding: round to nearest, ties to even, for every operation and conversion.
* Flush to zero on input: a subnormal operand (exponent field 0, fraction nonzero) is
  treated as a zero of the same sign, by every operation including the comparison.
* Underflow ("tininess after rounding with unbounded exponent"): the exact result is
  rounded to 24 significant bits as if the exponent range were unbounded. If the rounded
  magnitude is below 2^-126 the result is a zero with the result's sign; if it is at or
  above 2^128 the result is an infinity with the result's sign. No subnormal is produced.
* NaN: every NaN result is the canonical quiet NaN ``QNAN = 0x7FC00000`` (sign 0),
  whatever the NaN operands' payloads and signs.
* Special values follow IEEE 754: inf - inf, 0 * inf, 0 / 0, inf / inf and sqrt of a
  negative nonzero number give QNAN; x / 0 (x nonzero, not NaN) gives an infinity with
  the XOR of the signs; sqrt(-0) = -0; an exact zero sum or difference is +0, except
  (-0) + (-0) = -0 (and (-0) - (+0) = -0).

Compared with NumPy float32 (IEEE with gradual underflow), results are bit-identical
except in exactly these cases (tests/numerics/test_fp32.py checks they are the only ones):

1. an operand is subnormal (NumPy uses its value, we use a signed zero);
2. NumPy's result is subnormal (we return the zero with the same sign);
3. NumPy's result is +-2^-126 but the exact result rounded to 24 bits with unbounded
   exponent is 2^-126 - 2^-150 (exact magnitude in [2^-126 - 2^-150, 2^-126 - 2^-151)):
   NumPy rounds up into the normal range at subnormal granularity, we return zero;
4. a NaN result: NumPy propagates payload/sign, we return 0x7FC00000.

Implementation and exactness
----------------------------
add, sub, mul, div and sqrt evaluate the operation in float64 on the (exactly
converted, flushed) operands and then round the float64 result to 24 significant bits
(ties to even) with an integer operation on its bit pattern, with unbounded exponent,
before the range checks above. A product of two 24-bit significands has at most 48 bits
and is exact in float64, so ``mul`` rounds once. For add, sub, div and sqrt the float64
step is itself a rounding, so the result is a double rounding; it equals the single
correct rounding because the intermediate precision 53 satisfies 53 >= 2*24 + 2 (S. A.
Figueroa, "When is double rounding innocuous?", ACM SIGNUM Newsletter 30(3), 1995;
formal proof: P. Roux, "Innocuous double rounding of basic arithmetic operations",
Journal of Formalized Reasoning 7(1), 2014). The theorem needs both roundings in
round-to-nearest-even with no exponent limit on the intermediate: every intermediate
here lies in [2^-254, 2^256], inside float64's normal range. The second rounding is
done on 24 bits with unbounded exponent, exactly the rounding the specification names.
An independent exact integer/Fraction model (:mod:`navgate.numerics.fp32_exact`)
cross-checks this in the tests. Integer conversions use pure integer arithmetic.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "QNAN",
    "POS_INF",
    "NEG_INF",
    "POS_ZERO",
    "NEG_ZERO",
    "MIN_NORMAL",
    "MAX_NORMAL",
    "f32_to_bits",
    "bits_to_f32",
    "is_nan",
    "is_inf",
    "is_zero",
    "is_subnormal",
    "flush_subnormal",
    "fp32_add",
    "fp32_sub",
    "fp32_mul",
    "fp32_div",
    "fp32_sqrt",
    "fp32_neg",
    "fp32_abs",
    "fp32_compare",
    "fp32_from_int",
    "fp32_to_int",
    "fp32_from_fixed",
    "fp32_to_fixed",
    "float_to_bits",
    "floats_to_bits",
    "bits_to_float",
]

QNAN = 0x7FC00000
POS_INF = 0x7F800000
NEG_INF = 0xFF800000
POS_ZERO = 0x00000000
NEG_ZERO = 0x80000000
MIN_NORMAL = 0x00800000  # 2^-126
MAX_NORMAL = 0x7F7FFFFF  # (2 - 2^-23) * 2^127

_SIGN = np.uint32(0x80000000)
_EXP = np.uint32(0x7F800000)
_FRAC = np.uint32(0x007FFFFF)
_ABS = np.uint32(0x7FFFFFFF)


# ----------------------------------------------------------------------------- helpers


def _as_bits(a) -> np.ndarray:
    """Validate and convert bit patterns to a uint32 array."""
    arr = np.asarray(a)
    if arr.dtype == np.uint32:
        return arr
    if arr.dtype.kind == "f":
        raise TypeError("fp32 operands are uint32 bit patterns; use f32_to_bits() on floats")
    if arr.dtype.kind not in "iuO" and arr.dtype != bool:
        raise TypeError(f"cannot interpret dtype {arr.dtype} as float32 bit patterns")
    if arr.dtype.kind == "O":
        arr = arr.astype(np.int64)
    if arr.size and (arr.min() < 0 or arr.max() > 0xFFFFFFFF):
        raise ValueError("float32 bit patterns must lie in [0, 2**32)")
    return arr.astype(np.uint32)


def _out(x: np.ndarray, scalar: bool):
    return x[()] if scalar else x


def _is_scalar(*args) -> bool:
    return all(np.ndim(a) == 0 for a in args)


def f32_to_bits(x) -> np.ndarray:
    """NumPy's float32 conversion of ``x`` (float64 values are rounded by NumPy, with
    gradual underflow), returned as uint32 bit patterns."""
    scalar = _is_scalar(x)
    out = np.asarray(x, dtype=np.float32).view(np.uint32)
    return _out(np.array(out, copy=True), scalar)


def float_to_bits(value) -> int:
    """One value rounded to float32 (NumPy, RNE) as its bit pattern, NaN as the canonical
    quiet NaN (:data:`QNAN`): what a PS driver writes into a float register."""
    v = np.float32(value)
    if v != v:
        return QNAN
    return int(v.view(np.uint32))


def floats_to_bits(values) -> np.ndarray:
    """:func:`float_to_bits` of every element (uint32 array, the input's shape)."""
    v = np.asarray(values, np.float64).astype(np.float32)
    out = v.view(np.uint32).copy()
    out[np.isnan(v)] = QNAN
    return out


def bits_to_float(bits) -> float:
    """A float32 bit pattern (an int in [0, 2**32)) as the Python float it represents."""
    return float(np.uint32(int(bits) & 0xFFFFFFFF).view(np.float32))


def bits_to_f32(b) -> np.ndarray:
    """Reinterpret uint32 bit patterns as float32 values (no conversion)."""
    scalar = _is_scalar(b)
    out = np.array(_as_bits(b), copy=True).view(np.float32)
    return _out(out, scalar)


def is_nan(b) -> np.ndarray:
    a = _as_bits(b)
    return (a & _ABS) > _EXP


def is_inf(b) -> np.ndarray:
    a = _as_bits(b)
    return (a & _ABS) == _EXP


def is_zero(b) -> np.ndarray:
    """True for +-0 (not for subnormals; see :func:`flush_subnormal`)."""
    a = _as_bits(b)
    return (a & _ABS) == 0


def is_subnormal(b) -> np.ndarray:
    a = _as_bits(b)
    return ((a & _EXP) == 0) & ((a & _FRAC) != 0)


def flush_subnormal(b) -> np.ndarray:
    """Replace subnormal patterns by the zero of the same sign (the input flush)."""
    scalar = _is_scalar(b)
    a = _as_bits(b)
    out = np.where((a & _EXP) == 0, a & _SIGN, a).astype(np.uint32)
    return _out(out, scalar)


def _to_f64(a: np.ndarray) -> np.ndarray:
    """Flush subnormal inputs, then convert exactly to float64."""
    flushed = np.where((a & _EXP) == 0, a & _SIGN, a).astype(np.uint32)
    with np.errstate(invalid="ignore"):  # signalling-NaN patterns convert quietly
        return flushed.view(np.float32).astype(np.float64)


def _round_f64(r: np.ndarray) -> np.ndarray:
    """Round float64 values to binary32 with the navgate rules (see module docstring).

    NaN -> QNAN; the magnitude is rounded to 24 significant bits ties-to-even on the
    float64 bit pattern (unbounded exponent), then < 2^-126 -> signed zero and
    >= 2^128 -> signed infinity.
    """
    b = np.array(r, dtype=np.float64, order="C").view(np.uint64)
    sign = ((b >> np.uint64(63)).astype(np.uint32)) << np.uint32(31)
    mag = b & np.uint64(0x7FFFFFFFFFFFFFFF)
    nan = mag > np.uint64(0x7FF0000000000000)
    # ties-to-even on the 29 dropped fraction bits; a carry ripples into the exponent
    lsb = (mag >> np.uint64(29)) & np.uint64(1)
    rounded = (mag + (np.uint64(0x0FFFFFFF) + lsb)) >> np.uint64(29)
    e32 = (rounded >> np.uint64(23)).astype(np.int64) - (1023 - 127)
    frac = (rounded & np.uint64(0x7FFFFF)).astype(np.uint32)
    under = e32 < 1
    over = e32 > 254
    e_field = np.clip(e32, 0, 255).astype(np.uint32) << np.uint32(23)
    out = sign | e_field | frac
    out = np.where(under, sign, out)
    out = np.where(over, sign | _EXP, out)
    out = np.where(nan, np.uint32(QNAN), out)
    return out.astype(np.uint32)


def _binary(op, a, b):
    scalar = _is_scalar(a, b)
    x = _to_f64(_as_bits(a))
    y = _to_f64(_as_bits(b))
    with np.errstate(all="ignore"):
        r = op(x, y)
    return _out(_round_f64(np.asarray(r)), scalar)


# ----------------------------------------------------------------------------- arithmetic


def fp32_add(a, b):
    """a + b (bit patterns in, bit pattern out)."""
    return _binary(np.add, a, b)


def fp32_sub(a, b):
    """a - b."""
    return _binary(np.subtract, a, b)


def fp32_mul(a, b):
    """a * b."""
    return _binary(np.multiply, a, b)


def fp32_div(a, b):
    """a / b, correctly rounded; x/0 = signed infinity, 0/0 = inf/inf = QNAN."""
    return _binary(np.divide, a, b)


def fp32_sqrt(a):
    """Square root, correctly rounded; sqrt(-0) = -0, sqrt(negative nonzero) = QNAN."""
    scalar = _is_scalar(a)
    x = _to_f64(_as_bits(a))
    with np.errstate(all="ignore"):
        r = np.sqrt(x)
    return _out(_round_f64(np.asarray(r)), scalar)


def fp32_neg(a):
    """Sign flip (NaN in -> QNAN out, subnormal in -> flushed zero, as the datapath)."""
    scalar = _is_scalar(a)
    x = _as_bits(a)
    out = np.where((x & _EXP) == 0, x & _SIGN, x) ^ _SIGN
    out = np.where(is_nan(x), np.uint32(QNAN), out).astype(np.uint32)
    return _out(out, scalar)


def fp32_abs(a):
    """Magnitude (NaN in -> QNAN out, subnormal in -> +0)."""
    scalar = _is_scalar(a)
    x = _as_bits(a)
    out = np.where((x & _EXP) == 0, np.uint32(0), x & _ABS)
    out = np.where(is_nan(x), np.uint32(QNAN), out).astype(np.uint32)
    return _out(out, scalar)


def fp32_compare(a, b) -> dict[str, np.ndarray]:
    """IEEE comparison after the input flush: returns bool arrays ``lt``, ``eq``, ``gt``,
    ``unordered`` (exactly one is true per element). -0 == +0; any NaN -> unordered;
    a subnormal compares equal to zero."""
    scalar = _is_scalar(a, b)
    x = _as_bits(a)
    y = _as_bits(b)
    unordered = is_nan(x) | is_nan(y)

    def key(v):
        v = np.where((v & _EXP) == 0, np.uint32(0), v)
        mag = (v & _ABS).astype(np.int64)
        return np.where((v & _SIGN) != 0, -mag, mag)

    kx, ky = np.broadcast_arrays(key(x), key(y))
    unordered = np.broadcast_to(unordered, kx.shape)
    res = {
        "lt": ~unordered & (kx < ky),
        "eq": ~unordered & (kx == ky),
        "gt": ~unordered & (kx > ky),
        "unordered": np.array(unordered, copy=True),
    }
    if scalar:
        res = {k: bool(v) for k, v in res.items()}
    return res


# ----------------------------------------------------------------------------- conversions


def _check_width(width: int, lo: int = 2, hi: int = 64) -> None:
    if not isinstance(width, (int, np.integer)) or not lo <= int(width) <= hi:
        raise ValueError(f"width must be an integer in [{lo}, {hi}], got {width!r}")


def _as_signed(i, width: int) -> np.ndarray:
    arr = np.asarray(i)
    if arr.dtype.kind == "f":
        raise TypeError("integer operands expected (fixed-point values are integers)")
    if arr.dtype.kind == "O":
        py = [int(v) for v in arr.ravel()]
        lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
        if py and (min(py) < lo or max(py) > hi):
            raise ValueError(f"value out of range for a signed {width}-bit integer")
        return np.array(py, dtype=np.int64).reshape(arr.shape)
    if arr.dtype == np.uint64 and arr.size and arr.max() > np.iinfo(np.int64).max:
        raise ValueError(f"value out of range for a signed {width}-bit integer")
    arr = arr.astype(np.int64)
    if width < 64 and arr.size:
        lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
        if arr.min() < lo or arr.max() > hi:
            raise ValueError(f"value out of range for a signed {width}-bit integer")
    return arr


def _int_to_f32(i: np.ndarray, scale_exp: int) -> np.ndarray:
    """Round the exact value ``i * 2**scale_exp`` (int64 i) to binary32 bits."""
    neg = i < 0
    # magnitude as uint64 (|-2^63| = 2^63 fits)
    mag = np.where(neg, ~i, i).astype(np.uint64) + neg.astype(np.uint64)
    zero = mag == 0
    _, e = np.frexp(mag.astype(np.float64))
    p = np.clip(e.astype(np.int64) - 1, 0, 63)
    # float64 conversion may round up to the next power of two: correct the msb position
    too_big = (mag >> p.astype(np.uint64)) == 0
    p = np.where(too_big & ~zero, p - 1, p)
    s_right = np.maximum(p - 23, 0).astype(np.uint64)
    s_left = np.maximum(23 - p, 0).astype(np.uint64)
    q = (mag >> s_right) << s_left
    rem = mag & ((np.uint64(1) << s_right) - np.uint64(1))
    half = (np.uint64(1) << s_right) >> np.uint64(1)
    odd = (q & np.uint64(1)) == 1
    up = (s_right > 0) & ((rem > half) | ((rem == half) & odd))
    q = q + up.astype(np.uint64)
    carry = q >> np.uint64(24) != 0
    q = np.where(carry, q >> np.uint64(1), q)
    p = p + carry
    e_biased = p + scale_exp + 127
    sign = np.where(neg, _SIGN, np.uint32(0)).astype(np.uint32)
    frac = (q & np.uint64(0x7FFFFF)).astype(np.uint32)
    field = (np.clip(e_biased, 0, 255).astype(np.uint32)) << np.uint32(23)
    out = sign | field | frac
    out = np.where(e_biased < 1, sign, out)
    out = np.where(e_biased > 254, sign | _EXP, out)
    out = np.where(zero, np.uint32(0), out)
    return out.astype(np.uint32)


def fp32_from_int(i, width: int = 32):
    """Signed two's complement ``width``-bit integer(s) -> binary32, ties to even.

    Values outside the signed range of ``width`` raise ValueError. 0 -> +0.
    """
    _check_width(width)
    scalar = _is_scalar(i)
    return _out(_int_to_f32(_as_signed(i, width), 0), scalar)


def fp32_from_fixed(x, frac_bits: int, width: int):
    """Signed Q value ``x * 2**-frac_bits`` (``width``-bit two's complement integers)
    -> binary32, ties to even; a result below 2^-126 in magnitude flushes to zero."""
    _check_width(width)
    scalar = _is_scalar(x)
    return _out(_int_to_f32(_as_signed(x, width), -int(frac_bits)), scalar)


def _f32_to_int(a: np.ndarray, scale_exp: int, width: int):
    """Round ``value(a) * 2**scale_exp`` to a signed ``width``-bit integer, ties to even,
    saturating. NaN -> 0 with the flag set; +-inf -> saturated with the flag set."""
    a = np.where((a & _EXP) == 0, a & _SIGN, a).astype(np.uint32)
    nan = (a & _ABS) > _EXP
    inf = (a & _ABS) == _EXP
    neg = (a & _SIGN) != 0
    e = ((a >> np.uint32(23)) & np.uint32(0xFF)).astype(np.int64)
    zero = e == 0
    m = ((a & _FRAC) | np.uint32(0x800000)).astype(np.uint64)
    sh = e - 150 + scale_exp  # value = m * 2^sh
    left = np.clip(sh, 0, 40).astype(np.uint64)
    right = np.clip(-sh, 0, 30).astype(np.uint64)
    q = (m << left) >> right
    rem = m & ((np.uint64(1) << right) - np.uint64(1))
    half = (np.uint64(1) << right) >> np.uint64(1)
    odd = (q & np.uint64(1)) == 1
    up = (right > 0) & ((rem > half) | ((rem == half) & odd))
    mag = q + up.astype(np.uint64)
    pos_lim = np.uint64((1 << (width - 1)) - 1)
    neg_lim = np.uint64(1 << (width - 1))
    huge = sh > 40  # magnitude >= 2^63 -> overflows every width <= 64
    over = inf | huge | np.where(neg, mag > neg_lim, mag > pos_lim)
    mag = np.where(over, np.where(neg, neg_lim, pos_lim), mag)
    mag = np.where(zero | nan, np.uint64(0), mag)
    with np.errstate(over="ignore"):  # two's complement negation in uint64 wraps by design
        val = np.where(neg, (~mag) + np.uint64(1), mag).view(np.int64)
    flag = (over & ~zero) | nan
    return val, flag


def fp32_to_int(a, width: int = 32):
    """binary32 -> signed ``width``-bit integer, round to nearest ties to even,
    saturating. Returns ``(value, flag)`` with int64 values; ``flag`` is True when the
    rounded value did not fit (saturated, including +-inf) or the input was NaN (value 0).
    Subnormal inputs give 0."""
    _check_width(width)
    scalar = _is_scalar(a)
    v, f = _f32_to_int(_as_bits(a), 0, width)
    return _out(v, scalar), _out(f, scalar)


def fp32_to_fixed(a, frac_bits: int, width: int):
    """binary32 -> signed Q value with ``frac_bits`` fraction bits in ``width`` bits:
    ``round_ties_even(value * 2**frac_bits)``, saturating. Returns ``(value, flag)`` as
    :func:`fp32_to_int` (flag: saturated or NaN)."""
    _check_width(width)
    scalar = _is_scalar(a)
    v, f = _f32_to_int(_as_bits(a), int(frac_bits), width)
    return _out(v, scalar), _out(f, scalar)
