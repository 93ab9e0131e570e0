"""Point-mass filter correlator: Bayesian consistency against truth drawn from its own prior,
the prior divided out of the fix, one fix per sample, and the rejections by reason."""

import math

import numpy as np
import pytest
from scipy.stats import chi2

from navgate.nav.earth import LocalTangent
from navgate.trn.correlators import METHODS, make_correlator
from navgate.trn.dem import Dem
from navgate.trn.pmf import PmfConfig, PointMassCorrelator
from navgate.trn.profile import ProfileSnapshot

#: the measurement model of the tests' profiles, told to the filter exactly
EXACT = PmfConfig(range_sigma_m=1.5, dem_sigma_m=0.0, velocity_sigma_mps=0.0)


@pytest.fixture(scope="module")
def dem():
    return Dem.default()


@pytest.fixture(scope="module")
def tangent(dem):
    return LocalTangent(*dem.center, 0.0)


def make_profile(dem, tangent, start, heading, offset, noise, rng, n=30, spacing=30.0, t0=0.0):
    """Heights along a true straight track (plus noise and a baro bias); INS positions = true
    positions - offset, i.e. the shift p_true - p_ins is ``offset``."""
    s = np.arange(n) * spacing
    true_n = start[0] + s * math.cos(heading)
    true_e = start[1] + s * math.sin(heading)
    h = dem.height(*tangent.to_geodetic(true_n, true_e)) + rng.standard_normal(n) * noise - 23.0
    return ProfileSnapshot(h, true_n - offset[0], true_e - offset[1], t0 + np.arange(n) * 0.5)


def mean_nees_band(k, p=0.999):
    return chi2.ppf((1 - p) / 2, 2 * k) / k, chi2.ppf((1 + p) / 2, 2 * k) / k


def test_posterior_and_fix_are_consistent_with_truth_drawn_from_the_prior(dem, tangent):
    """Shifts drawn from N(0, P): the posterior (mean, cov) and the prior-free fix (z, R) both
    have NEES ~ chi-square(2); their means over the trials lie in the 99.9 % band."""
    rng = np.random.default_rng(7)
    prior = np.array([[40.0**2, 300.0], [300.0, 25.0**2]])
    chol = np.linalg.cholesky(prior)
    post_nees, fix_nees = [], []
    for _ in range(40):
        offset = chol @ rng.standard_normal(2)
        prof = make_profile(dem, tangent, rng.uniform(-8000, 6000, 2), rng.uniform(0, 2 * np.pi),
                            offset, 1.5, rng)
        res = PointMassCorrelator(dem, tangent, EXACT).correlate(prof, 40.0, prior_cov=prior)
        if not res.accepted:
            assert res.reason in ("flat terrain", "multimodal"), res.reason
            continue
        e_post = np.array([res.posterior_mean_n, res.posterior_mean_e]) - offset
        post_nees.append(e_post @ np.linalg.solve(res.posterior_cov, e_post))
        e_fix = np.array([res.shift_n, res.shift_e]) - offset
        fix_nees.append(e_fix @ np.linalg.solve(res.cov, e_fix))
        # the fix refers to the mean sample time, the newest sample being "now"
        assert res.lag_s == pytest.approx(prof.time[-1] - prof.time.mean())
        assert res.fix_n == pytest.approx(np.mean(prof.pos_n) + res.shift_n)
    assert len(post_nees) >= 25
    lo, hi = mean_nees_band(len(post_nees))
    assert lo <= np.mean(post_nees) <= hi, (lo, np.mean(post_nees), hi)
    lo, hi = mean_nees_band(len(fix_nees))
    assert lo <= np.mean(fix_nees) <= hi, (lo, np.mean(fix_nees), hi)


def test_dividing_out_the_prior_gives_the_likelihood_information(dem, tangent):
    """R^-1 = P_post^-1 - P_prior^-1: the fix is looser than the posterior, and a wider prior
    leaves the fix (nearly) unchanged while it changes the posterior."""
    rng = np.random.default_rng(3)
    prof = make_profile(dem, tangent, (-2000.0, 1500.0), 0.7, (12.0, -9.0), 1.5, rng, n=40)
    fixes = []
    for sigma in (20.0, 60.0):
        res = PointMassCorrelator(dem, tangent, EXACT).correlate(
            prof, sigma, prior_cov=np.eye(2) * sigma**2)
        assert res.accepted, res.reason
        info = np.linalg.inv(res.posterior_cov) - np.eye(2) / sigma**2
        assert np.allclose(np.linalg.inv(res.cov), info, rtol=1e-6)
        assert np.all(np.linalg.eigvalsh(res.cov - res.posterior_cov) > 0)
        fixes.append(res)
    a, b = fixes
    sd = math.sqrt(np.linalg.eigvalsh(a.cov).max())
    assert math.hypot(a.shift_n - b.shift_n, a.shift_e - b.shift_e) < sd
    assert np.allclose(a.cov, b.cov, rtol=0.3)


