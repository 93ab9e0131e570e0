"""Bit-true integer CORDIC (vectoring = atan2/magnitude, rotation = cos/sin).

References: J. E. Volder, "The CORDIC trigonometric computing technique", IRE Trans.
Electronic Computers EC-8(3), 1959; R. Andraka, "A survey of CORDIC algorithms for
FPGA based computers", FPGA '98; Y. H. Hu, "The quantization effects of the CORDIC
algorithm", IEEE Trans. Signal Processing 40(4), 1992 (error analysis). Seed 001 uses a
vectoring CORDIC for atan2 with 16-bit angles where 32768 = 180 degrees; seed 003
(section 3.1.8) computes arctangents in a 16-bit fixed-point CORDIC core between
float32 -> fix16 and fix16 -> float32 converters.

Formats
-------
* Angles are binary angles: a full circle is ``2**angle_bits`` units, held as a signed
  ``angle_bits``-bit integer in ``[-2**(angle_bits-1), 2**(angle_bits-1))`` that wraps
  modulo a full circle. ``angle_bits=16``: 16384 = 90 deg, -32768 = 180 deg (seed 001's
  "32768 = 180 degrees"; +180 deg wraps to -32768).
* Vectoring inputs ``x, y`` are signed ``width``-bit integers (any common scale).
  They are shifted left by ``guard_bits`` into registers of ``width + guard_bits + 2``
  bits (2 bits of growth: sqrt(2) for the corner of the square, K < 1.65 for the gain).
* Rotation outputs are ``QFormat(width, width - 2)``: 1.0 = ``2**(width-2)``.

Datapath (what the gateware does, step for step)
------------------------------------------------
Vectoring, ``cordic_vectoring``: pre-rotation into the right half-plane by +-90 deg
(exact: a swap and a negation): if x < 0 and y >= 0, (x, y) <- (y, -x), z = +90 deg;
if x < 0 and y < 0, (x, y) <- (-y, x), z = -90 deg; else z = 0. Then for
i = 0 .. n-1, with ``d = +1`` when the y register is >= 0 (its sign bit is 0) else -1::

    x' = x + d * (y >>> i);  y' = y - d * (x >>> i);  z' = z + d * T[i]

``>>>`` is the arithmetic shift (floor). The angle is z wrapped to ``angle_bits``; the
magnitude is ``x_n >>> guard_bits`` = K_n * |(x, y)| (gain not removed) or, with
``compensate=True``, ``(x_n * round(2**c / K_n)) >>> (c + guard_bits)`` with
``c = gain_frac_bits`` (default ``width + 2``). Input (0, 0) gives magnitude 0 and the
meaningless angle sum(T) (about +99.9 deg): the caller must gate it.

Rotation, ``cordic_rotation``: z = angle; if z > +90 deg, z -= 180 deg, and if
z < -90 deg, z += 180 deg, remembering to negate the outputs. x = round(2**(F+g) / K_n)
(F = width - 2, g = guard_bits, the gain compensation is folded into the start
vector), y = 0. For i = 0 .. n-1 with ``d = +1`` when z >= 0 else -1::

    x' = x - d * (y >>> i);  y' = y + d * (x >>> i);  z' = z - d * T[i]

then the optional negation, and cos = x >>> g, sin = y >>> g.

The table ``T[i] = round(atan(2**-i) * 2**angle_bits / (2*pi))`` (nearest integer;
the exact values are irrational so there are no ties). ``cordic_gain(n)`` =
prod_{i<n} sqrt(1 + 4**-i) (-> 1.6467602581...).

Error bounds
------------
Derived in :func:`cordic_error_bound` (vectoring, radians) and
:func:`cordic_rotation_error_bound` (rotation, output LSBs); docs/numerics.md repeats
the derivations. Both are worst-case (rigorous) bounds, not statistics.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "atan_table",
    "cordic_gain",
    "cordic_vectoring",
    "cordic_rotation",
    "cordic_error_bound",
    "cordic_rotation_error_bound",
    "angle_to_radians",
    "radians_to_angle",
]


def _check(width: int, iterations: int, angle_bits: int, guard_bits: int) -> None:
    if not 2 <= width <= 40:
        raise ValueError(f"width must be in [2, 40], got {width}")
    if not 1 <= iterations <= 40:
        raise ValueError(f"iterations must be in [1, 40], got {iterations}")
    if not 4 <= angle_bits <= 48:
        raise ValueError(f"angle_bits must be in [4, 48], got {angle_bits}")
    if not 0 <= guard_bits <= 16:
        raise ValueError(f"guard_bits must be in [0, 16], got {guard_bits}")


def atan_table(iterations: int, angle_bits: int = 16) -> np.ndarray:
    """``T[i] = round(atan(2**-i) * 2**angle_bits / (2*pi))``, i < iterations (int64)."""
    return np.array(
        [round(math.atan(2.0**-i) * 2.0**angle_bits / (2 * math.pi)) for i in range(iterations)],
        dtype=np.int64,
    )


def cordic_gain(iterations: int) -> float:
    """CORDIC gain K_n = prod_{i<n} sqrt(1 + 4**-i)."""
    return math.prod(math.sqrt(1.0 + 4.0**-i) for i in range(iterations))


def angle_to_radians(angle, angle_bits: int = 16):
    """Binary angle (full circle = 2**angle_bits) -> radians (float64)."""
    return np.asarray(angle, dtype=np.float64) * (2 * math.pi / 2.0**angle_bits)


def radians_to_angle(rad, angle_bits: int = 16):
    """Radians -> nearest binary angle, wrapped to the signed ``angle_bits`` range."""
    a = np.rint(np.asarray(rad, dtype=np.float64) * (2.0**angle_bits / (2 * math.pi)))
    return _wrap(a.astype(np.int64), angle_bits)


def _wrap(z, bits: int):
    m = (1 << bits) - 1
    low = z & m
    return np.where(low >= (1 << (bits - 1)), low - (1 << bits), low)


def _int_in(v, width: int, name: str) -> np.ndarray:
    arr = np.asarray(v)
    if arr.dtype.kind not in "iu":
        raise TypeError(f"{name}: integer inputs expected, got dtype {arr.dtype}")
    arr = arr.astype(np.int64)
    lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
    if arr.size and (arr.min() < lo or arr.max() > hi):
        raise ValueError(f"{name} out of range for a signed {width}-bit integer")
    return arr


def cordic_vectoring(x, y, width: int, iterations: int, angle_bits: int = 16,
                     guard_bits: int = 0, compensate: bool = False,
                     gain_frac_bits: int | None = None):
    """atan2(y, x) and magnitude by vectoring CORDIC -> ``(magnitude, angle)``.

    ``angle`` is a signed ``angle_bits``-bit binary angle (full circle 2**angle_bits).
    ``magnitude`` (>= 0) is ``K_n * |(x, y)|`` floored to input units
    (``compensate=False``; < K sqrt(2) 2**(width-1) < 2**(width+1): unsigned ``width + 1``
    bits) or the gain-compensated ``|(x, y)|`` (``compensate=True``; < 2**width: unsigned
    ``width`` bits). Both int64 arrays (scalars for scalar inputs).
    """
    _check(width, iterations, angle_bits, guard_bits)
    scalar = np.ndim(x) == 0 and np.ndim(y) == 0
    X = _int_in(x, width, "x") << guard_bits
    Y = _int_in(y, width, "y") << guard_bits
    X, Y = np.broadcast_arrays(X, Y)
    quarter = 1 << (angle_bits - 2)
    left = X < 0
    up = Y >= 0
    z = np.where(left, np.where(up, quarter, -quarter), 0).astype(np.int64)
    X, Y = (np.where(left, np.where(up, Y, -Y), X), np.where(left, np.where(up, -X, X), Y))
    table = atan_table(iterations, angle_bits)
    for i in range(iterations):
        dx = Y >> i
        dy = X >> i
        pos = Y >= 0
        X, Y = np.where(pos, X + dx, X - dx), np.where(pos, Y - dy, Y + dy)
        z = np.where(pos, z + table[i], z - table[i])
    angle = _wrap(z, angle_bits)
    if compensate:
        c = width + 2 if gain_frac_bits is None else int(gain_frac_bits)
        kinv = round(2.0**c / cordic_gain(iterations))
        mag = (X * kinv) >> (c + guard_bits)
    else:
        mag = X >> guard_bits
    if scalar:
        return mag[()], angle[()]
    return mag, angle


def cordic_rotation(angle, width: int, iterations: int, angle_bits: int = 16,
                    guard_bits: int = 0):
    """cos and sin of a binary angle by rotation CORDIC -> ``(cos, sin)`` in
    ``QFormat(width, width - 2)`` (1.0 = 2**(width-2)); int64 arrays.

    The gain is compensated by starting from x0 = round(2**(width-2+guard_bits) / K_n).
    """
    _check(width, iterations, angle_bits, guard_bits)
    if width < 4:
        raise ValueError("rotation needs width >= 4")
    scalar = np.ndim(angle) == 0
    z = _int_in(angle, angle_bits, "angle")
    quarter = 1 << (angle_bits - 2)
    half = 1 << (angle_bits - 1)
    flip = (z > quarter) | (z < -quarter)
    z = np.where(z > quarter, z - half, np.where(z < -quarter, z + half, z))
    frac = width - 2 + guard_bits
    x0 = round(2.0**frac / cordic_gain(iterations))
    X = np.full(z.shape, x0, dtype=np.int64)
    Y = np.zeros(z.shape, dtype=np.int64)
    table = atan_table(iterations, angle_bits)
    for i in range(iterations):
        dx = Y >> i
        dy = X >> i
        pos = z >= 0
        X, Y = np.where(pos, X - dx, X + dx), np.where(pos, Y + dy, Y - dy)
        z = np.where(pos, z - table[i], z + table[i])
    X = np.where(flip, -X, X)
    Y = np.where(flip, -Y, Y)
    c, s = X >> guard_bits, Y >> guard_bits
    if scalar:
        return c[()], s[()]
    return c, s


def _table_error(iterations: int, angle_bits: int) -> float:
    """sum_i |T[i] - atan(2^-i)| in radians (each term <= 0.5 LSB)."""
    lsb = 2 * math.pi / 2.0**angle_bits
    t = atan_table(iterations, angle_bits)
    return float(sum(abs(int(t[i]) * lsb - math.atan(2.0**-i)) for i in range(iterations)))


def cordic_error_bound(width: int, iterations: int, angle_bits: int = 16,
                       guard_bits: int = 0, min_magnitude: float | None = None) -> float:
    """Worst-case |angle - atan2(y, x)| in radians of :func:`cordic_vectoring` for every
    input with sqrt(x^2 + y^2) >= ``min_magnitude`` (input units; default 2**(width-2),
    a quarter of full scale: the truncation term grows as 1/magnitude).

    Derivation. Write alpha_i = atan(2^-i), T_i its table value, n = iterations, and let
    psi_i be the angle of the exact (untruncated) pseudo-rotation of the pre-rotated input
    by the decisions taken so far, so the output error is
    ``psi_n + sum_i d_i (alpha_i - T_i)``.

    1. Table: |sum_i d_i (alpha_i - T_i)| <= sum_i |alpha_i - T_i| <= n/2 LSB (the exact
       sum of the table's rounding errors is used).
    2. Truncation: step i >= 1 floors two shifted terms, so the computed vector differs
       from the exact micro-rotation of the previous computed vector by |delta_i| < sqrt(2)
       (internal LSBs); step 0 shifts by 0 and is exact. That turns the vector's angle by
       eta_i <= asin(sqrt(2) / (r_i sqrt(1 + 4^-i))) with r_i a lower bound on the
       magnitude: r_0 = min_magnitude * 2**guard_bits, r_{i+1} = r_i sqrt(1 + 4^-i) -
       sqrt(2) (a micro-rotation never shrinks a vector). E = sum_{i=1}^{n-1} eta_i.
    3. Convergence: the decision is the sign of the computed angle phi_i = psi_i + E_i
       with |E_i| <= E. With S_i = sum_{j>=i} alpha_j + alpha_{n-1} (and alpha_i <=
       S_{i+1}, |psi_0| <= 90 deg <= S_0), induction gives |psi_i| <= S_i + E: a correct
       decision gives |psi_{i+1}| <= max(|psi_i| - alpha_i, alpha_i), a wrong one needs
       |psi_i| <= E and gives |psi_{i+1}| <= E + alpha_i. Hence |psi_n| <= alpha_{n-1} + E.

    Bound = atan(2^-(n-1)) + sum_i |alpha_i - T_i| + E.
    """
    _check(width, iterations, angle_bits, guard_bits)
    if min_magnitude is None:
        min_magnitude = 2.0 ** (width - 2)
    r = float(min_magnitude) * 2.0**guard_bits
    e_trunc = 0.0
    for i in range(iterations):
        rotated = r * math.sqrt(1.0 + 4.0**-i)  # |exact micro-rotation of v_i| >= this
        if i > 0:
            if rotated <= 2.0 * math.sqrt(2.0):
                return math.pi  # magnitude too small for a useful bound
            e_trunc += math.asin(math.sqrt(2.0) / rotated)
            rotated -= math.sqrt(2.0)
        r = rotated
    residual = math.atan(2.0 ** -(iterations - 1))
    return residual + _table_error(iterations, angle_bits) + e_trunc


def cordic_rotation_error_bound(width: int, iterations: int, angle_bits: int = 16,
                                guard_bits: int = 0) -> float:
    """Worst-case |cos_out - 2**F cos(a)| (and the same for sin) of
    :func:`cordic_rotation`, in output LSBs (F = width - 2, a = angle in radians).

    Derivation. The z path is exact integer arithmetic on the table, so the rotation
    actually applied is ``a - z_n + sum_i d_i (alpha_i - T_i)``.
    1. Residual: with S_i = sum_{j>=i} T_j + T_{n-1} and the slack
       c = max(0, 90deg - S_0, max_i (T_i - S_{i+1})), induction as in
       :func:`cordic_error_bound` gives |z_n| <= T_{n-1} + c (binary-angle units).
    2. Table: sum_i |alpha_i - T_i| radians. Angle error dphi = (1) + (2); it moves each
       component by at most A * dphi where A = x0 * K_n / 2**g (output LSBs).
    3. Gain: |A - 2**F| = |x0 K_n - 2**(F+g)| / 2**g <= 0.5 K_n / 2**g.
    4. Truncation: step i >= 1 adds |delta_i| < sqrt(2) internal LSBs, then amplified by
       the later micro-rotations: sum_{i=1}^{n-1} sqrt(2) prod_{j>i} sqrt(1 + 4^-j),
       divided by 2**g.
    5. The final floor by g bits (and the exact negation): < 1 output LSB.
    """
    _check(width, iterations, angle_bits, guard_bits)
    F = width - 2
    g = guard_bits
    t = [int(v) for v in atan_table(iterations, angle_bits)]
    lsb = 2 * math.pi / 2.0**angle_bits
    S = [0] * (iterations + 1)
    for i in range(iterations - 1, -1, -1):
        S[i] = S[i + 1] + t[i]
    S = [s + t[-1] for s in S]  # S_i = sum_{j>=i} T_j + T_{n-1}
    quarter = 1 << (angle_bits - 2)
    slack = max([0, quarter - S[0]] + [t[i] - S[i + 1] for i in range(iterations)])
    dphi = (t[-1] + slack) * lsb + _table_error(iterations, angle_bits)
    K = cordic_gain(iterations)
    x0 = round(2.0 ** (F + g) / K)
    amp = x0 * K / 2.0**g
    gain_err = abs(x0 * K - 2.0 ** (F + g)) / 2.0**g
    trunc = 0.0
    for i in range(1, iterations):
        trunc += math.sqrt(2.0) * math.prod(
            math.sqrt(1.0 + 4.0**-j) for j in range(i + 1, iterations))
    return amp * dphi + gain_err + trunc / 2.0**g + 1.0
