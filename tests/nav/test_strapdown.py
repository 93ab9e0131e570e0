"""Strapdown mechanization: physics bars (stationary drift, error-free dynamic flight) and the
trajectory simulator's IMU readings against independent analytic values."""

import math

import numpy as np
import pytest

from navgate.nav import earth, strapdown
from navgate.nav.rotations import euler_to_dcm, euler_to_quat
from navgate.sim import trajectory as tr

LAT0 = math.radians(36.6)
LON0 = math.radians(-84.2)
RATE = 400.0


def test_stationary_one_hour_drift_below_one_millimetre():
    """The pyins bar: an hour at rest with exact readings drifts under 1 mm.

    Readings are built here from first principles, not by the simulator: the gyro sees only
    the Earth rate, the accelerometer minus gravity.
    """
    roll, pitch, yaw = 0.02, -0.01, 1.1
    h = 250.0
    c_bn = euler_to_dcm(roll, pitch, yaw)
    gyro = c_bn.T @ (earth.OMEGA_IE * np.array([math.cos(LAT0), 0.0, -math.sin(LAT0)]))
    accel = c_bn.T @ np.array([0.0, 0.0, -earth.gravity(LAT0, h)])
    n = int(3600 * RATE)
    nav0 = strapdown.make_nav_state(LAT0, LON0, h, np.zeros(3), euler_to_quat(roll, pitch, yaw))
    final = strapdown.integrate_final(nav0, np.tile(gyro, (n, 1)), np.tile(accel, (n, 1)), 1 / RATE)
    rn, re = earth.radii(LAT0)
    drift = math.sqrt(((final[0] - LAT0) * rn) ** 2 + ((final[1] - LON0) * re * math.cos(LAT0)) ** 2
                      + (final[2] - h) ** 2)
    assert drift < 1e-3
    assert np.abs(final[3:6]).max() < 1e-6


def test_simulator_stationary_readings_are_earth_rate_and_gravity():
    traj = tr.stationary(lat0=LAT0, lon0=LON0, h0=100.0, duration_s=1.0, roll=0.1, pitch=0.05,
                         yaw=-2.0)
    gyro, accel = traj.imu()
    c_bn = euler_to_dcm(0.1, 0.05, -2.0)
    w = c_bn.T @ (earth.OMEGA_IE * np.array([math.cos(LAT0), 0.0, -math.sin(LAT0)]))
    f = c_bn.T @ np.array([0.0, 0.0, -earth.gravity(LAT0, 100.0)])
    # exact up to rounding: the readings are constant over an interval at rest
    assert np.allclose(gyro, w, atol=1e-13)
    assert np.allclose(accel, f, atol=1e-11)
    assert math.isclose(np.linalg.norm(gyro[0]) * 180 / math.pi * 3600, 15.041, abs_tol=1e-3)


def _segments():
    return [tr.straight(40), tr.turn(90, 3), tr.climb(150, 5), tr.speed_change(75, 40),
            tr.turn(-135, 4), tr.straight(30), tr.climb(-100, 4), tr.turn(45, 2)]


def test_error_free_ten_minute_dynamic_flight_reproduces_truth():
    traj = tr.generate(_segments(), lat0=LAT0, lon0=LON0, h0=1200.0, heading0=0.4, speed0=60.0,
                       rate_hz=RATE, duration_s=600.0)
    gyro, accel = traj.imu()
    states = strapdown.integrate(traj.states[0], gyro, accel, traj.dt)
    rn, re = earth.radii(traj.lat[-1])
    north = (states[-1, 0] - traj.lat[-1]) * rn
    east = (states[-1, 1] - traj.lon[-1]) * re * math.cos(traj.lat[-1])
    assert math.hypot(north, east) < 0.5  # issue target; measured ~1e-7 m
    assert np.abs(states[:, 3:6] - traj.v_ned).max() < 1e-6
    # the flight really is dynamic
    assert np.degrees(np.abs(traj.roll)).max() > 15
    assert np.ptp(traj.h) > 140


def test_simulator_readings_in_steady_coordinated_turn_match_analytic_kinematics():
    """Independent of the inverse mechanization: Euler-rate kinematics plus Earth/transport rate."""
    rate = math.radians(3.0)
    speed = 60.0
    traj = tr.generate([tr.straight(5), tr.turn(360, 3.0, ramp_s=3.0)], lat0=LAT0, lon0=LON0,
                       h0=1000.0, heading0=0.0, speed0=speed, rate_hz=RATE, duration_s=60.0)
    gyro, accel = traj.imu()
    k = int(40 * RATE)  # well inside the steady part of the turn
    roll, yaw = traj.roll[k], traj.yaw[k]
    assert math.isclose(math.tan(roll), speed * rate / earth.gravity(traj.lat[k], traj.h[k]),
                        rel_tol=1e-9)
    c_bn = euler_to_dcm(roll, 0.0, yaw)
    lat, h, v = traj.lat[k], traj.h[k], traj.v_ned[k]
    w_ie = earth.earth_rate_ned(lat)
    w_en = earth.transport_rate_ned(lat, h, v)
    # ZYX Euler kinematics with constant roll, zero pitch: w_nb^b = yaw_rate [0, sin r, cos r]
    w_nb_b = rate * np.array([0.0, math.sin(roll), math.cos(roll)])
    expected_gyro = w_nb_b + c_bn.T @ (w_ie + w_en)
    # specific force: a_n - g_n + (2 w_ie + w_en) x v, with a_n = yaw_rate x v (horizontal)
    a_n = np.cross([0.0, 0.0, rate], v)
    g_n = np.array([0.0, 0.0, earth.gravity(lat, h)])
    expected_accel = c_bn.T @ (a_n - g_n + np.cross(2 * w_ie + w_en, v))
    # interval averages vs mid-interval values: differences are O(dt^2 * second derivative)
    # of rates that change by the Earth/transport terms only: bounded far below 1e-7
    mid = 0.5 * (gyro[k - 1] + gyro[k])
    assert np.allclose(mid, expected_gyro, atol=2e-8)
    assert np.allclose(0.5 * (accel[k - 1] + accel[k]), expected_accel, atol=2e-5)
    # and the classic result for a coordinated turn: specific force along body z, g / cos(roll),
    # up to the Coriolis and transport terms |(2 w_ie + w_en) x v| <= (2 Omega + V/R) V
    coriolis = (2 * earth.OMEGA_IE + speed / earth.A) * speed
    assert abs(accel[k, 1]) < coriolis and abs(accel[k, 0]) < coriolis
    assert abs(-accel[k, 2] - g_n[2] / math.cos(roll)) < coriolis


def test_bad_segments_rejected():
    with pytest.raises(ValueError):
        tr.Segment(-1.0)
    with pytest.raises(ValueError):
        tr.turn(90, 0.0)
    with pytest.raises(ValueError):
        tr.generate([], lat0=0, lon0=0, h0=0, heading0=0, speed0=50)
