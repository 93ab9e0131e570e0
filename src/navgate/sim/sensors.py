"""Sensor error models: ADIS16500-class IMU, BMP390-class barometer, laser/radar AGL rangers.

Every model takes a ``seed`` (NumPy ``default_rng``) so the same command gives the same numbers.

IMU (seed 000 "IMU Interface": ADIS16500 over SPI burst at 400 Hz). The output words are
16-bit two's complement with seed 000's LSBs, 0.00625 deg/s (gyro) and 1.25 mg (accel);
readings beyond the word range saturate and are counted. Error model per axis, on the
interval-average readings:

    raw = M_true (x + b_turn_on + b_in_run(t) + n(t)) + b_factory

where ``M_true = I + diag(scale) + misalignment`` and ``b_factory`` are the factory
calibration the seed-000 calibration block removes
(:class:`navgate.nav.calibration.ImuCalibration`),
``b_turn_on`` is a random constant per run, ``b_in_run`` a first-order Gauss-Markov process
whose standard deviation is the in-run bias stability, and ``n`` white noise from the
angle/velocity random walk: per-sample sigma = ARW / sqrt(dt).

ADIS16500 figures (Analog Devices ADIS16500 data sheet, "Specifications", typical values):
gyro angle random walk 0.29 deg/sqrt(h), in-run bias stability 8.1 deg/h; accelerometer
velocity random walk 0.06 m/s/sqrt(h), in-run bias stability 12.8 micro-g. They were taken
from the data sheet as remembered, not re-read in this environment: docs/sensors.md lists
them for checking against the current revision. The run's random constant ("turn-on" bias,
what is left after the factory and seed-000 calibration) is modelled as 0.05 deg/s (gyro)
and 2 mg (accel), 1 sigma.

Barometer (BMP390-class; Bosch BMP390 data sheet, rev. 1.4): RMS pressure noise 0.9 Pa at
x8 oversampling without IIR filtering (about 7.5 cm), relative accuracy +-3 Pa, absolute
accuracy +-50 Pa: a constant offset drawn with sigma 25 Pa (~2 m) plus a random-walk drift
(weather and temperature) of 0.5 Pa/sqrt(min). Altitude from the ISA barometric formula.

AGL rangers: a body-fixed downward beam; over locally flat terrain the slant range is
AGL / (cos(roll) cos(pitch)). Each preset has a minimum and maximum range (out-of-range
samples return no measurement, flagged), noise sigma = max(abs, rel * range), and a
dropout probability (no return, flagged). Benewake TF-Luna: 0.2-8 m, +-6 cm to 3 m and
+-2 % beyond (Benewake TF-Luna product manual); ``long-range``: a 0.5-1500 m class laser/radar
altimeter, sigma = max(0.3 m, 0.3 %), 2 % dropouts, for flight at useful heights (seeds README:
the Benewake 9-byte frame stays, only the range changes).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numba import njit

from navgate.devices import bmp390, tfluna
from navgate.devices.adis16500 import (
    ACCEL_LSB_M_S2,
    GYRO_LSB_RAD_S,
    encode_accel,
    encode_gyro,
    quantize_words,  # noqa: F401  (re-exported: callers used sim.sensors.quantize_words)
)
from navgate.devices.adis16500 import STANDARD_GRAVITY as G0

DEG = math.pi / 180.0


@dataclass(frozen=True)
class ImuSpec:
    """Error budget of an IMU (SI units). A zero disables that error source."""

    name: str = "ADIS16500"
    gyro_arw: float = 0.29 * DEG / 60.0  #: rad/sqrt(s)
    gyro_bias_instability: float = 8.1 * DEG / 3600.0  #: rad/s (1 sigma of the GM process)
    gyro_bias_tau: float = 600.0  #: s, correlation time of the in-run bias
    gyro_turn_on_sigma: float = 0.05 * DEG  #: rad/s
    accel_vrw: float = 0.06 / 60.0  #: m/s/sqrt(s)
    accel_bias_instability: float = 12.8e-6 * G0  #: m/s^2
    accel_bias_tau: float = 600.0
    accel_turn_on_sigma: float = 2e-3 * G0  #: m/s^2
    scale_factor_sigma: float = 1e-3  #: factory-calibrated, removed by calibration
    misalignment_sigma: float = 0.05 * DEG  #: rad, factory-calibrated
    factory_gyro_bias_sigma: float = 0.2 * DEG  #: rad/s, removed by calibration
    factory_accel_bias_sigma: float = 10e-3 * G0
    gyro_lsb: float = GYRO_LSB_RAD_S
    accel_lsb: float = ACCEL_LSB_M_S2
    quantize: bool = True


ADIS16500 = ImuSpec()

IDEAL_IMU = ImuSpec(
    name="ideal", gyro_arw=0.0, gyro_bias_instability=0.0, gyro_turn_on_sigma=0.0,
    accel_vrw=0.0, accel_bias_instability=0.0, accel_turn_on_sigma=0.0,
    scale_factor_sigma=0.0, misalignment_sigma=0.0, factory_gyro_bias_sigma=0.0,
    factory_accel_bias_sigma=0.0, quantize=False,
)


@dataclass
class ImuRecord:
    """What the IMU produced over a flight."""

    gyro_words: np.ndarray  #: (N, 3) int16 words (or float words when not quantized)
    accel_words: np.ndarray
    gyro_turn_on_bias: np.ndarray  #: (3,) rad/s, truth (for scoring only)
    accel_turn_on_bias: np.ndarray
    gyro_bias: np.ndarray  #: (N, 3) total error bias in SI (turn-on + in-run), truth
    accel_bias: np.ndarray
    saturated: int  #: number of saturated words
    calibration: object  #: the factory calibration (navgate.nav.calibration.ImuCalibration)


@njit(cache=True)
def _first_order(w, phi, y0):
    """y[k] = w[k] + phi y[k-1] with y[-1] = y0 along axis 0 of the (n, 3) ``w``.

    The same recursion, in the same arithmetic, as ``scipy.signal.lfilter([1], [1, -phi], w,
    zi=[phi y0])`` (transposed direct form II: y = 1 w + z, z = 0 w + phi y), without
    importing scipy.signal (2 s) for it (issue 32)."""
    out = np.empty(w.shape)
    for axis in range(w.shape[1]):
        y = y0[axis]
        for k in range(w.shape[0]):
            y = w[k, axis] + phi * y
            out[k, axis] = y
    return out


def _gauss_markov(rng, n, sigma, tau, dt):
    """(n, 3) first-order Gauss-Markov samples, stationary with std ``sigma``."""
    if sigma == 0.0:
        return np.zeros((n, 3))
    phi = math.exp(-dt / tau)
    drive = sigma * math.sqrt(1.0 - phi * phi)
    w = rng.standard_normal((n, 3)) * drive
    x = rng.standard_normal(3) * sigma
    return _first_order(w, phi, x)


class ImuModel:
    """Turns error-free readings into the words an ADIS16500-class IMU would output."""

    def __init__(self, spec: ImuSpec = ADIS16500, rate_hz: float = 400.0, seed: int = 0):
        if not rate_hz > 0:
            raise ValueError("IMU rate must be positive")
        self.spec = spec
        self.rate_hz = float(rate_hz)
        self.rng = np.random.default_rng(seed)

    def measure(self, gyro, accel) -> ImuRecord:
        from navgate.nav.calibration import ImuCalibration

        spec, rng = self.spec, self.rng
        gyro = np.asarray(gyro, float)
        accel = np.asarray(accel, float)
        if gyro.shape != accel.shape or gyro.ndim != 2 or gyro.shape[1] != 3:
            raise ValueError("gyro and accel must both be (N, 3) arrays")
        n = gyro.shape[0]
        dt = 1.0 / self.rate_hz

        def matrix(scale_sigma, mis_sigma):
            m = np.eye(3) + np.diag(rng.standard_normal(3) * scale_sigma)
            off = rng.standard_normal((3, 3)) * mis_sigma
            np.fill_diagonal(off, 0.0)
            return m + off

        m_gyro = matrix(spec.scale_factor_sigma, spec.misalignment_sigma)
        m_accel = matrix(spec.scale_factor_sigma, spec.misalignment_sigma)
        fb_gyro = rng.standard_normal(3) * spec.factory_gyro_bias_sigma
        fb_accel = rng.standard_normal(3) * spec.factory_accel_bias_sigma
        turn_on_g = rng.standard_normal(3) * spec.gyro_turn_on_sigma
        turn_on_a = rng.standard_normal(3) * spec.accel_turn_on_sigma
        bias_g = turn_on_g + _gauss_markov(rng, n, spec.gyro_bias_instability,
                                           spec.gyro_bias_tau, dt)
        bias_a = turn_on_a + _gauss_markov(rng, n, spec.accel_bias_instability,
                                           spec.accel_bias_tau, dt)
        noise_g = rng.standard_normal((n, 3)) * (spec.gyro_arw / math.sqrt(dt))
        noise_a = rng.standard_normal((n, 3)) * (spec.accel_vrw / math.sqrt(dt))
        raw_g = (gyro + bias_g + noise_g) @ m_gyro.T + fb_gyro
        raw_a = (accel + bias_a + noise_a) @ m_accel.T + fb_accel
        saturated = 0
        if spec.quantize:  # the part's output words (devices.adis16500 encoders)
            words_g, sat_g = encode_gyro(raw_g, spec.gyro_lsb)
            words_a, sat_a = encode_accel(raw_a, spec.accel_lsb)
            saturated = sat_g + sat_a
        else:
            words_g = raw_g / spec.gyro_lsb
            words_a = raw_a / spec.accel_lsb
        cal = ImuCalibration(
            gyro_bias=fb_gyro, gyro_matrix=np.linalg.inv(m_gyro),
            accel_bias=fb_accel, accel_matrix=np.linalg.inv(m_accel),
            gyro_lsb=spec.gyro_lsb, accel_lsb=spec.accel_lsb,
        )
        return ImuRecord(words_g, words_a, turn_on_g, turn_on_a, bias_g, bias_a, saturated, cal)


# ---------------------------------------------------------------------------------------------
# Barometer

P0_PA = 101325.0
ISA_LAPSE_K = 2.25577e-5  #: 1/m, ISA troposphere: (1 - k h)
ISA_EXPONENT = 5.25588


def isa_pressure(h):
    """ISA static pressure (Pa) at altitude h (m), troposphere."""
    return P0_PA * (1.0 - ISA_LAPSE_K * np.asarray(h, float)) ** ISA_EXPONENT


def isa_altitude(p):
    """ISA altitude (m) for static pressure p (Pa): the inverse of isa_pressure."""
    return (1.0 - (np.asarray(p, float) / P0_PA) ** (1.0 / ISA_EXPONENT)) / ISA_LAPSE_K


@dataclass(frozen=True)
class BaroSpec:
    name: str = "BMP390"
    noise_pa: float = 0.9
    offset_sigma_pa: float = 25.0
    drift_pa_per_sqrt_s: float = 0.5 / math.sqrt(60.0)
    rate_hz: float = 25.0


BMP390 = BaroSpec()
IDEAL_BARO = BaroSpec(name="ideal", noise_pa=0.0, offset_sigma_pa=0.0, drift_pa_per_sqrt_s=0.0)


@dataclass
class BaroRecord:
    t: np.ndarray
    altitude: np.ndarray  #: ISA altitude (m) from the measured pressure
    pressure: np.ndarray
    valid: np.ndarray


class Barometer:
    """BMP390-class barometric altimeter: pressure with noise, offset and drift."""

    def __init__(self, spec: BaroSpec = BMP390, seed: int = 0):
        self.spec = spec
        self.rng = np.random.default_rng(seed)

    def measure(self, t, h_true) -> BaroRecord:
        spec, rng = self.spec, self.rng
        t = np.asarray(t, float)
        p = isa_pressure(h_true)
        dt = np.diff(t, prepend=t[0])
        drift = np.cumsum(rng.standard_normal(t.size) * spec.drift_pa_per_sqrt_s * np.sqrt(dt))
        offset = rng.standard_normal() * spec.offset_sigma_pa
        p_meas = p + offset + drift + rng.standard_normal(t.size) * spec.noise_pa
        valid = np.isfinite(p_meas) & (p_meas > 0)
        alt = np.where(valid, isa_altitude(np.where(valid, p_meas, P0_PA)), np.nan)
        return BaroRecord(t, alt, p_meas, valid)

    @staticmethod
    def raw_words(record: BaroRecord, temp_c=25.0, par=None):
        """The BMP390's 24-bit ADC values (uncomp_press, uncomp_temp) for the record's pressures
        (devices.bmp390 encoder; invalid samples encode 101325 Pa). The flight's figures use
        the pressures themselves: the encoder's rounding is below 0.02 Pa (2 mm)."""
        p = np.where(record.valid, record.pressure, P0_PA)
        return bmp390.encode(p, np.broadcast_to(temp_c, p.shape),
                             bmp390.DEFAULT_NVM if par is None else par)

    @property
    def altitude_noise_m(self) -> float:
        """Altitude noise (m, 1 sigma) equivalent to the pressure noise near sea level."""
        return self.spec.noise_pa / (P0_PA * ISA_LAPSE_K * ISA_EXPONENT)


