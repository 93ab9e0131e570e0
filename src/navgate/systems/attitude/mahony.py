"""Seed 003's attitude-solving algorithm: float64 reference model.

Reference: seed 003 (姿态解算算法电路的设计文档, the attitude-solving circuit of a rotorcraft
flight-control chip), sections 3.1.2-3.1.8 (module decomposition) and 4.2.4 (module test
cases, tables 4-1 to 4-7); R. Mahony, T. Hamel, J.-M. Pflimlin, "Nonlinear complementary
filters on the special orthogonal group", IEEE TAC 53(5), 2008 (the explicit complementary
filter this circuit implements).

One "solve" of the circuit runs its modules in the FSM order of figure 3-2:

1. ``INS_acc`` (:func:`acc_error`): normalise the accelerometer vector, cross it with the
   third column (c13, c23, c33) of the previous attitude matrix C_n^b:
   ``e_a = a/|a| x C[:, 2]``.
2. ``INS_mag`` (:func:`mag_error`): normalise the magnetometer vector, rotate it into the
   navigation frame with the previous matrix, ``h = C^T m``, form the reference flux
   ``b = (sqrt(hx^2 + hy^2), 0, hz)``, rotate back, ``w = C b``, and cross:
   ``e_m = m x w``.
3. ``INS_gyro`` (:func:`gyro_correction`): ``e = e_a + e_m``; integral state
   ``I += Ki T e``; corrected rate ``omega = s_g gyro + Kp e + I`` (new integral).
4. ``INS_quat`` (:func:`quat_update`): first-order Runge-Kutta (Euler) step of
   ``q_dot = 1/2 q (x) (0, omega)`` over the sample period T, then normalisation.
5. ``INS_matx`` (:func:`dcm_from_quat`): C_n^b from q with the ``1 - 2(...)`` diagonal
   form (table 4-5 feeds the unnormalised q = (1, 2, 3, 4) and expects c11 = -49).
6. ``INS_euler`` (:func:`euler_from_dcm`): pitch = -asin(c13), roll = atan2(c23, c33),
   yaw = atan2(c12, c11) wrapped to [0, 360) degrees (table 4-6: yaw 333.43 deg).

What the seed does not print, recovered from its tables (docs/seed003-attitude.md):

* The circuit takes the gyro in deg/s and multiplies it by pi/180 inside INS_gyro
  (table 4-3: omega_x = 21.0195 = 1 * pi/180 + 10 * 2 + 1.002).
* Kp = 10, Ki = 0.5, T = 0.002 s (tables 4-3 and 4-4: Ki T = 0.001, T/2 = 0.001). With these
  values this model reproduces all fifteen Matlab numbers of table 4-7 to the printed digits.
* The magnetometer's y component enters negated (``mag_sign = (1, -1, 1)``): table 4-2 is
  reproduced with it and with no other sign pattern; without it e_m would be orthogonal to m
  = (2, 2, 2), which the printed e_m = (-8.04738, -3.21895, 4.82842) is not.

Frame conventions. The quaternion is Hamilton scalar-first and maps body vectors into the
navigation frame (it is the quaternion of C_b^n, as everywhere in navgate); the circuit's
attitude matrix is its transpose C_n^b. The circuit's accelerometer term assumes the
accelerometer reads +|g| along the navigation z axis at rest (a z-up navigation frame);
``accel_sign = -1`` feeds the negated specific force instead, which makes the same equations
a NED/FRD filter (a level FRD accelerometer reads -g on z). Everything else is unchanged.

Two implementations share these equations: the per-module functions and
:class:`MahonyCircuitReference` (readable, used by the tests against the seed's tables and
by the bit-true model's tests) and :func:`mahony_batch`, a Numba loop over a whole log for
``navgate ahrs`` (tests check the two agree to rounding).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

DEG = math.pi / 180.0


@dataclass(frozen=True)
class MahonyParams:
    """Tunable parameters of the attitude-solving circuit ("固参可调": adjustable parameters).

    Defaults are the values recovered from seed 003's tables (see the module docstring).
    """

    kp: float = 10.0  #: proportional gain (rad/s per unit error)
    ki: float = 0.5  #: integral gain (rad/s^2 per unit error)
    dt: float = 0.002  #: sample period T (s)
    gyro_scale: float = DEG  #: gyro input units -> rad/s (circuit: deg/s)
    mag_sign: tuple[float, float, float] = (1.0, -1.0, 1.0)  #: magnetometer axis signs
    accel_sign: float = 1.0  #: +1: accel reads +g along nav z at rest; -1: NED specific force

    def __post_init__(self):
        for name in ("kp", "ki", "dt", "gyro_scale", "accel_sign"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"MahonyParams.{name} must be finite")
        if self.kp < 0 or self.ki < 0:
            raise ValueError("Kp and Ki must be non-negative")
        if not self.dt > 0:
            raise ValueError("the sample period must be positive")
        if len(self.mag_sign) != 3 or any(s not in (1.0, -1.0) for s in self.mag_sign):
            raise ValueError("mag_sign must be three values of +1 or -1")
        if self.accel_sign not in (1.0, -1.0):
            raise ValueError("accel_sign must be +1 or -1")


#: the circuit as seed 003's tables describe it
SEED003 = MahonyParams()

#: the same filter for SI inputs in NED/FRD (gyro rad/s, specific force, magnetometer as is)
NED_SI = MahonyParams(kp=1.0, ki=0.1, dt=0.01, gyro_scale=1.0, mag_sign=(1.0, 1.0, 1.0),
                      accel_sign=-1.0)


def _normalise(v):
    v = np.asarray(v, dtype=np.float64)
    n = math.sqrt(float(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]))
    if not n > 0 or not math.isfinite(n):
        raise ValueError("cannot normalise a zero or non-finite vector")
    return v / n


def acc_error(acc, c13, c23, c33, accel_sign: float = 1.0) -> np.ndarray:
    """INS_acc: ``(accel_sign * a/|a|) x (c13, c23, c33)`` (table 4-1)."""
    a = accel_sign * _normalise(acc)
    return np.cross(a, np.array([c13, c23, c33], dtype=np.float64))


def mag_error(mag, c, mag_sign=(1.0, -1.0, 1.0)) -> np.ndarray:
    """INS_mag: normalise, reference flux from the previous C_n^b, cross (table 4-2)."""
    c = np.asarray(c, dtype=np.float64)
    m = _normalise(np.asarray(mag, dtype=np.float64) * np.asarray(mag_sign, dtype=np.float64))
    h = c.T @ m
    b = np.array([math.hypot(h[0], h[1]), 0.0, h[2]])
    w = c @ b
    return np.cross(m, w)


def gyro_correction(gyro, e_acc, e_mag, integral, p: MahonyParams = SEED003):
    """INS_gyro: PI correction. Returns (omega rad/s, new integral) (table 4-3)."""
    e = np.asarray(e_acc, dtype=np.float64) + np.asarray(e_mag, dtype=np.float64)
    integral = np.asarray(integral, dtype=np.float64) + p.ki * p.dt * e
    omega = np.asarray(gyro, dtype=np.float64) * p.gyro_scale + p.kp * e + integral
    return omega, integral


def quat_update(q, omega, dt: float) -> np.ndarray:
    """INS_quat: first-order Runge-Kutta step of q_dot = q (x) (0, omega) / 2, normalised
    (table 4-4)."""
    q0, q1, q2, q3 = (float(x) for x in q)
    wx, wy, wz = (float(x) for x in omega)
    ht = 0.5 * dt
    r = np.array([
        q0 + (-q1 * wx - q2 * wy - q3 * wz) * ht,
        q1 + (q0 * wx + q2 * wz - q3 * wy) * ht,
        q2 + (q0 * wy - q1 * wz + q3 * wx) * ht,
        q3 + (q0 * wz + q1 * wy - q2 * wx) * ht,
    ])
    return _normalise4(r)


def _normalise4(q):
    n = math.sqrt(float(q @ q))
    if not n > 0 or not math.isfinite(n):
        raise ValueError("cannot normalise a zero or non-finite quaternion")
    return q / n


def dcm_from_quat(q) -> np.ndarray:
    """INS_matx: C_n^b (navigation to body) in the 1 - 2(...) form (table 4-5)."""
    q0, q1, q2, q3 = (float(x) for x in q)
    return np.array([
        [1 - 2 * (q2 * q2 + q3 * q3), 2 * (q1 * q2 + q0 * q3), 2 * (q1 * q3 - q0 * q2)],
        [2 * (q1 * q2 - q0 * q3), 1 - 2 * (q1 * q1 + q3 * q3), 2 * (q2 * q3 + q0 * q1)],
        [2 * (q1 * q3 + q0 * q2), 2 * (q2 * q3 - q0 * q1), 1 - 2 * (q1 * q1 + q2 * q2)],
    ])


def euler_from_dcm(c) -> tuple[float, float, float]:
    """INS_euler: (pitch, roll, yaw) in degrees from C_n^b; yaw in [0, 360) (table 4-6).

    pitch = -asin(c13) (c13 clipped to [-1, 1]), roll = atan2(c23, c33),
    yaw = atan2(c12, c11).
    """
    c = np.asarray(c, dtype=np.float64)
    pitch = -math.degrees(math.asin(min(1.0, max(-1.0, c[0, 2]))))
    roll = math.degrees(math.atan2(c[1, 2], c[2, 2]))
    yaw = math.degrees(math.atan2(c[0, 1], c[0, 0]))
    if yaw < 0.0:
        yaw += 360.0
    return pitch, roll, yaw


@dataclass
class SolveResult:
    """Everything one solve produces (the circuit's outputs plus the intermediates)."""

    e_acc: np.ndarray
    e_mag: np.ndarray
    omega: np.ndarray
    integral: np.ndarray
    q: np.ndarray
    c: np.ndarray
    pitch: float
    roll: float
    yaw: float


class MahonyCircuitReference:
    """The whole circuit (INS_top), float64: state q, C_n^b and the integral error.

    Reset state as section 3.1: C = I, q = (1, 0, 0, 0), integral = 0.
    """

    def __init__(self, params: MahonyParams = SEED003, q0=None):
        self.p = params
        self.q = np.array([1.0, 0.0, 0.0, 0.0]) if q0 is None else _normalise4(
            np.asarray(q0, dtype=np.float64).copy())
        self.c = dcm_from_quat(self.q)
        self.integral = np.zeros(3)

    def solve(self, acc, mag, gyro) -> SolveResult:
        """One in_data_en -> out_INS_finish cycle."""
        p = self.p
        e_a = acc_error(acc, self.c[0, 2], self.c[1, 2], self.c[2, 2], p.accel_sign)
        e_m = mag_error(mag, self.c, p.mag_sign)
        omega, self.integral = gyro_correction(gyro, e_a, e_m, self.integral, p)
        self.q = quat_update(self.q, omega, p.dt)
        self.c = dcm_from_quat(self.q)
        pitch, roll, yaw = euler_from_dcm(self.c)
        return SolveResult(e_a, e_m, omega, self.integral.copy(), self.q.copy(), self.c.copy(),
                           pitch, roll, yaw)


# ---------------------------------------------------------------------------------------------
# Whole-log filter (Numba)


@njit(cache=True)
def mahony_steps(gyro, acc, mag, dt, state, kp, ki, gyro_scale, mag_sign, accel_sign, use_mag,
                 out):
    """Advance ``state`` = (q0, q1, q2, q3, Ix, Iy, Iz) by every sample of the arrays, in
    place, writing the quaternion after sample k into ``out[k]``. The state's quaternion is
    used as is (not renormalised), so a log processed in pieces gives the same bits as the
    whole log (:class:`navgate.systems.attitude.estimate.AttitudeStream`)."""
    q0_, q1, q2, q3 = state[0], state[1], state[2], state[3]
    ix = state[4]
    iy = state[5]
    iz = state[6]
    for k in range(gyro.shape[0]):
        # previous C_n^b (1 - 2(...) form)
        c11 = 1.0 - 2.0 * (q2 * q2 + q3 * q3)
        c12 = 2.0 * (q1 * q2 + q0_ * q3)
        c13 = 2.0 * (q1 * q3 - q0_ * q2)
        c21 = 2.0 * (q1 * q2 - q0_ * q3)
        c22 = 1.0 - 2.0 * (q1 * q1 + q3 * q3)
        c23 = 2.0 * (q2 * q3 + q0_ * q1)
        c31 = 2.0 * (q1 * q3 + q0_ * q2)
        c32 = 2.0 * (q2 * q3 - q0_ * q1)
        c33 = 1.0 - 2.0 * (q1 * q1 + q2 * q2)
        ex = 0.0
        ey = 0.0
        ez = 0.0
        ax, ay, az = acc[k, 0], acc[k, 1], acc[k, 2]
        na = math.sqrt(ax * ax + ay * ay + az * az)
        if na > 0.0:
            ax, ay, az = accel_sign * ax / na, accel_sign * ay / na, accel_sign * az / na
            ex += ay * c33 - az * c23
            ey += az * c13 - ax * c33
            ez += ax * c23 - ay * c13
        if use_mag:
            mx = mag[k, 0] * mag_sign[0]
            my = mag[k, 1] * mag_sign[1]
            mz = mag[k, 2] * mag_sign[2]
            nm = math.sqrt(mx * mx + my * my + mz * mz)
            if nm > 0.0:
                mx, my, mz = mx / nm, my / nm, mz / nm
                hx = c11 * mx + c21 * my + c31 * mz
                hy = c12 * mx + c22 * my + c32 * mz
                hz = c13 * mx + c23 * my + c33 * mz
                bx = math.sqrt(hx * hx + hy * hy)
                bz = hz
                wx = c11 * bx + c13 * bz
                wy = c21 * bx + c23 * bz
                wz = c31 * bx + c33 * bz
                ex += my * wz - mz * wy
                ey += mz * wx - mx * wz
                ez += mx * wy - my * wx
        h = dt[k]
        ix += ki * h * ex
        iy += ki * h * ey
        iz += ki * h * ez
        gx = gyro[k, 0] * gyro_scale + kp * ex + ix
        gy = gyro[k, 1] * gyro_scale + kp * ey + iy
        gz = gyro[k, 2] * gyro_scale + kp * ez + iz
        ht = 0.5 * h
        r0 = q0_ + (-q1 * gx - q2 * gy - q3 * gz) * ht
        r1 = q1 + (q0_ * gx + q2 * gz - q3 * gy) * ht
        r2 = q2 + (q0_ * gy - q1 * gz + q3 * gx) * ht
        r3 = q3 + (q0_ * gz + q1 * gy - q2 * gx) * ht
        nr = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2 + r3 * r3)
        if not (nr > 0.0 and nr < math.inf):
            raise ValueError("gyro/acc/mag: the attitude update overflowed (inputs or gains "
                             "far out of range)")
        q0_, q1, q2, q3 = r0 / nr, r1 / nr, r2 / nr, r3 / nr
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = q0_, q1, q2, q3
    state[0], state[1], state[2], state[3] = q0_, q1, q2, q3
    state[4], state[5], state[6] = ix, iy, iz


