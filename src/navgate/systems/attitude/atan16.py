"""Seed 003's arctangent: float32 -> fix16 -> radian CORDIC -> fix16 -> float32 (bit-true).

Reference: seed 003 section 3.1.8 (反正切函数电路: ``in_a`` = cos, ``in_b`` = sin,
``out_result`` = radians; states 32to16, atan, 16to32) and table 4-6 (the Modelsim column,
which differs from Matlab by the fix16 quantisation).

The seed gives the structure but not the fixed-point formats. They were recovered from
table 4-6 (docs/seed003-attitude.md shows the search): the printed Modelsim angles are
exactly Q2.13 radians converted to float32 and to degrees (30.0047 deg = 4290 / 2^13 rad,
-63.4296 deg = -9069 / 2^13 rad), and the following datapath reproduces both:

1. ``float32 -> fix16``: both inputs to signed Q2.13 (16 bits, range [-4, 4)), round to
   nearest even, saturating (:func:`navgate.numerics.fp32.fp32_to_fixed`).
2. CORDIC vectoring, ``ITERATIONS = 15`` micro-rotations on the Q2.13 pair shifted left by
   ``GUARD = 2`` guard bits (x/y registers of 16 + 2 + 2 bits), angle accumulator in radians
   with ``Z_FRAC = 14`` fraction bits (Q2.14, 17 bits), table ``round(atan(2^-i) 2^14)``;
   decision d = +1 when y >= 0; pre-rotation into the right half-plane by +-pi/2
   (``round(pi/2 2^14)``) when x < 0, exactly as
   :func:`navgate.numerics.cordic.cordic_vectoring` does.
3. The accumulator is truncated toward zero to Q2.13 (drop one bit of the magnitude),
   range [-pi, pi] (|value| <= 25736 < 2^15).
4. ``fix16 -> float32`` (:func:`navgate.numerics.fp32.fp32_from_fixed`), exact.

Among the datapaths that reproduce table 4-6, this one also reproduces 8 of the 15 Modelsim
angles of table 4-7 exactly (all five pitches; the other values differ because the seed's
Modelsim attitude itself drifts away from its Matlab one, see docs/seed003-attitude.md).

Why a seed-specific loop rather than :func:`navgate.numerics.cordic.cordic_vectoring`: that
core accumulates *binary* angles (full circle = 2^angle_bits) and no binary-angle
configuration reproduces table 4-6 (checked for 14..23 angle bits, 10..20 iterations, 0..4
guard bits); the circuit accumulates radians. The loop below is the same datapath with a
radian table; if the numerics core grows a table argument this module should call it.
"""

from __future__ import annotations

import math

import numpy as np

from navgate.numerics.fp32 import fp32_from_fixed, fp32_to_fixed

IN_FRAC = 13  #: fix16 inputs are Q2.13
OUT_FRAC = 13  #: fix16 output is Q2.13 radians
WIDTH = 16
ITERATIONS = 15
GUARD = 2  #: guard bits below the Q2.13 inputs in the x/y registers
Z_FRAC = 14  #: fraction bits of the angle accumulator (radians)

#: round(atan(2^-i) * 2^Z_FRAC)
ATAN_TABLE = np.array([round(math.atan(2.0**-i) * 2.0**Z_FRAC) for i in range(ITERATIONS)],
                      dtype=np.int64)
HALF_PI_Z = round(math.pi / 2 * 2.0**Z_FRAC)


def cordic_atan_radians(x, y, iterations: int = ITERATIONS, z_frac: int = Z_FRAC,
                        out_frac: int = OUT_FRAC, guard: int = GUARD):
    """Vectoring CORDIC on signed fix16 integers -> angle atan2(y, x) as a signed
    fixed-point radian value with ``out_frac`` fraction bits (int64 array / scalar).

    Input (0, 0) gives the meaningless sum of the table (about 1.74 rad); callers gate it.
    """
    scalar = np.ndim(x) == 0 and np.ndim(y) == 0
    X, Y = np.broadcast_arrays(np.asarray(x, dtype=np.int64) << guard,
                               np.asarray(y, dtype=np.int64) << guard)
    table = ATAN_TABLE if (iterations, z_frac) == (ITERATIONS, Z_FRAC) else np.array(
        [round(math.atan(2.0**-i) * 2.0**z_frac) for i in range(iterations)], dtype=np.int64)
    half_pi = round(math.pi / 2 * 2.0**z_frac)
    left = X < 0
    up = Y >= 0
    z = np.where(left, np.where(up, half_pi, -half_pi), 0).astype(np.int64)
    X, Y = (np.where(left, np.where(up, Y, -Y), X), np.where(left, np.where(up, -X, X), Y))
    for i in range(iterations):
        dx = Y >> i
        dy = X >> i
        pos = Y >= 0
        X, Y = np.where(pos, X + dx, X - dx), np.where(pos, Y - dy, Y + dy)
        z = np.where(pos, z + table[i], z - table[i])
    sh = z_frac - out_frac
    if sh > 0:  # truncate toward zero
        out = np.where(z < 0, -((-z) >> sh), z >> sh)
    else:
        out = z << (-sh)
    return out[()] if scalar else out


def atan_fp32(cos_bits, sin_bits):
    """The whole atan circuit on float32 bit patterns: returns ``(radians_bits, angle_fix16,
    saturated)``; ``saturated`` flags an input that did not fit Q2.13 (or was NaN)."""
    xc, fx = fp32_to_fixed(cos_bits, IN_FRAC, WIDTH)
    ys, fy = fp32_to_fixed(sin_bits, IN_FRAC, WIDTH)
    ang = cordic_atan_radians(xc, ys)
    rad = fp32_from_fixed(ang, OUT_FRAC, WIDTH)
    return rad, ang, np.logical_or(fx, fy)
