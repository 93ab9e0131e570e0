"""The GPS-denied flight end to end: issue targets on the default flight, error-free
sensors, DEM voids and flights off the map pausing TRN without stopping the INS."""

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import chi2

from navgate.systems.ins_trn.ps import flight
from navgate.trn.dem import Dem


@pytest.fixture(scope="module")
def dem():
    return Dem.default()


@pytest.fixture(scope="module")
def default_flight(dem):
    return flight.fly(dem, flight.FlightConfig())


def test_default_flight_meets_the_trn_targets(default_flight):
    s = default_flight.summary()
    trn, ins = s["trn_aided"], s["ins_only"]
    assert s["duration_s"] == 600.0 and s["imu_rate_hz"] == 400.0
    assert trn["rms_horizontal_error_second_half_m"] <= 30.0
    assert ins["final_horizontal_error_m"] >= 10.0 * trn["final_horizontal_error_m"]
    assert trn["fixes_accepted"] >= 30
    assert trn["fixes_accepted"] + trn["fixes_rejected"] == trn["fixes_attempted"]


def test_default_flight_figures_are_those_of_the_float64_loop(dem):
    """The streaming navigator with the reference engine reproduces the batch loop's
    figures (seed 0, TERCOM): INS-only final 406.8 m, TRN 2nd-half RMS 23.7 m, NEES 1.26,
    47/8 fixes."""
    s = flight.fly(dem, flight.FlightConfig(),
                   trn=flight.TrnSettings(method="tercom")).summary()
    assert s["engine"] == "reference" and s["trn_aided"]["trn_method"] == "tercom"
    assert round(s["ins_only"]["final_horizontal_error_m"], 1) == 406.8
    assert round(s["trn_aided"]["rms_horizontal_error_second_half_m"], 1) == 23.7
    assert round(s["trn_aided"]["nees_position_mean"], 2) == 1.26
    assert (s["trn_aided"]["fixes_accepted"], s["trn_aided"]["fixes_rejected"]) == (47, 8)


def test_default_flight_with_the_point_mass_filter(default_flight):
    """The default TRN (point-mass filter) on the default flight, seed 0: final 5.8 m,
    second-half RMS 12.5 m against TERCOM's 23.7 m, and never worse than INS alone."""
    s = default_flight.summary()
    assert s["trn_aided"]["trn_method"] == "pmf"
    assert round(s["trn_aided"]["rms_horizontal_error_second_half_m"], 1) == 12.5
    assert round(s["trn_aided"]["final_horizontal_error_m"], 1) == 5.8
    assert s["trn_aided"]["final_horizontal_error_m"] < s["ins_only"]["final_horizontal_error_m"]


def test_default_flight_position_nees_is_consistent_with_two_dof_chi_square(default_flight):
    """Mean NEES over the flight against chi-square(2).

    Errors at 10 Hz are strongly correlated; the TRN-aided error decorrelates within about a
    minute (the fix cycle plus the filter's response), so the 600 s flight holds about ten
    independent samples: the mean of ten chi-square(2) draws lies in chi2(20)/10 with 99 %
    probability between 0.74 and 4.0.
    """
    nees = default_flight.summary()["trn_aided"]["nees_position_mean"]
    lo, hi = chi2.ppf([0.005, 0.995], 20) / 10
    assert lo <= nees <= hi, (lo, nees, hi)
    ins = default_flight.summary()["ins_only"]["nees_position_mean"]
    assert lo <= ins <= hi


def test_both_runs_use_the_same_sensor_data(default_flight):
    runs = default_flight.runs
    assert np.array_equal(runs["ins_only"].nav[0], runs["trn_aided"].nav[0])
    assert runs["ins_only"].t.size == runs["trn_aided"].t.size == 6001


def test_error_free_sensors_ten_minute_flight_under_half_a_metre(dem):
    res = flight.fly(dem, flight.FlightConfig(ideal_sensors=True, trn=False))
    assert res.summary()["ins_only"]["final_horizontal_error_m"] < 0.5


