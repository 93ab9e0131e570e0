"""TERCOM-style batch terrain correlator (the processor side of seed 000: the Pi 5's
"TRN correlation" that produces the fix and covariance written to TRN_POS_N/E, TRN_COV_*).

Given a terrain profile (h_terrain_i measured along the INS-indicated track p_i) the
correlator shifts the whole track by d = (d_north, d_east) over a search window and
compares with the DEM:

    MSD(d) = mean_i (r_i - mean(r))^2,   r_i = h_terrain_i - DEM(p_i + d)

Removing the mean makes the match insensitive to a barometric bias (and to the DEM's
vertical datum). The window is centred on the INS position and sized from the filter's
position covariance: half-width = clip(k_sigma * sigma_max + margin, min, max).

The shift measures the INS error averaged over the profile, i.e. (to first order in the
velocity error) the error at the profile's mean sample time, ``lag_s`` before the newest
sample; the filter update models that lag (navgate.nav.eskf, update_position_offset).

The best shift is refined to sub-grid precision with a quadratic fit to the 3 x 3
neighbourhood of the grid minimum. The fix covariance follows from the nonlinear
least-squares view of the match: with J the terrain gradients at the matched points
(minus their mean, because the mean is a free parameter) and s^2 = SSE / (n - 3) the
residual variance, Cov(d) = s^2 (J'J)^-1 (the Cramer-Rao form of TERCOM accuracy; Bergman,
Ljung & Gustafsson 1999, "Terrain navigation using Bayesian statistics"). The grid
quantisation variance step^2/12 is added and the result is scaled by ``cov_inflation`` to
cover the DEM interpolation error the residuals do not reveal, and by
1 + (roughness_scale / roughness)^2: in weakly informative terrain the match is non-linear
and multimodal, its errors exceed the Cramer-Rao form and are correlated from one
overlapping profile to the next (docs/trn.md has the measurements behind both factors).

Rejections, each with its reason in the log:

- "flat terrain": the terrain roughness along the matched track (standard deviation of
  the DEM heights) is below ``min_roughness_m``; the match would be noise;
- "ambiguous": a second local minimum outside the main lobe (farther than
  ``exclusion_radius_m``) has MSD less than ``ambiguity_ratio`` times the best;
- "peak on window edge": the minimum lies on the border, so the true match may be
  outside the window;
- "off map / DEM void": fewer than ``min_valid_fraction`` of the shifts have terrain for
  every profile point (the INS is near the map edge or over voids): TRN pauses;
- "too few samples" / "track too short".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from navgate.nav.earth import LocalTangent
from navgate.trn.dem import Dem, bilinear_at, window_around
from navgate.trn.profile import ProfileSnapshot


@njit(cache=True)
def msd_surface(heights, row0, col0, nrow, ncol, lat_north, lon_west, dlat, dlon, lat0, lon0,
                m_lat, m_lon, h_meas, pos_n, pos_e, shifts_n, shifts_e):
    """Mean-removed mean squared difference for every (shift_n, shift_e) on the grid.

    NaN where any profile point falls off the map or next to a void.
    """
    nn = shifts_n.shape[0]
    ne = shifts_e.shape[0]
    m = h_meas.shape[0]
    out = np.empty((nn, ne))
    for a in range(nn):
        for b in range(ne):
            s1 = 0.0
            s2 = 0.0
            bad = False
            for i in range(m):
                lat = lat0 + (pos_n[i] + shifts_n[a]) / m_lat
                lon = lon0 + (pos_e[i] + shifts_e[b]) / m_lon
                t = bilinear_at(heights, row0, col0, nrow, ncol, lat_north, lon_west, dlat,
                                dlon, lat, lon)
                if not math.isfinite(t):
                    bad = True
                    break
                r = h_meas[i] - t
                s1 += r
                s2 += r * r
            if bad:
                out[a, b] = math.nan
            else:
                mean = s1 / m
                out[a, b] = s2 / m - mean * mean
    return out


@dataclass(frozen=True)
class TercomConfig:
    min_samples: int = 40
    min_track_m: float = 800.0
    grid_step_m: float | None = None  #: default: a quarter of the DEM post spacing
    k_sigma: float = 4.0
    margin_m: float = 150.0
    min_half_width_m: float = 300.0
    max_half_width_m: float = 2500.0
    min_roughness_m: float = 10.0
    ambiguity_ratio: float = 3.0
    exclusion_radius_m: float | None = None  #: default: 2.5 DEM posts
    min_valid_fraction: float = 0.5
    cov_inflation: float = 1.5
    roughness_scale_m: float = 30.0  #: covariance x (1 + (scale / roughness)^2); 0 disables

    def __post_init__(self):
        from navgate.nav import validate

        # the MSD surface divides by the sample count; its ambiguity test needs two minima
        validate.positive_int("min_samples", self.min_samples, minimum=2)
        for name in ("min_track_m", "k_sigma", "margin_m", "min_half_width_m",
                     "max_half_width_m", "min_roughness_m", "roughness_scale_m"):
            validate.non_negative(name, getattr(self, name))
        for name in ("grid_step_m", "exclusion_radius_m"):
            if getattr(self, name) is not None:
                validate.positive(name, getattr(self, name))
        validate.positive("ambiguity_ratio", self.ambiguity_ratio)
        validate.positive("cov_inflation", self.cov_inflation)
        if not 0 <= self.min_valid_fraction <= 1:
            raise ValueError(f"min_valid_fraction: must be in [0, 1], got "
                             f"{self.min_valid_fraction}")
        if self.max_half_width_m < self.min_half_width_m:
            raise ValueError("max_half_width_m: must be at least min_half_width_m")


@dataclass
class TercomResult:
    accepted: bool
    reason: str
    time: float = math.nan  #: time of the newest profile sample (when the fix is made)
    lag_s: float = math.nan  #: newest sample time minus the profile's mean sample time
    fix_n: float = math.nan  #: mean matched position of the profile (map frame metres)
    fix_e: float = math.nan
    ins_n: float = math.nan  #: mean INS position of the profile (map frame metres)
    ins_e: float = math.nan
    shift_n: float = math.nan
    shift_e: float = math.nan
    cov: np.ndarray = field(default_factory=lambda: np.full((2, 2), np.nan))
    msd_best: float = math.nan
    ambiguity: float = math.nan  #: second-minimum MSD / best MSD
    roughness_m: float = math.nan
    half_width_m: float = math.nan
    samples: int = 0

    def as_row(self) -> dict:
        return {
            "time_s": self.time, "lag_s": self.lag_s, "accepted": self.accepted,
            "reason": self.reason,
            "fix_north_m": self.fix_n, "fix_east_m": self.fix_e,
            "shift_north_m": self.shift_n, "shift_east_m": self.shift_e,
            "sigma_north_m": math.sqrt(self.cov[0, 0]) if np.isfinite(self.cov[0, 0]) else math.nan,
            "sigma_east_m": math.sqrt(self.cov[1, 1]) if np.isfinite(self.cov[1, 1]) else math.nan,
            "msd_best_m2": self.msd_best, "ambiguity_ratio": self.ambiguity,
            "roughness_m": self.roughness_m, "search_half_width_m": self.half_width_m,
            "samples": self.samples,
        }


class TercomCorrelator:
    """Batch profile-to-DEM correlator producing a 2-D position fix with covariance."""

    def __init__(self, dem: Dem, tangent: LocalTangent, config: TercomConfig = TercomConfig()):
        self.dem = dem
        self.tangent = tangent
        self.config = config
        sn, se = dem.post_spacing_m()
        self.post_m = min(sn, se)
        self.step = config.grid_step_m or self.post_m / 4.0
        self.exclusion = config.exclusion_radius_m or 2.5 * max(sn, se)

    def _surface(self, profile, shifts_n, shifts_e):
        d, t = self.dem, self.tangent
        pad = max(float(np.max(np.abs(shifts_n))), float(np.max(np.abs(shifts_e)))) + self.post_m
        window = window_around(d, t, profile.pos_n, profile.pos_e, pad)
        return msd_surface(*window.kernel_args(),
                           t.lat0, t.lon0, t.m_per_rad_lat, t.m_per_rad_lon,
                           np.ascontiguousarray(profile.h_terrain),
                           np.ascontiguousarray(profile.pos_n),
                           np.ascontiguousarray(profile.pos_e), shifts_n, shifts_e)

    def _terrain(self, n, e):
        lat, lon = self.tangent.to_geodetic(n, e)
        return self.dem.height(lat, lon)

    def correlate(self, profile: ProfileSnapshot, sigma_max_m: float,
                  prior_cov=None) -> TercomResult:
        """Match ``profile``; the window follows ``sigma_max_m`` (``prior_cov`` is unused)."""
        for name in ("time", "pos_n", "pos_e"):
            if not np.all(np.isfinite(getattr(profile, name))):
                raise ValueError(f"profile.{name}: non-finite values in the terrain profile")
        cfg = self.config
        now = float(profile.time[-1]) if len(profile) else math.nan
        if len(profile) < cfg.min_samples:
            return TercomResult(False, "too few samples", now, samples=len(profile))
        if profile.track_length_m < cfg.min_track_m:
            return TercomResult(False, "track too short", now, samples=len(profile))
        if not (math.isfinite(sigma_max_m) and sigma_max_m >= 0):
            raise ValueError(f"sigma_max_m: position sigma must be finite and non-negative, "
                             f"got {sigma_max_m}")
        half = min(max(cfg.k_sigma * sigma_max_m + cfg.margin_m, cfg.min_half_width_m),
                   cfg.max_half_width_m)
        steps = int(math.ceil(half / self.step))
        grid = np.arange(-steps, steps + 1) * self.step
        surface = self._surface(profile, grid, grid)
        result = TercomResult(False, "", now, half_width_m=half, samples=len(profile))
        finite = np.isfinite(surface)
        if finite.mean() < cfg.min_valid_fraction or not finite[steps, steps]:
            result.reason = "off map / DEM void"
            return result
        filled = np.where(finite, surface, np.inf)
        ia, ib = np.unravel_index(np.argmin(filled), filled.shape)
        best = surface[ia, ib]
        result.msd_best = float(best)
        last = len(grid) - 1
        neighbourhood = filled[max(ia - 1, 0):ia + 2, max(ib - 1, 0):ib + 2]
        if ia in (0, last) or ib in (0, last) or not np.all(np.isfinite(neighbourhood)):
            result.reason = "peak on window edge"
            return result
        # sub-grid refinement: separable parabola through the 3 x 3 neighbourhood
        def vertex(fm, f0, fp):
            den = fm - 2.0 * f0 + fp
            return 0.0 if den <= 0 else float(np.clip(0.5 * (fm - fp) / den, -0.5, 0.5))

        dn = grid[ia] + self.step * vertex(filled[ia - 1, ib], best, filled[ia + 1, ib])
        de = grid[ib] + self.step * vertex(filled[ia, ib - 1], best, filled[ia, ib + 1])
        # ambiguity: best local minimum outside the main lobe
        gn, ge = np.meshgrid(grid, grid, indexing="ij")
        far = np.hypot(gn - grid[ia], ge - grid[ib]) > self.exclusion
        padded = np.pad(filled, 1, constant_values=np.inf)
        is_min = np.ones_like(filled, dtype=bool)
        for da in (-1, 0, 1):
            for db in (-1, 0, 1):
                if da or db:
                    is_min &= filled <= padded[1 + da:1 + da + filled.shape[0],
                                               1 + db:1 + db + filled.shape[1]]
        candidates = filled[far & is_min & finite]
        second = float(candidates.min()) if candidates.size else math.inf
        floor = max(best, 1e-6)
        result.ambiguity = second / floor
        # matched track, roughness and covariance
        pn = profile.pos_n + dn
        pe = profile.pos_e + de
        terrain = self._terrain(pn, pe)
        roughness = float(np.std(terrain))
        result.roughness_m = roughness
        result.shift_n, result.shift_e = float(dn), float(de)
        if roughness < cfg.min_roughness_m:
            result.reason = "flat terrain"
            return result
        if result.ambiguity < cfg.ambiguity_ratio:
            result.reason = "ambiguous"
            return result
        lat, lon = self.tangent.to_geodetic(pn, pe)
        grad_n, grad_e = self.dem.gradient(lat, lon)
        jac = np.column_stack([grad_n - grad_n.mean(), grad_e - grad_e.mean()])
        resid = profile.h_terrain - terrain
        resid = resid - resid.mean()
        n = len(profile)
        s2 = float(resid @ resid) / max(n - 3, 1)
        info = jac.T @ jac
        if not np.all(np.isfinite(info)) or np.linalg.cond(info) > 1e8:
            result.reason = "flat terrain"
            return result
        cov = s2 * np.linalg.inv(info) + np.eye(2) * self.step**2 / 12.0
        cov = cfg.cov_inflation * 0.5 * (cov + cov.T)
        if cfg.roughness_scale_m > 0:
            cov *= 1.0 + (cfg.roughness_scale_m / roughness) ** 2
        result.cov = cov
        result.ins_n = float(np.mean(profile.pos_n))
        result.ins_e = float(np.mean(profile.pos_e))
        result.fix_n = result.ins_n + float(dn)
        result.fix_e = result.ins_e + float(de)
        result.lag_s = float(profile.time[-1] - np.mean(profile.time))
        result.accepted = True
        result.reason = "ok"
        return result
