"""A GPS-denied flight over a DEM: route layout, sensor simulation, INS-only and INS+TRN runs.

This is the scenario behind ``navgate fly`` (seed 000 "Data Flow", processor and FPGA
sides together, in the float64 reference arithmetic):

1. :func:`plan_route` lays a closed circuit (four legs with coordinated turns, a climb, a
   descent and speed changes) inside the DEM's valid area, with a margin for the TRN
   search window, at a cruise altitude a clearance above the highest terrain under it.
2. :func:`simulate_sensors` generates the truth at the IMU rate, error-free IMU readings
   consistent with it, and the sensor outputs: ADIS16500 words, BMP390 altitude, AGL ranges.
3. :func:`run_navigation` runs the closed-loop INS + 15-state ESKF over the same sensor data,
   with barometric altitude updates, and (unless disabled) the altitude profile buffer,
   TERCOM correlator and seed-000 TRN position updates.
4. :func:`fly` does all of it for INS-only and INS+TRN and scores both against truth.

The flight starts at the moment GPS is lost: the INS is initialised from the GPS-aided
solution, whose errors are drawn from the initial covariance (position 5 m, velocity
0.1 m/s, roll/pitch 0.05 deg, heading 0.3 deg, residual accelerometer bias 1 mg, residual
gyro bias 10 deg/h), docs/scenario.md.
"""

from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, field

import numpy as np

from navgate.nav import eskf, strapdown
from navgate.nav.earth import LocalTangent, radii
from navgate.nav.rotations import quat_from_rotvec, quat_multiply, quat_to_dcm_array
from navgate.sim import sensors, trajectory
from navgate.trn.dem import Dem
from navgate.trn.profile import ACCEPTED, ProfileBuffer
from navgate.trn.tercom import TercomConfig, TercomCorrelator

DEG = math.pi / 180.0


class RouteError(ValueError):
    """The route cannot be laid out inside the DEM (too small, too many voids)."""


@dataclass(frozen=True)
class FlightConfig:
    duration_s: float = 600.0
    imu_rate_hz: float = 400.0
    seed: int = 0
    ideal_sensors: bool = False
    trn: bool = True
    speed_mps: float = 60.0
    turn_rate_dps: float = 3.0
    clearance_m: float = 300.0
    climb_m: float = 150.0
    margin_m: float = 2000.0
    max_leg_m: float = 9000.0
    ranger: str = "long-range"
    baro_rate_hz: float = 25.0
    ranger_rate_hz: float = 10.0
    fix_interval_s: float = 10.0
    log_rate_hz: float = 10.0
    profile_spacing_m: float = 30.0
    lag_compensation: bool = True
    # initial (GPS-aided) uncertainty at the moment GPS is lost
    init_pos_sigma_m: float = 5.0
    init_alt_sigma_m: float = 2.0
    init_vel_sigma_mps: float = 0.1
    init_tilt_sigma_rad: float = 0.05 * DEG
    init_heading_sigma_rad: float = 0.3 * DEG
    init_accel_bias_sigma: float = 1e-3 * sensors.G0
    init_gyro_bias_sigma: float = 10.0 * DEG / 3600.0
    tercom: TercomConfig = field(default_factory=TercomConfig)

    def __post_init__(self):
        checks = {
            "duration_s": self.duration_s > 0 and math.isfinite(self.duration_s),
            "imu_rate_hz": self.imu_rate_hz >= 50 and math.isfinite(self.imu_rate_hz),
            "speed_mps": 5 <= self.speed_mps <= 400,
        }
        for name, ok in checks.items():
            if not ok:
                raise ValueError(f"invalid {name}: {getattr(self, name)}")
        if self.ranger not in sensors.RANGER_PRESETS:
            raise ValueError(f"unknown ranger {self.ranger!r}; choose from "
                             f"{', '.join(sensors.RANGER_PRESETS)}")


@dataclass
class Route:
    segments: list
    lat0: float
    lon0: float
    h0: float
    heading0: float
    speed0: float


