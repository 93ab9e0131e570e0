"""Seed 003's attitude-solving circuit, float32 bit-true model (what the gateware must match).

Reference: seed 003 sections 3.1.2-3.1.8 and 4.2.4; the float64 twin is
:mod:`navgate.systems.attitude.mahony` (same equations, same parameters). Arithmetic is
:mod:`navgate.numerics.fp32` (IEEE binary32, round to nearest even, flush-to-zero on
input and output, canonical NaN): every value is a ``uint32`` bit pattern and every
arrow below is one rounded operation of one float32 core, in this order. The seed gives
the module boundaries and state sequence but not the operation order inside a state; the
order chosen here is the textbook one (left-to-right sums, products first) and is the
specification the gateware follows (docs/seed003-attitude.md).

INS_acc
    ACC_NOR: ``s = (ax*ax + ay*ay) + az*az; n = sqrt(s); a_i = acc_i / n`` (three divides)
    ACC_CAL: ``exa = ay*c33 - az*c23; eya = az*c13 - ax*c33; eza = ax*c23 - ay*c13``
INS_mag
    MAG_NOR: the y component's sign is flipped (``mag_sign``, exact), then as ACC_NOR.
    MAG_FLU: ``hx = (c11*mx + c21*my) + c31*mz``, ``hy = (c12*mx + c22*my) + c32*mz``,
    ``hz = (c13*mx + c23*my) + c33*mz``; ``bx = sqrt(hx*hx + hy*hy)``, ``bz = hz``;
    ``wx = c11*bx + c13*bz``, ``wy = c21*bx + c23*bz``, ``wz = c31*bx + c33*bz``
    MAG_CAL: ``exm = my*wz - mz*wy; eym = mz*wx - mx*wz; ezm = mx*wy - my*wx``
INS_gyro
    GYRO_KPI: ``e = exa + exm``; ``exi = exi + (e*Ki)*T``
    GYRO_RSV: ``w = (gyro*D2R + Kp*e) + exi`` with ``D2R = float32(pi/180)``
INS_quat (``hT = T*0.5``, exact)
    QUAT_DIF: ``d0 = -((q1*wx + q2*wy) + q3*wz)``, ``d1 = (q0*wx + q2*wz) - q3*wy``,
    ``d2 = (q0*wy - q1*wz) + q3*wx``, ``d3 = (q0*wz + q1*wy) - q2*wx``
    QUAT_LK: ``q_i = q_i + d_i*hT``
    QUAT_NOR: ``n = sqrt(((q0*q0 + q1*q1) + q2*q2) + q3*q3); q_i = q_i / n``
INS_matx (``x + x`` is the exact doubling)
    ``c11 = 1 - 2(q2*q2 + q3*q3)``, ``c12 = 2(q1*q2 + q0*q3)``, ``c13 = 2(q1*q3 - q0*q2)``,
    ``c21 = 2(q1*q2 - q0*q3)``, ``c22 = 1 - 2(q1*q1 + q3*q3)``, ``c23 = 2(q2*q3 + q0*q1)``,
    ``c31 = 2(q1*q3 + q0*q2)``, ``c32 = 2(q2*q3 - q0*q1)``, ``c33 = 1 - 2(q1*q1 + q2*q2)``
INS_euler (atan = :func:`navgate.systems.attitude.atan16.atan_fp32`)
    EULER_P: ``pitch = atan(cos = sqrt(1 - c13*c13), sin = -c13)``; a negative ``1 - c13^2``
    (only for a non-orthonormal C) is replaced by +0 before the square root.
    EULER_R: ``roll = atan(cos = c33, sin = c23)``; EULER_Y: ``yaw = atan(c11, c12)``;
    each result in degrees is ``rad * R2D`` (``R2D = float32(180/pi)``), and a negative yaw
    gets ``+ 360``.

The model is vectorised: every input may be an array and all circuits in a batch run in
lock-step (used for the random-vector tests and for the gateware testbenches).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from navgate.numerics.fp32 import (
    f32_to_bits,
    fp32_add,
    fp32_compare,
    fp32_div,
    fp32_mul,
    fp32_neg,
    fp32_sqrt,
    fp32_sub,
    is_nan,
)
from navgate.systems.attitude.atan16 import atan_fp32
from navgate.systems.attitude.mahony import SEED003, MahonyParams

ONE = np.uint32(0x3F800000)
HALF = np.uint32(0x3F000000)
ZERO = np.uint32(0)
D2R = f32_to_bits(math.pi / 180.0)  #: 0x3C8EFA35
R2D = f32_to_bits(180.0 / math.pi)  #: 0x42652EE1
F360 = f32_to_bits(360.0)

A, S, M, D, SQ = fp32_add, fp32_sub, fp32_mul, fp32_div, fp32_sqrt


def _twice(x):
    return A(x, x)


def _normalise3(x, y, z):
    s = A(A(M(x, x), M(y, y)), M(z, z))
    n = SQ(s)
    return D(x, n), D(y, n), D(z, n)


def acc_error(ax, ay, az, c13, c23, c33, accel_sign: float = 1.0):
    """INS_acc on bit patterns -> (exa, eya, eza)."""
    if accel_sign < 0:
        ax, ay, az = fp32_neg(ax), fp32_neg(ay), fp32_neg(az)
    ax, ay, az = _normalise3(ax, ay, az)
    exa = S(M(ay, c33), M(az, c23))
    eya = S(M(az, c13), M(ax, c33))
    eza = S(M(ax, c23), M(ay, c13))
    return exa, eya, eza


def mag_error(mx, my, mz, c, mag_sign=(1.0, -1.0, 1.0)):
    """INS_mag on bit patterns; ``c`` = (c11, c12, c13, c21, c22, c23, c31, c32, c33)."""
    c11, c12, c13, c21, c22, c23, c31, c32, c33 = c
    comps = [mx, my, mz]
    comps = [fp32_neg(v) if s < 0 else v for v, s in zip(comps, mag_sign, strict=True)]
    mx, my, mz = _normalise3(*comps)
    hx = A(A(M(c11, mx), M(c21, my)), M(c31, mz))
    hy = A(A(M(c12, mx), M(c22, my)), M(c32, mz))
    hz = A(A(M(c13, mx), M(c23, my)), M(c33, mz))
    bx = SQ(A(M(hx, hx), M(hy, hy)))
    bz = hz
    wx = A(M(c11, bx), M(c13, bz))
    wy = A(M(c21, bx), M(c23, bz))
    wz = A(M(c31, bx), M(c33, bz))
    exm = S(M(my, wz), M(mz, wy))
    eym = S(M(mz, wx), M(mx, wz))
    ezm = S(M(mx, wy), M(my, wx))
    return exm, eym, ezm


def gyro_correction(g, ea, em, ei, kp, ki, dt, gyro_scale=D2R):
    """INS_gyro: (gx, gy, gz), (exa..), (exm..), (exi..) -> ((wx, wy, wz), (exi'..))."""
    w_out, i_out = [], []
    for gk, ak, mk, ik in zip(g, ea, em, ei, strict=True):
        e = A(ak, mk)
        ik = A(ik, M(M(e, ki), dt))
        w_out.append(A(A(M(gk, gyro_scale), M(kp, e)), ik))
        i_out.append(ik)
    return tuple(w_out), tuple(i_out)


def quat_update(q, w, half_t):
    """INS_quat: first-order Runge-Kutta step and normalisation on bit patterns."""
    q0, q1, q2, q3 = q
    wx, wy, wz = w
    d0 = fp32_neg(A(A(M(q1, wx), M(q2, wy)), M(q3, wz)))
    d1 = S(A(M(q0, wx), M(q2, wz)), M(q3, wy))
    d2 = A(S(M(q0, wy), M(q1, wz)), M(q3, wx))
    d3 = S(A(M(q0, wz), M(q1, wy)), M(q2, wx))
    r = [A(qi, M(di, half_t)) for qi, di in zip((q0, q1, q2, q3), (d0, d1, d2, d3),
                                                  strict=True)]
    n = SQ(A(A(A(M(r[0], r[0]), M(r[1], r[1])), M(r[2], r[2])), M(r[3], r[3])))
    return tuple(D(ri, n) for ri in r)


def dcm_from_quat(q):
    """INS_matx: C_n^b in the 1 - 2(...) form -> (c11, c12, c13, c21, ..., c33)."""
    q0, q1, q2, q3 = q
    c11 = S(ONE, _twice(A(M(q2, q2), M(q3, q3))))
    c12 = _twice(A(M(q1, q2), M(q0, q3)))
    c13 = _twice(S(M(q1, q3), M(q0, q2)))
    c21 = _twice(S(M(q1, q2), M(q0, q3)))
    c22 = S(ONE, _twice(A(M(q1, q1), M(q3, q3))))
    c23 = _twice(A(M(q2, q3), M(q0, q1)))
    c31 = _twice(A(M(q1, q3), M(q0, q2)))
    c32 = _twice(S(M(q2, q3), M(q0, q1)))
    c33 = S(ONE, _twice(A(M(q1, q1), M(q2, q2))))
    return c11, c12, c13, c21, c22, c23, c31, c32, c33


@dataclass
class EulerBits:
    pitch: np.ndarray  #: degrees, float32 bits
    roll: np.ndarray
    yaw: np.ndarray  #: degrees in [0, 360)
    pitch_fix: np.ndarray  #: Q2.13 radians from the atan core
    roll_fix: np.ndarray
    yaw_fix: np.ndarray
    saturated: np.ndarray  #: a float32 -> fix16 conversion saturated (or saw NaN)


def euler_from_dcm(c11, c12, c13, c23, c33) -> EulerBits:
    """INS_euler on bit patterns (inputs as the port list of table 3-6)."""
    one_minus = S(ONE, M(c13, c13))
    neg = fp32_compare(one_minus, ZERO)["lt"]
    one_minus = np.where(neg, ZERO, one_minus).astype(np.uint32)
    cos_p = SQ(one_minus)
    p_rad, p_fix, s1 = atan_fp32(cos_p, fp32_neg(c13))
    r_rad, r_fix, s2 = atan_fp32(c33, c23)
    y_rad, y_fix, s3 = atan_fp32(c11, c12)
    pitch = M(p_rad, R2D)
    roll = M(r_rad, R2D)
    yaw = M(y_rad, R2D)
    yaw = np.where(fp32_compare(yaw, ZERO)["lt"], A(yaw, F360), yaw).astype(np.uint32)
    sat = np.logical_or(np.logical_or(s1, s2), s3)
    return EulerBits(pitch, roll, yaw, p_fix, r_fix, y_fix, sat)


@dataclass
class SolveBits:
    """Outputs and intermediates of one solve, all float32 bit patterns."""

    e_acc: tuple
    e_mag: tuple
    omega: tuple
    integral: tuple
    q: tuple
    c: tuple
    euler: EulerBits
    invalid: np.ndarray  #: True where any output is NaN (zero or non-finite input vector)


class MahonyCircuitFP32:
    """The whole circuit (INS_top) in float32, ``batch`` independent copies in lock-step.

    Reset: C = I, q = (1, 0, 0, 0), integral = 0 (seed 003 section 3.1). Inputs to
    :meth:`solve` are float32 bit patterns (use :func:`navgate.numerics.fp32.f32_to_bits`).
    Bad inputs (a zero accelerometer or magnetometer vector, NaN, infinity) follow IEEE
    arithmetic as the circuit would, and are *flagged*: ``SolveBits.invalid``.
    """

    def __init__(self, params: MahonyParams = SEED003, batch: int | tuple = 1):
        self.p = params
        shape = (batch,) if isinstance(batch, int) else tuple(batch)
        self.kp = f32_to_bits(params.kp)
        self.ki = f32_to_bits(params.ki)
        self.dt = f32_to_bits(params.dt)
        self.half_t = M(self.dt, HALF)
        self.gyro_scale = D2R if params.gyro_scale == SEED003.gyro_scale else f32_to_bits(
            params.gyro_scale)

        def full(v):
            return np.full(shape, v, dtype=np.uint32)

        self.q = (full(ONE), full(ZERO), full(ZERO), full(ZERO))
        self.c = tuple(full(ONE if i in (0, 4, 8) else ZERO) for i in range(9))
        self.integral = (full(ZERO), full(ZERO), full(ZERO))

    def solve(self, acc, mag, gyro) -> SolveBits:
        """One solve; ``acc``, ``mag``, ``gyro`` are 3-sequences of bit-pattern arrays."""
        p = self.p
        c = self.c
        ea = acc_error(*acc, c[2], c[5], c[8], p.accel_sign)
        em = mag_error(*mag, c, p.mag_sign)
        w, self.integral = gyro_correction(gyro, ea, em, self.integral, self.kp, self.ki,
                                           self.dt, self.gyro_scale)
        self.q = quat_update(self.q, w, self.half_t)
        self.c = dcm_from_quat(self.q)
        c = self.c
        eu = euler_from_dcm(c[0], c[1], c[2], c[5], c[8])
        outs = list(self.q) + list(c) + [eu.pitch, eu.roll, eu.yaw]
        invalid = np.zeros(np.shape(outs[0]), dtype=bool)
        for o in outs:
            invalid = invalid | is_nan(o)
        return SolveBits(ea, em, w, self.integral, self.q, c, eu, invalid)