@njit(cache=True)
def mahony_batch(gyro, acc, mag, dt, q0, kp, ki, gyro_scale, mag_sign, accel_sign, use_mag):
    """Run the seed-003 filter over a log; returns (N, 4) quaternions (of C_b^n).

    ``gyro``, ``acc``, ``mag``: (N, 3) float64; ``dt``: (N,) step into each sample (dt[0]
    is unused: Q[0] = q0, the attitude before the first update). Sample k >= 1 updates
    Q[k-1] with its own gyro/acc/mag and period dt[k]. A zero accelerometer (or
    magnetometer) vector skips that correction for the sample; ``use_mag`` False runs the
    accelerometer-only (IMU) variant. Same equations, same order as
    :class:`MahonyCircuitReference`; the loop is :func:`mahony_steps`.
    """
    n = gyro.shape[0]
    out = np.empty((n, 4))
    nq = math.sqrt(q0[0] * q0[0] + q0[1] * q0[1] + q0[2] * q0[2] + q0[3] * q0[3])
    state = np.zeros(7)
    for i in range(4):
        state[i] = q0[i] / nq
        out[0, i] = state[i]
    mahony_steps(gyro[1:], acc[1:], mag[1:], dt[1:], state, kp, ki, gyro_scale, mag_sign,
                 accel_sign, use_mag, out[1:])
    return out