def _circuit(leg_n, leg_e, cfg: FlightConfig):
    v = cfg.speed_mps
    fast = v * 1.2
    climb_rate = 5.0
    climb_dist = cfg.climb_m / climb_rate * v
    segs = [
        trajectory.straight(max(leg_n - climb_dist, 1.0) / v / 2, label="leg 1"),
        trajectory.climb(cfg.climb_m, climb_rate, label="climb"),
        trajectory.straight(max(leg_n - climb_dist, 1.0) / v / 2, label="leg 1"),
        trajectory.turn(90, cfg.turn_rate_dps),
        trajectory.speed_change(fast, leg_e / (0.5 * (v + fast)), label="leg 2, speed up"),
        trajectory.turn(90, cfg.turn_rate_dps),
        trajectory.straight(max(leg_n - climb_dist, 1.0) / fast / 2, label="leg 3"),
        trajectory.climb(-cfg.climb_m, climb_rate, label="descent"),
        trajectory.straight(max(leg_n - climb_dist, 1.0) / fast / 2, label="leg 3"),
        trajectory.turn(90, cfg.turn_rate_dps),
        trajectory.speed_change(v, leg_e / (0.5 * (v + fast)), label="leg 4, slow down"),
        trajectory.turn(90, cfg.turn_rate_dps),
    ]
    return segs


def plan_route(dem: Dem, cfg: FlightConfig) -> Route:
    """Lay the default circuit out inside ``dem``'s valid area (raises RouteError)."""
    south, north, west, east = dem.valid_bounds()
    lat_c = 0.5 * (south + north)
    rn, re = radii(lat_c)
    extent_n = (north - south) * rn
    extent_e = (east - west) * re * math.cos(lat_c)
    radius = cfg.speed_mps * 1.2 / (cfg.turn_rate_dps * DEG)
    avail_n = extent_n - 2 * cfg.margin_m
    avail_e = extent_e - 2 * cfg.margin_m
    leg_n = min(cfg.max_leg_m, avail_n - 2 * radius)
    leg_e = min(cfg.max_leg_m, avail_e - 2 * radius)
    min_leg = 2000.0
    if leg_n < min_leg or leg_e < min_leg:
        need = 2 * (min_leg + 2 * radius + 2 * cfg.margin_m) / 2
        raise RouteError(
            f"DEM too small for the route: its valid area is {extent_n / 1000:.1f} x "
            f"{extent_e / 1000:.1f} km, the circuit needs at least {need / 1000:.1f} x "
            f"{need / 1000:.1f} km at {cfg.speed_mps:.0f} m/s")
    segs = _circuit(leg_n, leg_e, cfg)
    # fly once at the DEM centre to measure the circuit's extent, then centre it
    lat_mid, lon_mid = 0.5 * (south + north), 0.5 * (west + east)
    probe = trajectory.generate(segs, lat0=lat_mid, lon0=lon_mid, h0=1000.0, heading0=0.0,
                                speed0=cfg.speed_mps, rate_hz=10.0, duration_s=cfg.duration_s)
    tangent = LocalTangent(lat_mid, lon_mid)
    pn, pe = tangent.to_ned(probe.lat, probe.lon)
    dn = -0.5 * (pn.min() + pn.max())
    de = -0.5 * (pe.min() + pe.max())
    lat0, lon0 = tangent.to_geodetic(dn, de)
    lat_track, lon_track = tangent.to_geodetic(pn + dn, pe + de)
    terrain = dem.height(lat_track, lon_track)
    if np.mean(np.isfinite(terrain)) < 0.5:
        raise RouteError("DEM has too many voids under the route (over half the track)")
    h0 = float(np.nanmax(terrain)) + cfg.clearance_m
    return Route(segs, float(lat0), float(lon0), h0, 0.0, cfg.speed_mps)


@dataclass
class SensorData:
    truth: trajectory.Trajectory
    imu: sensors.ImuRecord
    gyro: np.ndarray  #: calibrated readings (rad/s), (N-1, 3)
    accel: np.ndarray
    baro: sensors.BaroRecord
    baro_index: np.ndarray  #: IMU sample boundary of each baro sample
    ranger: sensors.RangerRecord
    ranger_index: np.ndarray
    terrain_truth: np.ndarray  #: DEM height under the truth at ranger times
    ideal: bool


