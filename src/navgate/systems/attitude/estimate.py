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

from dataclasses import dataclass, replace

import numpy as np

from navgate.nav.rotations import dcm_to_euler_array, quat_to_dcm_array
from navgate.sim.imu_log import ImuLog
from navgate.systems.attitude.complementary import accel_mag_quat, run_complementary
from navgate.systems.attitude.mahony import NED_SI, run_mahony

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


def resolve_axes(log: ImuLog, axes: str) -> str:
    if axes == "auto":
        return "flu" if log.style == "x-io" else "frd"
    if axes not in ("frd", "flu"):
        raise ValueError(f"axes must be auto, frd or flu, got {axes!r}")
    return axes


def estimate_attitude(log: ImuLog, method: str = "mahony", *, axes: str = "auto",
                      kp: float = NED_SI.kp, ki: float = NED_SI.ki, gain: float = 0.02,
                      use_mag: bool = True, init: str = "accel") -> AttitudeResult:
    axes = resolve_axes(log, axes)
    s = FLU_TO_FRD if axes == "flu" else np.ones(3)
    gyro, acc = log.gyro * s, log.acc * s
    mag = log.mag * s if (use_mag and log.mag is not None) else None
    if init == "accel":
        q0 = accel_mag_quat(acc[0], None if mag is None else mag[0])
    elif init == "identity":
        q0 = np.array([1.0, 0.0, 0.0, 0.0])
    else:
        raise ValueError(f"init must be accel or identity, got {init!r}")
    if method == "mahony":
        params = replace(NED_SI, kp=kp, ki=ki)
        q = run_mahony(gyro, acc, mag, t=log.t, params=params, q0=q0)
    elif method == "complementary":
        q = run_complementary(gyro, acc, mag, t=log.t, alpha=gain, q0=q0)
    else:
        raise ValueError(f"unknown filter {method!r} (mahony or complementary)")
    roll, pitch, yaw = dcm_to_euler_array(quat_to_dcm_array(q))
    return AttitudeResult(log.t, q, np.degrees(roll), np.degrees(pitch), np.degrees(yaw), axes,
                          mag is not None)
