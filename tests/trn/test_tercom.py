"""TERCOM correlator on the real embedded DEM: recovers a known offset within its own
covariance, and refuses flat, ambiguous and off-map cases with the right reason."""

import math

import numpy as np
import pytest

from navgate.nav.earth import LocalTangent
from navgate.trn.dem import Dem
from navgate.trn.profile import ProfileSnapshot
from navgate.trn.tercom import TercomConfig, TercomCorrelator


@pytest.fixture(scope="module")
def dem():
    return Dem.default()


def make_profile(dem, tangent, start_n, start_e, heading, offset, noise, rng, n=64, spacing=30.0):
    """Terrain heights measured along a true straight track; INS positions offset by ``offset``."""
    s = np.arange(n) * spacing
    true_n = start_n + s * math.cos(heading)
    true_e = start_e + s * math.sin(heading)
    lat, lon = tangent.to_geodetic(true_n, true_e)
    h = dem.height(lat, lon) + rng.standard_normal(n) * noise + 37.0  # plus a baro bias
    return ProfileSnapshot(h, true_n + offset[0], true_e + offset[1], np.arange(n) * 0.5)


def test_recovers_known_offset_within_reported_covariance(dem):
    tangent = LocalTangent(*dem.center, 0.0)
    corr = TercomCorrelator(dem, tangent)
    rng = np.random.default_rng(4)
    nees = []
    for _trial in range(12):
        start = rng.uniform(-8000, 6000, 2)
        offset = rng.uniform(-150, 150, 2)
        prof = make_profile(dem, tangent, *start, rng.uniform(0, 2 * math.pi), offset, 2.0, rng)
        res = corr.correlate(prof, sigma_max_m=80.0)
        if not res.accepted:
            assert res.reason in ("ambiguous", "flat terrain")
            continue
        err = np.array([res.shift_n + offset[0], res.shift_e + offset[1]])
        nees.append(err @ np.linalg.solve(res.cov, err))
        assert np.hypot(*err) < 30.0
        assert res.lag_s == pytest.approx(31.5 - 15.75)  # newest minus mean sample time
    assert len(nees) >= 8
    # chi-square(2) per accepted trial; the mean over >= 8 trials stays below its 99.9 % point
    # for 2k dof divided by k (about 2.9 for k = 8): an overconfident covariance would not
    assert np.mean(nees) < 2.9


def test_flat_terrain_is_rejected(dem):
    flat = Dem(np.full((200, 200), 300.0) + np.random.default_rng(0).normal(0, 0.3, (200, 200)),
               dem.lat_north, dem.lon_west, dem.dlat, dem.dlon, name="flat")
    tangent = LocalTangent(*flat.center, 0.0)
    prof = make_profile(flat, tangent, 0.0, 0.0, 0.3, (20.0, -10.0), 0.5, np.random.default_rng(1))
    res = TercomCorrelator(flat, tangent).correlate(prof, 50.0)
    assert not res.accepted and res.reason in ("flat terrain", "ambiguous")


def test_periodic_terrain_is_ambiguous(dem):
    i = np.arange(300)
    # ridges every 8 posts running north-south: a track along a ridge matches every ridge
    ridges = 100.0 * np.sin(2 * math.pi * i / 8.0)[None, :] + 0.0 * i[:, None]
    rough = ridges + np.random.default_rng(2).normal(0, 0.5, (300, 300)) + 400.0
    d = Dem(rough, dem.lat_north, dem.lon_west, dem.dlat, dem.dlon, name="ridges")
    tangent = LocalTangent(*d.center, 0.0)
    prof = make_profile(d, tangent, -1000.0, 0.0, 0.02, (0.0, 0.0), 0.5, np.random.default_rng(3))
    res = TercomCorrelator(d, tangent, TercomConfig(max_half_width_m=1500)).correlate(prof, 300.0)
    assert not res.accepted and res.reason in ("ambiguous", "flat terrain")


def test_off_map_pauses_trn_and_short_profiles_wait(dem):
    tangent = LocalTangent(*dem.center, 0.0)
    corr = TercomCorrelator(dem, tangent)
    rng = np.random.default_rng(5)
    prof = make_profile(dem, tangent, 0.0, 0.0, 0.0, (0.0, 0.0), 1.0, rng)
    far = ProfileSnapshot(prof.h_terrain, prof.pos_n + 60_000.0, prof.pos_e, prof.time)
    assert corr.correlate(far, 50.0).reason == "off map / DEM void"
    short = ProfileSnapshot(prof.h_terrain[:10], prof.pos_n[:10], prof.pos_e[:10], prof.time[:10])
    assert corr.correlate(short, 50.0).reason == "too few samples"
    with pytest.raises(ValueError):
        corr.correlate(prof, math.nan)