# ---------------------------------------------------------------------------------------------
# AGL ranger

RANGE_OK, RANGE_DROPOUT, RANGE_OUT_OF_RANGE = 0, 1, 2


@dataclass(frozen=True)
class RangerSpec:
    name: str
    min_range: float
    max_range: float
    noise_abs: float
    noise_rel: float
    dropout_prob: float
    rate_hz: float = 10.0


TF_LUNA = RangerSpec("tf-luna", 0.2, 8.0, 0.06, 0.02, 0.01, rate_hz=100.0)
LONG_RANGE = RangerSpec("long-range", 0.5, 1500.0, 0.3, 0.003, 0.02, rate_hz=10.0)
RANGER_PRESETS = {s.name: s for s in (TF_LUNA, LONG_RANGE)}


@dataclass
class RangerRecord:
    t: np.ndarray
    slant_range: np.ndarray  #: m (NaN where no return)
    status: np.ndarray  #: RANGE_OK / RANGE_DROPOUT / RANGE_OUT_OF_RANGE

    @property
    def valid(self):
        return self.status == RANGE_OK

    def frames(self, unit_m: float = tfluna.UNIT_M, temp_c: float = 25.0) -> np.ndarray:
        """The Benewake 9-byte UART frames (devices.tfluna) of the record: no return or out of
        range sends distance 0 with strength 0 (unreliable), a return strength 1000."""
        strength = np.where(self.valid, 1000, 0)
        return tfluna.encode_frames(np.where(self.valid, self.slant_range, np.nan), strength,
                                    temp_c, unit_m)