def test_dem_void_under_the_route_pauses_trn_but_not_the_ins(dem):
    cfg = flight.FlightConfig(duration_s=240.0, seed=3)
    route = flight.plan_route(dem, cfg)
    holed = Dem(dem.heights.copy(), dem.lat_north, dem.lon_west, dem.dlat, dem.dlon, "holed")
    # a void 4 km wide across the first leg, 1-3 km north of the start
    i0 = int((dem.lat_north - route.lat0) / dem.dlat)
    j0 = int((route.lon0 - dem.lon_west) / dem.dlon)
    holed.heights[i0 - 35:i0 - 10, j0 - 25:j0 + 25] = np.nan
    data = flight.simulate_sensors(route, holed, cfg)
    assert np.mean(data.ranger.valid) < 0.95  # the ranger saw the hole as no-return
    init = flight.initial_estimate(data, cfg)
    run = flight.run_navigation(data, holed, cfg, init, use_trn=True, name="trn_aided")
    assert np.all(np.isfinite(run.nav)) and np.all(np.isfinite(run.sigma))
    assert run.profile_counts.get("ranger invalid", 0) > 50
    applied = [f for f in run.fixes if f["applied"]]
    assert applied, "TRN resumes after the void"
    err = flight.score(run, data.truth, 40).horizontal_error
    assert err[-1] < 60.0


def test_flight_off_the_map_pauses_trn(dem):
    cfg = flight.FlightConfig(duration_s=200.0, seed=2)
    route = flight.plan_route(dem, cfg)
    data = flight.simulate_sensors(route, dem, cfg)
    # the navigator only has the western third of the map: the route leaves it
    cols = dem.shape[1] // 3
    west = Dem(dem.heights[:, :cols].copy(), dem.lat_north, dem.lon_west, dem.dlat, dem.dlon,
               "west")
    init = flight.initial_estimate(data, cfg)
    run = flight.run_navigation(data, west, cfg, init, use_trn=True, name="trn_aided")
    reasons = {f["reason"] for f in run.fixes}
    assert "off map / DEM void" in reasons
    assert np.all(np.isfinite(run.nav))


def test_route_that_does_not_fit_is_refused(dem):
    small = Dem(dem.heights[:60, :60].copy(), dem.lat_north, dem.lon_west, dem.dlat, dem.dlon, "s")
    with pytest.raises(flight.RouteError, match="DEM too small"):
        flight.plan_route(small, flight.FlightConfig())


def test_bad_configuration_rejected():
    with pytest.raises(ValueError):
        flight.FlightConfig(duration_s=-1)
    with pytest.raises(ValueError):
        flight.FlightConfig(ranger="sonar")
    assert replace(flight.FlightConfig(), seed=4).seed == 4
    assert math.isclose(flight.FlightConfig().speed_mps, 60.0)


def test_flat_real_terrain_mostly_pauses_tercom(shared_data):
    """The shared Texas GeoTIFF is flat under the route: TERCOM must mostly decline to fix."""
    path = shared_data / "pysheds_dem.tif"
    if not path.exists():
        pytest.skip("pysheds_dem.tif not present")
    res = flight.fly(Dem.from_file(path), flight.FlightConfig(duration_s=300.0),
                     trn=flight.TrnSettings(method="tercom"))
    s = res.summary()["trn_aided"]
    reasons = s["fix_rejection_reasons"]
    correlated = s["fixes_attempted"] - reasons.get("too few samples", 0)
    assert reasons.get("flat terrain", 0) >= 0.75 * correlated
    assert s["fixes_accepted"] <= 3


def test_flat_real_terrain_pmf_never_worse_than_ins_only(shared_data):
    """Over the flat Texas GeoTIFF the point-mass filter takes only what the terrain gives:
    INS+TRN ends no worse than INS alone, with a covariance that covers the error."""
    path = shared_data / "pysheds_dem.tif"
    if not path.exists():
        pytest.skip("pysheds_dem.tif not present")
    res = flight.fly(Dem.from_file(path), flight.FlightConfig(duration_s=300.0, seed=1))
    s = res.summary()
    assert s["trn_aided"]["trn_method"] == "pmf"
    assert (s["trn_aided"]["final_horizontal_error_m"]
            <= s["ins_only"]["final_horizontal_error_m"])
    assert s["trn_aided"]["nees_position_mean"] < chi2.ppf(0.999, 2)


def test_the_scenario_config_holds_no_trn_settings():
    """The navigator's TRN settings are its own (trn_settings.TrnSettings), not the
    scenario's: FlightConfig has none of their fields and refuses them."""
    from dataclasses import fields

    from navgate.systems.ins_trn.ps.trn_settings import LEGACY_KEYS

    names = {f.name for f in fields(flight.FlightConfig)}
    assert not names & set(LEGACY_KEYS)
    with pytest.raises(TypeError):
        flight.FlightConfig(trn_method="tercom")