def simulate_sensors(route: Route, dem: Dem, cfg: FlightConfig) -> SensorData:
    rng_seeds = np.random.SeedSequence(cfg.seed).spawn(4)
    seeds = [int(s.generate_state(1)[0]) for s in rng_seeds]
    truth = trajectory.generate(route.segments, lat0=route.lat0, lon0=route.lon0, h0=route.h0,
                                heading0=route.heading0, speed0=route.speed0,
                                rate_hz=cfg.imu_rate_hz, duration_s=cfg.duration_s)
    gyro_true, accel_true = truth.imu()
    spec = sensors.IDEAL_IMU if cfg.ideal_sensors else sensors.ADIS16500
    imu = sensors.ImuModel(spec, cfg.imu_rate_hz, seed=seeds[0]).measure(gyro_true, accel_true)
    gyro, accel = imu.calibration.apply(imu.gyro_words, imu.accel_words)
    n = len(truth)
    baro_every = max(1, int(round(cfg.imu_rate_hz / cfg.baro_rate_hz)))
    baro_index = np.arange(baro_every, n, baro_every)
    baro_spec = sensors.IDEAL_BARO if cfg.ideal_sensors else sensors.BMP390
    baro = sensors.Barometer(baro_spec, seed=seeds[1]).measure(truth.t[baro_index],
                                                              truth.h[baro_index])
    ranger_every = max(1, int(round(cfg.imu_rate_hz / cfg.ranger_rate_hz)))
    ranger_index = np.arange(ranger_every, n, ranger_every)
    terrain = dem.height(truth.lat[ranger_index], truth.lon[ranger_index])
    ranger = sensors.Ranger(sensors.RANGER_PRESETS[cfg.ranger], seed=seeds[2],
                            ideal=cfg.ideal_sensors).measure(
        truth.t[ranger_index], truth.h[ranger_index] - terrain,
        truth.roll[ranger_index], truth.pitch[ranger_index])
    return SensorData(truth, imu, gyro, accel, baro, baro_index, ranger, ranger_index,
                      terrain, cfg.ideal_sensors)


@dataclass
class InitialEstimate:
    nav: np.ndarray
    p0: np.ndarray
    bias_a: np.ndarray
    bias_g: np.ndarray


def initial_estimate(data: SensorData, cfg: FlightConfig) -> InitialEstimate:
    """The INS state at GPS loss: truth plus errors drawn from P0 (none with ideal sensors)."""
    truth = data.truth
    nav = truth.states[0].copy()
    sig = [cfg.init_pos_sigma_m, cfg.init_pos_sigma_m, cfg.init_alt_sigma_m]
    p0 = eskf.initial_covariance(
        pos_sigma=np.array(sig), vel_sigma=cfg.init_vel_sigma_mps,
        att_sigma=np.array([cfg.init_tilt_sigma_rad, cfg.init_tilt_sigma_rad,
                            cfg.init_heading_sigma_rad]),
        accel_bias_sigma=cfg.init_accel_bias_sigma, gyro_bias_sigma=cfg.init_gyro_bias_sigma)
    # true bias at t0 as the calibrated readings see it (turn-on + in-run)
    bias_a = data.imu.accel_bias[0].copy()
    bias_g = data.imu.gyro_bias[0].copy()
    if data.ideal:
        return InitialEstimate(nav, p0 * 1e-6, bias_a, bias_g)
    rng = np.random.default_rng(np.random.SeedSequence(cfg.seed).spawn(5)[4])
    dx = rng.standard_normal(15) * np.sqrt(np.diag(p0))
    est = eskf.ErrorStateFilter(nav, p0, eskf.FilterConfig(1, 1, 1, 1, 1, 1),
                                bias_a0=bias_a, bias_g0=bias_g)
    # apply_correction subtracts: pass -dx to *add* the error dx (estimate = truth + dx)
    est.apply_correction(-dx)
    return InitialEstimate(est.nav.copy(), p0, est.bias_a.copy(), est.bias_g.copy())


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
    correlator = TercomCorrelator(dem, tangent, cfg.tercom)
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
                result = correlator.correlate(buffer.snapshot(), sigma_max)
                row = result.as_row()
                row["applied"] = False
                row["nis"] = math.nan
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


@dataclass
class Score:
    horizontal_error: np.ndarray  #: m, at the log times
    north_error: np.ndarray
    east_error: np.ndarray
    nees: np.ndarray  #: position (N, E) NEES at the log times

    def summary(self, t) -> dict:
        half = t >= t[0] + 0.5 * (t[-1] - t[0])
        e = self.horizontal_error
        return {
            "final_horizontal_error_m": float(e[-1]),
            "rms_horizontal_error_m": float(np.sqrt(np.mean(e**2))),
            "max_horizontal_error_m": float(np.max(e)),
            "rms_horizontal_error_second_half_m": float(np.sqrt(np.mean(e[half] ** 2))),
            "nees_position_mean": float(np.mean(self.nees)),
        }


def score(run: NavRun, truth: trajectory.Trajectory, log_every: int) -> Score:
    idx = np.arange(run.t.size) * log_every
    idx = np.minimum(idx, len(truth) - 1)
    lat_t, lon_t = truth.lat[idx], truth.lon[idx]
    rn, re = radii(lat_t[0])
    en = (run.nav[:, 0] - lat_t) * (rn + truth.h[idx])
    ee = (run.nav[:, 1] - lon_t) * (re + truth.h[idx]) * np.cos(lat_t)
    pnn = run.sigma[:, 0] ** 2
    pee = run.sigma[:, 1] ** 2
    pne = run.p_ne
    det = pnn * pee - pne**2
    with np.errstate(divide="ignore", invalid="ignore"):
        nees = (pee * en**2 - 2 * pne * en * ee + pnn * ee**2) / det
    nees = np.where(det > 0, nees, np.nan)
    return Score(np.hypot(en, ee), en, ee, nees)


