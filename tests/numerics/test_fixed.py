"""navgate.numerics.fixed: exhaustive small-width checks and random wide-width checks
against a plain Python-integer reference written from the definitions."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from navgate.numerics.fixed import (
    QFormat,
    fits,
    fixed_abs,
    fixed_add,
    fixed_add_full,
    fixed_add_trunc,
    fixed_mul,
    fixed_mul_full,
    fixed_mul_trunc,
    fixed_neg,
    fixed_sub,
    fixed_sub_full,
    fixed_sub_trunc,
    mul_full_format,
    quantize,
    rescale,
    saturate,
    to_float,
    wrap,
)

# ----------------------------------------------------------------------------- reference


def ref_fit(v: int, fmt: QFormat, mode: str) -> tuple[int, bool]:
    lo, hi = -(1 << (fmt.width - 1)), (1 << (fmt.width - 1)) - 1
    over = not lo <= v <= hi
    if mode == "saturate":
        return min(max(v, lo), hi), over
    m = v % (1 << fmt.width)  # Python % is non-negative: the low `width` bits
    return (m - (1 << fmt.width) if m > hi else m), over


def ref_shift(v: int, shift: int, rounding: str) -> int:
    """v * 2^-shift: floor, or floor(x + 1/2) (ties toward +inf)."""
    if shift <= 0:
        return v << -shift
    if rounding == "truncate":
        return math.floor(v / (1 << shift)) if abs(v) < 2**50 else v >> shift
    q, r = divmod(v, 1 << shift)  # q = floor, 0 <= r < 2^shift
    return q + (1 if 2 * r >= (1 << shift) else 0)


def _all(fmt):
    return np.arange(fmt.min_int, fmt.max_int + 1, dtype=np.int64)


# ----------------------------------------------------------------------------- tests


def test_qformat():
    f = QFormat(20, 10)  # seed 004 default
    assert (f.int_bits, f.min_int, f.max_int, f.lsb) == (9, -(2**19), 2**19 - 1, 2.0**-10)
    assert f.max_value == (2**19 - 1) / 1024 and f.min_value == -512.0
    assert mul_full_format(f, f) == QFormat(40, 20)
    with pytest.raises(ValueError):
        QFormat(1, 0)


@pytest.mark.parametrize("mode", ["saturate", "wrap"])
def test_add_sub_exhaustive(mode):
    fmt = QFormat(6, 3)
    a, b = (x.ravel() for x in np.meshgrid(_all(fmt), _all(fmt)))
    for op, pyop in ((fixed_add, int.__add__), (fixed_sub, int.__sub__)):
        v, o = op(a, b, fmt, mode)
        want = [ref_fit(pyop(int(x), int(y)), fmt, mode) for x, y in zip(a, b, strict=True)]
        np.testing.assert_array_equal(v, [w[0] for w in want])
        np.testing.assert_array_equal(o, [w[1] for w in want])
    np.testing.assert_array_equal(fixed_add_full(a, b, fmt), a + b)
    np.testing.assert_array_equal(fixed_sub_full(a, b, fmt), a - b)


def test_seed004_trunc_defaults_wrap():
    """Seed 004: the adder drops the carry MSB and the multiplier keeps the aligned
    middle bits p[N+FRAC-1:FRAC] -> two's complement wrap, flagged."""
    f = QFormat(20, 10)
    assert fixed_add_trunc(2**19 - 1, 1, f) == (-(2**19), True)
    assert fixed_sub_trunc(-(2**19), 1, f) == (2**19 - 1, True)
    # 511.999 * 2.0 = 1023.998 -> (2^19-1)*2^11 >> 10 = 2^20 - 2 -> wraps to -2
    assert fixed_mul_trunc(2**19 - 1, 2048, f) == (-2, True)
    assert fixed_mul_trunc(2**19 - 1, 2048, f, mode="saturate") == (2**19 - 1, True)
    # truncation is floor: -3 LSB * 1 LSB = -3 * 2^-20 -> floor(-3/1024) = -1 LSB
    assert fixed_mul_trunc(-3, 1, f) == (-1, False)
    assert fixed_mul(-3, 1, f, f, f, rounding="nearest") == (0, False)
    # the slice definition, bit for bit, on random operands
    rng = np.random.default_rng(0)
    a = rng.integers(f.min_int, f.max_int + 1, 50_000)
    b = rng.integers(f.min_int, f.max_int + 1, 50_000)
    v, o = fixed_mul_trunc(a, b, f)
    p = fixed_mul_full(a, b, f)
    sliced = (p >> 10) & ((1 << 20) - 1)  # bits [29:10] of the 40-bit product
    sliced = np.where(sliced >= 2**19, sliced - 2**20, sliced)
    np.testing.assert_array_equal(v, sliced)
    np.testing.assert_array_equal(o, ((p >> 10) < f.min_int) | ((p >> 10) > f.max_int))


@pytest.mark.parametrize("rounding, mode", list(itertools.product(
    ["truncate", "nearest"], ["saturate", "wrap"])))
def test_mul_exhaustive_mixed_formats(rounding, mode):
    fa, fb, fo = QFormat(6, 4), QFormat(5, 1), QFormat(6, 2)
    a, b = (x.ravel() for x in np.meshgrid(_all(fa), _all(fb)))
    v, o = fixed_mul(a, b, fa, fb, fo, rounding, mode)
    for k in range(a.size):
        want = ref_fit(ref_shift(int(a[k]) * int(b[k]), 4 + 1 - 2, rounding), fo, mode)
        assert (int(v[k]), bool(o[k])) == want, (int(a[k]), int(b[k]))
    # output with more fraction bits than the product: exact left shift
    v, o = fixed_mul(a, b, fa, fb, QFormat(16, 7), rounding, mode)
    np.testing.assert_array_equal(v, (a * b) << 2)
    assert not o.any()


