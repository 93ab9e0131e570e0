"""navgate.numerics.fp32: directed IEEE edge cases, the complete list of deviations from
NumPy float32 over large random sets, and an exact (Fraction/integer) cross-check."""

from __future__ import annotations

import numpy as np
import pytest

from navgate.numerics import fp32_exact as E
from navgate.numerics.fp32 import (
    MAX_NORMAL,
    MIN_NORMAL,
    NEG_INF,
    NEG_ZERO,
    POS_INF,
    QNAN,
    bits_to_f32,
    f32_to_bits,
    flush_subnormal,
    fp32_add,
    fp32_compare,
    fp32_div,
    fp32_from_fixed,
    fp32_from_int,
    fp32_mul,
    fp32_sqrt,
    fp32_sub,
    fp32_to_fixed,
    fp32_to_int,
    is_inf,
    is_nan,
    is_subnormal,
)

ABS = np.uint32(0x7FFFFFFF)
N_RANDOM = 120_000  # per generator family; >= 100,000 vectors per op in total
ONE = 0x3F800000


def h(x: float) -> int:
    return int(f32_to_bits(np.float32(x)))


# ----------------------------------------------------------------------------- directed

ADD_CASES = [
    (0x00000000, 0x00000000, 0x00000000),
    (0x80000000, 0x80000000, 0x80000000),  # (-0) + (-0) = -0
    (0x00000000, 0x80000000, 0x00000000),
    (0x80000000, 0x00000000, 0x00000000),
    (ONE, ONE | 0x80000000, 0x00000000),  # exact zero sum is +0
    (POS_INF, ONE, POS_INF),
    (NEG_INF, NEG_INF, NEG_INF),
    (POS_INF, NEG_INF, QNAN),
    (0x7FC00123, ONE, QNAN),  # payload dropped
    (0xFFC00000, ONE, QNAN),  # sign of NaN dropped
    (0x7F800001, ONE, QNAN),  # signalling NaN
    (MAX_NORMAL, MAX_NORMAL, POS_INF),
    (MAX_NORMAL, 0x73000000, POS_INF),  # + half ulp(max), tie to even -> 2^128 -> inf
    (MAX_NORMAL, 0x72FFFFFF, MAX_NORMAL),  # just under half ulp
    (ONE, 0x33800000, ONE),  # 1 + 2^-24: tie, 1.0 is even
    (0x3F800001, 0x33800000, 0x3F800002),  # tie, rounds up to the even neighbour
    (ONE, 0x33800001, 0x3F800001),  # just above the tie
    (0x3F800001, 0xBF800000, 0x34000000),  # cancellation: exact 2^-23
    (0x00000001, 0x00000000, 0x00000000),  # subnormal input flushed
    (0x80000001, 0x80000000, 0x80000000),  # flushed to -0, (-0)+(-0)
    (0x007FFFFF, MIN_NORMAL, MIN_NORMAL),  # subnormal operand counts as 0
    (0x00800001, 0x80800000, 0x00000000),  # exact 2^-149: subnormal result -> +0
    (0x00800000, 0x80800001, 0x80000000),  # -2^-149 -> -0
    (0x01000001, 0x80800000, 0x00800002),  # 2^-125+2^-148-2^-126: normal, exact
]

SUB_CASES = [
    (0x80000000, 0x00000000, 0x80000000),  # (-0) - (+0) = -0
    (0x00000000, 0x00000000, 0x00000000),
    (POS_INF, POS_INF, QNAN),
    (POS_INF, NEG_INF, POS_INF),
    (0x3F800001, ONE, 0x34000000),
]

MUL_CASES = [
    (0x00000000, POS_INF, QNAN),
    (0x80000000, NEG_INF, QNAN),
    (0x80000000, 0x40A00000, 0x80000000),  # -0 * 5 = -0
    (0xC0000000, 0xC0400000, 0x40C00000),  # -2 * -3 = 6
    (0x5F800000, 0x5F800000, POS_INF),  # 2^64 * 2^64 = 2^128
    (0x5F000000, 0x5F800000, 0x7F000000),  # 2^127
    (0x1F800000, 0x1F000000, 0x00000000),  # 2^-64 * 2^-65 = 2^-129 -> +0
    (0x9F800000, 0x1F000000, 0x80000000),  # -> -0
    (0x3F7FFFFF, MIN_NORMAL, 0x00000000),  # 2^-126 - 2^-150: zero (NumPy: 2^-126)
    (0x3F7FFFFF, 0x00800001, MIN_NORMAL),  # rounds to 2^-126 with 24 bits
    (0x3FC00000, 0x3F800001, 0x3FC00002),  # 1.5 (1 + 2^-23): tie -> even
    (0x3FC00000, 0x3F800003, 0x3FC00004),  # 1.5 (1 + 3 2^-23): tie -> even
    (0x00400000, 0x7F000000, 0x00000000),  # subnormal input * 2^127 = 0
    (MAX_NORMAL, 0x3F800001, POS_INF),
    (0x7FC00000, 0x00000000, QNAN),
]

