"""Seed 002's simulation: an aircraft flight, Table-1 sensor errors, 1 Hz GPS with a 30 s outage,
the GPS-only solution and the closed-loop GPS/INS solution, scored against truth.

Reference: seed 002, "Sensor modelling" (Table 1), "GPS module" (WGS-84 Flat/Flon conversion
of north/east metres to latitude/longitude, 1 s update) and "Results and discussions" (a
250 s flight). Truth and error-free IMU readings come from :mod:`navgate.sim.trajectory`;
sensor errors from :class:`navgate.sim.sensors.ImuModel` with a Table-1 specification;
the INS is :mod:`navgate.systems.gpsins.ins` (RK4, 100 Hz) and the filter either the full
filter :mod:`navgate.systems.gpsins.augmented` (``filter="full"``, the default: the nine
navigation error states plus the sensor model's biases and scale factors, noise from the
sensor model), smoothable by :mod:`navgate.systems.gpsins.smoother`, or the seed's 9-state
:mod:`navgate.systems.gpsins.filter` (``filter="seed"``, with the pessimistic Q below).
Scoring: the whole-flight ratio (GPS/INS RMS over every sample, outage included,
over GPS-only RMS over its valid fixes) and the outage-excluded ratio, each beside the
trajectory-exact bound (:func:`trajectory_bound`).

Table 1 interpretation (the seed's table is garbled; docs/seed002-gpsins.md has the
argument):

* accelerometer scale factor 250 mV/g with "+-25/3 mV/g": the +-25 mV/g is the data
  sheet's unit-to-unit tolerance of the nominal scale factor, a 3-sigma limit, so
  sigma = 8.33 mV/g = 3.33 % (each simulated unit draws its own scale factors from it);
* gyro scale factor 1.11 mV/(deg/s) with "+-10/3 %": likewise sigma = 3.33 %;
* an installed unit is calibrated before use (multi-position tumble for the accelerometers,
  rate table for the gyros: :func:`calibrate_scale`), which removes the tolerance and
  leaves a residual, 0.3 % (1 sigma) for both sensors: the order of the temperature and
  nonlinearity terms of MEMS data sheets that a room-temperature calibration does not
  remove (docs/seed002-gpsins.md). ``Table1(scale_calibrated=False)`` /
  ``--imu table1-uncalibrated`` flies the whole tolerance instead (the earlier reading);
* "0 g offset of the gyroscope, 2500 mV, +-625/3 mV": "0 g offset" is accelerometer
  language (the zero-g output level, V_DD/2 = 2500 mV); sigma = 208 mV = 0.83 g is the
  unit-to-unit spread of that analog level, which no INS can fly with: the pre-flight level
  calibration (aircraft at rest, specific force (0, 0, -g)) measures and removes it, and on
  the z axis that also removes the scale-factor error at 1 g. What remains in flight is the
  offset's drift after calibration, taken as 1 mg (1 sigma, a random constant);
* "typical turn-on drift of the gyroscope" (value lost): 0.003 deg/s (11 deg/h) 1 sigma, a
  random constant per run (what is left of the gyro null after its power-up calibration);
* white noise (the seed models none): accelerometer 100 ug/sqrt(Hz), gyro
  0.015 (deg/s)/sqrt(Hz), MEMS values. (The ADXRS652 data-sheet noise, about
  0.06 (deg/s)/sqrt(Hz) as recalled, is selectable with ``--gyro-noise``);
* GPS: 20 m (1 sigma) per axis (north, east, down), white, 1 Hz.

With this gyro (0.015 deg/s/sqrt(Hz), 0.003 deg/s) no causal filter reaches the earlier
"GPS/INS RMS at most one third of GPS-only" on this flight in expectation: the optimal
filter's expected ratio is 0.40 in the one-channel model and 0.418 along the real trajectory
with every error state (:mod:`navgate.systems.gpsins.bound`). :data:`TACTICAL_TABLE1`
(``--imu tactical``) is a tactical-grade IMU with which the 9-state filter does reach it.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace

import numpy as np
from numba import njit

from navgate.nav.earth import radii_array
from navgate.nav.rotations import quat_from_rotvec, quat_multiply
from navgate.sim import sensors, trajectory
from navgate.systems.gpsins import augmented, bound, smoother
from navgate.systems.gpsins import filter as kf
from navgate.systems.gpsins.ins import EARTH_WGS84, rk4_step

DEG = math.pi / 180.0
G0 = sensors.G0


@dataclass(frozen=True)
class Table1:
    """Seed 002 Table 1 and the values navgate chose where it is garbled or missing."""

    accel_scale_mv_per_g: float = 250.0
    accel_scale_tol_mv_per_g: float = 25.0  #: +-, a 3-sigma limit
    accel_zero_g_mv: float = 2500.0
    accel_zero_g_tol_mv: float = 625.0  #: +-, 3 sigma: removed by pre-flight calibration
    gyro_scale_mv_per_dps: float = 1.11
    gyro_scale_tol_pct: float = 10.0  #: +-, 3 sigma
    accel_residual_offset_g: float = 1e-3  #: 1 sigma, drift after the pre-flight calibration
    gyro_turn_on_drift_dps: float = 0.003  #: 1 sigma (the table's lost value)
    accel_noise_ug_rthz: float = 100.0
    gyro_noise_dps_rthz: float = 0.015
    gps_sigma_m: float = 20.0
    #: the unit's scale factors are calibrated before use (multi-position / rate-table
    #: calibration); False flies the raw data-sheet tolerance (the earlier reading)
    scale_calibrated: bool = True
    accel_scale_residual: float = 0.003  #: 1 sigma, scale-factor error left after calibration
    gyro_scale_residual: float = 0.003  #: 1 sigma, likewise

    @property
    def accel_scale_sigma(self) -> float:
        """Unit-to-unit tolerance of the nominal scale factor (1 sigma, relative)."""
        return self.accel_scale_tol_mv_per_g / 3.0 / self.accel_scale_mv_per_g

    @property
    def gyro_scale_sigma(self) -> float:
        """Unit-to-unit tolerance of the nominal scale factor (1 sigma, relative)."""
        return self.gyro_scale_tol_pct / 3.0 / 100.0

    @property
    def accel_scale_in_flight(self) -> float:
        """Scale-factor error (1 sigma) the INS flies with: the calibration residual, or the
        whole tolerance if the unit is not calibrated."""
        return self.accel_scale_residual if self.scale_calibrated else self.accel_scale_sigma

    @property
    def gyro_scale_in_flight(self) -> float:
        return self.gyro_scale_residual if self.scale_calibrated else self.gyro_scale_sigma

    def imu_spec(self) -> sensors.ImuSpec:
        """An :class:`ImuSpec` for :class:`navgate.sim.sensors.ImuModel`: readings in SI
        (LSB 1, no quantisation), no factory calibration, the scale factor kept (the
        Table-1 scale errors are *not* calibrated out)."""
        if not math.isclose(self.accel_scale_sigma, self.gyro_scale_sigma):
            raise ValueError("ImuModel draws one scale-factor sigma for both sensors")
        return sensors.ImuSpec(
            name="seed002-table1",
            gyro_arw=self.gyro_noise_dps_rthz * DEG,
            gyro_bias_instability=0.0,
            gyro_turn_on_sigma=self.gyro_turn_on_drift_dps * DEG,
            accel_vrw=self.accel_noise_ug_rthz * 1e-6 * G0,
            accel_bias_instability=0.0,
            accel_turn_on_sigma=self.accel_residual_offset_g * G0,
            scale_factor_sigma=self.accel_scale_sigma,
            misalignment_sigma=0.0,
            factory_gyro_bias_sigma=0.0,
            factory_accel_bias_sigma=0.0,
            gyro_lsb=1.0,
            accel_lsb=1.0,
            quantize=False,
        )


@dataclass(frozen=True)
class GpsInsConfig:
    duration_s: float = 300.0
    rate_hz: float = 100.0
    gps_rate_hz: float = 1.0
    outage_start_s: float = 240.0
    outage_s: float = 30.0
    seed: int = 0
    speed_mps: float = 60.0
    turn_rate_dps: float = 3.0
    lat0_deg: float = 17.72  #: Visakhapatnam (the authors' Andhra University)
    lon0_deg: float = 83.32
    h0_m: float = 1000.0
    heading0_deg: float = 30.0
    table1: Table1 = field(default_factory=Table1)
    # initial INS error (1 sigma) and the filter's P0
    init_pos_sigma_m: float = 5.0
    init_vel_sigma_mps: float = 0.1
    init_tilt_sigma_deg: float = 0.1
    init_heading_sigma_deg: float = 1.0
    # filter process noise (spectral densities, per sqrt(Hz)): pessimistic, as the seed
    # prescribes for a filter without bias states (derivation in docs/seed002-gpsins.md)
    q_accel: float = 0.005  #: m/s^2/sqrt(Hz), floor for body x and y
    q_accel_z: float = 0.05  #: m/s^2/sqrt(Hz), floor for body z (covers the residual offset
    #: over an outage: 1 mg^2 * 30 s; horizontal offsets are absorbed by the tilt estimate)
    q_gyro: float = 5e-4  #: rad/s/sqrt(Hz), floor per body axis
    #: scale-factor sigma the filter assumes (accelerometer, gyro); None: the IMU model's
    #: in-flight value (Table1.accel_scale_in_flight, gyro_scale_in_flight)
    q_scale_factor_accel: float | None = None
    q_scale_factor_gyro: float | None = None
    q_tau_s: float = 30.0  #: correlation time that turns it into noise density
    #: "full": the filter with the sensors' own error states (augmented.py; its noise is the
    #: sensor model's white noise); "seed": the seed's 9-state filter with the pessimistic
    #: floors above (filter.py)
    filter: str = "full"
    #: sensor blocks the full filter carries (accelerometer bias, gyro bias, accelerometer
    #: scale, gyro scale); None: carried where the sensor model has that error (sigma > 0).
    #: A block not carried is covered by process noise (bias^2 tau, (sf x excitation)^2 tau)
    carry: tuple = (None, None, None, None)
    smoother: str = "none"  #: "none", "rts" (fixed interval) or "fixed-lag" (full filter)
    lag_s: float = 10.0  #: fixed-lag smoother's lag (s)

    @property
    def q_sf_accel(self) -> float:
        v = self.q_scale_factor_accel
        return self.table1.accel_scale_in_flight if v is None else v

    @property
    def q_sf_gyro(self) -> float:
        v = self.q_scale_factor_gyro
        return self.table1.gyro_scale_in_flight if v is None else v

    def __post_init__(self):
        if not (self.duration_s >= 60 and math.isfinite(self.duration_s)):
            raise ValueError(f"duration must be at least 60 s, got {self.duration_s}")
        if not 10 <= self.rate_hz <= 1000:
            raise ValueError(f"rate_hz: INS rate must be within 10..1000 Hz, got {self.rate_hz}")
        if not 0 < self.gps_rate_hz <= self.rate_hz:
            raise ValueError("GPS rate must be positive and at most the INS rate")
        if self.outage_s < 0 or self.outage_start_s < 0:
            raise ValueError("outage start and length must be non-negative")
        if self.outage_s > 0 and self.outage_start_s + self.outage_s > self.duration_s:
            raise ValueError("the GPS outage must end before the flight does")
        if not 20 <= self.speed_mps <= 300:
            raise ValueError("speed must be within 20..300 m/s")
        if self.filter not in FILTERS:
            raise ValueError(f"unknown filter {self.filter!r}; choose from {', '.join(FILTERS)}")
        if self.smoother not in SMOOTHERS:
            raise ValueError(f"unknown smoother {self.smoother!r}; choose from "
                             f"{', '.join(SMOOTHERS)}")
        if self.smoother != "none" and self.filter != "full":
            raise ValueError("the smoothers run on the full filter (filter='full')")
        if len(self.carry) != 4 or any(c not in (None, True, False) for c in self.carry):
            raise ValueError("carry must be four flags (True, False or None)")
        if not (math.isfinite(self.lag_s) and 0 <= self.lag_s <= self.duration_s):
            raise ValueError(f"lag must be within 0..{self.duration_s:g} s, got {self.lag_s}")

    @property
    def lag_epochs(self) -> int:
        """The fixed lag in GPS epochs, rounded down (no more delay than asked)."""
        return int(math.floor(self.lag_s * self.gps_rate_hz + 1e-9))


FILTERS = ("full", "seed")
SMOOTHERS = ("none", "rts", "fixed-lag")


#: no sensor errors at all (the filter then needs almost no process noise)
IDEAL_TABLE1 = Table1(accel_scale_tol_mv_per_g=0.0, gyro_scale_tol_pct=0.0,
                      accel_residual_offset_g=0.0, gyro_turn_on_drift_dps=0.0,
                      accel_noise_ug_rthz=1e-3, gyro_noise_dps_rthz=1e-6,
                      accel_scale_residual=0.0, gyro_scale_residual=0.0)


def ideal_config(cfg: GpsInsConfig) -> GpsInsConfig:
    """The same flight with an error-free IMU and a filter tuned for it."""
    return replace(cfg, table1=IDEAL_TABLE1, q_accel=1e-3, q_accel_z=1e-3, q_gyro=1e-5,
                   q_scale_factor_accel=0.0, q_scale_factor_gyro=0.0)


def with_gyro_noise(cfg: GpsInsConfig, noise_dps_rthz: float) -> GpsInsConfig:
    """Another gyro white noise; the filter's gyro floor follows it: the floor is the
    root-sum-square of the white noise and a drift part, which is kept (default: the floor
    5e-4 rad/s/sqrt(Hz) less the default noise 2.6e-4 leaves 4.3e-4 for drift and
    scale-factor residue)."""
    old = cfg.table1.gyro_noise_dps_rthz * DEG
    drift_part = math.sqrt(max(cfg.q_gyro ** 2 - old ** 2, 0.0))
    q = math.hypot(drift_part, noise_dps_rthz * DEG)
    return replace(cfg, table1=replace(cfg.table1, gyro_noise_dps_rthz=noise_dps_rthz),
                   q_gyro=q)


def uncalibrated_config(cfg: GpsInsConfig) -> GpsInsConfig:
    """The earlier reading of Table 1: the +-3.33 % (1 sigma) scale-factor tolerances are
    flown uncalibrated (the filter's scale-factor term assumes them too)."""
    return replace(cfg, table1=replace(cfg.table1, scale_calibrated=False))


#: A tactical-grade MEMS IMU (ADIS16495-class; data-sheet figures as recalled, not re-read:
#: gyro angle random walk 0.09 deg/sqrt(h), in-run bias stability 0.8 deg/h, accelerometer
#: velocity random walk 0.008 m/s/sqrt(h)), with the same Table-1 scale tolerances calibrated
#: out to 0.1 % and a 0.1 mg accelerometer offset left after the level calibration. Not the
#: paper's sensors: it shows which sensor grade the one-third RMS target needs
#: (docs/seed002-gpsins.md).
TACTICAL_TABLE1 = Table1(gyro_noise_dps_rthz=0.09 / 60.0, gyro_turn_on_drift_dps=0.8 / 3600.0,
                         accel_noise_ug_rthz=0.008 / 60.0 / G0 * 1e6,
                         accel_residual_offset_g=1e-4, accel_scale_residual=1e-3,
                         gyro_scale_residual=1e-3)


def sensor_model_q(t1: Table1, tau_s: float = 30.0) -> tuple[float, float]:
    """Process-noise floors (accelerometer m/s^2/sqrt(Hz), gyro rad/s/sqrt(Hz)) from the
    sensor model: white noise plus the residual constant (offset, drift) seen as noise over
    the correlation time tau, sqrt(n^2 + b^2 tau)."""
    qa = math.hypot(t1.accel_noise_ug_rthz * 1e-6 * G0,
                    t1.accel_residual_offset_g * G0 * math.sqrt(tau_s))
    qg = math.hypot(t1.gyro_noise_dps_rthz * DEG,
                    t1.gyro_turn_on_drift_dps * DEG * math.sqrt(tau_s))
    return qa, qg


def tactical_config(cfg: GpsInsConfig) -> GpsInsConfig:
    """The same flight with :data:`TACTICAL_TABLE1` and process noise from its sensor model."""
    qa, qg = sensor_model_q(TACTICAL_TABLE1, cfg.q_tau_s)
    return replace(cfg, table1=TACTICAL_TABLE1, q_accel=qa, q_accel_z=qa, q_gyro=qg)


IMU_CHOICES = ("table1", "table1-uncalibrated", "tactical", "ideal")


def config_for_imu(cfg: GpsInsConfig, imu: str) -> GpsInsConfig:
    """``cfg`` with the named IMU model (and the filter tuning that goes with it)."""
    if imu == "table1":
        return cfg
    if imu == "table1-uncalibrated":
        return uncalibrated_config(cfg)
    if imu == "tactical":
        return tactical_config(cfg)
    if imu == "ideal":
        return ideal_config(cfg)
    raise ValueError(f"unknown IMU model {imu!r}; choose from {', '.join(IMU_CHOICES)}")


def flight_plan(cfg: GpsInsConfig):
    """Climb, turns, speed change and cruise (aircraft-like), then straight to the end."""
    segs = [
        trajectory.straight(20.0, label="take-over, level"),
        trajectory.climb(300.0, 5.0, label="climb 300 m"),
        trajectory.turn(90.0, cfg.turn_rate_dps, label="turn right 90"),
        trajectory.straight(20.0, label="cruise"),
        trajectory.turn(-90.0, cfg.turn_rate_dps, label="turn left 90"),
        trajectory.speed_change(cfg.speed_mps + 10.0, 20.0, label="accelerate"),
    ]
    used = sum(s.duration_s for s in segs)
    segs.append(trajectory.straight(max(cfg.duration_s - used, 1.0), label="cruise"))
    return segs


@dataclass
class GpsData:
    t: np.ndarray  #: fix times (s)
    index: np.ndarray  #: IMU sample index of each fix
    lla: np.ndarray  #: (M, 3) measured lat, lon (rad), h (m)
    valid: np.ndarray  #: False inside the outage
    noise_ned: np.ndarray  #: (M, 3) the drawn errors (north, east, down) m


def simulate_gps(truth: trajectory.Trajectory, cfg: GpsInsConfig, rng) -> GpsData:
    """1 Hz fixes: truth plus white N/E/D errors converted with the WGS-84 radii
    (the seed's F_lat = (M + h) and F_lon = (N + h) cos(lat) per radian)."""
    step = int(round(cfg.rate_hz / cfg.gps_rate_hz))
    idx = np.arange(step, len(truth), step)
    sig = cfg.table1.gps_sigma_m
    noise = rng.standard_normal((idx.size, 3)) * sig
    lat, lon, h = truth.lat[idx], truth.lon[idx], truth.h[idx]
    rm, rn = radii_array(lat)
    lla = np.column_stack([lat + noise[:, 0] / (rm + h),
                           lon + noise[:, 1] / ((rn + h) * np.cos(lat)),
                           h - noise[:, 2]])
    t = truth.t[idx]
    valid = ~((t >= cfg.outage_start_s) & (t < cfg.outage_start_s + cfg.outage_s))
    return GpsData(t, idx, lla, valid, noise)


@njit(cache=True)
def process_noise(f_b, w_b, qa0, qg0, sf_acc, sf_gyro, tau, qa, qg):
    """Per-axis spectral densities for this step (in place into ``qa``, ``qg``):
    white-noise floor plus the scale-factor error seen as noise while the axis is excited,
    (sf * excitation)^2 * tau (a constant error over the correlation time tau has the
    variance growth of white noise with that density). The accelerometer's excitation is
    its departure from the level calibration point (0, 0, -g)."""
    for i in range(3):
        # the accelerometer scale error is calibrated at (0, 0, -g): it acts on the departure
        f_dep = f_b[i] + (G0 if i == 2 else 0.0)
        qa[i] = qa0[i] + (sf_acc * f_dep) ** 2 * tau
        qg[i] = qg0[i] + (sf_gyro * w_b[i]) ** 2 * tau


@njit(cache=True)
def _run(x0, P0, gyro, accel, dt, gps_idx, gps_lla, gps_valid, sigma, qa0, qg0, sf_acc,
         sf_gyro, tau):
    """The closed-loop GPS/INS loop: RK4 INS + covariance propagation at the IMU rate,
    GPS updates at their samples. Returns states (N+1, 10), position covariance in metres
    (N+1, 3, 3), innovations (M, 3) and innovation variances (M, 3)."""
    n = gyro.shape[0]
    states = np.empty((n + 1, 10))
    ppos = np.empty((n + 1, 3, 3))
    innov = np.full((gps_idx.shape[0], 3), np.nan)
    s_diag = np.full((gps_idx.shape[0], 3), np.nan)
    x = x0.copy()
    P = P0.copy()
    states[0] = x
    qa = np.empty(3)
    qg = np.empty(3)
    # the scale-factor term uses 1 s running means of the readings, so that white sensor
    # noise does not masquerade as excitation
    lp = min(1.0, dt / 1.0)
    f_avg = accel[0].copy()
    w_avg = gyro[0].copy()
    j = 0
    for k in range(n):
        f_b = accel[k]
        x = rk4_step(x, f_b, gyro[k], dt, EARTH_WGS84)
        f_avg += lp * (f_b - f_avg)
        w_avg += lp * (gyro[k] - w_avg)
        process_noise(f_avg, w_avg, qa0, qg0, sf_acc, sf_gyro, tau, qa, qg)
        kf.propagate(P, x, f_b, dt, qa, qg, EARTH_WGS84)
        while j < gps_idx.shape[0] and gps_idx[j] <= k + 1:
            if gps_idx[j] == k + 1 and gps_valid[j]:
                dx, z, S = kf.gps_update(P, x, gps_lla[j], sigma)
                kf.apply_correction(x, dx)
                for m in range(3):
                    innov[j, m] = z[m]
                    s_diag[j, m] = S[m, m]
            j += 1
        states[k + 1] = x
        hd = kf.measurement_scale(x)
        for a in range(3):
            for b in range(3):
                ppos[k + 1, a, b] = P[a, b] * hd[a] * hd[b]
    hd = kf.measurement_scale(x0)
    for a in range(3):
        for b in range(3):
            ppos[0, a, b] = P0[a, b] * hd[a] * hd[b]
    return states, ppos, innov, s_diag


@dataclass
class Solution:
    name: str
    t: np.ndarray
    err_ned: np.ndarray  #: (N, 3) north, east, down error (m)
    horizontal_error: np.ndarray
    sigma_ned: np.ndarray | None = None  #: (N, 3) 1-sigma (m)
    nees: np.ndarray | None = None


@dataclass
class GpsInsResult:
    cfg: GpsInsConfig
    truth: trajectory.Trajectory
    gps: GpsData
    states: np.ndarray
    ppos: np.ndarray
    gps_only: Solution
    gps_ins: Solution
    imu_record: sensors.ImuRecord
    innovations: np.ndarray
    innovation_var: np.ndarray
    wall_time_s: float = 0.0
    #: the full filter's stored forward pass (for the smoothers); None for the seed filter
    forward: dict | None = None
    smoothed: Solution | None = None  #: the smoother cfg.smoother asks for

    def smooth(self, lags=(None,)) -> list[Solution]:
        """Smoothed solutions of the full filter: one per lag (None: RTS, L: fixed lag of L
        GPS epochs), scored like the filter's (navgate.systems.gpsins.smoother)."""
        if self.forward is None:
            raise ValueError("smoothing needs the full filter (filter='full')")
        fw = self.forward
        dt = 1.0 / self.cfg.rate_hz
        off = fw["off"]
        states, fcs, wcs, qas, qgs = (fw[k] for k in ("states", "fcs", "wcs", "qas", "qgs"))

        def interval(k0, k1, P_start):
            return augmented.interval_covariances(np.ascontiguousarray(P_start), states, fcs,
                                                  wcs, qas, qgs, dt, k0, k1, off)

        out = []
        for sm in smoother.sweep(fw["ep_idx"], fw["p_post"], fw["p_prior"], fw["dxs"],
                                 interval, len(states), dt, lags):
            st = states[:, :3] - sm.pos_err
            scale = augmented.position_scale(st)
            cov = sm.pos_cov * scale[:, :, None] * scale[:, None, :]
            name = "rts" if sm.lag_epochs is None else f"fixed-lag {sm.lag_epochs}"
            out.append(_solution(name, self.truth, st, cov))
        return out

    @property
    def outage_mask(self) -> np.ndarray:
        c = self.cfg
        t = self.truth.t
        return (t >= c.outage_start_s) & (t < c.outage_start_s + c.outage_s)

    def summary(self) -> dict:
        c = self.cfg
        gi = self.gps_ins
        out = self.outage_mask
        sig = gi.sigma_ned
        within_axis = (np.abs(gi.err_ned[:, :2]) <= 3 * sig[:, :2]).all(axis=1)
        horiz_3s = 3 * np.sqrt(sig[:, 0] ** 2 + sig[:, 1] ** 2)
        valid = self.gps.valid
        s = {
            "duration_s": c.duration_s,
            "ins_rate_hz": c.rate_hz,
            "gps_rate_hz": c.gps_rate_hz,
            "outage": {"start_s": c.outage_start_s, "length_s": c.outage_s},
            "seed": c.seed,
            "table1_interpretation": {
                "accel_scale_factor_sigma": c.table1.accel_scale_sigma,
                "gyro_scale_factor_sigma": c.table1.gyro_scale_sigma,
                "accel_residual_offset_g": c.table1.accel_residual_offset_g,
                "gyro_turn_on_drift_dps": c.table1.gyro_turn_on_drift_dps,
                "scale_calibrated": c.table1.scale_calibrated,
                "accel_scale_factor_in_flight_sigma": c.table1.accel_scale_in_flight,
                "gyro_scale_factor_in_flight_sigma": c.table1.gyro_scale_in_flight,
                "accel_noise_ug_rthz": c.table1.accel_noise_ug_rthz,
                "gyro_noise_dps_rthz": c.table1.gyro_noise_dps_rthz,
                "gps_sigma_m": c.table1.gps_sigma_m,
            },
            "gps_only": {
                "fixes": int(valid.sum()),
                "rms_horizontal_error_m": float(np.sqrt(np.mean(
                    self.gps_only.horizontal_error[valid] ** 2))),
                "rms_vertical_error_m": float(np.sqrt(np.mean(
                    self.gps_only.err_ned[valid, 2] ** 2))),
            },
            "gps_ins": {
                "rms_horizontal_error_m": float(np.sqrt(np.mean(gi.horizontal_error ** 2))),
                "rms_horizontal_error_at_fixes_m": float(np.sqrt(np.mean(
                    gi.horizontal_error[self.gps.index[valid]] ** 2))),
                "rms_vertical_error_m": float(np.sqrt(np.mean(gi.err_ned[:, 2] ** 2))),
                "max_horizontal_error_m": float(gi.horizontal_error.max()),
                "max_horizontal_error_during_outage_m": float(
                    gi.horizontal_error[out].max()) if out.any() else None,
                "horizontal_error_at_outage_end_m": float(
                    gi.horizontal_error[out][-1]) if out.any() else None,
                "outage_within_3sigma_per_axis_fraction": float(
                    within_axis[out].mean()) if out.any() else None,
                "outage_within_3sigma_horizontal_fraction": float(
                    (gi.horizontal_error[out] <= horiz_3s[out]).mean()) if out.any() else None,
                "max_3sigma_horizontal_during_outage_m": float(
                    horiz_3s[out].max()) if out.any() else None,
                "nees_position_mean": float(np.mean(gi.nees)),
                "nees_position_dof": 3,
            },
            "wall_time_s": self.wall_time_s,
        }
        s["gps_ins"]["rms_ratio_to_gps_only"] = (s["gps_ins"]["rms_horizontal_error_m"]
                                                 / s["gps_only"]["rms_horizontal_error_m"])
        ms_go = s["gps_only"]["rms_horizontal_error_m"] ** 2
        s["filter"] = {"kind": c.filter, "n_states": int(self.forward["n"]) if self.forward
                       else kf.NX, "states": self.forward["names"] if self.forward else
                       augmented.state_names(np.full(4, -1))}
        if self.forward is not None:
            s["gps_ins"]["fixes_rejected_non_finite"] = int(self.forward["rejected"].sum())
        s["gps_ins"]["rms_horizontal_error_outside_outage_m"] = float(np.sqrt(np.mean(
            gi.horizontal_error[~out] ** 2)))
        s["ratio_whole_flight"] = s["gps_ins"]["rms_ratio_to_gps_only"]
        s["ratio_outage_excluded"] = float(np.sqrt(np.mean(gi.horizontal_error[~out] ** 2)
                                                   / ms_go))
        tb = trajectory_bound(c)
        s["bound_causal"] = tb.ratio_causal
        s["bound_rts"] = tb.ratio_smoothed(None)
        s["trajectory_bound"] = {
            "causal": {"ratio_whole_flight": tb.ratio_causal,
                       "ratio_outage_excluded": tb.ratio_causal_outage_excluded},
            "fixed_lag": {"lag_s": c.lag_epochs / c.gps_rate_hz,
                          "ratio_whole_flight": tb.ratio_smoothed(c.lag_epochs),
                          "ratio_outage_excluded": tb.ratio_smoothed(c.lag_epochs, True)},
            "rts": {"ratio_whole_flight": tb.ratio_smoothed(None),
                    "ratio_outage_excluded": tb.ratio_smoothed(None, True)},
            "n_states": tb.n_states,
            "states": tb.state_names,
            "note": "expected (ensemble mean-square) ratios of the filter matched to the sensor "
                    "model, carrying every error state it has, along this flight's trajectory, "
                    "and of its smoothers (navgate.systems.gpsins.bound.trajectory_bound); "
                    "compare with ratios pooled over seeds",
        }
        if self.smoothed is not None:
            sm = self.smoothed
            s["gps_ins_smoothed"] = {
                "smoother": c.smoother,
                "lag_s": c.lag_epochs / c.gps_rate_hz if c.smoother == "fixed-lag" else None,
                "rms_horizontal_error_m": float(np.sqrt(np.mean(sm.horizontal_error ** 2))),
                "rms_horizontal_error_outside_outage_m": float(np.sqrt(np.mean(
                    sm.horizontal_error[~out] ** 2))),
                "rms_vertical_error_m": float(np.sqrt(np.mean(sm.err_ned[:, 2] ** 2))),
                "max_horizontal_error_during_outage_m": float(
                    sm.horizontal_error[out].max()) if out.any() else None,
                "ratio_whole_flight": float(np.sqrt(np.mean(sm.horizontal_error ** 2)
                                                    / ms_go)),
                "ratio_outage_excluded": float(np.sqrt(np.mean(sm.horizontal_error[~out] ** 2)
                                                       / ms_go)),
                "bound": (tb.ratio_smoothed(None) if c.smoother == "rts"
                          else tb.ratio_smoothed(c.lag_epochs)),
                "nees_position_mean": float(np.mean(sm.nees)),
                "nees_position_dof": 3,
            }
        b = optimal_bound(c)
        s["optimal_filter_bound"] = {
            "rms_horizontal_error_m": b.rms_horizontal_m,
            "rms_ratio_to_gps_only": b.ratio_to_gps_only,
            "note": "one-channel cross-check (straight, level flight, gyro noise and drift "
                    "only): expected ratio of the optimal filter for this IMU's white noise "
                    "and gyro drift (given a bias state); the trajectory bound above is the "
                    "one to compare with (navgate.systems.gpsins.bound)",
        }
        return s


def sensor_sigmas(t1: Table1) -> np.ndarray:
    """1-sigma of the four sensor error blocks the IMU model flies with: accelerometer bias
    (m/s^2), gyro bias (rad/s), accelerometer and gyro scale factors (relative)."""
    return np.array([t1.accel_residual_offset_g * G0, t1.gyro_turn_on_drift_dps * DEG,
                     t1.accel_scale_in_flight, t1.gyro_scale_in_flight])


def white_densities(t1: Table1) -> tuple[float, float]:
    """The sensor model's white-noise densities: accelerometer (m/s^2)^2/Hz, gyro
    (rad/s)^2/Hz (our assumption: Table 1 gives none; docs/seed002-gpsins.md)."""
    return (t1.accel_noise_ug_rthz * 1e-6 * G0) ** 2, (t1.gyro_noise_dps_rthz * DEG) ** 2


def full_filter_setup(cfg: GpsInsConfig, P0_nav: np.ndarray, every_block: bool = False):
    """Layout, P0 and process noise of the full filter, all from the sensor model: the
    blocks ``cfg.carry`` asks for (default: those the model has; ``every_block``: all the
    model has, as the bound carries them); white noise, plus bias^2 tau and the
    scale-factor excitation term for a block the model has but the filter does not carry.
    Returns (off, P0, qa0 (3,), qg0 (3,), sf_acc, sf_gyro)."""
    sig = sensor_sigmas(cfg.table1)
    carry = tuple(bool(sig[i] > 0) if (every_block or cfg.carry[i] is None)
                  else bool(cfg.carry[i]) for i in range(4))
    off, n = augmented.layout(carry)
    P0 = np.zeros((n, n))
    P0[:kf.NX, :kf.NX] = P0_nav
    for b in range(4):
        if off[b] >= 0:
            for i in range(3):
                P0[off[b] + i, off[b] + i] = sig[b] ** 2
    qa_w, qg_w = white_densities(cfg.table1)
    tau = cfg.q_tau_s
    qa0 = np.full(3, qa_w + (0.0 if carry[0] else sig[0] ** 2 * tau))
    qg0 = np.full(3, qg_w + (0.0 if carry[1] else sig[1] ** 2 * tau))
    sf_acc = 0.0 if carry[2] else float(sig[2])
    sf_gyro = 0.0 if carry[3] else float(sig[3])
    return off, P0, qa0, qg0, sf_acc, sf_gyro


def make_truth(cfg: GpsInsConfig) -> trajectory.Trajectory:
    """The flight's truth (independent of the seed)."""
    return trajectory.generate(
        flight_plan(cfg), lat0=cfg.lat0_deg * DEG, lon0=cfg.lon0_deg * DEG, h0=cfg.h0_m,
        heading0=cfg.heading0_deg * DEG, speed0=cfg.speed_mps, rate_hz=cfg.rate_hz,
        duration_s=cfg.duration_s)


def _nav_p0(truth: trajectory.Trajectory, cfg: GpsInsConfig) -> np.ndarray:
    return initial_state(truth, cfg, np.random.default_rng(0))[1]


def trajectory_bound(cfg: GpsInsConfig) -> bound.TrajectoryBound:
    """:func:`navgate.systems.gpsins.bound.trajectory_bound` for this flight and IMU model:
    every error state the sensor model has, its white noise, the scenario's GPS epochs,
    outage and initial sigmas; the causal filter, the RTS smoother and the fixed-lag
    smoother of ``cfg.lag_s``. Cached per flight (the seed does not enter)."""
    return _trajectory_bound(replace(cfg, seed=0, filter="full", smoother="none",
                                     carry=(None, None, None, None)))


@functools.lru_cache(maxsize=8)
def _trajectory_bound(cfg: GpsInsConfig) -> bound.TrajectoryBound:
    truth = make_truth(cfg)
    gyro, accel = truth.imu()
    off, P0, qa0, qg0, _, _ = full_filter_setup(cfg, _nav_p0(truth, cfg), every_block=True)
    n = gyro.shape[0]
    gps = simulate_gps(truth, cfg, np.random.default_rng(0))
    ep_idx = np.concatenate([[0], gps.index]).astype(np.int64)
    t = truth.t
    outage = (t >= cfg.outage_start_s) & (t < cfg.outage_start_s + cfg.outage_s)
    return bound.trajectory_bound(
        truth.states, accel, gyro, 1.0 / cfg.rate_hz, ep_idx, gps.valid, P0,
        np.tile(qa0, (n, 1)), np.tile(qg0, (n, 1)), cfg.table1.gps_sigma_m, off, outage,
        lags=(None, cfg.lag_epochs))


def _solution(name, truth, pos, cov_m) -> Solution:
    """Score positions ``pos`` (N+1, 3: lat, lon, h) with covariance ``cov_m`` (N+1, 3, 3) in
    metres of (north, east, up)."""
    err = _ned_error(pos[:, 0], pos[:, 1], pos[:, 2], truth)
    e_s = np.column_stack([err[:, 0], err[:, 1], -err[:, 2]])
    nees = np.einsum("ni,nij,nj->n", e_s, np.linalg.inv(cov_m), e_s)
    sigma = np.sqrt(np.stack([cov_m[:, 0, 0], cov_m[:, 1, 1], cov_m[:, 2, 2]], axis=1))
    return Solution(name, truth.t, err, np.hypot(err[:, 0], err[:, 1]), sigma, nees)


def optimal_bound(c: GpsInsConfig) -> bound.BoundResult:
    """:func:`navgate.systems.gpsins.bound.flight_bound` for this configuration's IMU and flight."""
    t1 = c.table1
    return bound.flight_bound(
        t1.gyro_noise_dps_rthz * DEG, t1.accel_noise_ug_rthz * 1e-6 * G0,
        gyro_bias=t1.gyro_turn_on_drift_dps * DEG, gps_sigma=t1.gps_sigma_m,
        duration_s=c.duration_s, outage_start_s=c.outage_start_s, outage_s=c.outage_s,
        p0=(c.init_pos_sigma_m, c.init_vel_sigma_mps, c.init_tilt_sigma_deg * DEG))


def _ned_error(lat, lon, h, truth):
    rm, rn = radii_array(truth.lat)
    n = (lat - truth.lat) * (rm + truth.h)
    e = (lon - truth.lon) * (rn + truth.h) * np.cos(truth.lat)
    d = -(h - truth.h)
    return np.column_stack([n, e, d])


def calibrate_scale(rec: sensors.ImuRecord, gyro, accel, t1: Table1, rng):
    """The unit's scale-factor calibration before flight (multi-position tumble for the
    accelerometers, rate table for the gyros). ``rec`` carries the unit's true scale matrices
    (the data-sheet tolerance drawn by :class:`ImuModel`); the calibration estimates each
    diagonal with a relative error drawn from the residual sigma and divides it out.
    Returns (gyro, accel, M_acc) where M_acc is the accelerometer scale matrix still left in
    the readings (for the level calibration). Without calibration (``scale_calibrated``
    False) the readings are returned unchanged and M_acc is the whole tolerance."""
    m_acc = np.linalg.inv(rec.calibration.accel_matrix)
    if not t1.scale_calibrated:
        return gyro, accel, m_acc
    m_gyro = np.linalg.inv(rec.calibration.gyro_matrix)
    d_acc = 1.0 + rng.standard_normal(3) * t1.accel_scale_residual
    d_gyro = 1.0 + rng.standard_normal(3) * t1.gyro_scale_residual
    est_acc = m_acc * d_acc  # M diag(1 + d): the calibration's estimate of the scale matrix
    est_gyro = m_gyro * d_gyro
    gyro = np.ascontiguousarray(gyro @ np.linalg.inv(est_gyro).T)
    accel = np.ascontiguousarray(accel @ np.linalg.inv(est_acc).T)
    return gyro, accel, np.linalg.inv(est_acc) @ m_acc


def initial_state(truth: trajectory.Trajectory, cfg: GpsInsConfig, rng):
    """INS start: truth at t = 0 plus errors drawn from the initial sigmas; and P0."""
    rm, rn = radii_array(truth.lat[0])
    h0 = truth.h[0]
    sp, sv = cfg.init_pos_sigma_m, cfg.init_vel_sigma_mps
    st, sh = cfg.init_tilt_sigma_deg * DEG, cfg.init_heading_sigma_deg * DEG
    dpos = rng.standard_normal(3) * sp
    dvel = rng.standard_normal(3) * sv
    eps = rng.standard_normal(3) * np.array([st, st, sh])
    x0 = np.empty(10)
    x0[0] = truth.lat[0] + dpos[0] / (rm + h0)
    x0[1] = truth.lon[0] + dpos[1] / ((rn + h0) * math.cos(truth.lat[0]))
    x0[2] = h0 - dpos[2]
    x0[3:6] = truth.v_ned[0] + dvel
    # C_hat = (I - E) C: the computed attitude is the truth turned by -eps
    x0[6:10] = quat_multiply(quat_from_rotvec(-eps), truth.q[0])
    P0 = np.diag([(sp / (rm + h0)) ** 2, (sp / ((rn + h0) * math.cos(truth.lat[0]))) ** 2,
                  sp ** 2, sv ** 2, sv ** 2, sv ** 2, st ** 2, st ** 2, sh ** 2])
    return x0, P0


def simulate(cfg: GpsInsConfig, progress=None) -> GpsInsResult:
    """Generate the flight and sensors, run GPS-only and GPS/INS, score both."""
    import time as _time

    start = _time.perf_counter()
    rng = np.random.default_rng(cfg.seed)
    seeds = rng.integers(0, 2**31 - 1, 3)
    if progress:
        progress("trajectory")
    truth = make_truth(cfg)
    if progress:
        progress("sensors")
    gyro_true, accel_true = truth.imu()
    model = sensors.ImuModel(cfg.table1.imu_spec(), rate_hz=cfg.rate_hz, seed=int(seeds[0]))
    rec = model.measure(gyro_true, accel_true)
    gyro = np.ascontiguousarray(np.asarray(rec.gyro_words, float))
    accel = np.asarray(rec.accel_words, float)
    # pre-flight level calibration: the zero-g offsets are measured with the aircraft level at
    # rest (specific force (0, 0, -g)), which also absorbs the z scale-factor error at 1 g:
    # subtract (M - I)(0, 0, -g). The residual offset/drift is ImuModel's turn-on term.
    gyro, accel, m_acc = calibrate_scale(rec, gyro, accel, cfg.table1,
                                         np.random.default_rng((int(seeds[0]), 1)))
    accel = np.ascontiguousarray(accel - (m_acc - np.eye(3)) @ np.array([0.0, 0.0, -G0]))
    gps = simulate_gps(truth, cfg, np.random.default_rng(int(seeds[1])))
    x0, P0 = initial_state(truth, cfg, np.random.default_rng(int(seeds[2])))
    if progress:
        progress("GPS/INS")
    sig = np.full(3, cfg.table1.gps_sigma_m)
    dt = 1.0 / cfg.rate_hz
    forward = None
    if cfg.filter == "seed":
        qa = np.array([cfg.q_accel ** 2, cfg.q_accel ** 2, cfg.q_accel_z ** 2])
        qg = np.full(3, cfg.q_gyro ** 2)
        states, ppos, innov, sdiag = _run(x0, P0, gyro, accel, dt, gps.index.astype(np.int64),
                                          gps.lla, gps.valid, sig, qa, qg, cfg.q_sf_accel,
                                          cfg.q_sf_gyro, cfg.q_tau_s)
    else:
        off, P0f, qa0, qg0, sf_acc, sf_gyro = full_filter_setup(cfg, P0)
        ep_idx = np.concatenate([[0], gps.index]).astype(np.int64)
        (states, fcs, wcs, qas, qgs, ppos, p_post, p_prior, dxs, comps, innov,
         sdiag, rejected) = augmented.run(x0, P0f, gyro, accel, dt, ep_idx, gps.lla, gps.valid, sig,
                                qa0, qg0, sf_acc, sf_gyro, cfg.q_tau_s, off)
        forward = dict(off=off, n=P0f.shape[0], names=augmented.state_names(off),
                       ep_idx=ep_idx, states=states, fcs=fcs, wcs=wcs, qas=qas, qgs=qgs,
                       p_post=p_post, p_prior=p_prior, dxs=dxs, comps=comps,
                       rejected=rejected)
    if progress:
        progress("scoring")
    # ppos is in metres of (dlat, dlon, dh) scaled = (north, east, up) errors of the INS;
    # _solution maps the error to that convention for the NEES
    gi = _solution("gps_ins", truth, states[:, :3], ppos)
    gerr = np.column_stack([gps.noise_ned[:, 0], gps.noise_ned[:, 1], gps.noise_ned[:, 2]])
    go = Solution("gps_only", gps.t, gerr, np.hypot(gerr[:, 0], gerr[:, 1]))
    res = GpsInsResult(cfg, truth, gps, states, ppos, go, gi, rec, innov, sdiag,
                       forward=forward)
    if cfg.smoother != "none":
        if progress:
            progress("smoothing")
        lag = None if cfg.smoother == "rts" else cfg.lag_epochs
        res.smoothed = res.smooth((lag,))[0]
    res.wall_time_s = _time.perf_counter() - start
    return res
