"""Float32 test vectors and model adapters for the ``navgate.gateware.fp32`` cores.

Used by tests/gateware/test_fp32_*.py and by anyone re-running the cores through
:mod:`navgate.gateware.verify`.  Random vectors are seeded and biased towards the
places where float datapaths go wrong (Muller et al., Handbook of Floating-Point
Arithmetic, 2nd ed., ch. 7-8; Goldberg 1991):

* exponent differences around the alignment-shifter width (far/near paths,
  sticky bits), catastrophic cancellation (equal exponents, nearby fractions);
* significands with few set bits, so that exact halfway cases (ties) and exact
  results are frequent;
* exponents near the underflow (2**-126) and overflow (2**128) thresholds,
  including significands of all ones whose rounding carries across them;
* special values (signed zeros, subnormals, infinities, quiet and signalling
  NaNs with payloads) mixed into every batch.

``CASES`` maps each block name of ``navgate.gateware.fp32.BLOCKS`` (plus
``fp32_sub``, the adder with its ``sub`` bit set) to a :class:`Fp32Case`: how to
build the DUT, the bit-true model from ``navgate.numerics.fp32`` and the random
and directed vector generators.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from navgate.numerics import fp32 as F

from .verify import f32_formatter

__all__ = ["SPECIALS", "Fp32Case", "CASES", "f32", "cross", "DIV_DIRECTED", "SQRT_DIRECTED"]

U32 = np.uint32


def f32(sign, exp, frac) -> np.ndarray:
    """Assemble bit patterns from sign, biased exponent and fraction arrays."""
    sign = np.asarray(sign).astype(np.uint64) & 1
    exp = np.asarray(exp).astype(np.uint64) & 0xFF
    frac = np.asarray(frac).astype(np.uint64) & 0x7FFFFF
    return ((sign << 31) | (exp << 23) | frac).astype(U32)


_SPECIAL_MAGNITUDES = [
    0x00000000,  # zero
    0x00000001,  # smallest subnormal
    0x00400000,  # mid subnormal
    0x007FFFFF,  # largest subnormal
    0x00800000,  # smallest normal 2**-126
    0x00800001,
    0x00FFFFFF,
    0x01000000,
    0x0C000000,  # 2**-103: products/quotients underflow around here
    0x33800000,  # 2**-24
    0x34000000,  # 2**-23 (ulp of 1)
    0x3F000000,  # 0.5
    0x3F7FFFFF,  # 1 - 2**-24
    0x3F800000,  # 1
    0x3F800001,  # 1 + 2**-23
    0x3FC00000,  # 1.5
    0x3FFFFFFF,
    0x40000000,  # 2
    0x40400000,  # 3
    0x4B000000,  # 2**23
    0x4B7FFFFF,
    0x4F000000,  # 2**31
    0x5F000000,  # 2**63
    0x7E800000,  # 2**126
    0x7F000000,  # 2**127
    0x7F7FFFFE,
    0x7F7FFFFF,  # largest normal
    0x7F800000,  # infinity
    0x7F800001,  # signalling NaN
    0x7FC00000,  # quiet NaN
    0x7FFFFFFF,  # NaN with full payload
]
SPECIALS = np.array(_SPECIAL_MAGNITUDES + [v | 0x80000000 for v in _SPECIAL_MAGNITUDES],
                    dtype=U32)
"""Directed operand values: each magnitude with both signs."""


def cross(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """All ordered pairs of ``values`` (for exhaustive special-value tables)."""
    a, b = np.meshgrid(values, values, indexing="ij")
    return a.ravel().astype(U32), b.ravel().astype(U32)


# ----------------------------------------------------------------------- random pieces


def _bits(rng, n):
    return rng.integers(0, 1 << 32, n, dtype=np.uint64).astype(U32)


def _sign(rng, n):
    return rng.integers(0, 2, n)


def _frac(rng, n):
    return rng.integers(0, 1 << 23, n)


def _sparse_frac(rng, n, max_bits=3):
    """Fractions with at most ``max_bits`` set bits (short significands -> ties)."""
    out = np.zeros(n, dtype=np.int64)
    for _ in range(max_bits):
        keep = rng.random(n) < 0.7
        out |= np.where(keep, np.int64(1) << rng.integers(0, 23, n), 0)
    return out


def _edge_frac(rng, n):
    """Fractions near 0 or near all ones (rounding carries out of the significand)."""
    k = rng.integers(0, 64, n)
    return np.where(rng.random(n) < 0.5, k, (1 << 23) - 1 - k)


def _special(rng, n):
    return SPECIALS[rng.integers(0, len(SPECIALS), n)]


def _mix(rng, n, parts):
    """Concatenate generator outputs with the given weights, then shuffle."""
    weights = np.array([w for w, _ in parts], dtype=float)
    counts = np.floor(weights / weights.sum() * n).astype(int)
    counts[0] += n - counts.sum()
    chunks = [gen(rng, c) for c, (_, gen) in zip(counts, parts, strict=True) if c > 0]
    keys = chunks[0].keys()
    out = {k: np.concatenate([c[k] for c in chunks]) for k in keys}
    perm = rng.permutation(n)
    return {k: v[perm] for k, v in out.items()}


def _clip_exp(e):
    return np.clip(e, 0, 255)


# ----------------------------------------------------------------------- add / sub


def _add_parts(sub_bit):
    def uniform(rng, n):
        return {"a": _bits(rng, n), "b": _bits(rng, n)}

    def exp_diff(rng, n):
        ea = rng.integers(1, 255, n)
        d = rng.integers(-30, 31, n)
        fr = np.where(rng.random(n) < 0.3, _edge_frac(rng, n), _frac(rng, n))
        return {"a": f32(_sign(rng, n), ea, _frac(rng, n)),
                "b": f32(_sign(rng, n), _clip_exp(ea + d), fr)}

    def cancel(rng, n):
        a = f32(_sign(rng, n), rng.integers(1, 255, n), _frac(rng, n))
        delta = rng.integers(-1, 2, n) * (np.int64(1) << rng.integers(0, 24, n))
        delta += rng.integers(-3, 4, n)
        b = (a.astype(np.int64) + delta).astype(U32)
        # opposite effective sign: b gets a's sign flipped for add, same sign for sub
        flip = np.uint32(0 if sub_bit else 0x80000000)
        return {"a": a, "b": (b & U32(0x7FFFFFFF)) | ((a & U32(0x80000000)) ^ flip)}

    def sparse(rng, n):
        ea = rng.integers(1, 255, n)
        d = rng.integers(-26, 27, n)
        return {"a": f32(_sign(rng, n), ea, _sparse_frac(rng, n)),
                "b": f32(_sign(rng, n), _clip_exp(ea + d), _sparse_frac(rng, n))}

    def overflow(rng, n):
        return {"a": f32(_sign(rng, n), rng.integers(250, 255, n), _edge_frac(rng, n)),
                "b": f32(_sign(rng, n), rng.integers(248, 255, n), _frac(rng, n))}

    def underflow(rng, n):
        return {"a": f32(_sign(rng, n), rng.integers(0, 6, n), _frac(rng, n)),
                "b": f32(_sign(rng, n), rng.integers(0, 6, n), _frac(rng, n))}

    def special(rng, n):
        a = np.where(rng.random(n) < 0.5, _special(rng, n), _bits(rng, n))
        return {"a": a.astype(U32), "b": _special(rng, n)}

    parts = [(0.25, uniform), (0.25, exp_diff), (0.15, cancel), (0.15, sparse),
             (0.05, overflow), (0.07, underflow), (0.08, special)]

    def with_sub(gen):
        def g(rng, n):
            d = gen(rng, n)
            d["sub"] = np.full(n, sub_bit, dtype=np.uint8)
            return d
        return g

    return [(w, with_sub(g)) for w, g in parts]


def _swap_ab(gen):
    def g(rng, n):
        d = gen(rng, n)
        flip = rng.random(n) < 0.5
        a = np.where(flip, d["b"], d["a"])
        b = np.where(flip, d["a"], d["b"])
        d = dict(d)
        d["a"], d["b"] = a.astype(U32), b.astype(U32)
        return d
    return g


def _add_model(x):
    a, b = x["a"].astype(U32), x["b"].astype(U32)
    return {"r": np.where(x["sub"] == 1, F.fp32_sub(a, b), F.fp32_add(a, b))}


def _add_directed(sub_bit):
    def gen():
        a, b = cross(SPECIALS)
        return {"a": a, "b": b, "sub": np.full(len(a), sub_bit, dtype=np.uint8)}
    return gen


# ----------------------------------------------------------------------- mul


def _mul_parts():
    def uniform(rng, n):
        return {"a": _bits(rng, n), "b": _bits(rng, n)}

    def boundary(rng, n):
        ea = rng.integers(1, 255, n)
        # target product exponent near 0 (underflow) or near 255 (overflow)
        target = np.where(rng.random(n) < 0.5, rng.integers(-2, 4, n), rng.integers(251, 257, n))
        eb = _clip_exp(target + 127 - ea)
        fa = np.where(rng.random(n) < 0.5, _edge_frac(rng, n), _frac(rng, n))
        fb = np.where(rng.random(n) < 0.5, _edge_frac(rng, n), _frac(rng, n))
        return {"a": f32(_sign(rng, n), ea, fa), "b": f32(_sign(rng, n), np.maximum(eb, 1), fb)}

    def sparse(rng, n):
        return {"a": f32(_sign(rng, n), rng.integers(90, 165, n), _sparse_frac(rng, n, 4)),
                "b": f32(_sign(rng, n), rng.integers(90, 165, n), _sparse_frac(rng, n, 4))}

    def moderate(rng, n):
        return {"a": f32(_sign(rng, n), rng.integers(60, 195, n), _frac(rng, n)),
                "b": f32(_sign(rng, n), rng.integers(60, 195, n), _frac(rng, n))}

    def special(rng, n):
        a = np.where(rng.random(n) < 0.5, _special(rng, n), _bits(rng, n))
        return {"a": a.astype(U32), "b": _special(rng, n)}

    return [(0.25, uniform), (0.3, boundary), (0.15, sparse), (0.2, moderate),
            (0.1, _swap_ab(special))]


# ----------------------------------------------------------------------- div


def _div_parts():
    def uniform(rng, n):
        return {"a": _bits(rng, n), "b": _bits(rng, n)}

    def exact(rng, n):
        # a = b * q with a short q: exact quotients and halfway quotients
        b = f32(_sign(rng, n), rng.integers(80, 175, n), _frac(rng, n))
        q = f32(_sign(rng, n), rng.integers(80, 175, n), _sparse_frac(rng, n, 3))
        a = F.fp32_mul(b, q)
        tweak = rng.integers(-1, 2, n)  # neighbours of the exact product
        return {"a": (a.astype(np.int64) + tweak).astype(U32), "b": b}

    def boundary(rng, n):
        eb = rng.integers(1, 255, n)
        target = np.where(rng.random(n) < 0.5, rng.integers(-2, 3, n), rng.integers(252, 257, n))
        ea = np.clip(target - 127 + eb, 1, 254)
        fa = np.where(rng.random(n) < 0.5, _edge_frac(rng, n), _frac(rng, n))
        fb = np.where(rng.random(n) < 0.5, _edge_frac(rng, n), _frac(rng, n))
        return {"a": f32(_sign(rng, n), ea, fa), "b": f32(_sign(rng, n), eb, fb)}

    def close(rng, n):
        # significands nearly equal: the pre-normalisation decision point
        fa = _frac(rng, n)
        fb = np.clip(fa + rng.integers(-4, 5, n), 0, (1 << 23) - 1)
        return {"a": f32(_sign(rng, n), rng.integers(1, 255, n), fa),
                "b": f32(_sign(rng, n), rng.integers(1, 255, n), fb)}

    def moderate(rng, n):
        return {"a": f32(_sign(rng, n), rng.integers(60, 195, n), _frac(rng, n)),
                "b": f32(_sign(rng, n), rng.integers(60, 195, n), _frac(rng, n))}

    def special(rng, n):
        a = np.where(rng.random(n) < 0.5, _special(rng, n), _bits(rng, n))
        return {"a": a.astype(U32), "b": _special(rng, n)}

    return [(0.2, uniform), (0.2, exact), (0.2, boundary), (0.15, close), (0.15, moderate),
            (0.1, _swap_ab(special))]


# ----------------------------------------------------------------------- sqrt


def _sqrt_parts():
    def uniform(rng, n):
        return {"a": _bits(rng, n)}

    def positive(rng, n):
        return {"a": f32(0, rng.integers(1, 255, n), _frac(rng, n))}

    def squares(rng, n):
        # exact squares of short significands, and their neighbours
        x = f32(0, rng.integers(64, 191, n), _sparse_frac(rng, n, 3) & ~((1 << 11) - 1))
        sq = F.fp32_mul(x, x)
        return {"a": (sq.astype(np.int64) + rng.integers(-1, 2, n)).astype(U32)}

    def edges(rng, n):
        return {"a": f32(_sign(rng, n) & (rng.random(n) < 0.2), rng.integers(1, 255, n),
                         _edge_frac(rng, n))}

    def special(rng, n):
        return {"a": _special(rng, n)}

    return [(0.25, uniform), (0.3, positive), (0.2, squares), (0.15, edges), (0.1, special)]


def _sqrt_model(x):
    return {"r": F.fp32_sqrt(x["a"].astype(U32))}


# ----------------------------------------------------------------------- compare


def _compare_parts():
    def uniform(rng, n):
        return {"a": _bits(rng, n), "b": _bits(rng, n)}

    def equal(rng, n):
        a = _bits(rng, n)
        return {"a": a, "b": a.copy()}

    def neighbours(rng, n):
        a = _bits(rng, n)
        return {"a": a, "b": (a.astype(np.int64) + rng.integers(-2, 3, n)).astype(U32)}

    def negated(rng, n):
        a = _bits(rng, n)
        return {"a": a, "b": a ^ U32(0x80000000)}

    def special(rng, n):
        return {"a": _special(rng, n), "b": _special(rng, n)}

    return [(0.3, uniform), (0.2, equal), (0.2, neighbours), (0.1, negated), (0.2, special)]


def _compare_model(x):
    r = F.fp32_compare(x["a"].astype(U32), x["b"].astype(U32))
    return {"lt": r["lt"], "equal": r["eq"], "gt": r["gt"], "unordered": r["unordered"]}


# ----------------------------------------------------------------------- conversions


def _from_fixed_parts(width):
    lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1

    def uniform(rng, n):
        return {"x": rng.integers(lo, hi, n, endpoint=True, dtype=np.int64)}

    def scaled(rng, n):
        x = rng.integers(lo, hi, n, endpoint=True, dtype=np.int64)
        return {"x": x >> rng.integers(0, width, n)}

    def ties(rng, n):
        # (2**24 + odd/even) * 2**k +- 2**(k-1): exact halfway cases for width > 25
        if width <= 25:
            return uniform(rng, n)
        k = rng.integers(1, width - 25, n)
        base = (np.int64(1) << 24) + rng.integers(0, 1 << 24, n)
        x = (base << k) + rng.integers(-1, 2, n) * (np.int64(1) << (k - 1))
        x = np.minimum(x, hi)
        return {"x": np.where(rng.random(n) < 0.5, -x, x)}

    def edges(rng, n):
        vals = np.array([0, 1, -1, 2, -2, lo, hi, lo + 1, hi - 1], dtype=np.int64)
        return {"x": vals[rng.integers(0, len(vals), n)]}

    return [(0.3, uniform), (0.35, scaled), (0.25, ties), (0.1, edges)]


def _to_fixed_parts(width, frac_bits):
    def uniform(rng, n):
        return {"a": _bits(rng, n)}

    def in_range(rng, n):
        # values * 2**frac_bits in [2**-3, 2**(width + 1)]: rounding and saturation
        e = rng.integers(-3, width + 2, n) - frac_bits + 127
        return {"a": f32(_sign(rng, n), np.clip(e, 1, 254), _frac(rng, n))}

    def ties(rng, n):
        # (k + 1/2) * 2**-frac_bits, exactly representable when k < 2**22
        kmax = min(1 << 22, 1 << max(1, width - 1))
        k = rng.integers(0, kmax, n).astype(np.float64)
        v = (k + 0.5) * np.exp2(-frac_bits)
        bits = np.asarray(F.f32_to_bits(v), dtype=U32)
        return {"a": bits | (_sign(rng, n).astype(U32) << U32(31))}

    def limits(rng, n):
        # around +-2**(width-1) after scaling
        e = width - 1 - frac_bits + 127 + rng.integers(-1, 2, n)
        return {"a": f32(_sign(rng, n), np.clip(e, 1, 254), _edge_frac(rng, n))}

    def special(rng, n):
        return {"a": _special(rng, n)}

    return [(0.2, uniform), (0.35, in_range), (0.2, ties), (0.15, limits), (0.1, special)]


# ----------------------------------------------------------------------- registry


@dataclass
class Fp32Case:
    """How to verify one float32 block."""

    name: str
    make: Callable[[], object]
    model: Callable[[dict[str, np.ndarray]], dict[str, np.ndarray]]
    parts: list
    directed: Callable[[], dict[str, np.ndarray]]
    formatters: dict

    def random(self, n: int, seed: int) -> dict[str, np.ndarray]:
        """``n`` biased random vectors from ``seed``."""
        return _mix(np.random.default_rng(seed), n, self.parts)


_FMT2 = {"a": f32_formatter, "b": f32_formatter, "r": f32_formatter}


def _binary_directed():
    a, b = cross(SPECIALS)
    return {"a": a, "b": b}


def _make_cases(from_width=32, from_frac=16, to_width=32, to_frac=16):
    from .fp32 import (
        Fp32Add,
        Fp32Compare,
        Fp32Div,
        Fp32FromFixed,
        Fp32FromInt,
        Fp32Mul,
        Fp32Sqrt,
        Fp32ToFixed,
        Fp32ToInt,
    )

    def from_fixed(cls, width, fb):
        def model(x):
            return {"r": F.fp32_from_fixed(x["x"], fb, width)}

        def directed():
            lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
            vals = [0, 1, -1, lo, hi, lo + 1, hi - 1]
            vals += [s * (1 << k) + d for k in range(1, width - 1) for d in (-1, 0, 1)
                     for s in (1, -1)]
            vals = [v for v in vals if lo <= v <= hi]
            return {"x": np.array(vals, dtype=np.int64)}
        return model, directed

    def to_fixed(width, fb):
        def model(x):
            v, f = F.fp32_to_fixed(x["a"].astype(U32), fb, width)
            return {"r": v, "overflow": f}

        def directed():
            base = [SPECIALS]
            for e in range(-3, width + 3):
                scale = 127 + e - fb
                if 1 <= scale <= 254:
                    base.append(f32([0, 1, 0, 1, 0, 1], scale,
                                    [0, 0, 1 << 22, 1 << 22, (1 << 23) - 1, (1 << 23) - 1]))
            return {"a": np.concatenate(base).astype(U32)}
        return model, directed

    ff_model, ff_dir = from_fixed(Fp32FromFixed, from_width, from_frac)
    fi_model, fi_dir = from_fixed(Fp32FromInt, 32, 0)
    tf_model, tf_dir = to_fixed(to_width, to_frac)
    ti_model, ti_dir = to_fixed(32, 0)
    return {
        "fp32_add": Fp32Case("fp32_add", Fp32Add, _add_model, _add_parts(0),
                             _add_directed(0), _FMT2),
        "fp32_sub": Fp32Case("fp32_sub", Fp32Add, _add_model, _add_parts(1),
                             _add_directed(1), _FMT2),
        "fp32_mul": Fp32Case("fp32_mul", Fp32Mul,
                             lambda x: {"r": F.fp32_mul(x["a"].astype(U32), x["b"].astype(U32))},
                             _mul_parts(), _binary_directed, _FMT2),
        "fp32_div": Fp32Case("fp32_div", Fp32Div,
                             lambda x: {"r": F.fp32_div(x["a"].astype(U32), x["b"].astype(U32))},
                             _div_parts(), _binary_directed, _FMT2),
        "fp32_sqrt": Fp32Case("fp32_sqrt", Fp32Sqrt, _sqrt_model, _sqrt_parts(),
                              lambda: {"a": SPECIALS.copy()}, _FMT2),
        "fp32_compare": Fp32Case("fp32_compare", Fp32Compare, _compare_model, _compare_parts(),
                                 _binary_directed, _FMT2),
        "fp32_from_int": Fp32Case("fp32_from_int", Fp32FromInt, fi_model,
                                  _from_fixed_parts(32), fi_dir, {"r": f32_formatter}),
        "fp32_from_fixed": Fp32Case("fp32_from_fixed",
                                    lambda: Fp32FromFixed(from_width, from_frac), ff_model,
                                    _from_fixed_parts(from_width), ff_dir, {"r": f32_formatter}),
        "fp32_to_int": Fp32Case("fp32_to_int", Fp32ToInt, ti_model, _to_fixed_parts(32, 0),
                                ti_dir, {"a": f32_formatter}),
        "fp32_to_fixed": Fp32Case("fp32_to_fixed", lambda: Fp32ToFixed(to_width, to_frac),
                                  tf_model, _to_fixed_parts(to_width, to_frac), tf_dir,
                                  {"a": f32_formatter}),
    }


CASES: dict[str, Fp32Case] = _make_cases()


def conversion_cases(from_width, from_frac, to_width, to_frac) -> dict[str, Fp32Case]:
    """Cases for the fixed-point converters with other Q formats."""
    c = _make_cases(from_width, from_frac, to_width, to_frac)
    return {"fp32_from_fixed": c["fp32_from_fixed"], "fp32_to_fixed": c["fp32_to_fixed"]}


_QNAN, _PINF, _NINF = 0x7FC00000, 0x7F800000, 0xFF800000

#: hand-derived divide cases (a, b, expected, why), shared by the pipelined and the
#: iterative divider's tests
DIV_DIRECTED = [
    (0x3F800000, 0x40400000, 0x3EAAAAAB, "1/3 = 0.0101...b -> 0x3EAAAAAB (round up)"),
    (0x40000000, 0x40400000, 0x3F2AAAAB, "2/3"),
    (0x40C00000, 0x40400000, 0x40000000, "6/3 = 2 exactly"),
    (0x41100000, 0x40400000, 0x40400000, "9/3 = 3 exactly (no pre-normalisation)"),
    (0x3F800000, 0x3FC00000, 0x3F2AAAAB, "1/1.5: ma < mb, pre-normalised"),
    (0x3FFFFFFF, 0x3FFFFFFF, 0x3F800000, "x/x = 1 with all-ones significands"),
    (0x3F800000, 0x3F7FFFFF, 0x3F800001, "1/(1-2^-24) = 1+2^-24+2^-48+...: just above the tie"),
    (0x3F800000, 0x3F800001, 0x3F7FFFFE, "1/(1+2^-23) = 1-2^-23+2^-46: just above a tie -> down"),
    (0x3F7FFFFF, 0x3F800001, 0x3F7FFFFD, "(1-2^-24)/(1+2^-23): rounds to 1-3*2^-24"),
    (0x3F800000, 0x7F7FFFFF, 0x00000000, "1/max ~ 2^-128 -> +0"),
    (0x00800000, 0x3F800001, 0x00000000, "2^-126/(1+2^-23) rounds below 2^-126 -> 0"),
    (0x00800000, 0x3F7FFFFF, 0x00800001, "2^-126/(1-2^-24) = 2^-126(1+2^-24+..) -> +1 ulp"),
    (0x00800000, 0x3F800000, 0x00800000, "2^-126/1: smallest normal stays"),
    (0x00800000, 0x40000000, 0x00000000, "2^-126/2 = 2^-127 -> +0 (flushed)"),
    (0x80FFFFFF, 0x40000000, 0x80000000, "-(2^-125 - 2^-149)/2 = -2^-126(1-2^-24) exact -> -0"),
    (0x7F7FFFFF, 0x3F000000, _PINF, "max/0.5 overflows"),
    (0x7F7FFFFF, 0x3F800000, 0x7F7FFFFF, "max/1 = max"),
    (0x7F7FFFFF, 0xBF7FFFFF, _NINF, "max/-(1-2^-24) = -max(1+2^-24..) -> -inf"),
    (0x7F000000, 0x3F000000, _PINF, "2^127/0.5 = 2^128 -> +inf"),
    (0x3F800000, 0x00000000, _PINF, "1/+0"),
    (0x3F800000, 0x80000000, _NINF, "1/-0"),
    (0xBF800000, 0x00000001, _NINF, "-1/subnormal: subnormal reads as +0"),
    (0x00000000, 0x00000000, _QNAN, "0/0"),
    (0x00000001, 0x80000002, _QNAN, "subnormal/subnormal = 0/0"),
    (0x007FFFFF, 0x3F800000, 0x00000000, "subnormal/1 = +0"),
    (_PINF, _NINF, _QNAN, "inf/inf"),
    (_PINF, 0x00000000, _PINF, "inf/0"),
    (_NINF, 0x40000000, _NINF, "-inf/2"),
    (0x00000000, _PINF, 0x00000000, "0/inf"),
    (0x3F800000, _NINF, 0x80000000, "1/-inf = -0"),
    (0x80000000, 0x3F800000, 0x80000000, "-0/1 = -0"),
    (0x7FC00000, 0x00000000, _QNAN, "NaN/0"),
    (0x3F800000, 0xFF800001, _QNAN, "1/-sNaN"),
]

#: hand-derived square-root cases (a, expected, why), shared by the pipelined and the
#: iterative square root's tests
SQRT_DIRECTED = [
    (0x40800000, 0x40000000, "sqrt(4) = 2"),
    (0x40000000, 0x3FB504F3, "sqrt(2) = 1.0110101000001001111001100110011...b -> 0x3FB504F3"),
    (0x3F800000, 0x3F800000, "sqrt(1) = 1"),
    (0x41100000, 0x40400000, "sqrt(9) = 3 (odd exponent path)"),
    (0x3E800000, 0x3F000000, "sqrt(0.25) = 0.5"),
    (0x00800000, 0x20000000, "sqrt(2^-126) = 2^-63"),
    (0x01000000, 0x203504F3, "sqrt(2^-125) = 2^-63 sqrt(2)"),
    (0x7F7FFFFF, 0x5F7FFFFF, "sqrt(max) = 2^64 sqrt(1-2^-24) -> 2^64(1-2^-24)"),
    (0x7F000000, 0x5F3504F3, "sqrt(2^127) = 2^63 sqrt(2)"),
    (0x3F7FFFFF, 0x3F7FFFFF, "sqrt(1-2^-24) = 1-2^-25-..: just below the tie -> 1-2^-24"),
    (0x3F800001, 0x3F800000, "sqrt(1+2^-23) = 1+2^-24-..: just below the tie -> 1"),
    (0x407FFFFF, 0x3FFFFFFF, "sqrt(4-2^-21) = 2-2^-23-..: rounds to 2-2^-23"),
    (0x00000000, 0x00000000, "sqrt(+0) = +0"),
    (0x80000000, 0x80000000, "sqrt(-0) = -0"),
    (0x00000001, 0x00000000, "sqrt(subnormal) = +0"),
    (0x80000001, 0x80000000, "sqrt(-subnormal) = sqrt(-0) = -0"),
    (0xBF800000, _QNAN, "sqrt(-1)"),
    (0x80800000, _QNAN, "sqrt(-2^-126)"),
    (_PINF, _PINF, "sqrt(inf)"),
    (_NINF, _QNAN, "sqrt(-inf)"),
    (0x7F800001, _QNAN, "sqrt(sNaN)"),
    (0xFFC00000, _QNAN, "sqrt(-qNaN)"),
]