DIV_CASES = [
    (ONE, 0x00000000, POS_INF),
    (0xBF800000, 0x00000000, NEG_INF),
    (ONE, 0x80000000, NEG_INF),
    (0x00000000, 0x00000000, QNAN),
    (POS_INF, NEG_INF, QNAN),
    (ONE, POS_INF, 0x00000000),
    (0xBF800000, POS_INF, 0x80000000),
    (NEG_INF, 0x40000000, NEG_INF),
    (ONE, 0x40400000, 0x3EAAAAAB),  # 1/3
    (0x40000000, 0x40400000, 0x3F2AAAAB),  # 2/3
    (ONE, 0x00000001, POS_INF),  # subnormal divisor is zero
    (0x00000001, ONE, 0x00000000),
    (MIN_NORMAL, 0x40000000, 0x00000000),  # 2^-127 -> 0
    (MAX_NORMAL, 0x3F000000, POS_INF),  # max / 0.5 overflows
    (MIN_NORMAL, 0x3F800001, 0x00000000),  # just below 2^-126 -> 0 (NumPy: subnormal)
]

SQRT_CASES = [
    (0x00000000, 0x00000000),
    (0x80000000, 0x80000000),  # sqrt(-0) = -0
    (0xBF800000, QNAN),
    (POS_INF, POS_INF),
    (NEG_INF, QNAN),
    (0x40800000, 0x40000000),
    (0x40000000, 0x3FB504F3),  # sqrt(2)
    (0x00000001, 0x00000000),  # flushed
    (0x80000001, 0x80000000),  # flushed to -0 -> -0, not NaN
    (MAX_NORMAL, 0x5F7FFFFF),
    (MIN_NORMAL, 0x20000000),  # 2^-63
    (0xFFC00000, QNAN),
]


@pytest.mark.parametrize("op, cases", [
    (fp32_add, ADD_CASES), (fp32_sub, SUB_CASES), (fp32_mul, MUL_CASES), (fp32_div, DIV_CASES),
])
def test_directed_binary(op, cases):
    exact = {fp32_add: E.add, fp32_sub: E.sub, fp32_mul: E.mul, fp32_div: E.div}[op]
    for a, b, want in cases:
        got = int(op(a, b))
        assert got == want, f"{op.__name__}({a:#010x}, {b:#010x}) = {got:#010x} != {want:#010x}"
        assert exact(a, b) == want, f"exact reference disagrees on {a:#010x}, {b:#010x}"
    # vectorised form gives the same answers
    a, b, want = (np.array(c, dtype=np.uint32) for c in zip(*cases, strict=True))
    np.testing.assert_array_equal(op(a, b), want)


def test_directed_sqrt():
    for a, want in SQRT_CASES:
        assert int(fp32_sqrt(a)) == want, f"sqrt({a:#010x})"
        assert E.sqrt(a) == want


def test_scalar_and_types():
    r = fp32_add(ONE, ONE)
    assert isinstance(r, np.uint32) and int(r) == 0x40000000
    assert fp32_add(np.array([ONE]), ONE).shape == (1,)
    with pytest.raises(TypeError):
        fp32_add(np.float32(1.0), ONE)
    with pytest.raises(ValueError):
        fp32_add(-1, ONE)
    with pytest.raises(ValueError):
        fp32_add(2**32, ONE)


