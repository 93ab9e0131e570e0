"""Attitude from an IMU log: the engine behind ``navgate ahrs``.

Body axes. navgate works in NED with FRD body axes, where a level accelerometer reads
(0, 0, -g). Many loggers (x-io's among them) use z-up sensor axes that read (0, 0, +g) when
flat; ``axes="flu"`` maps such a log to FRD first (x, -y, -z for gyro, accelerometer and
magnetometer alike: a 180 deg turn about x), ``axes="frd"`` takes it as is. ``axes="auto"``
picks "flu" for x-io style headers and "frd" otherwise.

Filters: ``mahony`` is seed 003's algorithm (:mod:`navgate.systems.attitude.mahony`) run in NED with
SI inputs (``accel_sign = -1``, no magnetometer sign flip, gyro already in rad/s);
``complementary`` is :mod:`navgate.systems.attitude.complementary`. Both start from the
accelerometer/magnetometer attitude of the first sample (``init="accel"``) or from identity.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from navgate.nav.rotations import dcm_to_euler_array, quat_to_dcm_array
from navgate.sim.imu_log import ImuLog, nominal_period
from navgate.systems.attitude.complementary import accel_mag_quat, complementary_steps
from navgate.systems.attitude.mahony import NED_SI, mahony_steps

FLU_TO_FRD = np.array([1.0, -1.0, -1.0])


@dataclass
class AttitudeResult:
    t: np.ndarray
    q: np.ndarray  #: (N, 4) quaternion of C_b^n (NED, FRD)
    roll_deg: np.ndarray
    pitch_deg: np.ndarray
    yaw_deg: np.ndarray  #: (-180, 180], from magnetic north when a magnetometer was used
    axes: str
    used_mag: bool
    gaps: int = 0  #: filter restarts at time gaps


def resolve_axes(log: ImuLog, axes: str) -> str:
    if axes == "auto":
        return "flu" if log.style == "x-io" else "frd"
    if axes not in ("frd", "flu"):
        raise ValueError(f"axes must be auto, frd or flu, got {axes!r}")
    return axes


#: the shortest sample period a log may have (100 kHz, the fastest rate the log reader takes
#: for an IMU, above the 32 kHz of the fastest MEMS output data rates): a picosecond step
#: integrates nothing and leaves the filter at its first attitude
MIN_SAMPLE_PERIOD_S = 1e-5

#: the proportional gain's bound, kp * T < 1 (the CLI's rule): each step removes the fraction
#: kp T of the attitude error; at kp T >= 1 the correction overshoots every sample
KP_DT_MAX = 1.0


def check_run(*, method: str, dt: float, kp: float, ki: float, gain: float = 0.02,
              acc0=None, use_mag: bool = True) -> None:
    """The one validation of a log and of the gains that every ``ahrs`` engine (the float64
    reference, the float32 circuit model, its gateware) runs before filtering, so that the
    circuit engines refuse what the reference refuses. ValueError naming the argument:

    * ``dt`` (the log's nominal sample period, s): finite, >= :data:`MIN_SAMPLE_PERIOD_S`;
    * ``kp``, ``ki``: finite and >= 0, and the discrete loop stable. Linearised, a small
      attitude error theta gives the error vector e = M theta, M = sum over the reference
      vectors used (accelerometer, magnetometer) of (I - v v'), whose eigenvalues c lie in
      [0, 2] (in [0, 1] with the accelerometer alone). Per eigen-direction the Euler step
      (i += ki T e; w = kp e + i; theta -= T w) is [theta, i]' <- [[1 - c kp T - c ki T^2,
      -T], [c ki T, 1]] [theta, i]', stable iff (Jury) c kp T < 2 and
      c ki T^2 < 4 - 2 c kp T; both tighten as c grows, so c = 2 (1 without a magnetometer)
      is the bound: with a magnetometer kp T < 1 (the CLI's rule) and ki T^2 < 2 (1 - kp T)
      (``--ki 1e5`` at 100 Hz: ki T^2 = 10, unstable); without one, kp T < 1 still
      (:data:`KP_DT_MAX`) and ki T^2 < 4 - 2 kp T;
    * ``gain`` (complementary): in [0, 1];
    * ``acc0`` (the first sample's specific force): not zero; the filters level on it.
    """
    from navgate.nav import validate

    dt = validate.finite_scalar("dt", dt)
    if not dt >= MIN_SAMPLE_PERIOD_S:
        raise ValueError(f"dt: the log's sample period is {dt:g} s, below "
                         f"{MIN_SAMPLE_PERIOD_S:g} s ({1 / MIN_SAMPLE_PERIOD_S:.0f} Hz); "
                         "timestamps must be in seconds")
    if method == "mahony":
        kp = validate.non_negative("kp", kp)
        ki = validate.non_negative("ki", ki)
        if not kp * dt < KP_DT_MAX:
            raise ValueError(f"kp: {kp:g} with a {dt:g} s sample period gives kp * dt = "
                             f"{kp * dt:.3g}; the discrete filter needs kp * dt < {KP_DT_MAX:g}"
                             f" (here kp < {KP_DT_MAX / dt:.4g})")
        c = 2.0 if use_mag else 1.0
        ki_max = (4.0 - 2.0 * c * kp * dt) / (c * dt * dt)
        if not ki < ki_max:
            raise ValueError(f"ki: {ki:g} with kp {kp:g} and a {dt:g} s sample period makes "
                             f"the integral loop unstable (here ki < {ki_max:.4g}; see "
                             "navgate.systems.attitude.estimate.check_run)")
    elif method == "complementary":
        if not 0.0 <= validate.finite_scalar("gain", gain) <= 1.0:
            raise ValueError(f"gain: complementary gain must be in [0, 1], got {gain}")
    else:
        raise ValueError(f"method: unknown filter {method!r} (mahony or complementary)")
    if acc0 is not None:
        a = validate.finite_array("acc", acc0, (3,))
        if not float(a @ a) > 0.0:
            raise ValueError("acc: the first sample's specific force is zero; cannot level "
                             "on a zero specific force")


#: a step longer than this many nominal sample periods is a gap: the filter restarts
GAP_PERIODS = 5.0


def gap_steps(t) -> np.ndarray:
    """The time steps of ``t`` longer than :data:`GAP_PERIODS` nominal periods
    (:func:`navgate.sim.imu_log.nominal_period`): the gaps at which the reference filter
    restarts, and which a fixed-rate circuit runs through and counts."""
    from navgate.sim.imu_log import nominal_period

    steps = np.diff(np.asarray(t, dtype=np.float64))
    nominal = nominal_period(t)
    return steps[steps > GAP_PERIODS * nominal] if math.isfinite(nominal) else steps[:0]


class AttitudeStream:
    """Run an attitude filter over a log delivered in blocks, carrying the filter state, so
    that any split of the log gives the same bits as the whole log in one call.

    A time step longer than ``gap_s`` restarts the filter at the sample after the gap (from
    that sample's accelerometer/magnetometer attitude with ``init="accel"``, identity
    otherwise; Mahony's integral term zeroed), instead of integrating the gyro across it;
    ``gaps`` counts the restarts. ``mag`` blocks may be None (no magnetometer).
    """

    def __init__(self, method: str = "mahony", *, axes: str = "frd", kp: float = NED_SI.kp,
                 ki: float = NED_SI.ki, gain: float = 0.02, use_mag: bool = True,
                 init: str = "accel", gap_s: float = math.inf):
        from navgate.nav import validate

        if method not in ("mahony", "complementary"):
            raise ValueError(f"method: unknown filter {method!r} (mahony or complementary)")
        if axes not in ("frd", "flu"):
            raise ValueError(f"axes: must be frd or flu, got {axes!r}")
        if init not in ("accel", "identity"):
            raise ValueError(f"init: must be accel or identity, got {init!r}")
        if method == "complementary" and not 0.0 <= gain <= 1.0:
            raise ValueError(f"gain: complementary gain must be in [0, 1], got {gain}")
        self.method, self.axes, self.init, self.use_mag = method, axes, init, use_mag
        self.params = replace(NED_SI, kp=validate.non_negative("kp", kp),
                              ki=validate.non_negative("ki", ki))
        self.gain = gain
        self.gap_s = validate.positive("gap_s", gap_s) if math.isfinite(gap_s) else math.inf
        if method == "mahony" and math.isfinite(self.gap_s) and self.params.kp * self.gap_s >= 2:
            raise ValueError(f"kp: kp * dt can reach {self.params.kp * self.gap_s:.3g} >= 2 "
                             "(unstable discrete filter); lower kp")
        self.state = np.zeros(7)
        self.last_t = None
        self.gaps = 0
        self.used_mag = False

    def _start(self, acc, mag) -> None:
        if self.init == "accel":
            q0 = accel_mag_quat(acc, mag)
        else:
            q0 = np.array([1.0, 0.0, 0.0, 0.0])
        nq = math.sqrt(q0[0] * q0[0] + q0[1] * q0[1] + q0[2] * q0[2] + q0[3] * q0[3])
        self.state[:] = 0.0
        for i in range(4):
            self.state[i] = q0[i] / nq

    def update(self, t, gyro, acc, mag=None) -> np.ndarray:
        """Quaternions (N, 4) of C_b^n after each sample of the block.

        ``t`` (N,) finite and strictly increasing (also across blocks), ``gyro``/``acc``/
        ``mag`` finite (N, 3): checked once per block (ValueError naming the argument), as the
        compiled steps index [k, 0..2] without bounds checks."""
        from navgate.nav import validate

        t = validate.finite_array("t", t, (-1,))
        n = t.size
        gyro = validate.finite_array("gyro", gyro, (n, 3))
        acc = validate.finite_array("acc", acc, (n, 3))
        if mag is not None:
            mag = validate.finite_array("mag", mag, (n, 3))
        if n and ((n > 1 and not np.all(np.diff(t) > 0))
                  or (self.last_t is not None and not t[0] > self.last_t)):
            raise ValueError("t: time must strictly increase")
        s = FLU_TO_FRD if self.axes == "flu" else np.ones(3)
        gyro = np.ascontiguousarray(gyro * s)
        acc = np.ascontiguousarray(acc * s)
        use_mag = self.use_mag and mag is not None
        m = np.ascontiguousarray(mag * s) if use_mag else np.zeros_like(gyro)
        self.used_mag = self.used_mag or use_mag
        n = t.size
        out = np.empty((n, 4))
        if n == 0:
            return out
        prev = self.last_t
        dts = np.empty(n)
        dts[0] = math.inf if prev is None else t[0] - prev
        dts[1:] = np.diff(t)
        restart = dts > self.gap_s
        restart[0] = restart[0] or prev is None
        starts = np.flatnonzero(restart)
        self.gaps += starts.size - (1 if prev is None else 0)
        bounds = [0, *starts.tolist(), n]
        pieces = [(bounds[i], bounds[i + 1]) for i in range(len(bounds) - 1)
                  if bounds[i + 1] > bounds[i]]
        p = self.params
        for lo, hi in pieces:
            first = lo
            if restart[lo]:
                self._start(acc[lo], m[lo] if use_mag else None)
                out[lo] = self.state[:4]
                first = lo + 1
            if hi > first:
                if self.method == "mahony":
                    mahony_steps(gyro[first:hi], acc[first:hi], m[first:hi], dts[first:hi],
                                 self.state, p.kp, p.ki, p.gyro_scale,
                                 np.asarray(p.mag_sign, dtype=np.float64), p.accel_sign,
                                 use_mag, out[first:hi])
                else:
                    q = self.state[:4].copy()
                    complementary_steps(gyro[first:hi], acc[first:hi], m[first:hi],
                                        dts[first:hi], q, self.gain, use_mag, out[first:hi])
                    self.state[:4] = q
        self.last_t = float(t[-1])
        return out


def euler_deg(q):
    """(roll, pitch, yaw) in degrees of quaternions (N, 4)."""
    roll, pitch, yaw = dcm_to_euler_array(quat_to_dcm_array(q))
    return np.degrees(roll), np.degrees(pitch), np.degrees(yaw)


def estimate_attitude(log: ImuLog, method: str = "mahony", *, axes: str = "auto",
                      kp: float = NED_SI.kp, ki: float = NED_SI.ki, gain: float = 0.02,
                      use_mag: bool = True, init: str = "accel",
                      gap_periods: float | None = GAP_PERIODS) -> AttitudeResult:
    """The whole log in one call (same result as :class:`AttitudeStream` over any blocks).
    ``gap_periods`` x the nominal period (:func:`navgate.sim.imu_log.nominal_period`) is the
    gap that restarts the filter; None never restarts."""
    axes = resolve_axes(log, axes)
    gap = (math.inf if gap_periods is None
           else gap_periods * nominal_period(log.t))
    stream = AttitudeStream(method, axes=axes, kp=kp, ki=ki, gain=gain, use_mag=use_mag,
                            init=init, gap_s=gap if math.isfinite(gap) else math.inf)
    if len(log.t) > 1:  # the checks every engine shares (check_run)
        check_run(method=method, dt=nominal_period(log.t), kp=kp, ki=ki, gain=gain,
                  acc0=log.acc[0] if init == "accel" else None,
                  use_mag=use_mag and log.mag is not None)
    q = stream.update(log.t, log.gyro, log.acc, log.mag if use_mag else None)
    roll, pitch, yaw = euler_deg(q)
    res = AttitudeResult(log.t, q, roll, pitch, yaw, axes, stream.used_mag)
    res.gaps = stream.gaps
    return res