def run_mahony(gyro, acc, mag=None, dt=None, *, t=None, params: MahonyParams = NED_SI,
               q0=None) -> np.ndarray:
    """Convenience wrapper around :func:`mahony_batch` (checks shapes, builds dt).

    Validates its arguments (ValueError naming the argument): finite (N, 3) gyro/acc/mag,
    finite strictly increasing ``t`` or a positive ``dt``, a unit ``q0``, and a stable gain:
    ``kp * dt < 2`` for every step (the error feedback of the Euler step multiplies the
    attitude error by about 1 - kp dt per sample)."""
    from navgate.nav import validate

    gyro = np.ascontiguousarray(validate.finite_array("gyro", gyro, (-1, 3)))
    n = gyro.shape[0]
    acc = np.ascontiguousarray(validate.finite_array("acc", acc, (n, 3)))
    use_mag = mag is not None
    mag = (np.ascontiguousarray(validate.finite_array("mag", mag, (n, 3))) if use_mag
           else np.zeros((n, 3)))
    if t is not None:
        t = validate.finite_array("t", t, (n,))
        dts = np.empty(n)
        dts[0] = 0.0
        dts[1:] = np.diff(t)
        if n > 1 and not (dts[1:] > 0).all():
            raise ValueError("t: time must strictly increase")
    else:
        dts = np.full(n, validate.positive("dt", params.dt if dt is None else dt))
    q_init = (np.array([1.0, 0.0, 0.0, 0.0]) if q0 is None
              else validate.unit_quaternion("q0", q0))
    if n > 1 and params.kp * float(np.max(dts[1:])) >= 2.0:
        raise ValueError(f"kp: kp * dt = {params.kp * float(np.max(dts[1:])):.3g} >= 2, the "
                         "discrete filter is unstable (lower kp)")
    return mahony_batch(gyro, acc, mag, dts, q_init, params.kp, params.ki, params.gyro_scale,
                        np.asarray(params.mag_sign, dtype=np.float64), params.accel_sign,
                        use_mag)