def test_compare():
    vals = [NEG_INF, 0xFF7FFFFF, 0xBF800000, NEG_ZERO, 0x00000000, 0x00000001, ONE,
            MAX_NORMAL, POS_INF, QNAN, 0xFFC00001]
    order = [0, 1, 2, 3, 3, 3, 4, 5, 6, None, None]  # subnormal == 0 == -0
    a = np.array([v for v in vals for _ in vals], dtype=np.uint32)
    b = np.array([v for _ in vals for v in vals], dtype=np.uint32)
    r = fp32_compare(a, b)
    oa = [order[i] for i in range(len(vals)) for _ in vals]
    ob = [order[j] for _ in vals for j in range(len(vals))]
    for k, (x, y) in enumerate(zip(oa, ob, strict=True)):
        if x is None or y is None:
            assert r["unordered"][k] and not (r["lt"][k] or r["eq"][k] or r["gt"][k])
        else:
            assert (r["lt"][k], r["eq"][k], r["gt"][k], r["unordered"][k]) == (
                x < y, x == y, x > y, False)
    s = fp32_compare(QNAN, QNAN)
    assert s == {"lt": False, "eq": False, "gt": False, "unordered": True}


def test_compare_random_vs_numpy():
    rng = np.random.default_rng(11)
    a = _normal_bits(rng, N_RANDOM)
    b = np.where(rng.random(N_RANDOM) < 0.3, a ^ np.uint32(1), _normal_bits(rng, N_RANDOM))
    b = b.astype(np.uint32)
    r = fp32_compare(a, b)
    fa, fb = bits_to_f32(a), bits_to_f32(b)
    np.testing.assert_array_equal(r["lt"], fa < fb)
    np.testing.assert_array_equal(r["eq"], fa == fb)
    np.testing.assert_array_equal(r["gt"], fa > fb)


# ----------------------------------------------------------------------------- generators


def _normal_bits(rng, n, emin=1, emax=254):
    s = rng.integers(0, 2, n, dtype=np.uint32) << np.uint32(31)
    e = rng.integers(emin, emax + 1, n).astype(np.uint32) << np.uint32(23)
    f = rng.integers(0, 1 << 23, n, dtype=np.uint32)
    return (s | e | f).astype(np.uint32)


