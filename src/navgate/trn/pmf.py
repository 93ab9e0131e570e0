"""Point-mass filter (PMF) terrain-referenced navigation: the whole position likelihood on a
grid instead of one correlation peak.

Reference: Bergman, Ljung & Gustafsson, "Point-mass filter and Cramer-Rao bound for
terrain-aided navigation" (CDC 1997) and "Terrain navigation using Bayesian statistics"
(IEEE Control Systems 19(3), 1999); the same Bayesian grid is behind SITAN's successors and
MBARI's AUV terrain-relative navigation. This module is the batch form of the filter (the
form the processor side of seed 000 runs on a profile snapshot, documented in docs/trn.md):

- State: the horizontal INS position error at the mean time of the profile segment,
  expressed as the shift ``s = p_true - p_ins`` (north, east, metres), on a regular grid.
  The grid's half-width is ``k_sigma`` times the largest prior standard deviation plus a
  margin (the prior is the filter's 2 x 2 position covariance), its step a fraction of the
  DEM post and of the prior sigma; when the posterior is narrower than two steps the grid
  is rebuilt around it with a finer step.
- Motion: the INS positions stored in the profile carry the vehicle's motion between the
  samples; the INS error drift over the segment is the motion uncertainty, a random term of
  standard deviation ``velocity_sigma_mps * |t_i - t_mean|`` per sample, which enters the
  measurement noise through the terrain gradient (below).
- Measurement, every ranger sample of the segment (h_i = h_baro - AGL):
  ``h_i = DEM(p_i + s) + b + v_i`` with an unknown common offset b (barometric bias, DEM
  datum), marginalised with a flat prior, and
  ``var(v_i) = range_sigma^2 + dem_sigma^2 + |grad DEM(p_i + s)|^2 sigma_rel_i^2``.
  The log-likelihood of a shift is then
  ``-1/2 [sum w_i r_i^2 - (sum w_i r_i)^2 / sum w_i + sum log var_i + log sum w_i]``
  with ``r_i = h_i - DEM(p_i + s)`` and ``w_i = 1 / var_i``.
- Posterior = likelihood x Gaussian prior N(0, P_prior), normalised over the grid; the fix is
  its mean and covariance (moment matching, plus the grid quantisation step^2/12): the
  covariance is the honest second moment even when the posterior has several modes.
- The filter already holds the prior, so the fix handed to it is the posterior with the prior
  divided out (information form): ``R^-1 = P_post^-1 - P_prior^-1``, ``z = R P_post^-1 m``.
  Directions in which the terrain gave no information get a large variance (a 1-D fix across
  a ridge is a fix too).
- Segments do not overlap: every ranger sample informs one fix only (samples used by an
  accepted fix are not used again), so successive fixes have independent errors and the
  filter can take them at face value. Samples of an attempt that produced no fix stay and
  the next attempt uses a longer segment.

Integrity checks, each rejection with its reason:

- "too few samples" / "track too short": the fresh segment is not long enough yet;
- "off map / DEM void": fewer than ``min_valid_fraction`` of the grid has terrain;
- "profile inconsistent with DEM": even the best shift leaves a normalised residual
  ``chi2_min`` above ``max_noise_scale^2`` times the chi-square(n - 3)
  ``consistency_probability`` quantile: the true position is outside the window
  (divergence) or the DEM does not describe the terrain. (Residuals up to
  ``max_noise_scale`` times the modelled noise are a noise-model mismatch, handled by the
  tempering below, not a divergence: a terrain mismatch leaves residuals of the terrain's
  own relief, far larger);
- "multimodal": the posterior has more than ``max_tail_mass`` of its mass beyond the
  3-sigma ellipse of its own moments, i.e. separated modes a Gaussian fix cannot carry;
- "flat terrain": the terrain added too little information: the fix's best standard
  deviation is above ``max_info_ratio`` times the prior's (or the DEM heights along the
  track vary by less than ``min_roughness_m``).

When the residuals exceed the model (chi2_min / (n - 3) > 1) the log-likelihood is divided
by that ratio (the noise scaled to the residuals, as in the TERCOM covariance), which keeps
the fix honest over a DEM with errors larger than ``dem_sigma_m``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from navgate.nav.earth import LocalTangent
from navgate.trn.dem import Dem, bilinear_at, window_around
from navgate.trn.profile import ProfileSnapshot
from navgate.trn.tercom import TercomResult


@njit(cache=True)
def pmf_loglik(heights, row0, col0, nrow, ncol, lat_north, lon_west, dlat, dlon, lat0, lon0,
               m_lat, m_lon, h_meas, pos_n, pos_e, var_base, rel_var, shifts_n, shifts_e,
               grad_step):
    """Log-likelihood and chi-square of every (shift_n, shift_e) on the grid.

    The common offset is marginalised (flat prior); the per-sample variance adds the terrain
    gradient at the shifted point times ``rel_var``. NaN where any sample is off the map.
    """
    nn = shifts_n.shape[0]
    ne = shifts_e.shape[0]
    m = h_meas.shape[0]
    loglik = np.empty((nn, ne))
    chi2 = np.empty((nn, ne))
    for a in range(nn):
        for b in range(ne):
            sw = 0.0
            swr = 0.0
            swr2 = 0.0
            slog = 0.0
            bad = False
            for i in range(m):
                n = pos_n[i] + shifts_n[a]
                e = pos_e[i] + shifts_e[b]
                lat = lat0 + n / m_lat
                lon = lon0 + e / m_lon
                t = bilinear_at(heights, row0, col0, nrow, ncol, lat_north, lon_west, dlat,
                                dlon, lat, lon)
                if not math.isfinite(t):
                    bad = True
                    break
                var = var_base[i]
                if rel_var[i] > 0.0:
                    tn1 = bilinear_at(heights, row0, col0, nrow, ncol, lat_north, lon_west,
                                      dlat, dlon, lat + grad_step / m_lat, lon)
                    tn0 = bilinear_at(heights, row0, col0, nrow, ncol, lat_north, lon_west,
                                      dlat, dlon, lat - grad_step / m_lat, lon)
                    te1 = bilinear_at(heights, row0, col0, nrow, ncol, lat_north, lon_west,
                                      dlat, dlon, lat, lon + grad_step / m_lon)
                    te0 = bilinear_at(heights, row0, col0, nrow, ncol, lat_north, lon_west,
                                      dlat, dlon, lat, lon - grad_step / m_lon)
                    if math.isfinite(tn1) and math.isfinite(tn0) and math.isfinite(te1) \
                            and math.isfinite(te0):
                        gn = (tn1 - tn0) / (2.0 * grad_step)
                        ge = (te1 - te0) / (2.0 * grad_step)
                        var += (gn * gn + ge * ge) * rel_var[i]
                w = 1.0 / var
                r = h_meas[i] - t
                sw += w
                swr += w * r
                swr2 += w * r * r
                slog += math.log(var)
            if bad:
                loglik[a, b] = math.nan
                chi2[a, b] = math.nan
            else:
                c2 = swr2 - swr * swr / sw
                chi2[a, b] = c2
                loglik[a, b] = -0.5 * (c2 + slog + math.log(sw))
    return loglik, chi2


@dataclass(frozen=True)
class PmfConfig:
    min_samples: int = 15
    min_track_m: float = 400.0
    k_sigma: float = 4.0
    margin_m: float = 60.0
    min_half_width_m: float = 150.0
    max_half_width_m: float = 3000.0
    max_cells: int = 161  #: grid points per axis at most (the step grows to fit)
    grid_step_m: float | None = None  #: coarse step; default: a quarter of the DEM post
    refine_cells: int = 41  #: grid points per axis of the refined grid
    range_sigma_m: float = 3.0  #: ranger + barometer noise (long-range ranger at 1 km AGL)
    dem_sigma_m: float = 1.0  #: DEM height error (raise for real DEMs: SRTM ~5-10 m)
    velocity_sigma_mps: float = 0.3  #: INS velocity error over a segment (motion noise)
    consistency_probability: float = 0.999
    max_noise_scale: float = 2.0  #: residuals up to this x the model noise: tempered
    max_tail_mass: float = 0.05
    max_info_ratio: float = 0.7  #: fix sigma must be below this times the prior sigma
    min_roughness_m: float = 3.0
    min_valid_fraction: float = 0.5
    reuse_samples: bool = False  #: True: every attempt uses the whole snapshot (overlapping)

    def __post_init__(self):
        from navgate.nav import validate

        # n - 3 degrees of freedom (offset and 2-D shift) need at least 4 samples
        validate.positive_int("min_samples", self.min_samples, minimum=4)
        for name in ("min_track_m", "margin_m", "dem_sigma_m", "velocity_sigma_mps",
                     "min_roughness_m"):
            validate.non_negative(name, getattr(self, name))
        for name in ("k_sigma", "min_half_width_m", "max_half_width_m", "max_noise_scale",
                     "max_info_ratio"):
            validate.positive(name, getattr(self, name))
        # the likelihood weighs every sample by 1 / (range_sigma^2 + dem_sigma^2 + ...)
        validate.positive("range_sigma_m", self.range_sigma_m)
        if self.grid_step_m is not None:
            validate.positive("grid_step_m", self.grid_step_m)
        validate.positive_int("max_cells", self.max_cells, minimum=3)
        validate.positive_int("refine_cells", self.refine_cells, minimum=3)
        validate.probability("consistency_probability", self.consistency_probability)
        validate.probability("max_tail_mass", self.max_tail_mass, open_high=False)
        validate.probability("min_valid_fraction", self.min_valid_fraction, open_low=False,
                             open_high=False)
        if self.max_half_width_m < self.min_half_width_m:
            raise ValueError("max_half_width_m: must be at least min_half_width_m")


@dataclass
class PmfResult(TercomResult):
    chi2_per_dof: float = math.nan
    tail_mass: float = math.nan
    info_ratio: float = math.nan
    posterior_mean_n: float = math.nan
    posterior_mean_e: float = math.nan
    posterior_cov: np.ndarray = field(default_factory=lambda: np.full((2, 2), np.nan))

    def as_row(self) -> dict:
        row = super().as_row()
        row.update({"chi2_per_dof": self.chi2_per_dof, "tail_mass": self.tail_mass,
                    "info_ratio": self.info_ratio})
        return row


class PointMassCorrelator:
    """Batch point-mass filter over the fresh part of a profile snapshot (module docstring)."""

    def __init__(self, dem: Dem, tangent: LocalTangent, config: PmfConfig = PmfConfig()):
        self.dem = dem
        self.tangent = tangent
        self.config = config
        sn, se = dem.post_spacing_m()
        self.post_m = min(sn, se)
        self.step = config.grid_step_m or self.post_m / 4.0
        self.used_until = -math.inf  #: samples up to this time informed an accepted fix
        self.widen = 1.0  #: search window factor (> 1 after a reinitialisation)

    # -- the interface the navigation loop and the integrity monitor use -------------------
    def reinitialise(self, widen: float = 3.0):
        """Divergence: search a wider window next time (and forget nothing else)."""
        self.widen = max(self.widen, widen)

    def _grid(self, profile, var_base, rel_var, centre, half, cells_step):
        d, t = self.dem, self.tangent
        steps = int(math.ceil(half / cells_step))
        g = np.arange(-steps, steps + 1) * cells_step
        gn = centre[0] + g
        ge = centre[1] + g
        pad = max(abs(centre[0]), abs(centre[1])) + half + cells_step + self.post_m
        window = window_around(d, t, profile.pos_n, profile.pos_e, pad)
        ll, c2 = pmf_loglik(*window.kernel_args(),
                            t.lat0, t.lon0, t.m_per_rad_lat, t.m_per_rad_lon,
                            np.ascontiguousarray(profile.h_terrain),
                            np.ascontiguousarray(profile.pos_n),
                            np.ascontiguousarray(profile.pos_e), var_base, rel_var, gn, ge,
                            0.5 * self.post_m)
        return gn, ge, ll, c2

    @staticmethod
    def _moments(gn, ge, logpost):
        finite = np.isfinite(logpost)
        lp = np.where(finite, logpost, -np.inf)
        w = np.exp(lp - lp.max())
        w /= w.sum()
        mn = float(np.sum(w.sum(axis=1) * gn))
        me = float(np.sum(w.sum(axis=0) * ge))
        dn = (gn - mn)[:, None]
        de = (ge - me)[None, :]
        cov = np.array([[np.sum(w * dn * dn), np.sum(w * dn * de)],
                        [np.sum(w * dn * de), np.sum(w * de * de)]])
        return w, np.array([mn, me]), cov

    def correlate(self, snapshot: ProfileSnapshot, sigma_max_m: float,
                  prior_cov=None) -> PmfResult:
        """Fix from the fresh part of ``snapshot`` (finite times, positions and heights),
        the window from ``sigma_max_m`` (finite, >= 0) or from ``prior_cov`` (its 2 x 2
        position block must be a finite symmetric positive semi-definite covariance)."""
        from navgate.nav import validate

        for name in ("time", "pos_n", "pos_e", "h_terrain"):
            validate.finite_array(f"snapshot.{name}", getattr(snapshot, name))
        validate.non_negative("sigma_max_m", sigma_max_m)
        if prior_cov is not None:
            pc = np.asarray(prior_cov, float)
            if pc.ndim != 2 or pc.shape[0] < 2 or pc.shape[1] < 2:
                raise ValueError(f"prior_cov: expected a covariance of at least 2 x 2, got "
                                 f"shape {pc.shape}")
            validate.covariance("prior_cov", pc[:2, :2], 2)
        cfg = self.config
        now = float(snapshot.time[-1]) if len(snapshot) else math.nan
        profile = snapshot
        if not cfg.reuse_samples and len(snapshot):
            keep = snapshot.time > self.used_until
            profile = ProfileSnapshot(snapshot.h_terrain[keep], snapshot.pos_n[keep],
                                      snapshot.pos_e[keep], snapshot.time[keep])
        n = len(profile)
        if n < cfg.min_samples:
            return PmfResult(False, "too few samples", now, samples=n)
        if profile.track_length_m < cfg.min_track_m:
            return PmfResult(False, "track too short", now, samples=n)
        if not math.isfinite(sigma_max_m):
            raise ValueError("position sigma must be finite")
        if prior_cov is None:
            prior = np.eye(2) * max(sigma_max_m, 1.0) ** 2
        else:
            prior = np.array(prior_cov, float)[:2, :2]
            prior = 0.5 * (prior + prior.T)
            if not np.all(np.isfinite(prior)):
                raise ValueError("prior covariance must be finite")
        prior = prior + np.eye(2) * 1e-6
        sig_prior = math.sqrt(max(np.linalg.eigvalsh(prior).max(), 1.0))
        sig_prior_min = math.sqrt(max(np.linalg.eigvalsh(prior).min(), 1e-6))
        half = min(max(cfg.k_sigma * sig_prior * self.widen + cfg.margin_m,
                       cfg.min_half_width_m), cfg.max_half_width_m * self.widen)
        step = max(min(self.step, sig_prior / 2.0), 2.0 * half / (cfg.max_cells - 1))
        result = PmfResult(False, "", now, half_width_m=half, samples=n)
        t_mean = float(np.mean(profile.time))
        var_base = np.full(n, cfg.range_sigma_m**2 + cfg.dem_sigma_m**2)
        rel_var = (cfg.velocity_sigma_mps * (profile.time - t_mean)) ** 2
        info_prior = np.linalg.inv(prior)
        gn, ge, ll, c2 = self._grid(profile, var_base, rel_var, (0.0, 0.0), half, step)
        finite = np.isfinite(ll)
        mid = gn.size // 2
        if finite.mean() < cfg.min_valid_fraction or not finite[mid, mid]:
            result.reason = "off map / DEM void"
            return result
        dof = max(n - 3, 1)

        def posterior(gn, ge, ll, temper=1.0):
            sn, se = np.meshgrid(gn, ge, indexing="ij")
            lp = -0.5 * (info_prior[0, 0] * sn * sn + 2 * info_prior[0, 1] * sn * se
                         + info_prior[1, 1] * se * se)
            return ll / temper + lp

        w, mean, cov = self._moments(gn, ge, posterior(gn, ge, ll))
        # refine around the posterior when it is narrower than the grid resolves
        for _ in range(2):
            sd_min = math.sqrt(max(np.linalg.eigvalsh(cov).min(), 0.0))
            sd_max = math.sqrt(max(np.linalg.eigvalsh(cov).max(), 0.0))
            if sd_min >= 2.0 * step:
                break
            fine_half = max(5.0 * sd_max, 3.0 * step)
            new_step = max(fine_half / ((cfg.refine_cells - 1) / 2), 0.05)
            if new_step >= step:
                break
            fgn, fge, fll, fc2 = self._grid(profile, var_base, rel_var, mean, fine_half,
                                            new_step)
            if not np.all(np.isfinite(fll)):
                break
            gn, ge, ll, c2, step = fgn, fge, fll, fc2, new_step
            w, mean, cov = self._moments(gn, ge, posterior(gn, ge, ll))
        # consistency of the best shift (on the finest grid evaluated)
        chi2_min = float(np.nanmin(c2))
        result.chi2_per_dof = chi2_min / dof
        from navgate.nav.eskf import chi2_gate  # chi2.ppf, cached, without scipy.stats

        if chi2_min > cfg.max_noise_scale**2 * chi2_gate(cfg.consistency_probability, dof):
            result.reason = "profile inconsistent with DEM"
            return result
        temper = max(1.0, chi2_min / dof)
        if temper > 1.0:
            w, mean, cov = self._moments(gn, ge, posterior(gn, ge, ll, temper))
        cov = cov + np.eye(2) * step**2 / 12.0
        # tail mass beyond the 3-sigma ellipse of the moments: separated modes
        ci = np.linalg.inv(cov)
        dn = (gn - mean[0])[:, None]
        de = (ge - mean[1])[None, :]
        d2 = ci[0, 0] * dn * dn + 2 * ci[0, 1] * dn * de + ci[1, 1] * de * de
        tail = float(np.sum(w[d2 > 9.0]))
        result.tail_mass = tail
        result.posterior_mean_n, result.posterior_mean_e = float(mean[0]), float(mean[1])
        result.posterior_cov = cov
        pn = profile.pos_n + mean[0]
        pe = profile.pos_e + mean[1]
        terrain = self.dem.height(*self.tangent.to_geodetic(pn, pe))
        result.roughness_m = float(np.nanstd(terrain))
        if tail > cfg.max_tail_mass:
            result.reason = "multimodal"
            return result
        # divide the prior out: the measurement the filter should receive
        info_post = np.linalg.inv(cov)
        info_meas = info_post - info_prior
        lam, vec = np.linalg.eigh(0.5 * (info_meas + info_meas.T))
        lam_max = float(lam.max())
        ratio = 1.0 / math.sqrt(lam_max) / sig_prior_min if lam_max > 0 else math.inf
        result.info_ratio = ratio
        if result.roughness_m < cfg.min_roughness_m or ratio > cfg.max_info_ratio:
            result.reason = "flat terrain"
            return result
        # directions without information: variance capped at 100 x the prior's
        lam = np.maximum(lam, 1.0 / (100.0 * sig_prior**2))
        r = vec @ np.diag(1.0 / lam) @ vec.T
        r = 0.5 * (r + r.T)
        z = r @ (info_post @ mean)
        result.shift_n, result.shift_e = float(z[0]), float(z[1])
        result.cov = r
        result.ins_n = float(np.mean(profile.pos_n))
        result.ins_e = float(np.mean(profile.pos_e))
        result.fix_n = result.ins_n + float(z[0])
        result.fix_e = result.ins_e + float(z[1])
        result.lag_s = float(now - t_mean)
        result.accepted = True
        result.reason = "ok"
        if not cfg.reuse_samples:
            self.used_until = float(profile.time[-1])
        self.widen = 1.0
        return result
