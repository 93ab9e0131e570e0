"""Seed 000 ``nav_output_formatter`` ("pack state for readout", module hierarchy,
``output_interface``): the INS state words -> the words of the register map's "INS State
Output" block (POS_N..YAW, docs/seed000-registers.md), Euler angles included, with flags.

Three faces, side by side (docs/seed000-output-formatter.md has the derivations):

* :func:`reference_format` - float64 (NumPy): POS_D in float64, the quaternion
  normalised, C_b^n, ZYX Euler angles with the ``asin`` argument clamped and an explicit
  gimbal-lock branch (roll = 0, yaw = atan2(-c12, c22) when cos(pitch) < 2^-26).
* :func:`formatter_bittrue` - the hardware's arithmetic: float32 (``navgate.numerics.fp32``:
  FTZ, RNE) and the integer CORDIC of ``navgate.numerics.cordic``.
* :class:`NavOutputFormatter` - Amaranth gateware, bit-exact to :func:`formatter_bittrue`.

Inputs (float32 bit patterns): the navigation state registers of the fp32 engine
(``fp32_program.NAV_REGS``: ``pN pE h vN vE vD q0..q3``) and ``ref_alt`` (the REF_ALT
register: the height of the NED origin, so POS_D = REF_ALT - h). The engine's Kahan
compensation words are not inputs: each is the rounding error of the register's last
addition, |c| <= ulp(x)/2, so x itself is a correct float32 rounding of x - c (up to a tie)
and a float32 readout of x - c would show the same word (docs/seed000-output-formatter.md).

Outputs: ``pos_n = pN``, ``pos_e = pE``, ``pos_d = ref_alt - h`` (one float32
subtraction), ``vel_* = v*``, ``quat_* = q*`` (the words themselves), ``roll pitch yaw``
(float32 radians, ZYX aerospace: C_b^n = Rz(yaw) Ry(pitch) Rx(roll); the quaternion is
Hamilton, scalar first, C_b^n, as in docs/conventions.md) and ``flags``
(:data:`FLAG_INVALID` ...).

Euler angles without products (the half-angle form; J. Bernardes and S. Viollet,
"Quaternion to Euler angles conversion: a direct, general and computationally efficient
method", PLoS ONE 17(11), 2022, specialised to ZYX). With a = yaw/2, b = pitch/2,
c = roll/2 the quaternion of Rz Ry Rx factors as::

    (q0 - q2, q3 + q1) = (cos b - sin b) (cos(a + c), sin(a + c))
    (q0 + q2, q3 - q1) = (cos b + sin b) (cos(a - c), sin(a - c))

so three CORDIC vectorings give everything: (M+, t+) of the first pair, (M-, t-) of the
second, and atan2(M-, M+) = pitch/2 + pi/4; then yaw = t+ + t-, roll = t+ - t-,
pitch = 2 atan2(M-, M+) - pi/2. Everything is invariant under q -> -q and under the scale of
q (a non-unit quaternion gives the angles of q/|q|), and the CORDIC gain cancels in the
third vectoring. Near gimbal lock (M+ or M- -> 0) the errors of yaw and roll are equal
(pitch -> +90 deg: same sign) or opposite (-90 deg): their ill-conditioned parts cancel in
the rotation they describe. At exact gimbal lock (a pair that is (0, 0) in fixed point) the
explicit rule roll = 0, yaw = 2 t- (+90 deg) or 2 t+ (-90 deg) applies.

Bit-true datapath (every step is what the gateware does):

1. ``ref_alt - h`` on the float32 adder;
2. each quaternion word to fixed point through the same adder: ``fp32_add(q, 6.0)`` lies in
   [4, 8) exactly when q is in [-2, 2) (exponent field 129), and its fraction field minus
   2^22 is round_ties_even(q 2^21) (Q2.21, 23 bits); -q1 and -q2 likewise as
   ``fp32_sub(6.0, q)`` (RNE is symmetric); any other exponent (NaN, inf, |q| >= 2) makes
   the result invalid;
3. exact integer sums a = k0 + (-k2), b = k3 + k1, c = k0 + k2, d = k3 + (-k1) (24 bits);
4. ``cordic_vectoring`` (width 24, 26 iterations, 32-bit binary angles, 5 guard bits) of
   (a, b) -> (m+, t+), of (c, d) -> (m-, t-), and of (min(m+, 2^23-1), min(m-, 2^23-1))
   -> (m3, alpha);
5. the gimbal rule as a substitution: m+ = 0 (pitch +90 deg) -> t+ := t-, m- = 0
   (pitch -90 deg) -> t- := t+ (m = 0 happens exactly when the pair is (0, 0)); then
   32-bit wrapping integer angles yaw = t+ + t-, roll = t+ - t- (0 under the rule), and
   p = clamp(alpha, 0, 2^30) - 2^29 (the clamp to [0, 90 deg] plays the part of the
   reference's asin clamp);
6. radians: ``fp32_mul(fp32_from_fixed(angle, 31, 32), PI_F32)`` for yaw and roll (angle in
   half-turns times pi) and ``fp32_mul(fp32_from_fixed(p, 31, 32), 2 PI_F32)`` for pitch
   (pitch = 2 p half-turns; doubling is exact);
7. validity from m3 = K^2 sqrt(2) |q| 2^21 (+ rounding): |q| outside [0.5, 1.5] (zero
   included) or step 2 invalid -> roll, pitch, yaw are the canonical NaN and
   :data:`FLAG_INVALID` is set; |q| outside [1 - 2^-12, 1 + 2^-12] sets
   :data:`FLAG_NON_UNIT` (angles of q/|q|); a gimbal-rule result sets :data:`FLAG_GIMBAL`;
   a non-finite POS/VEL/QUAT word (an input word or POS_D) sets :data:`FLAG_NONFINITE`.
   A NaN never leaves the block without a flag.

The error bound of step 4-6 against the float64 reference is derived in
:func:`euler_error_bound` (per angle, from the sample's M+ and M-) and
:func:`rotation_error_bound` (the rotation the three angles describe, uniform, gimbal lock
included).
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
from amaranth.hdl import Cat, Const, Module, Mux, Signal, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware.cordic import CordicAtan2Iterative
from navgate.gateware.fp32 import Fp32Add, Fp32FromFixed, Fp32Mul
from navgate.gateware.fp32.sqrt_iter import Fp32SqrtIter
from navgate.numerics.cordic import cordic_error_bound, cordic_gain, cordic_vectoring
from navgate.numerics.fp32 import (
    QNAN,
    bits_to_float,
    fp32_add,
    fp32_from_fixed,
    fp32_mul,
    fp32_sqrt,
    fp32_sub,
)
from navgate.systems.ins_trn.pl.shared_units import unit_members, unit_port

__all__ = [
    "STATE_WORDS", "IN_FIELDS", "PASS_THROUGH", "OUT_WORDS", "REGISTER_OF",
    "COV_FIELDS", "SIGMA_GROUPS", "SIGMA_WORDS", "SIGMA_REGISTER_OF", "sigma_bittrue",
    "FLAG_INVALID", "FLAG_NON_UNIT", "FLAG_GIMBAL", "FLAG_NONFINITE",
    "reference_format", "reference_euler", "formatter_bittrue",
    "euler_error_bound", "rotation_error_bound", "NavOutputFormatter",
]

STATE_WORDS = ("pN", "pE", "h", "vN", "vE", "vD", "q0", "q1", "q2", "q3")
IN_FIELDS = STATE_WORDS + ("ref_alt",)
#: output words that are input words as they are
PASS_THROUGH = {"pos_n": "pN", "pos_e": "pE", "vel_n": "vN", "vel_e": "vE", "vel_d": "vD",
                "quat_w": "q0", "quat_x": "q1", "quat_y": "q2", "quat_z": "q3"}
OUT_WORDS = ("pos_n", "pos_e", "pos_d", "vel_n", "vel_e", "vel_d",
             "quat_w", "quat_x", "quat_y", "quat_z", "roll", "pitch", "yaw")
#: output word -> register of registers.rdl
REGISTER_OF = {w: w.upper() for w in OUT_WORDS}

#: COV_POS/VEL/ATT: square roots of sums of P's diagonal words (position N+E, velocity,
#: attitude), summed in the order (a + b) + c on the formatter's adder
SIGMA_GROUPS = ((0, 1), (3, 4, 5), (6, 7, 8))
#: the diagonal words of P the sigmas read (stream input fields ``diag<k>``)
COV_FIELDS = tuple(f"diag{k}" for g in SIGMA_GROUPS for k in g)
SIGMA_WORDS = ("sigma_pos", "sigma_vel", "sigma_att")
SIGMA_REGISTER_OF = {"sigma_pos": "COV_POS", "sigma_vel": "COV_VEL", "sigma_att": "COV_ATT"}

FLAG_INVALID = 1  #: NaN/inf/|q_i| >= 2 quaternion word, or |q| outside [0.5, 1.5]: NaN angles
FLAG_NON_UNIT = 2  #: |q| outside [1 - 2^-12, 1 + 2^-12] (angles are those of q/|q|)
FLAG_GIMBAL = 4  #: exact gimbal lock in fixed point: roll = 0, the rule gives yaw
FLAG_NONFINITE = 8  #: a POS/VEL/QUAT output word is NaN or infinite

# --- number formats ----------------------------------------------------------------------
FRAC = 21  #: quaternion words -> Q2.21 (23-bit signed)
MAGIC = 6.0  #: 1.5 * 2^(23 - FRAC): q + MAGIC in [4, 8) puts round(q 2^21) in the fraction
MAGIC_BITS = 0x40C00000
MAGIC_EXP = 129
WIDTH = 24  #: CORDIC input width (sums of two Q2.21 words)
ITERATIONS = 26
GUARD = 5
ANGLE_BITS = 32
QUARTER = 1 << (ANGLE_BITS - 2)
SAT = (1 << (WIDTH - 1)) - 1  #: third vectoring's inputs are clamped to this
PI_BITS = 0x40490FDB  #: float32(pi)
TWO_PI_BITS = PI_BITS + (1 << 23)  #: float32(pi) * 2 (exponent + 1), exact
PI_F32 = bits_to_float(PI_BITS)
#: the gateware converts the binary angle as an integer (``fp32_from_int``, exactly
#: 2^31 times ``fp32_from_fixed(angle, 31, 32)``: the same 24-bit rounding, the exponent 31
#: higher) and multiplies by pi * 2^-31 (exponent 31 lower, exact): the same real product,
#: so the same rounded result (every product is far from the subnormal range); the converter
#: is then the barometer compensation's integer converter, shared (shared_units.py)
PI_BITS_INT = PI_BITS - (31 << 23)
TWO_PI_BITS_INT = TWO_PI_BITS - (31 << 23)
HALF_QUARTER = QUARTER >> 1  #: 45 deg
GAIN = cordic_gain(ITERATIONS)
#: m3 ~ NORM_SCALE * |q| (two gains, sqrt(2) of M+^2 + M-^2 = 2 |q|^2, 2^FRAC)
NORM_SCALE = GAIN * GAIN * math.sqrt(2.0) * 2.0**FRAC
NORM_LO = math.ceil(0.5 * NORM_SCALE)
NORM_HI = math.floor(1.5 * NORM_SCALE)
UNIT_TOL = 2.0**-12
UNIT_LO = math.ceil((1 - UNIT_TOL) * NORM_SCALE)
UNIT_HI = math.floor((1 + UNIT_TOL) * NORM_SCALE)
#: reference: gimbal branch when cos(pitch) < this
REF_GIMBAL_COS = 2.0**-26


def _bits(words, name):
    return np.asarray(words[name]).astype(np.uint32)


def _wrap(v):
    v = np.asarray(v, dtype=np.int64) & ((1 << ANGLE_BITS) - 1)
    return np.where(v >= (1 << (ANGLE_BITS - 1)), v - (1 << ANGLE_BITS), v)


def _nonfinite(b):
    return (np.asarray(b, dtype=np.uint32) & np.uint32(0x7F800000)) == np.uint32(0x7F800000)


# --- bit-true model ----------------------------------------------------------------------
def formatter_bittrue(words) -> dict:
    """The formatter in the hardware's arithmetic: ``words`` maps every name of
    :data:`IN_FIELDS` to float32 bit patterns (arrays of one shape); returns every
    :data:`OUT_WORDS` (uint32 arrays) and ``flags`` (int64), plus the intermediate integers
    ``t_plus t_minus alpha m_plus m_minus m3`` for the error analysis."""
    w = {k: _bits(words, k) for k in IN_FIELDS}
    shape = np.broadcast_shapes(*(v.shape for v in w.values()))
    w = {k: np.broadcast_to(v, shape) for k, v in w.items()}
    out = {name: w[src].copy() for name, src in PASS_THROUGH.items()}
    out["pos_d"] = fp32_sub(w["ref_alt"], w["h"])
    quat = [w[f"q{i}"] for i in range(4)]
    nonfinite = np.zeros(shape, dtype=bool)
    for name in OUT_WORDS[:10]:
        nonfinite |= _nonfinite(out[name])
    bad = np.zeros(shape, dtype=bool)

    def fixed(s):
        nonlocal bad
        s = np.asarray(s, dtype=np.uint32)
        bad |= ((s >> np.uint32(23)) & np.uint32(0xFF)) != MAGIC_EXP
        return (s & np.uint32(0x7FFFFF)).astype(np.int64) - (1 << 22)

    magic = np.uint32(MAGIC_BITS)
    k0, k1, k2, k3 = (fixed(fp32_add(qi, magic)) for qi in quat)
    # -q1 and -q2 converted by their own subtraction (RNE is symmetric: k1n = -k1, and the
    # range test admits q1, q2 in (-2, 2)), so that every pair is a plain sum
    k1n, k2n = fixed(fp32_sub(magic, quat[1])), fixed(fp32_sub(magic, quat[2]))
    cv = dict(width=WIDTH, iterations=ITERATIONS, angle_bits=ANGLE_BITS, guard_bits=GUARD)
    m_plus, t_plus = cordic_vectoring(k0 + k2n, k3 + k1, **cv)
    m_minus, t_minus = cordic_vectoring(k0 + k2, k3 + k1n, **cv)
    m_plus, t_plus = np.asarray(m_plus), np.asarray(t_plus)
    m_minus, t_minus = np.asarray(m_minus), np.asarray(t_minus)
    m3, alpha = cordic_vectoring(np.minimum(m_plus, SAT), np.minimum(m_minus, SAT), **cv)
    m3, alpha = np.asarray(m3), np.asarray(alpha)
    g_up = m_plus == 0  # pitch +90 deg: only t- = (yaw - roll)/2 is defined
    g_down = m_minus == 0  # pitch -90 deg: only t+ = (yaw + roll)/2 is defined
    t_plus = np.where(g_up, t_minus, t_plus)
    t_minus = np.where(g_down & ~g_up, t_plus, t_minus)
    yaw = _wrap(t_plus + t_minus)
    roll = _wrap(t_plus - t_minus)
    p = np.clip(alpha, 0, QUARTER) - HALF_QUARTER  # pitch / 2, binary angle
    invalid = bad | (m3 < NORM_LO) | (m3 > NORM_HI)
    for name, ang, scale in (("roll", roll, PI_BITS), ("pitch", p, TWO_PI_BITS),
                             ("yaw", yaw, PI_BITS)):
        rad = fp32_mul(fp32_from_fixed(ang, ANGLE_BITS - 1, ANGLE_BITS), np.uint32(scale))
        out[name] = np.where(invalid, np.uint32(QNAN), rad).astype(np.uint32)
    flags = (invalid * FLAG_INVALID
             + (~invalid & ((m3 < UNIT_LO) | (m3 > UNIT_HI))) * FLAG_NON_UNIT
             + (~invalid & (g_up | g_down)) * FLAG_GIMBAL
             + nonfinite * FLAG_NONFINITE).astype(np.int64)
    out["flags"] = flags
    out.update(t_plus=t_plus, t_minus=t_minus, alpha=alpha, m_plus=m_plus, m_minus=m_minus,
               m3=m3)
    return out


def sigma_bittrue(words) -> dict:
    """COV_POS/VEL/ATT in float32 (FTZ, RNE): ``words`` maps :data:`COV_FIELDS` to float32
    bit patterns; returns :data:`SIGMA_WORDS` (uint32 arrays): ``fp32_sqrt`` of the group's
    words summed as (a + b) + c. A negative sum gives the canonical NaN, as the square root
    does."""
    out = {}
    for name, group in zip(SIGMA_WORDS, SIGMA_GROUPS, strict=True):
        acc = _bits(words, f"diag{group[0]}")
        for k in group[1:]:
            acc = fp32_add(acc, _bits(words, f"diag{k}"))
        out[name] = np.asarray(fp32_sqrt(acc), dtype=np.uint32)
    return out


# --- float64 reference -------------------------------------------------------------------
def reference_euler(q):
    """(roll, pitch, yaw, cos_pitch) in float64 of quaternions ``q`` (N, 4), normalised
    first; ``asin`` argument clamped to [-1, 1]; gimbal branch (roll = 0,
    yaw = atan2(-c12, c22)) where cos(pitch) = hypot(c11, c21) < :data:`REF_GIMBAL_COS`."""
    q = np.asarray(q, dtype=np.float64)
    n = np.sqrt(np.sum(q * q, axis=-1))
    with np.errstate(invalid="ignore", divide="ignore"):
        u = q / n[..., None]
    q0, q1, q2, q3 = (u[..., i] for i in range(4))
    c11 = q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3
    c21 = 2 * (q1 * q2 + q0 * q3)
    c31 = 2 * (q1 * q3 - q0 * q2)
    c32 = 2 * (q2 * q3 + q0 * q1)
    c33 = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3
    c12 = 2 * (q1 * q2 - q0 * q3)
    c22 = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
    pitch = np.arcsin(np.clip(-c31, -1.0, 1.0))
    cos_p = np.hypot(c11, c21)
    lock = cos_p < REF_GIMBAL_COS
    roll = np.where(lock, 0.0, np.arctan2(c32, c33))
    yaw = np.where(lock, np.arctan2(-c12, c22), np.arctan2(c21, c11))
    return roll, pitch, yaw, cos_p


def reference_format(values) -> dict:
    """float64 reference: ``values`` maps :data:`IN_FIELDS` to float values (the float32
    words as numbers); returns float64 :data:`OUT_WORDS` and ``flags`` (same meaning as the
    bit-true flags, decided on exact |q|)."""
    v = {k: np.asarray(values[k], dtype=np.float64) for k in IN_FIELDS}
    out = {name: v[src] for name, src in PASS_THROUGH.items()}
    out["pos_d"] = v["ref_alt"] - v["h"]
    q = np.stack([v[f"q{i}"] for i in range(4)], axis=-1)
    with np.errstate(invalid="ignore", over="ignore"):
        n = np.sqrt(np.sum(q * q, axis=-1))
        finite = np.all(np.isfinite(q), axis=-1)
        invalid = ~finite | ~(n >= 0.5) | ~(n <= 1.5) | np.any(np.abs(q) >= 2.0, axis=-1)
        roll, pitch, yaw, cos_p = reference_euler(np.where(invalid[..., None], 1.0, q))
    nan = np.float64("nan")
    out["roll"] = np.where(invalid, nan, roll)
    out["pitch"] = np.where(invalid, nan, pitch)
    out["yaw"] = np.where(invalid, nan, yaw)
    nonfinite = np.zeros(n.shape, dtype=bool)
    for name in OUT_WORDS[:10]:
        nonfinite |= ~np.isfinite(out[name])
    lock = cos_p < REF_GIMBAL_COS
    out["flags"] = (invalid * FLAG_INVALID
                    + (~invalid & (np.abs(n - 1.0) > UNIT_TOL)) * FLAG_NON_UNIT
                    + (~invalid & lock) * FLAG_GIMBAL
                    + nonfinite * FLAG_NONFINITE).astype(np.int64)
    out["norm"] = n
    out["cos_pitch"] = cos_p
    return out


# --- error bounds ------------------------------------------------------------------------
#: per quaternion component, |fixed value / 2^21 - q|: rounding to Q2.21 (2^-22)
COMPONENT_ERR = 2.0**-22
#: each CORDIC input pair sums two components: |delta(a, b)| <= sqrt(2) * 2 * COMPONENT_ERR
PAIR_ERR = 2.0 * math.sqrt(2.0) * COMPONENT_ERR
_LSB = 2.0**-FRAC
#: truncation of the magnitude (internal LSBs -> input LSBs), as in the rotation bound
_MAG_TRUNC = sum(math.sqrt(2.0) * math.prod(math.sqrt(1 + 4.0**-j)
                                            for j in range(i + 1, ITERATIONS))
                 for i in range(1, ITERATIONS)) / 2.0**GUARD
#: float32 output: fp32_from_fixed rounding (2^-24 relative), the product's rounding
#: (2^-24), pi's own rounding (|PI_F32 - pi| / pi), times |angle| <= pi
OUTPUT_ERR = math.pi * (2 * 2.0**-24 + abs(PI_F32 - math.pi) / math.pi) * (1 + 2.0**-20)
#: float64 reference: asin near +-1 turns an argument error e into sqrt(2 e); with
#: e <= 8 eps (the roundings of c31 after normalisation) that is sqrt(16 * 2^-52) = 6e-8;
#: its gimbal branch (cos(pitch) < 2^-26) moves the rotation by at most 2 cos(pitch) < 3e-8
REFERENCE_ERR = 6e-8


def _cordic_angle_bound(mag):
    """|CORDIC angle - exact atan2| (rad) for an exact pair of magnitude ``mag`` (value
    units) perturbed by PAIR_ERR: perturbation + cordic_error_bound at the smaller radius."""
    if mag <= PAIR_ERR:
        return math.pi
    pert = math.asin(min(1.0, PAIR_ERR / mag))
    r = (mag - PAIR_ERR) / _LSB
    return pert + cordic_error_bound(WIDTH, ITERATIONS, ANGLE_BITS, GUARD, min_magnitude=r)


def _magnitude_err(mag):
    """|m - K mag 2^21| bound (input LSBs): perturbation, truncation, final floor, residual."""
    return (GAIN * PAIR_ERR / _LSB + _MAG_TRUNC + 1.0
            + GAIN * mag / _LSB * 2.0 ** (-2 * ITERATIONS + 2))


def euler_error_bound(m_plus, m_minus, norm=1.0):
    """Worst-case |roll|, |pitch|, |yaw| error (rad, angles compared modulo 2 pi) of
    :func:`formatter_bittrue` against :func:`reference_euler` for a quaternion of norm
    ``norm`` whose exact pairs have magnitudes ``m_plus`` = |(q0 - q2, q3 + q1)| and
    ``m_minus`` = |(q0 + q2, q3 - q1)| (float64). Returns (roll_yaw_bound, pitch_bound).

    yaw and roll are t+ +- t-: each gets the sum of the two half-angle errors (perturbation
    of the pair by PAIR_ERR plus the CORDIC bound at the reduced radius); pitch is
    2 alpha - 90 deg with alpha = atan2(m-, m+) from the measured magnitudes, whose errors
    (:func:`_magnitude_err`) perturb the pair (K m+, K m-) of radius K sqrt(2) |q| 2^21; the
    gain cancels. The float32 output step adds OUTPUT_ERR, the reference REFERENCE_ERR."""
    e_ry = _cordic_angle_bound(m_plus) + _cordic_angle_bound(m_minus) + OUTPUT_ERR
    radius = GAIN * math.sqrt(2.0) * norm / _LSB
    dm = math.hypot(_magnitude_err(m_plus), _magnitude_err(m_minus))
    if dm >= radius:
        return e_ry + REFERENCE_ERR, math.pi
    e_alpha = math.asin(dm / radius) + cordic_error_bound(
        WIDTH, ITERATIONS, ANGLE_BITS, GUARD, min_magnitude=radius - dm)
    return e_ry + REFERENCE_ERR, 2 * e_alpha + OUTPUT_ERR + REFERENCE_ERR


def rotation_error_bound(norm=1.0) -> float:
    """Worst-case angle (rad) of the rotation between C_b^n(roll, pitch, yaw) of
    :func:`formatter_bittrue` and the rotation of q/|q| (gimbal lock included).

    The map q -> (q0 - q2, q3 + q1, q0 + q2, q3 - q1)/sqrt(2) is orthogonal, so the
    quaternion error is |P' - P|/sqrt(2) with P = (M+ e^{i t+}, M- e^{i t-}) (unit q:
    M+^2 + M-^2 = 2). Per pair, |M' e^{i t'} - M e^{i t}| <= |dM| + M |dt| with
    M |dt| <= min(pi M, M e_cordic(M) + (pi/2) PAIR_ERR) + M OUTPUT_ERR (the gimbal rule
    sets t arbitrarily only where M <= PAIR_ERR-sized: pi M), and |dM| <= |dpitch| / sqrt(2)
    (M+- = sqrt(2) cos/sin(pitch/2 + pi/4)). The rotation angle is 4 asin(|dq| / 2).
    Evaluated over a grid of M (e_cordic decreases with M, so M_{k+1} e(M_k) bounds each
    interval)."""
    grid = np.concatenate([[0.0], np.geomspace(1e-9, math.sqrt(2.0) * 1.5, 400)])
    worst = 0.0
    for lo, hi in zip(grid[:-1], grid[1:], strict=True):
        e = _cordic_angle_bound(lo) if lo > 0 else math.pi
        t = min(math.pi * hi, hi * e + 0.5 * math.pi * PAIR_ERR) + hi * OUTPUT_ERR
        worst = max(worst, t)
    # pitch error: the worst over the same grid of (m_plus, m_minus) with m+^2 + m-^2 = 2
    e_pitch = 0.0
    for ang in np.linspace(0.0, math.pi / 2, 91):
        mp, mm = math.sqrt(2) * math.cos(ang), math.sqrt(2) * math.sin(ang)
        e_pitch = max(e_pitch, euler_error_bound(mp, mm, norm)[1])
    dq = math.hypot(worst + e_pitch / math.sqrt(2), worst + e_pitch / math.sqrt(2)) \
        / math.sqrt(2)
    return 4 * math.asin(min(1.0, dq / 2)) + REFERENCE_ERR


# --- gateware ----------------------------------------------------------------------------
IN_LAYOUT = data.StructLayout({name: unsigned(32) for name in IN_FIELDS + COV_FIELDS})
OUT_LAYOUT = data.StructLayout({**{name: unsigned(32) for name in OUT_WORDS + SIGMA_WORDS},
                                "flags": unsigned(4)})

#: adder schedule: cycle t (from the first busy cycle) -> (a, b, subtract, destination).
#: ``kx``/``ky`` hold -k2/k1 for the first vectoring (issued in cycle K_READY) and are
#: rewritten with k2/-k1 for the second one (their writes land after K_READY).
ADD_ISSUE = {
    0: ("q0", "magic", 0, "k0"), 1: ("magic", "q2", 1, "kx"), 2: ("q3", "magic", 0, "k3"),
    3: ("q1", "magic", 0, "ky"), 4: ("ref_alt", "h", 1, "pos_d"),
    5: ("q2", "magic", 0, "kx"), 6: ("magic", "q1", 1, "ky"),
    # the sigmas' sums: first terms, then the third terms once the first sums are written
    7: ("diag0", "diag1", 0, "s_pos"), 8: ("diag3", "diag4", 0, "s_vel"),
    9: ("diag6", "diag7", 0, "s_att"),
    8 + Fp32Add.LATENCY + 1: ("s_vel", "diag5", 0, "s_vel"),
    9 + Fp32Add.LATENCY + 1: ("s_att", "diag8", 0, "s_att"),
}
#: sigma sums: cycle from which each is written (its square root may issue)
SUM_READY = (7 + Fp32Add.LATENCY + 1, 8 + 2 * (Fp32Add.LATENCY + 1),
             9 + 2 * (Fp32Add.LATENCY + 1))
#: first vectoring: the cycle after the first four conversions are written
K_READY = 3 + Fp32Add.LATENCY + 1


class NavOutputFormatter(wiring.Component):
    """Seed 000 ``nav_output_formatter``: {IN_FIELDS, COV_FIELDS} (float32 words) ->
    {OUT_WORDS, SIGMA_WORDS, flags}.

    One float32 adder (12 operations: REF_ALT - h, six Q2.21 conversions and the five sums of
    the sigmas), one iterative CORDIC (three vectorings), one fixed -> float32 converter, one
    float32 multiplier (x pi, x 2 pi) and one iterative square root (the three sigmas), on a
    fixed schedule; one vector at a time. ``LATENCY`` = 106 cycles from the accepted input to
    the valid output; ``THROUGHPUT`` = 1/106 (the next input is accepted in the cycle the
    output is taken).
    """

    LATENCY = 106
    THROUGHPUT = Fraction(1, 106)

    def __init__(self, shared_units: bool = False):
        #: True: the adder and multiplier are outside (ports ``add_i/add_o/mul_i/mul_o`` of
        #: :mod:`navgate.systems.ins_trn.pl.shared_units`; results taken LATENCY cycles after
        #: their issue, as from its own cores)
        self.shared_units = shared_units
        super().__init__({"i": In(stream.Signature(IN_LAYOUT)),
                          "o": Out(stream.Signature(OUT_LAYOUT)),
                          **(unit_members() if shared_units else {})})

    def elaborate(self, platform):
        m = Module()
        if self.shared_units:
            add, mul = unit_port(self, "add"), unit_port(self, "mul")
        else:
            m.submodules.add = add = Fp32Add()
            m.submodules.mul = mul = Fp32Mul()
        m.submodules.cordic = cor = CordicAtan2Iterative(
            width=WIDTH, iterations=ITERATIONS, angle_bits=ANGLE_BITS, guard_bits=GUARD)
        if self.shared_units:  # the shared integer converter; pi scaled by 2^-31
            tof = unit_port(self, "cvt")
            pi_bits, two_pi_bits = PI_BITS_INT, TWO_PI_BITS_INT
        else:  # its own fixed-point converter (with Fp32FromInt here, Yosys 0.70's abc9
            # stops on an internal assertion while mapping the block alone)
            m.submodules.tof = tof = Fp32FromFixed(width=ANGLE_BITS, frac_bits=ANGLE_BITS - 1)
            pi_bits, two_pi_bits = PI_BITS, TWO_PI_BITS
        m.submodules.sqrt = sq = Fp32SqrtIter()
        m.d.comb += [add.o.ready.eq(1), cor.o.ready.eq(1), tof.o.ready.eq(1),
                     mul.o.ready.eq(1), sq.o.ready.eq(1)]

        x = Signal(IN_LAYOUT, reset_less=True)  # the state words, held until the next input
        pos_d = Signal(32, reset_less=True)
        yaw = Signal(32, reset_less=True)
        roll = Signal(32, reset_less=True)
        pitch = Signal(32, reset_less=True)
        flags = Signal(4, reset_less=True)
        busy = Signal()
        o_valid = Signal()
        t = Signal(5)  # adder-phase cycle counter (stops at 31)
        accept = Signal()
        m.d.comb += [
            self.i.ready.eq(~busy & (~o_valid | self.o.ready)),
            accept.eq(self.i.valid & self.i.ready),
            self.o.valid.eq(o_valid),
            self.o.payload.pos_d.eq(pos_d),
            self.o.payload.yaw.eq(yaw),
            self.o.payload.roll.eq(roll),
            self.o.payload.pitch.eq(pitch),
            self.o.payload.flags.eq(flags),
        ]
        for name, src in PASS_THROUGH.items():
            m.d.comb += getattr(self.o.payload, name).eq(getattr(x, src))
        sums = {n: Signal(32, name=n, reset_less=True) for n in ("s_pos", "s_vel", "s_att")}
        sigma = [Signal(32, name=n, reset_less=True) for n in SIGMA_WORDS]
        for name, sig in zip(SIGMA_WORDS, sigma, strict=True):
            m.d.comb += getattr(self.o.payload, name).eq(sig)
        with m.If(self.o.ready):
            m.d.sync += o_valid.eq(0)
        with m.If(busy & (t != 31)):
            m.d.sync += t.eq(t + 1)

        bad = Signal()  # a conversion left [4, 8): NaN, inf or |q_i| >= 2
        invalid = Signal()
        non_unit = Signal()
        g_up = Signal()
        g_down = Signal()

        # ---- float32 adder: REF_ALT - h, the Q2.21 conversions, the sigmas' sums --------
        r = add.o.payload.r
        magic = Const(MAGIC_BITS, 32)

        def operand(name):
            return magic if name == "magic" else sums[name] if name in sums else getattr(x, name)

        with m.If(busy):
            with m.Switch(t):
                for cyc, (a, b, sub, _dst) in ADD_ISSUE.items():
                    with m.Case(cyc):
                        m.d.comb += [
                            add.i.valid.eq(1),
                            add.i.payload.a.eq(operand(a)),
                            add.i.payload.b.eq(operand(b)),
                            add.i.payload.sub.eq(sub),
                        ]
        kregs = {n: Signal(signed(23), name=n, reset_less=True) for n in ("k0", "k3", "kx", "ky")}
        with m.If(busy):
            with m.Switch(t):
                for cyc, (_a, _b, _sub, dst) in ADD_ISSUE.items():
                    with m.Case(cyc + Fp32Add.LATENCY):
                        if dst == "pos_d":
                            m.d.sync += pos_d.eq(r)
                        elif dst in sums:
                            m.d.sync += sums[dst].eq(r)
                        else:
                            m.d.sync += kregs[dst].eq(r[0:23] ^ (1 << 22))
                            with m.If(r[23:31] != MAGIC_EXP):
                                m.d.sync += bad.eq(1)

        # ---- CORDIC: (k0 + kx, k3 + ky) twice, then the two magnitudes ------------------
        cv = Signal(2)  # vectorings issued
        cr = Signal(2)  # vectorings received
        t_plus = Signal(signed(ANGLE_BITS), reset_less=True)
        t_minus = Signal(signed(ANGLE_BITS), reset_less=True)
        s_plus = Signal(unsigned(WIDTH - 1), reset_less=True)
        s_minus = Signal(unsigned(WIDTH - 1), reset_less=True)
        third = cv == 2
        m.d.comb += [
            cor.i.valid.eq(busy & (t >= K_READY) & ((cv < 2) | (third & (cr == 2)))),
            cor.i.payload.x.eq(Mux(third, s_plus, kregs["k0"] + kregs["kx"])),
            cor.i.payload.y.eq(Mux(third, s_minus, kregs["k3"] + kregs["ky"])),
        ]
        with m.If(cor.i.valid & cor.i.ready):
            m.d.sync += cv.eq(cv + 1)
        mag = cor.o.payload.magnitude
        ang = cor.o.payload.angle
        zero = mag == 0
        with m.If(cor.o.valid):
            m.d.sync += cr.eq(cr + 1)
            with m.Switch(cr):
                with m.Case(0):
                    m.d.sync += [t_plus.eq(ang), g_up.eq(zero)]
                    m.d.sync += s_plus.eq(Mux(mag > SAT, SAT, mag))
                with m.Case(1):
                    # gimbal rule: t+ := t- (pitch +90 deg), t- := t+ (pitch -90 deg)
                    with m.If(g_up):
                        m.d.sync += t_plus.eq(ang)
                    m.d.sync += [t_minus.eq(Mux(zero & ~g_up, t_plus, ang)), g_down.eq(zero)]
                    m.d.sync += s_minus.eq(Mux(mag > SAT, SAT, mag))
                with m.Case(2):
                    # pitch / 2 = clamp(alpha, 0, 90 deg) - 45 deg = t+ - t-
                    with m.If(ang < 0):
                        m.d.sync += t_plus.eq(0)
                    with m.Elif(ang > QUARTER):
                        m.d.sync += t_plus.eq(QUARTER)
                    with m.Else():
                        m.d.sync += t_plus.eq(ang)
                    m.d.sync += [
                        t_minus.eq(HALF_QUARTER),
                        invalid.eq(bad | (mag < NORM_LO) | (mag > NORM_HI)),
                        non_unit.eq((mag < UNIT_LO) | (mag > UNIT_HI)),
                    ]

        # ---- sigmas: the three square roots, each once its sum is written ---------------
        si = Signal(2)  # square roots issued
        so = Signal(2)  # square roots received
        sum_ready = Signal()
        with m.Switch(si):
            for k, (name, ready) in enumerate(zip(sums, SUM_READY, strict=True)):
                with m.Case(k):
                    m.d.comb += [sum_ready.eq(t >= ready), sq.i.payload.eq(sums[name])]
        m.d.comb += sq.i.valid.eq(busy & (si != 3) & sum_ready)
        with m.If(sq.i.valid & sq.i.ready):
            m.d.sync += si.eq(si + 1)
        with m.If(sq.o.valid):
            m.d.sync += so.eq(so + 1)
            with m.Switch(so):
                for k, sig in enumerate(sigma):
                    with m.Case(k):
                        m.d.sync += sig.eq(sq.o.payload)

        # ---- angles -> float32 radians: yaw, roll after the second vectoring, pitch -----
        ci = Signal(2)  # conversions issued
        mr = Signal(2)  # products received
        sub = ci != 0  # yaw = t+ + t-, roll = t+ - t-, pitch / 2 = t+ - t-
        # one carry chain: ((t+ << 1) | 1) + ((t- ^ s) << 1 | s) = 2 (t+ + (t- ^ s) + s) + 1
        wide = Signal(ANGLE_BITS + 1)
        m.d.comb += wide.eq(Cat(Const(1, 1), t_plus)
                            + Cat(sub, t_minus ^ sub.replicate(ANGLE_BITS)))
        m.d.comb += [
            tof.i.valid.eq(busy & (((ci < 2) & (cr == 2)) | ((ci == 2) & (cr == 3)))),
            tof.i.payload.x.eq(wide[1:]),
            mul.i.valid.eq(tof.o.valid),
            mul.i.payload.a.eq(tof.o.payload.r),
            mul.i.payload.b.eq(Mux(mr == 2, two_pi_bits, pi_bits)),
        ]
        with m.If(tof.i.valid):
            m.d.sync += ci.eq(ci + 1)
        prod = mul.o.payload.r
        nonfinite = Signal()
        fin = [getattr(x, w)[23:31] == 0xFF for w in PASS_THROUGH.values()]
        m.d.comb += nonfinite.eq(Cat(*fin, pos_d[23:31] == 0xFF).any())
        with m.If(mul.o.valid):
            m.d.sync += mr.eq(mr + 1)
            with m.Switch(mr):
                with m.Case(0):
                    m.d.sync += yaw.eq(prod)
                with m.Case(1):
                    m.d.sync += roll.eq(prod)
                with m.Case(2):
                    m.d.sync += pitch.eq(prod)
                    m.d.sync += flags.eq(Cat(invalid, non_unit & ~invalid,
                                             (g_up | g_down) & ~invalid, nonfinite))
                    with m.If(invalid):
                        m.d.sync += [yaw.eq(QNAN), roll.eq(QNAN), pitch.eq(QNAN)]

        # the output is valid once the angles (three products) and the sigmas are in
        with m.If(busy & (mr == 3) & (so == 3)):
            m.d.sync += [busy.eq(0), o_valid.eq(1)]

        with m.If(accept):
            m.d.sync += [x.eq(self.i.payload), busy.eq(1), t.eq(0), cv.eq(0), cr.eq(0),
                         ci.eq(0), mr.eq(0), bad.eq(0), si.eq(0), so.eq(0)]
        return m