def _operands(rng, kind: str, n: int):
    """Operand pairs from several families, so that every deviation class occurs."""
    u = lambda: rng.integers(0, 2**32, n, dtype=np.uint64).astype(np.uint32)  # noqa: E731
    if kind == "uniform":  # all patterns: NaNs, infinities, subnormals, zeros
        return u(), u()
    if kind == "close":  # exponents within +-3 (cancellation), plus exact ties
        a = _normal_bits(rng, n, 30, 220)
        de = rng.integers(-3, 4, n)
        e = ((a >> np.uint32(23)) & np.uint32(0xFF)).astype(np.int64) + de
        b = _normal_bits(rng, n) & np.uint32(0x807FFFFF) | (e.astype(np.uint32) << np.uint32(23))
        tie = rng.random(n) < 0.2  # b = half an ulp of a (or 3/4, 1/4 ulp)
        eb = ((a >> np.uint32(23)) & np.uint32(0xFF)).astype(np.int64) - 24
        frac = rng.choice(np.array([0, 0x400000, 0x000001], dtype=np.uint32), n)
        tb = (rng.integers(0, 2, n, dtype=np.uint32) << np.uint32(31)) | (
            eb.astype(np.uint32) << np.uint32(23)) | frac
        return a, np.where(tie, tb, b).astype(np.uint32)
    if kind == "tiny":  # results around 2^-126: subnormal outputs and the boundary
        a = _normal_bits(rng, n, 1, 40)
        b = _normal_bits(rng, n, 1, 40)
        # near-cancelling pairs for add (opposite signs) and for sub (same signs)
        near = rng.random(n) < 0.5
        sign = np.where(rng.random(n) < 0.5, np.uint32(0x80000000), np.uint32(0))
        b2 = (a ^ sign.astype(np.uint32)) + rng.integers(-4, 5, n).astype(np.uint32)
        return a, np.where(near, b2, b).astype(np.uint32)
    if kind == "mulrange":  # products/quotients near underflow and overflow
        a = _normal_bits(rng, n, 1, 254)
        ea = ((a >> np.uint32(23)) & np.uint32(0xFF)).astype(np.int64)
        target = rng.choice(np.array([1, 2, 127, 252, 253, 254, 255]), n)
        eb = np.clip(target + 127 - ea + rng.integers(-1, 2, n), 1, 254)
        b = _normal_bits(rng, n) & np.uint32(0x807FFFFF) | (eb.astype(np.uint32) << 23)
        return a, b.astype(np.uint32)
    if kind == "divrange":
        a = _normal_bits(rng, n, 1, 254)
        ea = ((a >> np.uint32(23)) & np.uint32(0xFF)).astype(np.int64)
        target = rng.choice(np.array([1, 2, 127, 253, 254, 255]), n)
        eb = np.clip(ea - target + 127 + rng.integers(-1, 2, n), 1, 254)
        b = _normal_bits(rng, n) & np.uint32(0x807FFFFF) | (eb.astype(np.uint32) << 23)
        return a, b.astype(np.uint32)
    if kind == "multie":  # 1.5 * (1 + k 2^-23), k odd: exact ties to even
        k = (rng.integers(0, 1 << 22, n, dtype=np.uint32) << np.uint32(1)) | np.uint32(1)
        ea = rng.integers(60, 190, n).astype(np.uint32)
        a = (ea << np.uint32(23)) | np.uint32(0x400000)
        b = (np.uint32(127) << np.uint32(23)) | k
        return a.astype(np.uint32), b.astype(np.uint32)
    if kind == "boundary":  # exact results in [2^-126 - 2^-150, 2^-126 + small)
        # mul: P = ma * mb just above T = (2^24 - 1) 2^23, scaled so that T <-> 2^-126 -
        # 2^-150; div: (2^24 - 1) / 2^23 = 2 - 2^-23 scaled the same way
        ma = rng.integers(1 << 23, 1 << 24, n)
        T = (1 << 47) - (1 << 23)
        mb = np.minimum(-(-T // ma) + rng.integers(-1, 2, n), (1 << 24) - 1)
        ea = rng.integers(-126, 0, n)
        eb = -127 - ea
        s = rng.integers(0, 2, (2, n), dtype=np.uint32) << np.uint32(31)
        a = s[0] | ((ea + 127).astype(np.uint32) << 23) | (ma & 0x7FFFFF).astype(np.uint32)
        b = s[1] | ((eb + 127).astype(np.uint32) << 23) | (mb & 0x7FFFFF).astype(np.uint32)
        return a.astype(np.uint32), b.astype(np.uint32)
    if kind == "divboundary":
        ea = rng.integers(-126, 0, n)
        eb = ea + 127 + rng.integers(-1, 2, n)  # quotient (2 - 2^-23) 2^(ea - eb) ~ 2^-127
        s = rng.integers(0, 2, (2, n), dtype=np.uint32) << np.uint32(31)
        a = s[0] | ((ea + 127).astype(np.uint32) << 23) | np.uint32(0x7FFFFF)
        b = s[1] | ((eb + 127).astype(np.uint32) << 23)
        return a.astype(np.uint32), b.astype(np.uint32)
    raise ValueError(kind)


def _np_op(name):
    return {"add": np.add, "sub": np.subtract, "mul": np.multiply, "div": np.divide}[name]


OPS = {"add": fp32_add, "sub": fp32_sub, "mul": fp32_mul, "div": fp32_div}
EXACT = {"add": E.add, "sub": E.sub, "mul": E.mul, "div": E.div}
FAMILIES = {
    "add": ["uniform", "close", "tiny"],
    "sub": ["uniform", "close", "tiny"],
    "mul": ["uniform", "mulrange", "multie", "boundary"],
    "div": ["uniform", "divrange", "close", "divboundary"],
}


def _numpy_bits(op, *args):
    with np.errstate(all="ignore"):
        return np.asarray(op(*[bits_to_f32(a) for a in args])).view(np.uint32)


def _classify(ours, raw_np, inputs):
    """Boolean masks of the documented deviation classes (module docstring of fp32)."""
    sub_in = np.zeros(ours.shape, dtype=bool)
    for x in inputs:
        sub_in |= is_subnormal(x)
    nan = is_nan(raw_np)
    sub_out = is_subnormal(raw_np)
    boundary = ((raw_np & ABS) == MIN_NORMAL) & ((ours & ABS) == 0)
    return sub_in, sub_out, boundary, nan


def _check_against_numpy(name, ours, inputs, exact_fn, rng):
    """The only differences from NumPy are the four documented classes, each of which
    is checked for its own rule. Returns the class counts."""
    npop = _np_op(name) if name != "sqrt" else np.sqrt
    raw = _numpy_bits(npop, *inputs)
    sub_in, sub_out, boundary, nan = _classify(ours, raw, inputs)
    diff = ours != raw
    unexplained = diff & ~(sub_in | sub_out | boundary | nan)
    assert not unexplained.any(), (
        f"{name}: {int(unexplained.sum())} unexplained differences, first "
        f"{[hex(int(x[unexplained][0])) for x in inputs]}")
    # rule per class, evaluated on NumPy with the inputs flushed (class 1 removed)
    flushed = [flush_subnormal(x) for x in inputs]
    fl = _numpy_bits(npop, *flushed)
    _, f_sub, f_bnd, f_nan = _classify(ours, fl, flushed)
    assert (ours[f_nan] == QNAN).all()
    assert not (is_nan(ours) & ~f_nan).any()
    np.testing.assert_array_equal(ours[f_sub], fl[f_sub] & np.uint32(0x80000000))
    rest = ~(f_nan | f_sub | f_bnd)
    np.testing.assert_array_equal(ours[rest], fl[rest])
    # the boundary class and a sample of everything go through the exact reference
    idx = np.flatnonzero(f_bnd)
    idx = np.concatenate([idx[:500], np.flatnonzero(f_sub)[:300],
                          rng.choice(ours.size, 1500, replace=False)])
    for k in idx:
        args = [int(x[k]) for x in inputs]
        assert int(ours[k]) == exact_fn(*args), f"{name}{tuple(hex(a) for a in args)}"
    return {"sub_in": int(sub_in.sum()), "sub_out": int(sub_out.sum()),
            "boundary": int(boundary.sum()), "nan": int(nan.sum())}


@pytest.mark.parametrize("name", ["add", "sub", "mul", "div"])
def test_random_vs_numpy_only_documented_deviations(name):
    rng = np.random.default_rng({"add": 1, "sub": 2, "mul": 3, "div": 4}[name])
    totals = {"sub_in": 0, "sub_out": 0, "boundary": 0, "nan": 0}
    n_vec = 0
    for fam in FAMILIES[name]:
        a, b = _operands(rng, fam, N_RANDOM)
        ours = OPS[name](a, b)
        counts = _check_against_numpy(name, ours, [a, b], EXACT[name], rng)
        totals = {k: totals[k] + counts[k] for k in totals}
        n_vec += a.size
    assert n_vec >= 300_000
    # the generators must actually reach every deviation class they can reach
    # (an exact sum of normals is a multiple of 2^-149, so add/sub cannot hit the
    # boundary class: see docs/numerics.md)
    assert totals["sub_in"] > 100 and totals["nan"] > 100 and totals["sub_out"] > 100
    if name in ("mul", "div"):
        assert totals["boundary"] > 0


def test_random_sqrt_vs_numpy():
    rng = np.random.default_rng(5)
    a = np.concatenate([
        rng.integers(0, 2**32, N_RANDOM, dtype=np.uint64).astype(np.uint32),
        _normal_bits(rng, N_RANDOM) & np.uint32(0x7FFFFFFF),
    ])
    ours = fp32_sqrt(a)
    counts = _check_against_numpy("sqrt", ours, [a], E.sqrt, rng)
    assert counts["nan"] > 1000 and counts["sub_in"] > 100
    assert counts["sub_out"] == 0  # sqrt of a normal is never tiny


# ----------------------------------------------------------------------------- hard cases


def _pack(mant24: int, exp_unbiased: int, sign: int = 0) -> int:
    return (sign << 31) | ((exp_unbiased + 127) << 23) | (mant24 & 0x7FFFFF)


def test_div_near_midpoint_exact():
    """Quotients within a hair of a rounding midpoint (no exact ties exist for
    division): a = round(b * M) for M a 25-bit odd midpoint significand."""
    rng = np.random.default_rng(6)
    cases = []
    while len(cases) < 3000:
        mb = int(rng.integers(1 << 23, 1 << 24))
        M = int(rng.integers(1 << 24, 1 << 25)) | 1
        ma = (mb * M + (1 << 24)) >> 25
        if not (1 << 23) <= ma < (1 << 24):
            continue
        ea = int(rng.integers(-100, 100))
        eb = int(rng.integers(-20, 20))
        cases.append((_pack(ma, ea, int(rng.integers(0, 2))), _pack(mb, eb)))
    a = np.array([c[0] for c in cases], dtype=np.uint32)
    b = np.array([c[1] for c in cases], dtype=np.uint32)
    ours = fp32_div(a, b)
    np.testing.assert_array_equal(ours, _numpy_bits(np.divide, a, b))
    for k in range(len(cases)):
        assert int(ours[k]) == E.div(int(a[k]), int(b[k]))


def test_sqrt_near_midpoint_exact():
    rng = np.random.default_rng(7)
    vals = []
    for _ in range(3000):
        M = int(rng.integers(1 << 24, 1 << 25)) | 1  # sqrt target = midpoint
        S = M * M
        sh = S.bit_length() - 24
        ma = (S + (1 << (sh - 1))) >> sh
        if ma >> 24:
            continue
        # a = ma * 2^sh * 4^-k keeps sqrt(a) close to M 2^-k
        k = int(rng.integers(20, 40))
        e = sh - 2 * k + 23
        vals.append(_pack(ma, e))
    a = np.array(vals, dtype=np.uint32)
    ours = fp32_sqrt(a)
    np.testing.assert_array_equal(ours, _numpy_bits(np.sqrt, a))
    for k in range(a.size):
        assert int(ours[k]) == E.sqrt(int(a[k]))


# ----------------------------------------------------------------------------- conversions


def test_from_int_directed():
    cases = [
        (0, 32, 0x00000000), (1, 32, ONE), (-1, 32, 0xBF800000),
        ((1 << 24) + 1, 32, 0x4B800000),  # tie -> even (2^24)
        ((1 << 24) + 3, 32, 0x4B800002),  # tie -> even (2^24 + 4)
        (-(1 << 31), 32, 0xCF000000), ((1 << 31) - 1, 32, 0x4F000000),
        (-(1 << 63), 64, 0xDF000000), ((1 << 63) - 1, 64, 0x5F000000),
        (-128, 8, 0xC3000000), (127, 8, 0x42FE0000),
    ]
    for i, w, want in cases:
        assert int(fp32_from_int(i, w)) == want, (i, w)
        assert E.from_int(i) == want
    with pytest.raises(ValueError):
        fp32_from_int(128, 8)
    with pytest.raises(ValueError):
        fp32_from_int(np.array([1 << 40]), 32)
    with pytest.raises(TypeError):
        fp32_from_int(1.5)


def test_from_int_random():
    rng = np.random.default_rng(8)
    i32 = rng.integers(-(2**31), 2**31, N_RANDOM)
    np.testing.assert_array_equal(fp32_from_int(i32, 32),
                                  i32.astype(np.int32).astype(np.float32).view(np.uint32))
    # 64-bit: magnitudes of every size, against the exact reference
    bits = rng.integers(1, 63, 4000)
    i64 = [int(rng.integers(0, 2**62)) >> (62 - int(nb)) for nb in bits]
    i64 = [v if k % 2 else -v for k, v in enumerate(i64)] + [-(1 << 63), (1 << 63) - 1]
    ours = fp32_from_int(np.array(i64, dtype=np.int64), 64)
    for v, o in zip(i64, ours, strict=True):
        assert int(o) == E.from_int(v), v


def test_to_int_directed():
    cases = [
        (2.5, 32, 2, False), (3.5, 32, 4, False), (-2.5, 32, -2, False), (0.5, 32, 0, False),
        (1.5, 32, 2, False), (-0.5, 32, 0, False), (2.0**31, 32, 2**31 - 1, True),
        (-(2.0**31), 32, -(2**31), False), (2147483520.0, 32, 2147483520, False),
        (32767.5, 16, 32767, True), (-32768.5, 16, -32768, False),
        (-32769.0, 16, -32768, True), (1e30, 64, 2**63 - 1, True),
        (-(2.0**63), 64, -(2**63), False),
    ]
    for x, w, want, flag in cases:
        v, f = fp32_to_int(h(x), w)
        assert (int(v), bool(f)) == (want, flag), (x, w)
        assert E.to_int(h(x), w) == (want, flag)
    assert fp32_to_int(QNAN) == (0, True)
    assert fp32_to_int(POS_INF) == (2**31 - 1, True)
    assert fp32_to_int(NEG_INF) == (-(2**31), True)
    assert fp32_to_int(0x00000001) == (0, False)
    assert fp32_to_int(0x80000000) == (0, False)


def test_to_int_random():
    rng = np.random.default_rng(9)
    a = np.concatenate([_normal_bits(rng, N_RANDOM, 100, 165),
                        rng.integers(0, 2**32, 20000, dtype=np.uint64).astype(np.uint32)])
    for w in (32, 16, 64):
        v, f = fp32_to_int(a, w)
        lo, hi = -(2 ** (w - 1)), 2 ** (w - 1) - 1
        with np.errstate(invalid="ignore"):  # signalling NaN patterns
            x = bits_to_f32(flush_subnormal(a)).astype(np.float64)
            r = np.rint(x)  # ties to even, exact for float32 inputs
            want_flag = np.isnan(x) | (r > hi) | (r < lo)
            want = np.where(np.isnan(x), 0, np.clip(r, lo, hi))
        np.testing.assert_array_equal(f, want_flag)
        if w < 64:
            np.testing.assert_array_equal(v, want.astype(np.int64))
        for k in rng.choice(a.size, 500, replace=False):
            assert (int(v[k]), bool(f[k])) == E.to_int(int(a[k]), w)


def test_fixed_conversions():
    assert fp32_to_fixed(h(1.5), 10, 20) == (1536, False)
    assert fp32_to_fixed(h(-1.5), 10, 20) == (-1536, False)
    assert fp32_to_fixed(h(1000.0), 10, 20) == (2**19 - 1, True)
    assert fp32_to_fixed(h(2.0**-11), 10, 20) == (0, False)  # tie -> even 0
    assert fp32_to_fixed(h(3 * 2.0**-11), 10, 20) == (2, False)  # 1.5 LSB -> 2
    assert int(fp32_from_fixed(1536, 10, 20)) == h(1.5)
    assert int(fp32_from_fixed(-1, 200, 32)) == NEG_ZERO  # 2^-200 flushes, keeps sign
    assert int(fp32_from_fixed(1, -127, 8)) == h(2.0**127)
    assert int(fp32_from_fixed(1, -128, 8)) == POS_INF
    rng = np.random.default_rng(10)
    x = rng.integers(-(2**19), 2**19, N_RANDOM)
    np.testing.assert_array_equal(fp32_from_fixed(x, 10, 20),
                                  np.ldexp(x.astype(np.float64), -10).astype(np.float32)
                                  .view(np.uint32))
    a = _normal_bits(rng, N_RANDOM, 110, 140)
    v, f = fp32_to_fixed(a, 10, 20)
    r = np.rint(np.ldexp(bits_to_f32(a).astype(np.float64), 10))
    np.testing.assert_array_equal(v, np.clip(r, -(2**19), 2**19 - 1).astype(np.int64))
    np.testing.assert_array_equal(f, (r > 2**19 - 1) | (r < -(2**19)))
    for k in range(300):
        assert (int(v[k]), bool(f[k])) == E.to_int(int(a[k]), 20, 10)
        assert int(fp32_from_fixed(int(x[k]), 10, 20)) == E.from_int(int(x[k]), -10)


def test_helpers():
    assert int(f32_to_bits(1.0)) == ONE
    assert float(bits_to_f32(ONE)) == 1.0
    b = np.array([QNAN, POS_INF, 0x00000001, 0x00800000, 0x80000000], dtype=np.uint32)
    np.testing.assert_array_equal(is_nan(b), [1, 0, 0, 0, 0])
    np.testing.assert_array_equal(is_inf(b), [0, 1, 0, 0, 0])
    np.testing.assert_array_equal(is_subnormal(b), [0, 0, 1, 0, 0])


def test_neg_abs():
    from navgate.numerics.fp32 import fp32_abs, fp32_neg

    b = np.array([ONE, 0xBF800000, 0x00000000, 0x80000000, 0x00000001, 0x80000001, QNAN,
                  0xFFC00001, POS_INF], dtype=np.uint32)
    np.testing.assert_array_equal(
        fp32_neg(b), [0xBF800000, ONE, NEG_ZERO, 0x00000000, NEG_ZERO, 0x00000000, QNAN,
                      QNAN, NEG_INF])
    np.testing.assert_array_equal(
        fp32_abs(b), [ONE, ONE, 0, 0, 0, 0, QNAN, QNAN, POS_INF])
