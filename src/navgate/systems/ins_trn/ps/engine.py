"""Seed 000's PS/PL boundary: the interface of the PL engines, and the float64 reference engine.

Seed 000 ("System Architecture", "Data Flow", "Register Map") puts IMU calibration, strapdown
mechanization, covariance propagation, the altitude profile buffer and the Kalman update
engine in the FPGA fabric (PL); the processor (PS) runs the TRN correlation and writes fixes
through registers. :class:`PlEngine` is that boundary as the navigator
(:mod:`navgate.systems.ins_trn.ps.navigator`) sees it; everything the PS side does goes through
these calls, in the register-map groups of the seed:

=============================== =========================================================
call                            seed 000
=============================== =========================================================
``propagate(gyro_w, accel_w)``  IMU burst words -> ``imu_calibration`` -> ``ins_mechanization``
                                + ``covariance_propagator`` (one call may carry many samples;
                                the result is the same as one call per sample)
``update_altitude(h, sigma)``   ``kalman_update_engine``, 1-D (H = e_D)
``update_trn(y, cov, lag)``     ``kalman_update_engine``, 2-D TRN fix (TRN_FIX_N/E, TRN_COV)
``read_nav()``, ``read_bias()`` state registers (position, velocity, attitude, biases)
``read_cov_diag()``,            covariance diagonal; ``read_p_horizontal`` is the 2x2 block
``read_p_horizontal()``         the PS needs for the TRN search window and the NEES
``read_position_ned()``         position in the TRN map frame (metres about the reference
                                point the PS set, see :class:`Fp32Engine`)
``profile_push/read/shift``     ``altitude_profile_manager`` (64-entry buffer)
=============================== =========================================================

The reference engine is the float64 model (:mod:`navgate.nav.eskf`,
:mod:`navgate.nav.strapdown`, :class:`navgate.nav.calibration.ImuCalibration`); the float32
engine (:mod:`navgate.systems.ins_trn.ps.fp32_engine`) is the bit-true face of the gateware.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from navgate.nav import eskf, strapdown
from navgate.nav.earth import LocalTangent
from navgate.trn.profile import ProfileBuffer


@dataclass
class EngineSetup:
    """What the PS writes into the PL before the first IMU sample."""

    calibration: object  #: navgate.nav.calibration.ImuCalibration
    filter: eskf.FilterConfig
    rate_hz: float
    nav0: np.ndarray  #: [lat, lon, h, vN, vE, vD, q0..q3] (float64, rad)
    p0: np.ndarray  #: 15x15
    bias_a0: np.ndarray
    bias_g0: np.ndarray
    reference: LocalTangent  #: the reference point of the NED position (the TRN map frame)
    profile_spacing_m: float = 30.0
    t0: float = 0.0  #: the time of IMU sample count 0 (s; the profile's time base)


@dataclass
class UpdateOutcome:
    accepted: bool
    nis: float
    correction: np.ndarray  #: dx applied (15), zeros when rejected
    reason: str = ""


class PlEngine(ABC):
    """The PL side of seed 000 as the PS sees it (see the module docstring)."""

    name: str = "?"
    #: True where the engine takes the IMU's int16 output words only (its SPI pins), so a
    #: flight with the ideal sensors' float words cannot drive it
    needs_imu_words: bool = False

    def __init__(self, setup: EngineSetup):
        self.setup = setup
        self.accepted: dict = {}
        self.rejected: dict = {}
        self.imu_samples_rejected = 0
        self.samples = 0
        self.profile = ProfileBuffer(min_spacing_m=setup.profile_spacing_m)

    def _count(self, table, kind):
        table[kind] = table.get(kind, 0) + 1

    # -- IMU ----------------------------------------------------------------------------------
    @abstractmethod
    def propagate(self, gyro_words, accel_words) -> None:
        """Run (N, 3) gyro and accelerometer words through calibration, mechanization and
        covariance propagation, sample by sample."""

    # -- Kalman update engine -------------------------------------------------------------------
    @abstractmethod
    def update_altitude(self, h_meas: float, sigma: float) -> UpdateOutcome:
        """1-D barometric altitude update (innovation h_ins - h_meas)."""

    @abstractmethod
    def update_trn(self, y_ne, cov, lag_s: float) -> UpdateOutcome:
        """2-D TRN update with y = p_ins - p_fix (north, east, m), its 2x2 covariance and
        the fix's lag (the fix measured the error ``lag_s`` ago)."""

    @abstractmethod
    def inflate_p_horizontal(self, d_p) -> None:
        """Add the symmetric 2x2 ``d_p`` (m^2) to P's horizontal position block: the PS's
        answer to a TRN divergence (navgate.trn.integrity), written through registers."""

    # -- register reads ------------------------------------------------------------------------
    @abstractmethod
    def read_nav(self) -> np.ndarray:
        """[lat, lon, h, vN, vE, vD, q0, q1, q2, q3] (float64, rad)."""

    @abstractmethod
    def read_position_ned(self) -> tuple[float, float]:
        """(north, east) metres in the reference point's frame (the TRN map frame)."""

    @abstractmethod
    def read_bias(self) -> tuple[np.ndarray, np.ndarray]:
        """(accelerometer bias, gyro bias) estimates."""

    @abstractmethod
    def read_cov(self) -> np.ndarray:
        """The full 15x15 covariance (symmetric; the PL stores its upper triangle)."""

    def read_cov_diag(self) -> np.ndarray:
        return np.diag(self.read_cov()).copy()

    def read_p_horizontal(self) -> np.ndarray:
        return self.read_cov()[:2, :2].copy()

    # -- sensors read through the PL --------------------------------------------------------------
    #: True when the PS reads the barometer and the ranger from the PL's sensor interfaces (the
    #: float32 engines, which model the PL); the reference engine takes the record stream's
    #: values as they are
    pl_sensors: bool = False

    def prepare_baro(self, uncomp_press, uncomp_temp) -> None:  # noqa: B027 (optional hook)
        """The flight's barometer words ahead of time (a model may compute them at once)."""

    def read_baro(self, uncomp_press: int, uncomp_temp: int) -> float:
        """The PL's compensated pressure (Pa) for the BMP390's ADC words."""
        raise NotImplementedError(f"the {self.name} engine has no PL barometer path")

    def read_ranger(self, dist: int, strength: int) -> tuple[int, int]:
        """(distance word, strength) of the ranger frame as the PL's receiver reports it."""
        raise NotImplementedError(f"the {self.name} engine has no PL ranger path")

    # -- simulation figures ---------------------------------------------------------------------
    def hardware_stats(self) -> dict:
        """What a simulated PL counted during the run (cycles, interrupts, DMAs, ...); empty
        for the models."""
        return {}

    # -- altitude profile buffer ---------------------------------------------------------------
    def profile_push(self, **entry) -> str:
        return self.profile.add(**entry)

    def profile_read(self):
        return self.profile.snapshot()

    def profile_shift(self, d_north, d_east, d_vnorth, d_veast, now):
        self.profile.shift(d_north, d_east, d_vnorth, d_veast, now=now)