@pytest.mark.parametrize("fmt", [QFormat(32, 16), QFormat(40, 20), QFormat(64, 60)])
def test_wide_formats_random(fmt):
    """int64 path (32 bits) and the Python-int object path (products beyond 62 bits)."""
    rng = np.random.default_rng(fmt.width)
    n = 3000
    def draw():  # uniform over the signed fmt.width-bit range
        hi = rng.integers(-(2**62), 2**62, n).tolist()
        lo = rng.integers(0, 2, n).tolist()
        return [((h << 1) | b) >> (64 - fmt.width) for h, b in zip(hi, lo, strict=True)]

    a, b = draw(), draw()
    a[0], b[0] = fmt.min_int, fmt.min_int  # (-2^(N-1))^2: the only full-product extreme
    A = np.array(a, dtype=object)
    B = np.array(b, dtype=object)
    full = fixed_mul_full(A, B, fmt)
    assert [int(x) for x in full] == [x * y for x, y in zip(a, b, strict=True)]
    for mode in ("saturate", "wrap"):
        v, o = fixed_mul_trunc(A, B, fmt, mode)
        want = [ref_fit((x * y) >> fmt.frac, fmt, mode) for x, y in zip(a, b, strict=True)]
        assert [int(x) for x in v] == [w[0] for w in want]
        assert [bool(x) for x in o] == [w[1] for w in want]
        v, o = fixed_add(A, B, fmt, mode)
        want = [ref_fit(x + y, fmt, mode) for x, y in zip(a, b, strict=True)]
        assert [int(x) for x in v] == [w[0] for w in want]
        v, o = fixed_mul(A, B, fmt, fmt, fmt, "nearest", mode)
        want = [ref_fit(ref_shift(x * y, fmt.frac, "nearest"), fmt, mode)
                for x, y in zip(a, b, strict=True)]
        assert [int(x) for x in v] == [w[0] for w in want]


def test_neg_abs_saturate_wrap():
    f = QFormat(8, 4)
    assert fixed_neg(-128, f) == (127, True)
    assert fixed_neg(-128, f, mode="wrap") == (-128, True)
    assert fixed_abs(-128, f) == (127, True)
    assert fixed_abs(-5, f) == (5, False)
    assert saturate(300, f) == (127, True) and saturate(-300, f) == (-128, True)
    assert saturate(5, f) == (5, False)
    assert wrap(128, f) == (-128, True) and wrap(-129, f) == (127, True)
    assert wrap(2**70 + 3, f) == (3, True)  # arbitrary Python ints
    np.testing.assert_array_equal(fits(np.array([-129, -128, 127, 128]), f), [0, 1, 1, 0])


def test_quantize_and_to_float():
    f = QFormat(20, 10)
    x = np.array([1.5, -1.5, 2.0**-11, -(2.0**-11), 3 * 2.0**-11, 511.9996, 600.0, -600.0,
                  np.inf, -np.inf, -512.0])
    v, o = quantize(x, f)  # nearest: ties toward +inf
    np.testing.assert_array_equal(v, [1536, -1536, 1, 0, 2, 2**19 - 1, 2**19 - 1, -(2**19),
                                      2**19 - 1, -(2**19), -(2**19)])
    np.testing.assert_array_equal(o, [0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 0])
    v, o = quantize(x[:5], f, rounding="truncate")
    np.testing.assert_array_equal(v, [1536, -1536, 0, -1, 1])
    with pytest.raises(ValueError):
        quantize(np.nan, f)
    # a value where x + 0.5 would itself round in float64: 2^52 + 1 at frac 0
    assert quantize(2.0**52 + 1, QFormat(60, 0)) == (2**52 + 1, False)
    rng = np.random.default_rng(1)
    r = rng.uniform(-500, 500, 100_000)
    v, o = quantize(r, f)
    err = to_float(v, f) - r
    # nearest rounding: |error| <= half an LSB, and ties go up (error in (-1/2, 1/2] LSB)
    assert (err <= 0.5 * f.lsb).all() and (err > -0.5 * f.lsb).all() and not o.any()
    assert to_float(1536, f) == 1.5


def test_rescale():
    fi, fo = QFormat(8, 2), QFormat(8, 1)
    x = _all(fi)
    for rounding in ("truncate", "nearest"):
        v, o = rescale(x, fi, fo, rounding)
        want = [ref_fit(ref_shift(int(t), 1, rounding), fo, "saturate") for t in x]
        np.testing.assert_array_equal(v, [w[0] for w in want])
        np.testing.assert_array_equal(o, [w[1] for w in want])
    v, o = rescale(x, fi, QFormat(8, 4))  # up-shift by 2 overflows beyond +-32 LSB
    np.testing.assert_array_equal(o, (x < -32) | (x > 31))


def test_bad_input():
    f = QFormat(8, 4)
    with pytest.raises(ValueError):
        fixed_add(128, 0, f)  # operand not in its format
    with pytest.raises(TypeError):
        fixed_add(1.5, 0, f)
    with pytest.raises(ValueError):
        fixed_add(1, 0, f, mode="clip")
    with pytest.raises(ValueError):
        fixed_mul(1, 1, f, f, f, rounding="up")
