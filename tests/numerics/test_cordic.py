"""navgate.numerics.cordic: a hand-traced datapath case, the worst-case error bounds
(held, not absurdly loose, shrinking with iterations) over many random vectors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navgate.numerics.cordic import (
    angle_to_radians,
    atan_table,
    cordic_error_bound,
    cordic_gain,
    cordic_rotation,
    cordic_rotation_error_bound,
    cordic_vectoring,
    radians_to_angle,
)


def _wrapped_error(angle, angle_bits, ref_rad):
    d = angle_to_radians(angle, angle_bits) - ref_rad
    return np.abs((d + np.pi) % (2 * np.pi) - np.pi)


def _random_vectors(rng, width, n, rmin):
    """Random directions, magnitudes in [rmin, full scale], rounded onto the grid."""
    th = rng.uniform(-np.pi, np.pi, n)
    r = rng.uniform(rmin, 2 ** (width - 1) - 1, n)
    lo, hi = -(2 ** (width - 1)), 2 ** (width - 1) - 1
    x = np.clip(np.rint(r * np.cos(th)), lo, hi).astype(np.int64)
    y = np.clip(np.rint(r * np.sin(th)), lo, hi).astype(np.int64)
    keep = np.hypot(x, y) >= rmin
    # the corners and axes of the input square, all signs
    ex = np.array([hi, lo, 0, 0, hi, lo, lo, hi, lo, rmin], dtype=np.int64)
    ey = np.array([0, 0, hi, lo, hi, lo, hi, lo, -1, 0], dtype=np.int64)
    return np.concatenate([x[keep], ex]), np.concatenate([y[keep], ey])


def test_table_and_gain():
    # 16-bit binary angles (seed 001 scale): atan(2^-i) * 65536 / 2pi, rounded
    assert atan_table(16, 16).tolist() == [8192, 4836, 2555, 1297, 651, 326, 163, 81, 41,
                                           20, 10, 5, 3, 1, 1, 0]
    assert abs(cordic_gain(40) - 1.6467602581210656) < 1e-15
    assert cordic_gain(1) == math.sqrt(2)


def test_hand_traced_vectoring():
    """(1000, 0), 4 iterations, traced by hand from the docstring's recurrences; shows
    the arithmetic shift is a floor: -125 >>> 3 = -16."""
    # i0: y>=0: x=1000, y=-1000, z=8192;  i1: y<0: x=1500, y=-500, z=3356
    # i2: y<0: x=1625, y=-125, z=801;     i3: y<0: x=1625+16=1641, y=-125+203=78, z=-496
    assert cordic_vectoring(1000, 0, 16, 4) == (1641, -496)
    # pre-rotation: (-1000, 0) is 180 deg = -32768 up to the bound
    m, a = cordic_vectoring(-1000, 0, 16, 16)
    assert abs(int(a) + 32768) <= 16


def test_seed001_angle_scale():
    assert radians_to_angle(np.pi / 2) == 16384
    assert radians_to_angle(np.pi) == -32768  # +180 deg wraps
    assert radians_to_angle(-np.pi / 4) == -8192
    assert angle_to_radians(32767) < np.pi


NS_VEC = (4, 6, 8, 10, 12, 14, 16)
NS_ROT = (4, 6, 8, 10, 12, 16)


def _check_decrease(observed, bounds, residual):
    """The residual term atan(2^-(n-1)) falls 4x per two iterations; where it is at least
    twice the rest of the bound (table + truncation), bound and observed error must both
    fall by more than 2.5x. Once truncation dominates they level off (not checked)."""
    pairs = 0
    for k in range(len(bounds) - 1):
        if residual[k + 1] >= 2 * (bounds[k + 1] - residual[k + 1]):
            pairs += 1
            assert bounds[k + 1] < bounds[k] / 2.5, (k, bounds)
            assert observed[k + 1] < observed[k] / 2.5, (k, observed)
    assert pairs >= 1
    assert observed[0] > 5 * min(observed) and bounds[0] > 5 * min(bounds)


CONFIGS = [(16, 16, 0), (16, 16, 2), (12, 16, 0), (20, 20, 0), (16, 20, 3)]


@pytest.mark.parametrize("width, angle_bits, guard", CONFIGS)
def test_vectoring_error_bound(width, angle_bits, guard):
    rng = np.random.default_rng(width * 100 + angle_bits + guard)
    rmin = 2 ** (width - 2)
    x, y = _random_vectors(rng, width, 60_000, rmin)
    ref = np.arctan2(y, x)
    observed, bounds = [], []
    for n in NS_VEC:
        _, a = cordic_vectoring(x, y, width, n, angle_bits, guard_bits=guard)
        err = float(_wrapped_error(a, angle_bits, ref).max())
        bound = cordic_error_bound(width, n, angle_bits, guard, rmin)
        assert err <= bound, (n, err, bound)
        assert err > bound / 20, (n, err, bound)  # the bound is not absurdly loose
        observed.append(err)
        bounds.append(bound)
    _check_decrease(observed, bounds, [math.atan(2.0 ** -(n - 1)) for n in NS_VEC])


def test_vectoring_bound_grows_for_small_vectors():
    """The truncation term scales as 1/|v|: vectors 16x shorter get a looser bound that
    still holds."""
    rng = np.random.default_rng(3)
    width, n = 16, 14
    rmin = 2 ** (width - 6)
    th = rng.uniform(-np.pi, np.pi, 40_000)
    x = np.rint(rmin * 1.01 * np.cos(th)).astype(np.int64)
    y = np.rint(rmin * 1.01 * np.sin(th)).astype(np.int64)
    _, a = cordic_vectoring(x, y, width, n)
    err = _wrapped_error(a, 16, np.arctan2(y, x)).max()
    b_small = cordic_error_bound(width, n, 16, 0, rmin)
    assert err <= b_small
    assert b_small > 2 * cordic_error_bound(width, n, 16, 0, 2 ** (width - 2))


@pytest.mark.parametrize("width, angle_bits, guard", CONFIGS)
def test_vectoring_magnitude(width, angle_bits, guard):
    """Magnitude: x_n = K_n |v| cos(psi_n) + (propagated truncation), floored by g bits.
    |psi_n| <= the angle bound B, so with T = sum_{i>=1} sqrt(2) prod_{j>i} sqrt(1+4^-j)
    (internal LSBs, as in cordic_rotation_error_bound):
    |x_n/2^g - K|v|| <= K|v|(1 - cos B) + T/2^g + 1. Compensation multiplies by
    round(2^c/K)/2^c (relative error <= 2^-c K / 2) and floors again (+1)."""
    rng = np.random.default_rng(7)
    rmin = 2 ** (width - 2)
    x, y = _random_vectors(rng, width, 30_000, rmin)
    n = 16
    r = np.hypot(x, y)
    K = cordic_gain(n)
    B = cordic_error_bound(width, n, angle_bits, guard, rmin)
    T = sum(math.sqrt(2) * math.prod(math.sqrt(1 + 4.0**-j) for j in range(i + 1, n))
            for i in range(1, n))
    m, _ = cordic_vectoring(x, y, width, n, angle_bits, guard_bits=guard)
    lim = K * r * (1 - math.cos(B)) + T / 2**guard + 1
    assert (np.abs(m - K * r) <= lim).all()
    c = width + 2
    mc, _ = cordic_vectoring(x, y, width, n, angle_bits, guard_bits=guard, compensate=True)
    lim_c = lim / K * (1 + 2.0**-c * K) + r * 2.0**-c * K / 2 + 1
    assert (np.abs(mc - r) <= lim_c).all()
    assert np.abs(mc - r).max() > 0.2  # compensation actually floors / rounds somewhere
    assert mc.max() < 2 ** width  # fits width + 1 bits


@pytest.mark.parametrize("width, angle_bits, guard", CONFIGS + [(18, 24, 3)])
def test_rotation_error_bound(width, angle_bits, guard):
    step = max(1, 2 ** (angle_bits - 17))
    a = np.arange(-(2 ** (angle_bits - 1)), 2 ** (angle_bits - 1), step, dtype=np.int64)
    th = angle_to_radians(a, angle_bits)
    one = 2 ** (width - 2)
    observed, bounds = [], []
    for n in NS_ROT:
        c, s = cordic_rotation(a, width, n, angle_bits, guard)
        err = max(np.abs(c - one * np.cos(th)).max(), np.abs(s - one * np.sin(th)).max())
        bound = cordic_rotation_error_bound(width, n, angle_bits, guard)
        assert err <= bound, (n, err, bound)
        assert err > bound / 20, (n, err, bound)
        observed.append(err)
        bounds.append(bound)
        assert max(np.abs(c).max(), np.abs(s).max()) < 2 ** (width - 1)  # fits the format
    _check_decrease(observed, bounds, [one * math.atan(2.0 ** -(n - 1)) for n in NS_ROT])


def test_rotation_quadrants_exact_symmetry():
    """Pre-rotation by 180 deg negates exactly: f(a + 180deg) = -f(a) for |a| < 90deg."""
    a = np.arange(-16383, 16384, 7, dtype=np.int64)
    c1, s1 = cordic_rotation(a, 16, 14)
    c2, s2 = cordic_rotation(np.where(a < 0, a + 32768, a - 32768), 16, 14)
    np.testing.assert_array_equal(c2, -c1)
    np.testing.assert_array_equal(s2, -s1)


def test_bad_input():
    with pytest.raises(ValueError):
        cordic_vectoring(2**15, 0, 16, 8)
    with pytest.raises(TypeError):
        cordic_vectoring(1.0, 0.0, 16, 8)
    with pytest.raises(ValueError):
        cordic_rotation(0, 16, 0)
    with pytest.raises(ValueError):
        cordic_rotation(2**15, 16, 8, angle_bits=16)


# ----------------------------------------------------------------------------- bit level


def _ref_vectoring(x, y, width, n, abits, g, compensate, c):
    """Scalar Python-int transcription of the module docstring's recurrences (floor
    division by 2^i is the arithmetic shift)."""
    T = [round(math.atan(2.0**-i) * 2.0**abits / (2 * math.pi)) for i in range(n)]
    X, Y, z = x * 2**g, y * 2**g, 0
    if X < 0:
        X, Y, z = (Y, -X, 2 ** (abits - 2)) if Y >= 0 else (-Y, X, -(2 ** (abits - 2)))
    for i in range(n):
        d = 1 if Y >= 0 else -1
        X, Y, z = X + d * (Y // 2**i), Y - d * (X // 2**i), z + d * T[i]
    z = (z + 2 ** (abits - 1)) % 2**abits - 2 ** (abits - 1)
    if compensate:
        K = math.prod(math.sqrt(1 + 4.0**-i) for i in range(n))
        return (X * round(2.0**c / K)) // 2 ** (c + g), z
    return X // 2**g, z


def _ref_rotation(a, width, n, abits, g):
    T = [round(math.atan(2.0**-i) * 2.0**abits / (2 * math.pi)) for i in range(n)]
    q, h = 2 ** (abits - 2), 2 ** (abits - 1)
    flip = a > q or a < -q
    z = a - h if a > q else (a + h if a < -q else a)
    K = math.prod(math.sqrt(1 + 4.0**-i) for i in range(n))
    X, Y = round(2.0 ** (width - 2 + g) / K), 0
    for i in range(n):
        d = 1 if z >= 0 else -1
        X, Y, z = X - d * (Y // 2**i), Y + d * (X // 2**i), z - d * T[i]
    if flip:
        X, Y = -X, -Y
    return X // 2**g, Y // 2**g


@pytest.mark.parametrize("width, n, abits, g, comp", [
    (16, 16, 16, 0, False), (16, 12, 16, 2, True), (12, 9, 14, 1, False), (20, 20, 24, 3, True),
])
def test_bit_exact_against_scalar_transcription(width, n, abits, g, comp):
    rng = np.random.default_rng(width + n + abits + g)
    lo, hi = -(2 ** (width - 1)), 2 ** (width - 1)
    x = np.concatenate([rng.integers(lo, hi, 3000), [lo, hi - 1, 0, lo, -1, 0]])
    y = np.concatenate([rng.integers(lo, hi, 3000), [lo, lo, lo, 0, -1, 0]])
    m, a = cordic_vectoring(x, y, width, n, abits, g, compensate=comp)
    for k in range(x.size):
        want = _ref_vectoring(int(x[k]), int(y[k]), width, n, abits, g, comp, width + 2)
        assert (int(m[k]), int(a[k])) == want, (int(x[k]), int(y[k]))
    ang = np.concatenate([rng.integers(-(2 ** (abits - 1)), 2 ** (abits - 1), 3000),
                          [-(2 ** (abits - 1)), 2 ** (abits - 2), 2 ** (abits - 2) + 1, 0]])
    c, s = cordic_rotation(ang, width, n, abits, g)
    for k in range(ang.size):
        assert (int(c[k]), int(s[k])) == _ref_rotation(int(ang[k]), width, n, abits, g)