class ReferenceEngine(PlEngine):
    """Float64 engines: :class:`navgate.nav.eskf.ErrorStateFilter` and the float64 calibration.

    The calibration of a block of words is evaluated per sample and per axis in a fixed
    order (``(w * lsb - b) . M_i`` as three products summed left to right), so a sample's
    calibrated value does not depend on how the samples are blocked.
    """

    name = "reference"

    def __init__(self, setup: EngineSetup):
        super().__init__(setup)
        self.filter = eskf.ErrorStateFilter(setup.nav0, setup.p0, setup.filter,
                                            rate_hz=setup.rate_hz, bias_a0=setup.bias_a0,
                                            bias_g0=setup.bias_g0)
        self._tangent = setup.reference

    def calibrate(self, gyro_words, accel_words):
        cal = self.setup.calibration

        def one(words, lsb, bias, m):
            x = np.asarray(words, float) * lsb - bias
            out = np.empty(x.shape)
            for i in range(3):
                out[:, i] = x[:, 0] * m[i, 0] + x[:, 1] * m[i, 1] + x[:, 2] * m[i, 2]
            return out

        return (one(gyro_words, cal.gyro_lsb, cal.gyro_bias, cal.gyro_matrix),
                one(accel_words, cal.accel_lsb, cal.accel_bias, cal.accel_matrix))

    def propagate(self, gyro_words, accel_words) -> None:
        gyro, accel = self.calibrate(gyro_words, accel_words)
        f = self.filter
        before = f.imu_samples_rejected
        f.propagate(gyro, accel, 0, gyro.shape[0])
        self.imu_samples_rejected += f.imu_samples_rejected - before
        self.samples += gyro.shape[0]

    def _outcome(self, upd) -> UpdateOutcome:
        return UpdateOutcome(bool(upd.accepted), float(upd.nis), upd.correction,
                             "" if upd.accepted else "rejected by chi-square gate")

    def update_altitude(self, h_meas, sigma) -> UpdateOutcome:
        out = self._outcome(self.filter.update_altitude(h_meas, sigma))
        self.accepted, self.rejected = self.filter.accepted, self.filter.rejected
        return out

    def update_trn(self, y_ne, cov, lag_s) -> UpdateOutcome:
        out = self._outcome(self.filter.update_position_offset(y_ne, cov, lag_s))
        self.accepted, self.rejected = self.filter.accepted, self.filter.rejected
        return out

    def inflate_p_horizontal(self, d_p) -> None:
        d = 0.5 * (np.asarray(d_p, float) + np.asarray(d_p, float).T)
        self.filter.p[:2, :2] += d

    def read_nav(self):
        return self.filter.nav.copy()

    def read_position_ned(self):
        pn, pe = self._tangent.to_ned(self.filter.nav[0], self.filter.nav[1])
        return float(pn), float(pe)

    def read_bias(self):
        return self.filter.bias_a.copy(), self.filter.bias_g.copy()

    def read_cov(self):
        return self.filter.p.copy()

    def read_cov_diag(self):
        return np.diag(self.filter.p).copy()

    def read_p_horizontal(self):
        return self.filter.p[:2, :2].copy()


def nav_from_ned(reference: LocalTangent, pn, pe, h, v, q) -> np.ndarray:
    """Geodetic navigation state from NED metres about ``reference`` (PS side, float64)."""
    lat, lon = reference.to_geodetic(pn, pe)
    nav = np.empty(strapdown.NAV_SIZE)
    nav[0], nav[1], nav[2] = float(lat), float(lon), h
    nav[3:6] = v
    nav[6:10] = q
    return nav


def make_engine(name: str, setup: EngineSetup) -> PlEngine:
    """The engine registered as ``name`` (:mod:`.engine_registry`), set up with ``setup``."""
    from navgate.systems.ins_trn.ps.engine_registry import engine_class

    return engine_class(name)(setup)