def test_every_sample_informs_one_fix_only(dem, tangent):
    rng = np.random.default_rng(5)
    corr = PointMassCorrelator(dem, tangent, EXACT)
    prof = make_profile(dem, tangent, (1000.0, -3000.0), 0.2, (5.0, 5.0), 1.5, rng, n=40)
    first = corr.correlate(prof, 20.0)
    assert first.accepted and first.samples == 40
    again = corr.correlate(prof, 20.0)
    assert not again.accepted and again.reason == "too few samples" and again.samples == 0
    # 20 new samples continue the track: the next fix uses those only
    more = make_profile(dem, tangent, (1000.0 + 40 * 30 * math.cos(0.2),
                                       -3000.0 + 40 * 30 * math.sin(0.2)), 0.2, (5.0, 5.0),
                        1.5, rng, n=20, t0=20.0)
    both = ProfileSnapshot(*(np.concatenate([getattr(prof, k), getattr(more, k)])
                             for k in ("h_terrain", "pos_n", "pos_e", "time")))
    nxt = corr.correlate(both, 20.0)
    assert nxt.samples == 20


def test_flat_terrain_is_rejected(dem):
    flat = Dem(np.full((200, 200), 300.0) + np.random.default_rng(0).normal(0, 0.3, (200, 200)),
               dem.lat_north, dem.lon_west, dem.dlat, dem.dlon, name="flat")
    tangent = LocalTangent(*flat.center, 0.0)
    prof = make_profile(flat, tangent, (0.0, 0.0), 0.3, (20.0, -10.0), 0.5,
                        np.random.default_rng(1))
    res = PointMassCorrelator(flat, tangent).correlate(prof, 50.0)
    assert not res.accepted and res.reason == "flat terrain"
    assert res.info_ratio > PmfConfig().max_info_ratio or res.roughness_m < 3.0


def test_profile_that_the_dem_cannot_explain_is_flagged(dem, tangent):
    """Heights from far outside the search window: no shift fits, so no fix (divergence cue)."""
    rng = np.random.default_rng(2)
    prof = make_profile(dem, tangent, (-6000.0, -6000.0), 1.0, (0.0, 0.0), 1.5, rng, n=40)
    wrong = ProfileSnapshot(prof.h_terrain, prof.pos_n + 7000.0, prof.pos_e + 9000.0, prof.time)
    res = PointMassCorrelator(dem, tangent, EXACT).correlate(wrong, 20.0)
    assert not res.accepted
    assert res.reason == "profile inconsistent with DEM"
    assert res.chi2_per_dof > 4.0 * chi2.ppf(0.999, 37) / 37


def test_off_map_and_short_profiles(dem, tangent):
    rng = np.random.default_rng(0)
    corr = PointMassCorrelator(dem, tangent)
    prof = make_profile(dem, tangent, (0.0, 0.0), 0.0, (0.0, 0.0), 1.0, rng, n=10)
    assert corr.correlate(prof, 20.0).reason == "too few samples"
    far = ProfileSnapshot(np.full(30, 400.0), 60000.0 + np.arange(30) * 30.0, np.zeros(30),
                          np.arange(30) * 0.5)
    assert corr.correlate(far, 20.0).reason == "off map / DEM void"
    with pytest.raises(ValueError):
        corr.correlate(make_profile(dem, tangent, (0.0, 0.0), 0.0, (0.0, 0.0), 1.0, rng),
                       math.nan)


def test_registered_and_widened_after_reinitialisation(dem, tangent):
    assert "pmf" in METHODS
    corr = make_correlator("pmf", dem, tangent)
    assert isinstance(corr, PointMassCorrelator)
    prof = make_profile(dem, tangent, (0.0, 0.0), 0.0, (0.0, 0.0), 1.0,
                        np.random.default_rng(0), n=20)
    narrow = corr.correlate(prof, 30.0).half_width_m
    corr.used_until = -math.inf
    corr.reinitialise(3.0)
    wide = corr.correlate(prof, 30.0).half_width_m
    assert wide > 2.5 * narrow - 3 * PmfConfig().margin_m
