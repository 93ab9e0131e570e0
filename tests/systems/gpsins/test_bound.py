"""Seed 002 covariance bound (navgate.systems.gpsins.bound): the discretisation against closed
forms, the filter recursion against the information form and the discrete Riccati equation, and
what the bound says about the one-third RMS target for the Table-1 and tactical IMUs."""

import math

import numpy as np
import pytest
from scipy.linalg import solve_discrete_are

from navgate.systems.gpsins import bound, scenario


def test_van_loan_matches_the_double_integrator_closed_form():
    """p' = v, v' = w (density q): Phi = [[1, h], [0, 1]], Qd = q [[h^3/3, h^2/2],
    [h^2/2, h]] (Brown and Hwang, random-walk velocity); exact up to rounding."""
    F = np.array([[0.0, 1.0], [0.0, 0.0]])
    q, h = 0.37, 0.8
    phi, qd = bound.discretise(F, np.diag([0.0, q]), h)
    np.testing.assert_allclose(phi, [[1.0, h], [0.0, 1.0]], atol=1e-14)
    np.testing.assert_allclose(qd, q * np.array([[h**3 / 3, h**2 / 2], [h**2 / 2, h]]),
                               rtol=1e-12)


def test_static_position_averages_like_the_information_form():
    """No process noise, velocity and tilt known: after N fixes the position variance is
    1 / (1 / s0^2 + N / R) exactly (information form); the outage adds no fixes."""
    s0, r = 5.0, 20.0
    b = bound.flight_bound(0.0, 0.0, gps_sigma=r, duration_s=100.0, outage_start_s=40.0,
                           outage_s=30.0, p0=(s0, 0.0, 0.0))
    for t_s in (1, 10, 39, 55, 70, 100):
        n = t_s if t_s < 40 else (39 if t_s < 70 else t_s - 30)
        k = int(round(t_s / 0.1)) - 1
        assert b.position_var[k] == pytest.approx(1.0 / (1.0 / s0**2 + n / r**2), rel=1e-9)


def test_steady_state_solves_the_discrete_riccati_equation():
    """Long flight, no outage: the position variance just after a fix converges to the
    a-posteriori solution of the 1 s DARE of the same model (Table-1 gyro noise)."""
    qg, qa = 0.015 * math.pi / 180, 1e-3
    b = bound.flight_bound(qg, qa, duration_s=2000.0, outage_s=0.0)
    F, Qc = bound.channel_model(qg, qa)
    phi, qd = bound.discretise(F, Qc, 1.0)
    H = np.array([[1.0, 0.0, 0.0]])
    pm = solve_discrete_are(phi.T, H.T, qd, np.array([[400.0]]))
    pp = pm[0, 0] - pm[0, 0] ** 2 / (pm[0, 0] + 400.0)
    assert b.position_var[-1] == pytest.approx(pp, rel=1e-6)


def test_table1_gyro_cannot_reach_one_third_with_any_filter():
    """The Table-1 reading's gyro (0.015 deg/s/sqrt(Hz) white, 0.003 deg/s drift) bounds the
    whole-flight ratio of the optimal filter above 1/3 (0.40), even with a bias state the
    9-state filter does not have; the ADXRS652's data-sheet noise (about 0.06) gives 0.60.
    The tactical IMU's bound is below 1/3 (0.27); an error-free IMU's is the GPS averaging
    with the outage alone (0.23)."""
    cfg = scenario.GpsInsConfig()
    assert scenario.optimal_bound(cfg).ratio_to_gps_only > 1 / 3
    assert scenario.optimal_bound(scenario.with_gyro_noise(cfg, 0.06)).ratio_to_gps_only > 0.5
    assert scenario.optimal_bound(scenario.tactical_config(cfg)).ratio_to_gps_only < 1 / 3
    ideal = scenario.optimal_bound(scenario.ideal_config(cfg)).ratio_to_gps_only
    assert ideal < scenario.optimal_bound(scenario.tactical_config(cfg)).ratio_to_gps_only


def test_bad_input_is_rejected():
    with pytest.raises(ValueError):
        bound.flight_bound(-1.0)
    with pytest.raises(ValueError):
        bound.flight_bound(1e-4, gps_sigma=0.0)
