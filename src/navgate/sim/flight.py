"""The GPS-denied flight scenario over a DEM: route layout, truth, sensor simulation, scoring.

This is the scenario behind ``navgate fly`` (seed 000 "Data Flow"); the navigation that runs
on it lives with seed 000's system in :mod:`navgate.systems.ins_trn`:

1. :func:`plan_route` lays a closed circuit (four legs with coordinated turns, a climb, a
   descent and speed changes) inside the DEM's valid area, with a margin for the TRN
   search window, at a cruise altitude a clearance above the highest terrain under it.
2. :func:`simulate_sensors` generates the truth at the IMU rate, error-free IMU readings
   consistent with it, and the sensor outputs: ADIS16500 words, BMP390 altitude, AGL ranges.
3. :func:`initial_estimate` draws the GPS-aided solution at the moment GPS is lost, and
   :func:`score` compares a logged navigation solution with the truth.

The flight starts at the moment GPS is lost: the INS is initialised from the GPS-aided
solution, whose errors are drawn from the initial covariance (position 5 m, velocity
0.1 m/s, roll/pitch 0.05 deg, heading 0.3 deg, residual accelerometer bias 1 mg, residual
gyro bias 10 deg/h), docs/scenario.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from navgate.nav import eskf
from navgate.nav.earth import LocalTangent, radii
from navgate.sim import sensors, trajectory
from navgate.trn.dem import Dem

DEG = math.pi / 180.0


class RouteError(ValueError):
    """The route cannot be laid out inside the DEM (too small, too many voids)."""


@dataclass(frozen=True)
class FlightConfig:
    duration_s: float = 600.0
    imu_rate_hz: float = 400.0
    seed: int = 0
    ideal_sensors: bool = False
    #: fly the INS+TRN run beside the INS-only one: which runs the scenario asks for (how the
    #: navigator's TRN works, method, fix interval and so on, is the navigator's own
    #: configuration, seed 000's TrnSettings)
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
    log_rate_hz: float = 10.0
    profile_spacing_m: float = 30.0
    # initial (GPS-aided) uncertainty at the moment GPS is lost
    init_pos_sigma_m: float = 5.0
    init_alt_sigma_m: float = 2.0
    init_vel_sigma_mps: float = 0.1
    init_tilt_sigma_rad: float = 0.05 * DEG
    init_heading_sigma_rad: float = 0.3 * DEG
    init_accel_bias_sigma: float = 1e-3 * sensors.G0
    init_gyro_bias_sigma: float = 10.0 * DEG / 3600.0

    def __post_init__(self):
        checks = {
            "duration_s": self.duration_s > 0 and math.isfinite(self.duration_s),
            "imu_rate_hz": self.imu_rate_hz >= 50 and math.isfinite(self.imu_rate_hz),
            "speed_mps": 5 <= self.speed_mps <= 400,
        }
        for name, ok in checks.items():
            if not ok:
                raise ValueError(f"invalid {name}: {getattr(self, name)}")
        if self.duration_s < self.min_duration_s:
            raise ValueError(f"duration_s {self.duration_s:g} s is too short for the scenario: "
                             f"at least {self.min_duration_s:g} s (two periods of the slowest "
                             "sensor or log)")
        if self.ranger not in sensors.RANGER_PRESETS:
            raise ValueError(f"unknown ranger {self.ranger!r}; choose from "
                             f"{', '.join(sensors.RANGER_PRESETS)}")

    @property
    def min_duration_s(self) -> float:
        """The shortest flight with at least two samples of every sensor and of the log."""
        slowest = min(self.baro_rate_hz, self.ranger_rate_hz, self.log_rate_hz)
        return 2.0 / slowest


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


def score(run, truth: trajectory.Trajectory, log_every: int) -> Score:
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


__all__ = ["FlightConfig", "InitialEstimate", "Route", "RouteError", "Score", "SensorData",
           "initial_estimate", "plan_route", "score", "simulate_sensors"]
