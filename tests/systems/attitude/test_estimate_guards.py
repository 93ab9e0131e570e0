"""The attitude engines' one validation (estimate.check_run): the float64 reference
(estimate_attitude, and the CLI's streamed AttitudeStream) and the seed-003 circuit engines
(circuit_inputs, which fp32 and rtl share) refuse the same logs and gains with a ValueError
naming the argument: a picosecond sample period, a zero first specific force, kp * T >= 1,
an integral gain that makes the discrete loop unstable (Jury's test)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navgate.sim.imu_log import ImuLog
from navgate.systems.attitude.circuit_engine import circuit_inputs
from navgate.systems.attitude.estimate import (
    KP_DT_MAX,
    MIN_SAMPLE_PERIOD_S,
    AttitudeStream,
    check_run,
    estimate_attitude,
    euler_deg,
)

G0 = 9.80665
NAN = float("nan")


def log(n=200, dt=0.01, acc=(0.0, 0.0, -G0), t=None):
    tt = np.arange(n) * dt if t is None else t
    return ImuLog(tt, np.zeros((n, 3)), np.tile(acc, (n, 1)), np.tile([0.45, 0.0, 0.9], (n, 1)),
                  "plain", 0, {})


def raises_naming(name, fn, *args, **kwargs):
    with pytest.raises(ValueError) as info:
        fn(*args, **kwargs)
    assert str(info.value).startswith(name), str(info.value)
    return str(info.value)


def reference(lg, **kw):
    return estimate_attitude(lg, "mahony", axes="frd", **kw)


def circuit(lg, kp=1.0, ki=0.1):
    return circuit_inputs(lg, "frd", kp, ki)


ENGINES = {"reference": reference, "circuit": circuit}
BAD = {
    "picosecond step": ("dt", {"dt": 1e-12}, {}),
    "zero accelerometer": ("acc", {"acc": (0.0, 0.0, 0.0)}, {}),
    "kp 1e6": ("kp", {}, {"kp": 1e6}),
    "ki 1e5": ("ki", {}, {"ki": 1e5}),
    "negative ki": ("ki", {}, {"ki": -0.1}),
}


@pytest.mark.parametrize("engine", list(ENGINES))
@pytest.mark.parametrize("case", list(BAD), ids=list(BAD))
def test_every_engine_refuses_the_same(engine, case):
    name, log_kw, gains = BAD[case]
    raises_naming(name, ENGINES[engine], log(**log_kw), **gains)


def test_jury_bound_of_the_linearised_loop():
    """The bound is where the 2 x 2 error recursion of check_run's docstring (gain c = 2 with
    a magnetometer, 1 without) gets an eigenvalue outside the unit circle (kp = 1, T = 0.01)."""
    kp, dt = 1.0, 0.01
    for c, use_mag in ((2.0, True), (1.0, False)):
        limit = (4.0 - 2.0 * c * kp * dt) / (c * dt * dt)
        for ki, grows in ((0.99 * limit, False), (1.01 * limit, True)):
            a = np.array([[1 - c * kp * dt - c * ki * dt * dt, -dt], [c * ki * dt, 1.0]])
            assert (max(abs(np.linalg.eigvals(a))) > 1.0) == grows
        check_run(method="mahony", dt=dt, kp=kp, ki=0.99 * limit, use_mag=use_mag)
        raises_naming("ki", check_run, method="mahony", dt=dt, kp=kp, ki=1.01 * limit,
                      use_mag=use_mag)


@pytest.mark.parametrize("kp", [1.0, 20.0])
def test_the_bound_separates_level_from_divergent_runs(kp):
    """The filter itself (not its linearisation) on a level, still log with 1e-3 rad/s gyro
    noise, 30 s at 100 Hz: at 0.9 x the ki bound roll/pitch/yaw stay within 0.1 deg; at
    1.1 x (which check_run refuses) the error grows past 1 deg, as ki = 1e5 did before the check
    (roll -77 deg)."""
    dt = 0.01
    limit = (4.0 - 4.0 * kp * dt) / (2.0 * dt * dt)
    worst = {}
    for f in (0.9, 1.1):
        lg = log(n=3000)
        lg.gyro = np.random.default_rng(0).normal(0.0, 1e-3, (3000, 3))
        q = AttitudeStream("mahony", axes="frd", kp=kp, ki=f * limit).update(
            lg.t, lg.gyro, lg.acc, lg.mag)
        worst[f] = max(float(np.abs(a[-200:]).max()) for a in euler_deg(q))
    assert worst[0.9] < 0.1 and worst[1.1] > 1.0, worst
    raises_naming("ki", reference, log(), kp=kp, ki=1.1 * limit)


def test_bounds_at_their_edges():
    check_run(method="mahony", dt=MIN_SAMPLE_PERIOD_S, kp=1.0, ki=0.1)
    raises_naming("dt", check_run, method="mahony", dt=0.99 * MIN_SAMPLE_PERIOD_S, kp=1, ki=0)
    raises_naming("dt", check_run, method="mahony", dt=NAN, kp=1, ki=0)
    raises_naming("kp", check_run, method="mahony", dt=0.01, kp=KP_DT_MAX / 0.01, ki=0)
    raises_naming("gain", check_run, method="complementary", dt=0.01, kp=0, ki=0, gain=1.5)
    raises_naming("method", check_run, method="kalman", dt=0.01, kp=0, ki=0)


@pytest.mark.parametrize("name, kwargs", [
    ("t", {"t": [0.0, 0.01, 0.01]}),
    ("t", {"t": [0.0, NAN, 0.02]}),
    ("gyro", {"gyro": np.zeros((3, 2))}),  # read [k, 2] out of bounds before
    ("acc", {"acc": np.zeros((2, 3))}),
    ("mag", {"mag": np.full((3, 3), math.inf)}),
])
def test_attitude_stream_update_checks_its_block(name, kwargs):
    args = {"t": [0.0, 0.01, 0.02], "gyro": np.zeros((3, 3)),
            "acc": np.tile([0.0, 0.0, -G0], (3, 1)), "mag": None, **kwargs}
    raises_naming(name, AttitudeStream("mahony").update, **args)


def test_attitude_stream_time_must_advance_across_blocks():
    s = AttitudeStream("mahony")
    s.update([0.0, 0.01], np.zeros((2, 3)), np.tile([0.0, 0.0, -G0], (2, 1)))
    raises_naming("t", s.update, [0.01, 0.02], np.zeros((2, 3)), np.tile([0.0, 0.0, -G0], (2, 1)))
