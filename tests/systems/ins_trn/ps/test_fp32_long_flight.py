"""A one-hour INS + TRN flight with the float32 engine: P positive definite at every IMU
sample and after every update (Cholesky of the stored upper triangle, which makes P
symmetric by construction), no NaN. Slow: run with ``-m slow``."""

import numpy as np
import pytest

from navgate.systems.ins_trn.ps import flight
from navgate.systems.ins_trn.ps.fp32_engine import Fp32Engine
from navgate.systems.ins_trn.ps.navigator import Navigator, engine_setup
from navgate.trn.dem import Dem


@pytest.mark.slow
def test_one_hour_fp32_flight_keeps_p_positive_definite():
    dem = Dem.default()
    cfg = flight.FlightConfig(duration_s=3600.0)
    route = flight.plan_route(dem, cfg)
    data = flight.simulate_sensors(route, dem, cfg)
    init = flight.initial_estimate(data, cfg)
    stream = flight.flight_stream(data, dem, cfg, init)
    eng = Fp32Engine(engine_setup(stream.header, cfg), check_pd=True)
    run = Navigator(eng, cfg, t0=stream.header["t0"], dem=dem, use_trn=True).run(stream)
    assert eng.samples == 3600 * 400
    assert eng.pd_stats.tolist() == [0, 0]
    assert np.all(np.isfinite(run.nav)) and np.all(np.isfinite(run.sigma))
    applied = sum(f["applied"] for f in run.fixes)
    assert applied >= 100
    err = flight.score(run, data.truth, 40).horizontal_error
    assert np.sqrt(np.mean(err[len(err) // 2:] ** 2)) < 60.0
