"""The streaming navigator: record-by-record equals whole-stream, both engines behind the
PS/PL interface, the fp32 engine against the reference, the record log round trip and its
bad-record handling."""

import math

import numpy as np
import pytest

from navgate.nav.earth import LocalTangent
from navgate.systems.ins_trn.ps import flight
from navgate.systems.ins_trn.ps.flight import flight_stream
from navgate.systems.ins_trn.ps.navigator import Navigator, engine_setup, navigate
from navgate.systems.ins_trn.ps.pl_interface import make_engine
from navgate.systems.ins_trn.ps.records import (
    BARO,
    IMU,
    RANGER,
    LogError,
    read_log,
    write_log,
)
from navgate.trn.dem import Dem


@pytest.fixture(scope="module")
def short():
    dem = Dem.default()
    cfg = flight.FlightConfig(duration_s=40.0, seed=1)
    route = flight.plan_route(dem, cfg)
    data = flight.simulate_sensors(route, dem, cfg)
    init = flight.initial_estimate(data, cfg)
    return dem, cfg, data, flight_stream(data, dem, cfg, init)


def test_record_by_record_equals_whole_stream(short):
    dem, cfg, data, stream = short
    whole = navigate(stream, cfg, engine="reference", dem=dem, use_trn=True)
    nav = Navigator(make_engine("reference", engine_setup(stream.header, cfg)), cfg,
                    t0=stream.header["t0"], dem=dem, use_trn=True)
    for k, t, i in zip(stream.kind, stream.t, stream.index, strict=True):
        if k == IMU:
            payload = (stream.gyro_words[i], stream.accel_words[i])
        elif k == BARO:
            payload = (stream.baro_altitude[i], stream.baro_status[i] == 0)
        elif k == RANGER:
            payload = (stream.ranger_range[i], stream.ranger_status[i] == 0)
        else:
            continue
        nav.feed(k, float(t), payload)
    one = nav.finish()
    assert np.array_equal(one.nav, whole.nav) and np.array_equal(one.sigma, whole.sigma)
    assert one.accepted == whole.accepted and len(one.fixes) == len(whole.fixes)


def _feed_all(nav, stream):
    for k, t, i in zip(stream.kind, stream.t, stream.index, strict=True):
        if k == IMU:
            payload = (stream.gyro_words[i], stream.accel_words[i])
        elif k == BARO:
            payload = (stream.baro_altitude[i], stream.baro_status[i] == 0)
        elif k == RANGER:
            payload = (stream.ranger_range[i], stream.ranger_status[i] == 0)
        else:
            payload = ()
        nav.feed(k, float(t), payload)
    return nav.finish()


def test_stretches_with_a_fix_in_flight_and_bad_samples_equal_record_by_record(short):
    """The reference engine's stretches (Navigator.run -> run_records) against feed(): with
    a link latency (a stretch stops at the first record at or after a fix's time), invalid
    barometer samples, a non-finite IMU sample and truth records in the stream, the
    solution, the log and every count are the same bits."""
    import dataclasses

    dem, cfg, data, stream = short
    status = stream.baro_status.copy()
    status[5::17] = 1
    alt = stream.baro_altitude.copy()
    alt[9] = np.nan
    gw = stream.gyro_words.astype(float)
    gw[3000, 1] = np.nan
    bad = dataclasses.replace(stream, baro_status=status, baro_altitude=alt, gyro_words=gw)
    runs = []
    for whole in (True, False):
        nav = Navigator(make_engine("reference", engine_setup(bad.header, cfg)), cfg,
                        t0=bad.header["t0"], dem=dem, use_trn=True, trn_latency_s=1.3)
        runs.append(nav.run(bad) if whole else _feed_all(nav, bad))
    a, b = runs
    assert np.array_equal(a.nav, b.nav) and np.array_equal(a.sigma, b.sigma)
    assert np.array_equal(a.p_ne, b.p_ne) and np.array_equal(a.t, b.t)
    assert a.accepted == b.accepted and a.rejected == b.rejected
    assert a.rejected["baro invalid sample"] == np.count_nonzero(status) + 1
    assert a.imu_samples_rejected == b.imu_samples_rejected == 1
    assert [f["applied_at_s"] for f in a.fixes] == [f["applied_at_s"] for f in b.fixes]
    assert sum(f["applied"] for f in a.fixes) > 0
    assert all(f["applied_at_s"] >= f["time_s"] + 1.3 for f in a.fixes if f["applied"])


def test_fp32_engine_tracks_the_reference(short):
    """40 s INS+TRN: the float32 engine's position stays within a decimetre of the float64
    engine's (the float32 height/position quantum is 1e-4 m; the filter's 1-sigma is ~10 m)."""
    dem, cfg, data, stream = short
    ref = navigate(stream, cfg, engine="reference", dem=dem, use_trn=True)
    f32 = navigate(stream, cfg, engine="fp32", dem=dem, use_trn=True)
    d = flight.max_position_difference(dem, ref, f32)
    assert d < 0.1, d
    assert np.all(np.isfinite(f32.nav)) and np.all(np.isfinite(f32.sigma))
    # same filter decisions
    assert f32.accepted == ref.accepted and f32.rejected == ref.rejected
    assert [f["applied"] for f in f32.fixes] == [f["applied"] for f in ref.fixes]
    np.testing.assert_allclose(f32.sigma[-1, :9], ref.sigma[-1, :9], rtol=2e-3)


