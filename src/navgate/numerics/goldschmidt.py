"""Bit-true Goldschmidt reciprocal and division in fixed point.

References: R. E. Goldschmidt, "Applications of division by convergence", MSc thesis,
MIT, 1964; S. F. Oberman and M. J. Flynn, "Division algorithms and implementations",
IEEE Trans. Computers 46(8), 1997 (seed tables, quadratic convergence); M. D. Ercegovac
and T. Lang, "Digital Arithmetic", Morgan Kaufmann 2004, ch. 7. Seed 004 uses a
Goldschmidt divider ("goldschmidt_struct.v", "only multipliers and subtractors") for the
1/det of its 2x2 inverse in Q(N=20, FRAC=10); :func:`goldschmidt_reciprocal` and
:func:`goldschmidt_divide` are that operation on signed ``QFormat(width, frac)`` values.

Datapath (the gateware does exactly this; F = ``internal_frac``, default ``width``)
----------------------------------------------------------------------------------
1. Sign and magnitude: a = |d| (``width`` bits unsigned; |min_int| = 2**(width-1)).
   d = 0 -> saturated result and ``divide_by_zero``.
2. Normalise by the leading-one position p of a: ``D = a << (F - 1 - p)``, an unsigned
   integer with F fraction bits in [0.5, 1) (exact because F >= width). The divide also
   normalises the numerator the same way to [0.5, 1]; the reciprocal uses 1.0 = 2**F.
3. Seed x0 (F fraction bits):
   * ``seed="table"``: a ROM of 2**seed_bits words indexed by the ``seed_bits`` bits
     after D's leading one. Entry i covers D in [lo, hi) = [1/2 + i h, 1/2 + (i+1) h),
     h = 2**-(seed_bits+1), and holds round(2**F * 2 / (lo + hi)), the reciprocal of the
     midpoint, which equalises the relative error 1 - D x0 at both ends:
     |e0| <= h / (2 lo + h) <= 2**-(seed_bits+1) (exact maximum: :func:`seed_error`).
     ``goldschmidt_seed_table`` gives the ROM contents.
   * ``seed="linear"``: x0 = C1 - ((C2 * D) >> F), C1 = round(48/17 * 2**F),
     C2 = round(32/17 * 2**F) (minimax linear seed on [0.5, 1), |e0| <= 1/17).
4. N0 = (num * x0) >> F, D0 = (D * x0) >> F; then ``iterations`` times:
   ``G = 2*2**F - D`` (a subtraction, exact), ``N = (N * G) >> F``, ``D = (D * G) >> F``.
   Every ``>>`` is a floor (truncating multiplier). Registers: N, D, G < 2**(F+2)
   unsigned; products < 2**(2F+4).
5. Denormalise: shift N by the exponent difference; on a right shift by s > 0 the
   magnitude is rounded: ``rounding="nearest"`` (default) adds 2**(s-1) first (round half
   up), ``"truncate"`` floors. Then apply the sign (negating the rounded magnitude, so
   rounding is symmetric about zero) and saturate to ``width`` bits with ``overflow``.
   Truncated products leave N just below 2**F num/D, so "truncate" would give
   1/1.0 = 1 - 1 LSB; "nearest" returns 1.0 exactly.

Error: after k iterations the relative error of N is e0**(2**k) (exact arithmetic) plus
the truncation terms derived in :func:`goldschmidt_error_bound`.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "goldschmidt_seed_table",
    "goldschmidt_normalised",
    "goldschmidt_reciprocal",
    "goldschmidt_divide",
    "goldschmidt_error_bound",
    "seed_error",
]


def _check(width: int, frac: int, internal_frac: int | None) -> int:
    if not 2 <= width <= 30:
        raise ValueError(f"width must be in [2, 30], got {width}")
    if not 0 <= frac <= width:
        raise ValueError(f"frac must be in [0, width], got {frac}")
    F = width if internal_frac is None else int(internal_frac)
    if F < width:
        raise ValueError("internal_frac must be >= width (exact normalisation)")
    if 2 * F + 4 > 62 or F + 2 * width + 1 > 62:
        raise ValueError("internal_frac too large for the int64 model (2F+4 <= 62)")
    return F


def _seed_params(seed: str, seed_bits: int, F: int) -> None:
    if seed not in ("table", "linear"):
        raise ValueError(f"seed must be 'table' or 'linear', got {seed!r}")
    if seed == "table" and not 0 <= seed_bits <= min(16, F - 1):
        raise ValueError(f"seed_bits must be in [0, min(16, F-1)], got {seed_bits}")


def goldschmidt_seed_table(seed_bits: int, internal_frac: int) -> np.ndarray:
    """ROM contents: entry i = round(2**F * 2 / (lo_i + hi_i)) (int64, F frac bits)."""
    F = int(internal_frac)
    n = 1 << seed_bits
    # 2 / (lo + hi) with lo + hi = 1 + (2 i + 1) / 2**(seed_bits+1)
    out = []
    for i in range(n):
        den = (1 << (seed_bits + 1)) + 2 * i + 1  # (lo + hi) * 2**(seed_bits+1)
        num = 2 << (seed_bits + 1 + F)
        q, r = divmod(num, den)
        out.append(q + (1 if 2 * r >= den else 0))
    return np.array(out, dtype=np.int64)


def _linear_consts(F: int) -> tuple[int, int]:
    return round(48 / 17 * 2**F), round(32 / 17 * 2**F)


def seed_error(seed_bits: int, internal_frac: int, seed: str = "table") -> float:
    """Exact max over D in [0.5, 1) of |1 - D * x0(D)| for the quantised seed (the
    linear seed's ``(C2 * D) >> F`` truncation adds up to 2**-F, included)."""
    F = int(internal_frac)
    if seed == "table":
        tab = goldschmidt_seed_table(seed_bits, F)
        h = 2.0 ** -(seed_bits + 1)
        worst = 0.0
        for i, x in enumerate(tab):
            x0 = float(x) / 2.0**F
            lo = 0.5 + i * h
            worst = max(worst, abs(1 - lo * x0), abs(1 - (lo + h) * x0))
        return worst
    c1, c2 = _linear_consts(F)
    a, b = c1 / 2.0**F, c2 / 2.0**F
    pts = [0.5, 1.0, a / (2 * b)]
    vals = [abs(1 - D * (a - b * D)) for D in pts if 0.5 <= D <= 1.0]
    return max(vals) + 2.0**-F


def _seed(D: np.ndarray, F: int, seed: str, seed_bits: int) -> np.ndarray:
    if seed == "table":
        tab = goldschmidt_seed_table(seed_bits, F)
        idx = (D >> (F - 1 - seed_bits)) - (1 << seed_bits)
        if D.dtype == object:
            return np.array([int(tab[int(i)]) for i in np.ravel(idx)],
                            dtype=object).reshape(np.shape(D))
        return tab[idx]
    c1, c2 = _linear_consts(F)
    return c1 - ((c2 * D) >> F)


def goldschmidt_normalised(num, D, internal_frac: int, iterations: int, seed_bits: int = 4,
                           seed: str = "table") -> np.ndarray:
    """The core iteration on normalised operands (step 3-4 of the module docstring):
    ``num`` in [2**(F-1), 2**F] and ``D`` in [2**(F-1), 2**F) (F fraction bits);
    returns N ~ 2**F * num / D (floor-truncated products).

    The products need 2F + 4 bits: up to F = 29 they run in int64 (the result is int64); for
    wider F in Python integers (object arrays, the same floor arithmetic, exact at any F)."""
    F = int(internal_frac)
    _seed_params(seed, seed_bits, F)
    if iterations < 0:
        raise ValueError("iterations must be >= 0")
    dtype = np.int64 if 2 * F + 4 <= 62 else object
    num = np.asarray(num).astype(dtype)
    D = np.asarray(D).astype(dtype)
    if D.size and (D.min() < (1 << (F - 1)) or D.max() >= (1 << F)):
        raise ValueError("D must be normalised to [2**(F-1), 2**F)")
    if num.size and (num.min() < (1 << (F - 1)) or num.max() > (1 << F)):
        raise ValueError("num must be normalised to [2**(F-1), 2**F]")
    x0 = _seed(D, F, seed, seed_bits)
    N = (num * x0) >> F
    Dk = (D * x0) >> F
    two = 2 << F
    for _ in range(iterations):
        G = two - Dk
        N = (N * G) >> F
        Dk = (Dk * G) >> F
    return N


def _lead(a: np.ndarray) -> np.ndarray:
    """Position of the leading one of positive int64 values (< 2**53: frexp is exact)."""
    _, e = np.frexp(a.astype(np.float64))
    return e.astype(np.int64) - 1


def _check_rounding(rounding: str) -> None:
    if rounding not in ("nearest", "truncate"):
        raise ValueError(f"rounding must be 'nearest' or 'truncate', got {rounding!r}")


def _validate(v, width: int, name: str) -> np.ndarray:
    arr = np.asarray(v)
    if arr.dtype.kind not in "iu":
        raise TypeError(f"{name}: raw fixed-point integers expected, got dtype {arr.dtype}")
    arr = arr.astype(np.int64)
    if arr.size and (arr.min() < -(1 << (width - 1)) or arr.max() > (1 << (width - 1)) - 1):
        raise ValueError(f"{name} out of range for a signed {width}-bit integer")
    return arr


def _finish(mag: np.ndarray, shift: np.ndarray, neg: np.ndarray, width: int, rounding: str):
    """mag * 2**shift rounded (half up) or floored, signed, saturated -> (value, overflow)."""
    left = np.clip(shift, 0, 62).astype(np.int64)
    right = np.clip(-shift, 0, 62).astype(np.int64)
    # overflow test before a left shift so that int64 cannot wrap
    bl = np.where(mag > 0, _lead(np.maximum(mag, 1)) + 1, 0)
    # only a left shift can overflow; a right shift of a wide normalised value cannot
    too_big = (left > 0) & (bl + left > width + 1)
    q = np.where(too_big, 0, mag << np.where(too_big, 0, left))
    if rounding == "nearest":  # add half an output LSB before a right shift
        q = q + np.where(right > 0, np.left_shift(1, np.maximum(right - 1, 0)), 0)
    q = q >> right
    limit_pos = (1 << (width - 1)) - 1
    limit_neg = 1 << (width - 1)
    over = too_big | np.where(neg, q > limit_neg, q > limit_pos)
    q = np.where(over, np.where(neg, limit_neg, limit_pos), q)
    return np.where(neg, -q, q).astype(np.int64), over


def goldschmidt_reciprocal(d, width: int, frac: int, iterations: int = 3, seed_bits: int = 4,
                           internal_frac: int | None = None, seed: str = "table",
                           rounding: str = "nearest"):
    """1/d for signed ``QFormat(width, frac)`` raw integers d -> ``(value, flags)``.

    ``value`` is int64 raw Q(width, frac); ``flags`` is a dict of bool arrays:
    ``divide_by_zero`` (d == 0: value max_int) and ``overflow`` (|1/d| does not fit:
    value saturated to max_int / min_int by sign).
    """
    F = _check(width, frac, internal_frac)
    _seed_params(seed, seed_bits, F)
    _check_rounding(rounding)
    scalar = np.ndim(d) == 0
    dv = _validate(d, width, "d")
    zero = dv == 0
    neg = dv < 0
    a = np.where(zero, 1, np.abs(dv))
    p = _lead(a)
    D = a << (F - 1 - p)
    N = goldschmidt_normalised(np.full(D.shape, 1 << F, dtype=np.int64), D, F, iterations,
                               seed_bits, seed)
    # 1/d = (1/D) 2**(2 frac - p - 1) raw units, N = 2**F / D
    val, over = _finish(N, 2 * frac - p - 1 - F, neg, width, rounding)
    val = np.where(zero, (1 << (width - 1)) - 1, val)
    over = over & ~zero
    flags = {"divide_by_zero": zero, "overflow": over}
    if scalar:
        return val[()], {k: bool(v) for k, v in flags.items()}
    return val, flags


def goldschmidt_divide(n, d, width: int, frac: int, iterations: int = 3, seed_bits: int = 4,
                       internal_frac: int | None = None, seed: str = "table",
                       rounding: str = "nearest"):
    """n/d for signed ``QFormat(width, frac)`` raw integers -> ``(value, flags)``.

    Both operands are normalised to [0.5, 1) and the quotient is formed directly (not
    n * (1/d)). d == 0: ``divide_by_zero``, value saturated by the sign of n (0 for
    0/0). ``overflow``: the quotient does not fit, value saturated. The magnitude is
    rounded as ``rounding`` says (module docstring, step 5), then the sign applied.
    Error: |value - n/d| <= |n/d| * goldschmidt_error_bound(...) + 1/2 LSB (nearest)
    or + 1 LSB (truncate), where no flag is set.
    """
    F = _check(width, frac, internal_frac)
    _seed_params(seed, seed_bits, F)
    _check_rounding(rounding)
    scalar = np.ndim(n) == 0 and np.ndim(d) == 0
    nv = _validate(n, width, "n")
    dv = _validate(d, width, "d")
    nv, dv = np.broadcast_arrays(nv, dv)
    dzero = dv == 0
    nzero = nv == 0
    neg = (nv < 0) ^ (dv < 0)
    a = np.where(dzero, 1, np.abs(dv))
    b = np.where(nzero, 1, np.abs(nv))
    pd = _lead(a)
    pn = _lead(b)
    D = a << (F - 1 - pd)
    Nn = b << (F - 1 - pn)
    N = goldschmidt_normalised(Nn, D, F, iterations, seed_bits, seed)
    # n/d = (Nn/D) 2**(pn - pd) -> raw: (Nn/D) 2**(pn - pd + frac), N = 2**F Nn / D
    val, over = _finish(N, pn - pd + frac - F, neg, width, rounding)
    val = np.where(nzero, 0, val)
    over = over & ~nzero & ~dzero
    sat = np.where(nv < 0, -(1 << (width - 1)), (1 << (width - 1)) - 1)
    val = np.where(dzero, np.where(nzero, 0, sat), val).astype(np.int64)
    flags = {"divide_by_zero": dzero, "overflow": over}
    if scalar:
        return val[()], {k: bool(v) for k, v in flags.items()}
    return val, flags


def goldschmidt_error_bound(iterations: int, seed_bits: int, internal_frac: int,
                            seed: str = "table") -> float:
    """Worst-case relative error |N / (2**F num / D) - 1| of :func:`goldschmidt_normalised`.

    Derivation (u = 2**-F, every truncation t in [0, u)):

    * D path: D_0 = D x0 - t, so e_0 = 1 - D_0 satisfies |e_0| <= eps_0 = e0max + u with
      e0max = :func:`seed_error`. D_{k+1} = D_k (2 - D_k) - t = 1 - e_k**2 - t, hence
      0 <= e_{k+1} <= eps_{k+1} = eps_k**2 + u: the quadratic convergence, plus one
      truncation per step.
    * Ratio q = N/D: exact arithmetic keeps q_k = num/D (both are multiplied by the same
      factor). A step with truncations t_N, t_D multiplies q by
      (1 - t_N/P_N) / (1 - t_D/P_D), P_N, P_D the exact products. P_D = D_{k+1} + t >=
      1 - eps_{k+1}, and P_N = q P_D >= (1/2)(1 - rho)(1 - eps_{k+1}) since num/D >= 1/2
      (rho the drift so far). Each factor lies in [1 - u/P_N, 1/(1 - u/P_D)], so
      |log(q_k D / num)| <= sum over the k+1 multiply steps of -log(1 - u/P_N) -
      log(1 - u/P_D) =: L, rho = exp(L) - 1.
    * N_k = q_k D_k = (num/D)(1 + r)(1 - e_k) with |r| <= rho, so the relative error is
      at most eps_k + rho (1 + eps_k).

    For large errors this is eps_k ~ e0max**(2**k); at the end it is ~ (2k + 3) u.
    """
    F = int(internal_frac)
    _seed_params(seed, seed_bits, F)
    u = 2.0**-F
    eps = seed_error(seed_bits, F, seed) + u
    # seed multiply step: P_D = D x0 >= 1 - e0max, P_N = num x0 >= 1/2 (1 - e0max)
    e0 = seed_error(seed_bits, F, seed)
    L = -math.log(1 - u / (0.5 * (1 - e0))) - math.log(1 - u / (1 - e0))
    for _ in range(iterations):
        eps_next = eps * eps + u
        rho = math.expm1(L)
        pd = 1 - eps_next
        pn = 0.5 * (1 - rho) * (1 - eps_next)
        L += -math.log(1 - u / pn) - math.log(1 - u / pd)
        eps = eps_next
    rho = math.expm1(L)
    return eps + rho * (1 + eps)
