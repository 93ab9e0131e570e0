"""Seed 000's navigation loop over a recorded sensor stream: INS + 15-state ESKF with
barometric altitude updates and (optionally) TRN position fixes.

Processor and FPGA sides together, in the float64 reference arithmetic (seed 000 "Data
Flow"): the IMU samples drive the strapdown mechanization and covariance propagation
(:mod:`navgate.nav.strapdown`, :mod:`navgate.nav.eskf`); barometer samples give 1-D altitude
updates; ranger samples feed the altitude profile buffer (:mod:`navgate.trn.profile`), whose
snapshots the TERCOM correlator (:mod:`navgate.trn.tercom`) turns into 2-D position fixes with
a lag (docs/trn.md).
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass

import numpy as np

from navgate.nav import eskf, strapdown
from navgate.nav.earth import LocalTangent
from navgate.nav.rotations import quat_to_dcm_array
from navgate.sim import sensors
from navgate.sim.flight import FlightConfig, InitialEstimate, SensorData
from navgate.trn.correlators import make_correlator, make_monitor
from navgate.trn.dem import Dem
from navgate.trn.profile import ACCEPTED, ProfileBuffer


@dataclass
class NavRun:
    """Navigation output, logged at cfg.log_rate_hz."""

    name: str
    t: np.ndarray
    nav: np.ndarray  #: (M, 10)
    sigma: np.ndarray  #: (M, 15) square roots of P's diagonal
    p_ne: np.ndarray  #: (M,) P[0, 1]
    fixes: list  #: TercomResult rows (dicts) with "applied" and "nis"
    accepted: dict
    rejected: dict
    profile_counts: dict
    imu_samples_rejected: int
    wall_time_s: float


def run_navigation(data: SensorData, dem: Dem, cfg: FlightConfig, init: InitialEstimate, *,
                   use_trn: bool, name: str, progress=None) -> NavRun:
    """Closed-loop INS + ESKF over the sensor data, with baro and (optionally) TRN updates."""
    start_wall = _time.perf_counter()
    filter_cfg = eskf.FilterConfig.from_imu_spec(
        sensors.IDEAL_IMU if data.ideal else sensors.ADIS16500, rate_hz=cfg.imu_rate_hz,
        residual_accel_bias=cfg.init_accel_bias_sigma,
        residual_gyro_bias=cfg.init_gyro_bias_sigma)
    filt = eskf.ErrorStateFilter(init.nav, init.p0, filter_cfg, rate_hz=cfg.imu_rate_hz,
                                 bias_a0=init.bias_a, bias_g0=init.bias_g)
    baro_sigma = max(sensors.Barometer(sensors.BMP390).altitude_noise_m, 0.05)
    n_readings = data.gyro.shape[0]
    log_every = max(1, int(round(cfg.imu_rate_hz / cfg.log_rate_hz)))
    n_log = n_readings // log_every + 1
    out_nav = np.empty((n_log, strapdown.NAV_SIZE))
    out_sigma = np.empty((n_log, 16))
    out_nav[0] = filt.nav
    out_sigma[0, :15] = np.sqrt(np.diag(filt.p))
    p_ne = np.full(n_log, np.nan)
    p_ne[0] = filt.p[0, 1]

    # events at IMU sample boundaries: (index, kind, payload)
    events = [(int(k), 0, j) for j, k in enumerate(data.baro_index)]
    events += [(int(k), 1, j) for j, k in enumerate(data.ranger_index)]
    events += [(k, 2, 0) for k in range(log_every, n_readings + 1, log_every)]
    events.sort()
    tangent = LocalTangent(*dem.center, 0.0)
    correlator = make_correlator(cfg.trn_method, dem, tangent, cfg.tercom, pmf=cfg.pmf)
    monitor = make_monitor(correlator)
    buffer = ProfileBuffer(min_spacing_m=cfg.profile_spacing_m)
    fixes = []
    last_fix_t = -math.inf
    k_done = 0
    t0 = data.truth.t[0]
    dt = 1.0 / cfg.imu_rate_hz
    sigma_buf = np.empty((1, 16))
    nav_buf = np.empty((1, strapdown.NAV_SIZE))
    for k, kind, j in events:
        if k > n_readings:
            break
        if k > k_done:
            filt.propagate(data.gyro, data.accel, k_done, k, out_nav=nav_buf,
                           out_sigma=sigma_buf, out_every=10**9)
            if progress is not None:
                progress(k - k_done)
            k_done = k
        t_now = t0 + k * dt
        if kind == 2:
            row = k // log_every
            out_nav[row] = filt.nav
            out_sigma[row, :15] = np.sqrt(np.maximum(np.diag(filt.p), 0.0))
            p_ne[row] = filt.p[0, 1]
        elif kind == 0:
            h = data.baro.altitude[j]
            if np.isfinite(h):
                filt.update_altitude(h, baro_sigma)
            else:
                filt.rejected["baro invalid sample"] = filt.rejected.get(
                    "baro invalid sample", 0) + 1
        elif kind == 1 and use_trn:
            roll, pitch, _ = _euler(filt.nav[6:10])
            pn, pe = tangent.to_ned(filt.nav[0], filt.nav[1])
            # the newest barometer sample at or before this ranger sample
            jb = int(np.searchsorted(data.baro_index, k, "right")) - 1
            h_baro = data.baro.altitude[jb] if jb >= 0 else np.nan
            status = buffer.add(time=t_now, h_baro=float(h_baro),
                                slant_range=float(data.ranger.slant_range[j]),
                                range_valid=bool(data.ranger.valid[j]), roll=roll, pitch=pitch,
                                pos_n=float(pn), pos_e=float(pe))
            if status == ACCEPTED and t_now - last_fix_t >= cfg.fix_interval_s:
                last_fix_t = t_now
                sigma_max = math.sqrt(max(np.linalg.eigvalsh(filt.p[:2, :2]).max(), 0.0))
                result = correlator.correlate(buffer.snapshot(), sigma_max,
                                              prior_cov=filt.p[:2, :2])
                row = result.as_row()
                row["applied"] = False
                row["nis"] = math.nan
                upd = y = None
                if result.accepted:
                    # y = p_ins - p_fix = -shift, measured lag_s ago
                    y = np.array([result.ins_n - result.fix_n, result.ins_e - result.fix_e])
                    lag = result.lag_s if cfg.lag_compensation else 0.0
                    upd = filt.update_position_offset(y, result.cov, lag)
                    row["nis"] = upd.nis
                    row["applied"] = upd.accepted
                    if upd.accepted:
                        c = upd.correction
                        buffer.shift(-c[0], -c[1], -c[3], -c[4], now=t_now)
                    else:
                        row["reason"] = "rejected by chi-square gate"
                review = monitor.review(result, upd, y, sigma_max)
                row["integrity"] = review.event
                if review.inflate is not None:  # divergence: reopen the filter's position
                    filt.p[:2, :2] += review.inflate
                fixes.append(row)
    if k_done < n_readings:
        filt.propagate(data.gyro, data.accel, k_done, n_readings, out_nav=nav_buf,
                       out_sigma=sigma_buf, out_every=10**9)
        if progress is not None:
            progress(n_readings - k_done)
        out_nav[-1] = filt.nav
        out_sigma[-1, :15] = np.sqrt(np.maximum(np.diag(filt.p), 0.0))
        p_ne[-1] = filt.p[0, 1]
    t_log = t0 + np.arange(n_log) * log_every * dt
    return NavRun(name, t_log, out_nav, out_sigma[:, :15], p_ne, fixes, dict(filt.accepted),
                  dict(filt.rejected), dict(buffer.counts), filt.imu_samples_rejected,
                  _time.perf_counter() - start_wall)


def _euler(q):
    c = quat_to_dcm_array(np.asarray(q))
    return (math.atan2(c[2, 1], c[2, 2]), -math.asin(max(-1.0, min(1.0, c[2, 0]))),
            math.atan2(c[1, 0], c[0, 0]))