def test_fp32_position_is_ned_metres_about_the_reference_point(short):
    dem, cfg, data, stream = short
    eng = make_engine("fp32", engine_setup(stream.header, cfg))
    tan = LocalTangent(*dem.center, 0.0)
    nav0 = eng.read_nav()
    pn, pe = eng.read_position_ned()
    n_ref, e_ref = tan.to_ned(stream.header["initial"]["nav"][0],
                              stream.header["initial"]["nav"][1])
    # float32 registers: within half an ulp of the metre values
    assert abs(pn - n_ref) <= 2.0 ** (math.floor(math.log2(abs(n_ref) + 1)) - 24)
    assert abs(pe - e_ref) <= 2.0 ** (math.floor(math.log2(abs(e_ref) + 1)) - 24)
    lat, lon = tan.to_geodetic(pn, pe)
    assert nav0[0] == pytest.approx(float(lat), abs=1e-12)
    assert nav0[1] == pytest.approx(float(lon), abs=1e-12)


@pytest.mark.parametrize("engine", ["reference", "fp32"])
def test_log_round_trip_reproduces_the_run(short, tmp_path, engine):
    dem, cfg, data, stream = short
    path = tmp_path / "flight.log"
    write_log(stream, path)
    back = read_log(path)
    assert back.bad_records == {}
    assert np.array_equal(back.kind, stream.kind) and np.array_equal(back.t, stream.t)
    assert np.array_equal(back.gyro_words, stream.gyro_words)
    np.testing.assert_array_equal(back.baro_altitude, stream.baro_altitude)
    a = navigate(stream, cfg, engine=engine, dem=dem, use_trn=True)
    b = navigate(back, cfg, engine=engine, dem=dem, use_trn=True)
    assert np.array_equal(a.nav, b.nav) and np.array_equal(a.sigma, b.sigma)


def test_bad_records_are_counted_and_skipped(short, tmp_path):
    dem, cfg, data, stream = short
    path = tmp_path / "flight.log"
    write_log(stream, path)
    lines = path.read_text().splitlines()
    imu_lines = [i for i, ln in enumerate(lines) if ln.startswith("I,")]
    lines[imu_lines[100]] = lines[imu_lines[100]].rsplit(",", 2)[0]  # truncated
    lines[imu_lines[200]] = lines[imu_lines[200]].replace("I,", "I,nan,", 1).rsplit(",", 1)[0]
    t = lines[imu_lines[300]].split(",")
    lines[imu_lines[300]] = ",".join([t[0], "0.5", *t[2:]])  # time goes backwards
    t = lines[imu_lines[350]].split(",")
    lines[imu_lines[350]] = ",".join([t[0], "1e6", *t[2:]])  # one stamp far ahead
    lines[imu_lines[400]] = lines[imu_lines[400]].rsplit(",", 1)[0] + ",40000"  # not int16
    b_line = next(i for i, ln in enumerate(lines) if ln.startswith("B,"))
    lines[b_line] = lines[b_line].split(",")[0] + "," + lines[b_line].split(",")[1] + ",inf,0"
    lines.insert(5, "X,1,2,3")
    lines.append("I,1e9,1,2")  # a truncated last line
    path.write_text("\n".join(lines) + "\n")
    back = read_log(path)
    # resynchronised: each wrong stamp costs its own record only, not the rest of the log
    assert back.bad_records == {"truncated record": 2, "non-finite time": 1,
                                "time out of order": 2, "IMU word outside int16": 1,
                                "bad barometer sample": 1, "unknown record kind": 1}
    assert back.n_imu == stream.n_imu - 5
    assert back.records_read == len(stream) + 2  # the unknown kind and the truncated last line
    assert back.used_fraction == (len(stream) - 6) / (len(stream) + 2)
    run = navigate(back, cfg, engine="reference", dem=dem, use_trn=True)
    assert np.all(np.isfinite(run.nav))


def test_log_without_imu_records_is_an_error(tmp_path):
    path = tmp_path / "empty.log"
    path.write_text("navgate-records 1\nH {}\nB,1.0,100.0,0\n")
    with pytest.raises(LogError, match="no valid IMU record"):
        read_log(path)
    path.write_text("something else\n")
    with pytest.raises(LogError, match="not a navgate record log"):
        read_log(path)


def test_profile_attitude_equals_the_dcm_array_formula():
    """The navigator's scalar roll/pitch/yaw (one quaternion per ranger record) equals the
    formula on rotations.quat_to_dcm_array's elements bit for bit, including near +-90 deg
    pitch where the clip to [-1, 1] matters."""
    from navgate.nav.rotations import quat_to_dcm_array
    from navgate.systems.ins_trn.ps.navigator import _euler

    rng = np.random.default_rng(5)
    qs = rng.standard_normal((3000, 4))
    qs = np.concatenate([qs, [[1.0, 0.0, 1.0, 0.0], [1.0, 0.0, -1.0, 0.0]]])
    for q in qs / np.linalg.norm(qs, axis=1, keepdims=True):
        c = quat_to_dcm_array(q)
        want = (math.atan2(c[2, 1], c[2, 2]), -math.asin(max(-1.0, min(1.0, c[2, 0]))),
                math.atan2(c[1, 0], c[0, 0]))
        assert _euler(q) == want
