"""Segment-based flight trajectories: truth at the IMU rate and IMU readings consistent with it.

A flight is a list of :class:`Segment` s; each holds its commanded turn rate, vertical
speed and airspeed (= ground speed: no wind), reached from the previous segment's values
through a smooth (quintic "smootherstep") transition of ``ramp_s`` seconds, so rates and
accelerations stay continuous and the gyro never sees a step. Builders :func:`straight`,
:func:`turn`, :func:`climb` and :func:`speed_change` make segments from pilot-style numbers.

Kinematics (flat-Earth flight dynamics on the curved Earth, no wind):

- heading psi = psi0 + integral of the turn rate; vertical speed vz; flight-path angle
  gamma = asin(vz / V); NED velocity V [cos gamma cos psi, cos gamma sin psi, -sin gamma];
- attitude of a coordinated turn: roll = atan(V psi_dot / g), pitch = gamma + alpha
  (constant angle of attack ``alpha``), yaw = psi (ZYX Euler);
- positions from velocities with the mechanization's own trapezoidal update
  (navgate.nav.strapdown.integrate_position).

IMU readings come from :func:`navgate.nav.strapdown.imu_from_states`, the exact inverse of
one mechanization step, so error-free readings run through the mechanization reproduce the
truth to rounding. They include the Earth rate (a stationary gyro reads
Omega_ie [cos lat, 0, -sin lat] in NED) and the transport rate; tests check them against
independent analytic values (stationary, level flight, steady coordinated turns).

Reference: Groves (2013) sec. 5.4; pyins' trajectory simulator (nmayorov/pyins, sim.py) for
the inverse-strapdown idea.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from navgate.nav import strapdown
from navgate.nav.earth import gravity_array
from navgate.nav.rotations import dcm_to_quat_array, euler_to_dcm_array

STANDARD_GRAVITY = 9.80665


@dataclass(frozen=True)
class Segment:
    """One flight segment: commanded values held for ``duration_s`` after a smooth ramp."""

    duration_s: float
    turn_rate: float = 0.0  #: rad/s, positive = right turn (heading increasing)
    vertical_speed: float = 0.0  #: m/s, positive = climbing
    speed: float | None = None  #: m/s; None keeps the previous segment's speed
    ramp_s: float = 3.0  #: transition time from the previous segment's commands
    label: str = ""

    def __post_init__(self):
        if not (self.duration_s > 0 and math.isfinite(self.duration_s)):
            raise ValueError(f"segment duration must be positive, got {self.duration_s}")
        if self.ramp_s < 0:
            raise ValueError("segment ramp must be non-negative")
        if self.speed is not None and not self.speed > 0:
            raise ValueError(f"segment speed must be positive, got {self.speed}")


def straight(duration_s: float, *, speed: float | None = None, label: str = "straight") -> Segment:
    """Straight and level for ``duration_s`` (optionally changing speed during the ramp)."""
    return Segment(duration_s, speed=speed, label=label)


def turn(angle_deg: float, rate_dps: float = 3.0, *, ramp_s: float = 3.0,
         label: str = "") -> Segment:
    """Coordinated level turn through ``angle_deg`` (positive right) at ``rate_dps``.

    With smootherstep ramps in and out, the heading change of a segment of duration D with
    ramp r (followed by a ramp out of the same length) is rate * D exactly: the ramp-in
    deficit equals the ramp-out surplus. So D = angle / rate.
    """
    if rate_dps <= 0:
        raise ValueError("turn rate must be positive")
    rate = math.radians(abs(rate_dps)) * (1.0 if angle_deg >= 0 else -1.0)
    duration = abs(angle_deg) / abs(rate_dps)
    return Segment(duration, turn_rate=rate, ramp_s=ramp_s,
                   label=label or f"turn {angle_deg:+.0f} deg")


def climb(delta_h_m: float, rate_mps: float = 5.0, *, ramp_s: float = 3.0,
          label: str = "") -> Segment:
    """Straight climb (positive) or descent (negative) of ``delta_h_m`` at ``rate_mps``."""
    if rate_mps <= 0:
        raise ValueError("climb rate must be positive")
    vz = abs(rate_mps) * (1.0 if delta_h_m >= 0 else -1.0)
    return Segment(abs(delta_h_m) / abs(rate_mps), vertical_speed=vz, ramp_s=ramp_s,
                   label=label or f"climb {delta_h_m:+.0f} m")


def speed_change(new_speed: float, duration_s: float, *, ramp_s: float = 10.0,
                 label: str = "") -> Segment:
    """Straight, level, accelerating smoothly to ``new_speed`` over ``ramp_s``."""
    return Segment(duration_s, speed=new_speed, ramp_s=ramp_s,
                   label=label or f"speed {new_speed:.0f} m/s")


def _smootherstep(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (x * (6.0 * x - 15.0) + 10.0)


def command_profiles(segments, t, speed0):
    """Turn rate, vertical speed and speed commanded at times ``t`` (s)."""
    turn_rate = np.zeros_like(t)
    vz = np.zeros_like(t)
    speed = np.full_like(t, float(speed0))
    start = 0.0
    prev = (0.0, 0.0, float(speed0))
    for seg in segments:
        new = (seg.turn_rate, seg.vertical_speed, prev[2] if seg.speed is None else seg.speed)
        mask = t >= start
        ramp = _smootherstep((t[mask] - start) / seg.ramp_s) if seg.ramp_s > 0 else 1.0
        turn_rate[mask] = prev[0] + (new[0] - prev[0]) * ramp
        vz[mask] = prev[1] + (new[1] - prev[1]) * ramp
        speed[mask] = prev[2] + (new[2] - prev[2]) * ramp
        prev = new
        start += seg.duration_s
    # after the last segment: ease back to straight and level at the last speed
    mask = t >= start
    ramp = _smootherstep((t[mask] - start) / 3.0)
    turn_rate[mask] = prev[0] * (1.0 - ramp)
    vz[mask] = prev[1] * (1.0 - ramp)
    return turn_rate, vz, speed


@dataclass
class Trajectory:
    """Truth at the IMU rate: times, geodetic position, NED velocity, attitude."""

    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    v_ned: np.ndarray
    q: np.ndarray  #: (N, 4) Hamilton C_b^n
    roll: np.ndarray
    pitch: np.ndarray
    yaw: np.ndarray
    rate_hz: float
    labels: list = field(default_factory=list)

    @property
    def dt(self) -> float:
        return 1.0 / self.rate_hz

    @property
    def states(self) -> np.ndarray:
        """(N, 10) navigation states [lat, lon, h, vN, vE, vD, q0..q3]."""
        return np.column_stack([self.lat, self.lon, self.h, self.v_ned, self.q])

    def imu(self):
        """Error-free interval-average (gyro rad/s, accel m/s^2) readings, (N-1, 3) each.

        Reading k covers the interval [t_k, t_{k+1}].
        """
        return strapdown.imu_from_states(np.ascontiguousarray(self.states), self.dt)

    def __len__(self) -> int:
        return len(self.t)


def generate(segments, *, lat0: float, lon0: float, h0: float, heading0: float,
             speed0: float, rate_hz: float = 400.0, duration_s: float | None = None,
             alpha: float = 0.0) -> Trajectory:
    """Fly ``segments`` from the given start (angles in rad) and sample truth at ``rate_hz``.

    ``duration_s`` defaults to the sum of segment durations; if longer, the segment list is
    repeated (a circuit); if shorter, the flight is cut.
    """
    from navgate.nav import validate

    if not segments:
        raise ValueError("a trajectory needs at least one segment")
    validate.latitude_rad("lat0", lat0)
    if not (rate_hz > 0 and speed0 > 0):
        raise ValueError("rate and initial speed must be positive")
    total = sum(s.duration_s for s in segments)
    duration = total if duration_s is None else float(duration_s)
    if not duration > 0:
        raise ValueError("duration must be positive")
    repeats = max(1, math.ceil(duration / total))
    segs = list(segments) * repeats
    n = int(round(duration * rate_hz)) + 1
    t = np.arange(n) / rate_hz
    turn_rate, vz, speed = command_profiles(segs, t, speed0)
    dt = 1.0 / rate_hz
    increments = 0.5 * (turn_rate[1:] + turn_rate[:-1]) * dt
    heading = heading0 + np.concatenate([[0.0], np.cumsum(increments)])
    gamma = np.arcsin(np.clip(vz / speed, -1.0, 1.0))
    v_ned = np.column_stack([
        speed * np.cos(gamma) * np.cos(heading),
        speed * np.cos(gamma) * np.sin(heading),
        -speed * np.sin(gamma),
    ])
    lat, lon, h = strapdown.integrate_position(lat0, lon0, h0, v_ned, dt)
    g = gravity_array(lat, h)
    roll = np.arctan(speed * turn_rate / g)
    pitch = gamma + alpha
    yaw = np.angle(np.exp(1j * heading))
    q = dcm_to_quat_array(euler_to_dcm_array(roll, pitch, yaw))
    # keep the quaternion sign continuous (q and -q are the same attitude)
    flips = np.concatenate([[False], np.sum(q[1:] * q[:-1], axis=1) < 0])
    sign = np.where(np.cumsum(flips) % 2 == 1, -1.0, 1.0)
    q = q * sign[:, None]
    labels = []
    start = 0.0
    for s in segs:
        if start >= duration:
            break
        labels.append((start, s.label))
        start += s.duration_s
    return Trajectory(t, lat, lon, h, v_ned, q, roll, pitch, yaw, float(rate_hz), labels)


def stationary(*, lat0: float, lon0: float, h0: float, duration_s: float, rate_hz: float = 400.0,
               roll: float = 0.0, pitch: float = 0.0, yaw: float = 0.0) -> Trajectory:
    """A vehicle at rest on the Earth for ``duration_s`` (attitude fixed relative to NED)."""
    n = int(round(duration_s * rate_hz)) + 1
    t = np.arange(n) / rate_hz
    c = euler_to_dcm_array(np.full(n, roll), np.full(n, pitch), np.full(n, yaw))
    q = dcm_to_quat_array(c[:1]).repeat(n, axis=0)
    return Trajectory(t, np.full(n, lat0), np.full(n, lon0), np.full(n, float(h0)),
                      np.zeros((n, 3)), q, np.full(n, roll), np.full(n, pitch), np.full(n, yaw),
                      float(rate_hz), [(0.0, "stationary")])
