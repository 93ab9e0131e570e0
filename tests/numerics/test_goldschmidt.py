"""navgate.numerics.goldschmidt: seed accuracy, quadratic convergence inside the derived
bound, and the Q(20,10) reciprocal/divide of seed 004 with its flags."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from navgate.numerics.goldschmidt import (
    goldschmidt_divide,
    goldschmidt_error_bound,
    goldschmidt_normalised,
    goldschmidt_reciprocal,
    goldschmidt_seed_table,
    seed_error,
)

W, FR = 20, 10  # seed 004's Q(N=20, FRAC=10)
MAX, MIN = 2**19 - 1, -(2**19)


def test_seed_table_contents_and_error():
    F = 20
    tab = goldschmidt_seed_table(2, F)
    # entry i = round(2^F * 2 / (lo + hi)), lo + hi = 1 + (2i + 1)/8
    want = [round(Fraction(2 * 2**F) / (1 + Fraction(2 * i + 1, 8))) for i in range(4)]
    assert tab.tolist() == want
    assert goldschmidt_seed_table(0, F).tolist() == [round(Fraction(4, 3) * 2**F)]
    for sb in range(0, 8):
        e = seed_error(sb, F)
        # midpoint reciprocal: |1 - D x0| <= h / (2 lo + h) <= 2^-(sb+1), h = 2^-(sb+1),
        # plus the rounding of x0 to F bits (<= 2^-(F+1) * D < 2^-(F+1))
        h = 2.0 ** -(sb + 1)
        assert e <= h / (1 + h) + 2.0 ** -(F + 1)
        assert e >= h / (1 + h) - 2.0 ** -(F + 1)  # attained at the first entry's ends
    assert abs(seed_error(0, F, "linear") - 1 / 17) < 1e-5


@pytest.mark.parametrize("seed_bits, seed", [(0, "table"), (2, "table"), (4, "table"),
                                             (0, "linear")])
def test_quadratic_convergence_within_bound(seed_bits, seed):
    F = 20
    u = 2.0**-F
    rng = np.random.default_rng(seed_bits)
    D = rng.integers(2 ** (F - 1), 2**F, 100_000)
    num = rng.integers(2 ** (F - 1), 2**F + 1, 100_000)
    # the worst seeds: ends of every table interval
    h = 1 << (F - 1 - seed_bits) if seed == "table" else 1 << (F - 6)
    ends = np.arange(2 ** (F - 1), 2**F, h)
    D = np.concatenate([D, ends, ends + h - 1])
    num = np.concatenate([num, np.full(2 * ends.size, 2**F)])
    exact = num / D  # float64 relative error 1e-16, far below every figure here
    errs = []
    for k in range(5):
        N = goldschmidt_normalised(num, D, F, k, seed_bits, seed)
        err = float(np.abs(N / 2.0**F / exact - 1).max())
        bound = goldschmidt_error_bound(k, seed_bits, F, seed)
        assert err <= bound, (k, err, bound)
        errs.append(err)
        if bound > 1000 * u:  # quadratic regime: the bound is attained within 20 %
            assert err >= 0.8 * bound, (k, err, bound)
        else:  # truncation floor (2k + 3) u: still within a factor 4
            assert err >= bound / 4, (k, err, bound)
    # e_{k+1} ~ e_k^2 while above the truncation floor
    for k in range(4):
        if errs[k] ** 2 > 1000 * u:
            assert 0.8 * errs[k] ** 2 <= errs[k + 1] <= 1.2 * errs[k] ** 2 + 4 * u


def test_reciprocal_directed():
    cases = [
        (0, MAX, True, False), (1, MAX, False, True), (-1, MIN, False, True),
        (2, MAX, False, True), (-2, MIN, False, False),  # -2^-9 -> -512 = MIN exactly
        (1024, 1024, False, False), (-1024, -1024, False, False), (2048, 512, False, False),
        (512, 2048, False, False), (3072, 341, False, False), (MAX, 2, False, False),
        (MIN, -2, False, False),
    ]
    for d, want, dbz, ovf in cases:
        v, f = goldschmidt_reciprocal(d, W, FR)
        assert (int(v), f["divide_by_zero"], f["overflow"]) == (want, dbz, ovf), d


@pytest.mark.parametrize("rounding", ["nearest", "truncate"])
def test_reciprocal_random(rounding):
    rng = np.random.default_rng(1)
    d = np.concatenate([rng.integers(MIN, MAX + 1, 100_000), np.arange(-300, 301)])
    it, sb = 3, 4
    v, f = goldschmidt_reciprocal(d, W, FR, it, sb, rounding=rounding)
    rel = goldschmidt_error_bound(it, sb, W)
    dd = np.where(d == 0, 1, d)
    exact = 2.0 ** (2 * FR) / dd
    ok = ~f["overflow"] & ~f["divide_by_zero"]
    # |value - exact| <= |exact| rel + 1/2 (nearest) or + 1 (truncate), see the docstring
    slack = 0.5 if rounding == "nearest" else 1.0
    assert (np.abs(v - exact)[ok] <= np.abs(exact[ok]) * rel + slack).all()
    np.testing.assert_array_equal(f["divide_by_zero"], d == 0)
    # overflow exactly where the exact reciprocal is out of range (margin: rel error)
    clear_out = (exact > MAX + 1) | (exact < MIN - 1)
    clear_in = (exact < MAX - 1) & (exact > MIN + 1)
    assert f["overflow"][clear_out & (d != 0)].all()
    assert not f["overflow"][clear_in].any()
    assert (v[f["overflow"] & (d > 0)] == MAX).all() and (v[f["overflow"] & (d < 0)] == MIN).all()
    if rounding == "truncate":  # magnitude floored: never above |exact|
        assert (np.abs(v)[ok] <= np.abs(exact[ok]) + 1e-9).all()


def test_divide():
    rng = np.random.default_rng(2)
    n = rng.integers(MIN, MAX + 1, 100_000)
    d = rng.integers(MIN, MAX + 1, 100_000)
    d[:50] = 0
    n[:10] = 0
    it, sb = 3, 4
    q, f = goldschmidt_divide(n, d, W, FR, it, sb)
    rel = goldschmidt_error_bound(it, sb, W)
    exact = n * 2.0**FR / np.where(d == 0, 1, d)
    ok = ~f["overflow"] & ~f["divide_by_zero"]
    assert (np.abs(q - exact)[ok] <= np.abs(exact[ok]) * rel + 0.5).all()
    assert ok.sum() > 90_000 and f["overflow"].sum() > 100
    np.testing.assert_array_equal(f["divide_by_zero"], d == 0)
    dz = d == 0
    np.testing.assert_array_equal(q[dz], np.where(n[dz] > 0, MAX, np.where(n[dz] < 0, MIN, 0)))
    ov = f["overflow"]
    assert (np.abs(exact[ov]) > MAX - 1).all()
    np.testing.assert_array_equal(q[ov], np.where(exact[ov] > 0, MAX, MIN))
    # scalar form and exact small cases
    assert goldschmidt_divide(3 * 1024, 2 * 1024, W, FR) == (1536, {
        "divide_by_zero": False, "overflow": False})
    assert goldschmidt_divide(-1024, 3 * 1024, W, FR)[0] == -341
    assert goldschmidt_divide(0, 0, W, FR) == (0, {"divide_by_zero": True, "overflow": False})
    assert goldschmidt_divide(MAX, 1, W, FR) == (MAX, {"divide_by_zero": False,
                                                       "overflow": True})


def test_q20_error_shrinks_with_iterations():
    """The same quadratic law seen at the Q(20,10) output: max error in LSB of 1/d for
    d in [1, 4) (quotients 256..1024 LSB) falls as 1024 e0^(2^k) (e0 = 1/3: 341, 114,
    13) to below 1 LSB."""
    d = np.arange(1024, 4096)
    exact = 2.0**20 / d
    errs = []
    for it in range(4):
        v, _ = goldschmidt_reciprocal(d, W, FR, it, seed_bits=0)
        errs.append(float(np.abs(v - exact).max()))
        assert errs[-1] <= exact.max() * goldschmidt_error_bound(it, 0, W) + 0.5
    assert errs[0] > 300 and errs[1] > 100 and errs[2] > 10 and errs[3] < 1


def test_bad_input():
    with pytest.raises(ValueError):
        goldschmidt_reciprocal(2**19, W, FR)  # out of Q(20,10)
    with pytest.raises(ValueError):
        goldschmidt_reciprocal(5, W, FR, internal_frac=W - 1)
    with pytest.raises(ValueError):
        goldschmidt_reciprocal(5, 31, FR)
    with pytest.raises(TypeError):
        goldschmidt_reciprocal(1.0, W, FR)
    with pytest.raises(ValueError):
        goldschmidt_divide(1, 1, W, FR, seed="cubic")
    with pytest.raises(ValueError):
        goldschmidt_normalised(2**20, 2**18, 20, 2)  # D not normalised


def _ref_divide(n, d, width, frac, it, sb, F, rounding, recip):
    """Scalar Python-int transcription of the module docstring's datapath."""
    top, bot = (1 << (width - 1)) - 1, -(1 << (width - 1))
    if d == 0:
        return (top if recip else (top if n > 0 else bot if n < 0 else 0)), True, False
    if not recip and n == 0:
        return 0, False, False
    neg = (d < 0) != (n < 0) if not recip else d < 0
    a = abs(d)
    pd = a.bit_length() - 1
    D = a << (F - 1 - pd)
    if recip:
        num, e = 1 << F, 2 * frac - pd - 1 - F
    else:
        b = abs(n)
        pn = b.bit_length() - 1
        num, e = b << (F - 1 - pn), pn - pd + frac - F
    h = 1 << (F - 1 - sb)
    lo2 = (1 << (sb + 1)) + 2 * ((D - (1 << (F - 1))) // h) + 1
    x0 = round(Fraction(2 << (sb + 1 + F), lo2))  # ties cannot occur (odd denominator)
    N, Dk = (num * x0) >> F, (D * x0) >> F
    for _ in range(it):
        G = (2 << F) - Dk
        N, Dk = (N * G) >> F, (Dk * G) >> F
    if e >= 0:
        mag = N << e
    else:
        mag = (N + (1 << (-e - 1) if rounding == "nearest" else 0)) >> -e
    lim = -bot if neg else top
    over = mag > lim
    mag = min(mag, lim)
    return (-mag if neg else mag), False, over


@pytest.mark.parametrize("rounding", ["nearest", "truncate"])
@pytest.mark.parametrize("width, frac, it, sb", [(20, 10, 3, 4), (16, 14, 2, 3), (12, 0, 1, 2)])
def test_bit_exact_against_scalar_transcription(width, frac, it, sb, rounding):
    rng = np.random.default_rng(width + frac)
    lo, hi = -(2 ** (width - 1)), 2 ** (width - 1)
    n = np.concatenate([rng.integers(lo, hi, 2000), [0, 5, lo, hi - 1, 1, -1]])
    d = np.concatenate([rng.integers(lo, hi, 2000), [0, 0, lo, 1, hi - 1, lo]])
    F = width
    q, f = goldschmidt_divide(n, d, width, frac, it, sb, rounding=rounding)
    r, g = goldschmidt_reciprocal(d, width, frac, it, sb, rounding=rounding)
    for k in range(n.size):
        want = _ref_divide(int(n[k]), int(d[k]), width, frac, it, sb, F, rounding, False)
        got = (int(q[k]), bool(f["divide_by_zero"][k]), bool(f["overflow"][k]))
        assert got == want, (int(n[k]), int(d[k]))
        want = _ref_divide(1, int(d[k]), width, frac, it, sb, F, rounding, True)
        got = (int(r[k]), bool(g["divide_by_zero"][k]), bool(g["overflow"][k]))
        assert got == want, int(d[k])


def test_right_shift_of_a_wide_normalised_value_is_not_overflow():
    """Regression: Q(16,0) with 18 internal fraction bits; results need a right shift."""
    import numpy as np

    from navgate.numerics.goldschmidt import goldschmidt_reciprocal

    q, flags = goldschmidt_reciprocal(np.array([1, -32768, 2]), 16, 0, iterations=4,
                                      seed_bits=2, internal_frac=18)
    assert q.tolist() == [1, 0, 1]  # 1/1, 1/-32768 -> 0, 1/2 rounds half up to 1
    assert not flags["overflow"].any()