@dataclass
class FlightResult:
    config: FlightConfig
    dem: Dem
    route: Route
    data: SensorData
    runs: dict  #: name -> NavRun
    scores: dict  #: name -> Score
    log_every: int
    wall_time_s: float

    def summary(self) -> dict:
        cfg = self.config
        truth = self.data.truth
        out = {
            "duration_s": float(truth.t[-1] - truth.t[0]),
            "imu_rate_hz": cfg.imu_rate_hz,
            "wall_time_s": self.wall_time_s,
            "seed": cfg.seed,
            "ideal_sensors": cfg.ideal_sensors,
            "dem": {"name": self.dem.name, "rows": self.dem.shape[0], "cols": self.dem.shape[1],
                    "post_spacing_m": list(self.dem.post_spacing_m()),
                    "void_fraction": self.dem.void_fraction()},
            "route": {"start_lat_deg": math.degrees(self.route.lat0),
                      "start_lon_deg": math.degrees(self.route.lon0),
                      "cruise_altitude_m": self.route.h0,
                      "distance_km": float(np.sum(np.linalg.norm(truth.v_ned, axis=1))
                                           / cfg.imu_rate_hz / 1000.0)},
            "sensors": {"imu": "ideal" if cfg.ideal_sensors else sensors.ADIS16500.name,
                        "imu_saturated_words": self.data.imu.saturated,
                        "baro": "ideal" if cfg.ideal_sensors else sensors.BMP390.name,
                        "ranger": cfg.ranger,
                        "ranger_valid_fraction": float(np.mean(self.data.ranger.valid))},
        }
        for name, run in self.runs.items():
            s = self.scores[name].summary(run.t)
            s["baro_updates_accepted"] = run.accepted.get("baro", 0)
            s["baro_updates_rejected"] = run.rejected.get("baro", 0)
            s["baro_samples_invalid"] = run.rejected.get("baro invalid sample", 0)
            s["imu_samples_rejected"] = run.imu_samples_rejected
            s["wall_time_s"] = run.wall_time_s
            if name == "trn_aided":
                applied = [f for f in run.fixes if f["applied"]]
                reasons = {}
                for f in run.fixes:
                    if not f["applied"]:
                        reasons[f["reason"]] = reasons.get(f["reason"], 0) + 1
                s["fixes_attempted"] = len(run.fixes)
                s["fixes_accepted"] = len(applied)
                s["fixes_rejected"] = len(run.fixes) - len(applied)
                s["fix_rejection_reasons"] = reasons
                s["profile_sample_counts"] = run.profile_counts
                nis = [f["nis"] for f in applied]
                s["nis_trn_mean"] = float(np.mean(nis)) if nis else None
            out[name] = s
        return out


def fly(dem: Dem, cfg: FlightConfig, progress=None, stage=None, route: Route | None = None
        ) -> FlightResult:
    """Plan, simulate and navigate a flight; ``progress(n)`` reports IMU samples done."""
    start = _time.perf_counter()
    if route is None:
        if stage:
            stage("planning route")
        route = plan_route(dem, cfg)
    if stage:
        stage("simulating sensors")
    data = simulate_sensors(route, dem, cfg)
    init = initial_estimate(data, cfg)
    runs = {}
    if stage:
        stage("navigating: INS only")
    runs["ins_only"] = run_navigation(data, dem, cfg, init, use_trn=False, name="ins_only",
                                      progress=progress)
    if cfg.trn:
        if stage:
            stage("navigating: INS + TRN")
        runs["trn_aided"] = run_navigation(data, dem, cfg, init, use_trn=True,
                                           name="trn_aided", progress=progress)
    log_every = max(1, int(round(cfg.imu_rate_hz / cfg.log_rate_hz)))
    scores = {name: score(run, data.truth, log_every) for name, run in runs.items()}
    return FlightResult(cfg, dem, route, data, runs, scores, log_every,
                        _time.perf_counter() - start)


__all__ = ["FlightConfig", "FlightResult", "RouteError", "fly", "plan_route",
           "simulate_sensors", "run_navigation", "initial_estimate", "score",
           "quat_from_rotvec", "quat_multiply"]