class Ranger:
    """Body-fixed downward AGL ranger (laser or radar altimeter)."""

    def __init__(self, spec: RangerSpec = LONG_RANGE, seed: int = 0, ideal: bool = False):
        self.spec = replace(spec, noise_abs=0.0, noise_rel=0.0, dropout_prob=0.0) if ideal else spec
        self.rng = np.random.default_rng(seed)

    def measure(self, t, agl_true, roll, pitch) -> RangerRecord:
        """Slant ranges for true heights above terrain ``agl_true`` (NaN over DEM voids)."""
        spec, rng = self.spec, self.rng
        t = np.asarray(t, float)
        agl = np.asarray(agl_true, float)
        slant = agl / (np.cos(roll) * np.cos(pitch))
        sigma = np.maximum(spec.noise_abs, spec.noise_rel * np.abs(np.nan_to_num(slant)))
        meas = slant + rng.standard_normal(t.size) * sigma
        status = np.full(t.size, RANGE_OK, dtype=np.int8)
        out = ~np.isfinite(slant) | (slant < spec.min_range) | (slant > spec.max_range)
        status[out] = RANGE_OUT_OF_RANGE
        drop = rng.random(t.size) < spec.dropout_prob
        status[drop & ~out] = RANGE_DROPOUT
        meas = np.where(status == RANGE_OK, meas, np.nan)
        return RangerRecord(t, meas, status)
