"""Seed 000's PS/PL boundary: the interface every PL engine implements, its set-up and guards.

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

The engines: ``reference`` (:mod:`.reference_engine`, the float64 model of
:mod:`navgate.nav.eskf`, :mod:`navgate.nav.strapdown` and
:class:`navgate.nav.calibration.ImuCalibration`), ``fp32`` (:mod:`.fp32_engine`, the bit-true
face of the gateware), ``rtl`` and ``fpga-sim`` (the gateware in Verilator); they are found by
name through :mod:`.engine_registry`.
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


def check_setup(setup: EngineSetup) -> None:
    """What every engine refuses before it writes a register (ValueError naming the field):
    a non-positive or non-finite rate (the PL's dt = 1 / rate), a navigation state out of
    range, a P0 that is not a finite symmetric positive semi-definite 15 x 15 matrix, non-finite
    biases, a filter configuration that is not a FilterConfig."""
    from navgate.nav import validate

    validate.positive("rate_hz", setup.rate_hz)
    nav = validate.finite_array("nav0", setup.nav0, (strapdown.NAV_SIZE,))
    validate.nav_latitude("nav0[0] (latitude)", nav[0])
    validate.height_m("nav0[2] (height)", nav[2])
    validate.unit_quaternion("nav0[6:10] (attitude quaternion)", nav[6:10])
    validate.covariance("p0", setup.p0, eskf.N_STATES)
    validate.finite_array("bias_a0", setup.bias_a0, (3,))
    validate.finite_array("bias_g0", setup.bias_g0, (3,))
    if not isinstance(setup.filter, eskf.FilterConfig):
        raise ValueError(f"filter: expected a FilterConfig, got {type(setup.filter).__name__}")
    if not isinstance(setup.reference, LocalTangent):
        raise ValueError(f"reference: expected a LocalTangent, got "
                         f"{type(setup.reference).__name__}")
    validate.non_negative("profile_spacing_m", setup.profile_spacing_m)
    validate.finite_scalar("t0", setup.t0)


def check_imu_words(gyro_words, accel_words, *, finite: bool = True
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The IMU words of one ``propagate`` call as two float64 (N, 3) arrays of equal length,
    finite unless ``finite=False``. Every engine calls this first: a mis-shaped array would be
    read out of bounds by the compiled sample loops (memory safety), and a NaN word has no SPI
    encoding, so the PL engines refuse it. The float64 reference engine passes
    ``finite=False``: its compiled loop counts a non-finite sample as rejected
    (``imu_samples_rejected``) and integrates the last good one in its place, the same in a
    stretch of records and record by record."""
    from navgate.nav import validate

    # called for every block the navigator propagates (a few samples each): the fast path is
    # two conversions, two shape tests and one isfinite pass per array (a few microseconds);
    # validate.finite_array only runs to name the bad index
    try:
        gw = np.ascontiguousarray(gyro_words, dtype=np.float64)
        aw = np.ascontiguousarray(accel_words, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ValueError(f"gyro_words, accel_words: not numeric arrays ({error})") from None
    for name, w in (("gyro_words", gw), ("accel_words", aw)):
        if w.ndim != 2 or w.shape[1] != 3:
            raise ValueError(f"{name}: expected an N x 3 array of words, got shape {w.shape}")
        if finite and not np.isfinite(w).all():
            validate.finite_array(name, w)
    if gw.shape != aw.shape:
        raise ValueError(f"accel_words: {aw.shape[0]} samples, gyro_words {gw.shape[0]}")
    return gw, aw


def check_altitude(h_meas, sigma) -> tuple[float, float]:
    """A barometric update: finite height, finite positive sigma (a zero or negative sigma
    is a zero or negative R)."""
    from navgate.nav import validate

    return validate.finite_scalar("h_meas", h_meas), validate.positive("sigma", sigma)


def check_trn(y_ne, cov, lag_s) -> tuple[np.ndarray, np.ndarray, float]:
    """A TRN fix: finite 2-vector, 2 x 2 symmetric positive semi-definite covariance, finite
    lag >= 0 (a fix cannot measure the future)."""
    from navgate.nav import validate

    return (validate.finite_array("y_ne", y_ne, (2,)), validate.covariance("cov", cov, 2),
            validate.non_negative("lag_s", lag_s))


def check_inflate(d_p) -> np.ndarray:
    """The PS's answer to a divergence adds a 2 x 2 covariance: finite, symmetric, positive
    semi-definite (anything else could leave P indefinite or NaN)."""
    from navgate.nav import validate

    return validate.covariance("d_p", d_p, 2)


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
        check_setup(setup)
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

    # -- stretches of records in one call ------------------------------------------------------
    #: True when the engine takes whole stretches of IMU and barometer records in one call
    #: (:meth:`run_records`); the navigator then calls the per-record methods only for the
    #: other records
    batch_records: bool = False

    def run_records(self, stream, m0: int, m1: int, *, baro_sigma: float, log_every: int,
                    logged: int, log) -> tuple[int, int, float | None, int]:
        """Records m0..m1-1 of ``stream`` (IMU and barometer; others skipped) exactly as the
        per-record calls would run them, logging into ``log`` = (nav, sigma, p_ne) arrays
        (row ``logged`` onward, see :meth:`Navigator._log`). Returns (IMU samples run, rows
        logged in all, the newest barometer altitude or None when the stretch had none,
        invalid barometer samples)."""
        raise NotImplementedError(f"the {self.name} engine runs records one at a time")

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


def nav_from_ned(reference: LocalTangent, pn, pe, h, v, q) -> np.ndarray:
    """Geodetic navigation state from NED metres about ``reference`` (PS side, float64)."""
    lat, lon = reference.to_geodetic(pn, pe)
    nav = np.empty(strapdown.NAV_SIZE)
    nav[0], nav[1], nav[2] = float(lat), float(lon), h
    nav[3:6] = v
    nav[6:10] = q
    return nav


def make_engine(name: str, setup: EngineSetup, **options) -> PlEngine:
    """The engine registered as ``name`` (:mod:`.engine_registry`), set up with ``setup``
    (``options``: the engine's own keyword arguments, such as the ``board`` engine's board)."""
    from navgate.systems.ins_trn.ps.engine_registry import engine_class

    return engine_class(name)(setup, **options)

