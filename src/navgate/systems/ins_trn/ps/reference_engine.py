"""Seed 000's float64 reference engine: the PL's work done by the reference model on the PS.

:class:`ReferenceEngine` implements :class:`~navgate.systems.ins_trn.ps.pl_interface.PlEngine`
with :class:`navgate.nav.eskf.ErrorStateFilter` (strapdown mechanization, 15-state ESKF) and the
float64 IMU calibration of :mod:`navgate.nav.calibration`; it defines what the float32 engines
(``fp32``, ``rtl``, ``fpga-sim``) are measured against.
"""

from __future__ import annotations

import numpy as np

from navgate.nav import eskf, strapdown
from navgate.systems.ins_trn.ps.pl_interface import (
    EngineSetup,
    PlEngine,
    UpdateOutcome,
    check_altitude,
    check_imu_words,
    check_inflate,
    check_trn,
)


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
        self._cal = None  #: calibration arrays for the compiled loop (built on first use)
        self._counts = np.zeros(eskf.N_COUNTERS, np.int64)
        self._no_log = (np.empty((0, strapdown.NAV_SIZE)), np.empty((0, eskf.N_STATES)),
                        np.empty(0))
        self._no_baro = (np.empty(0), np.empty(0, np.int8))

    batch_records = True

    def calibrate(self, gyro_words, accel_words):
        """Calibrated readings (N, 3) of a block of words, the arithmetic of the compiled
        loops (:func:`navgate.nav.eskf.run_records` applies it sample by sample)."""
        cal = self.setup.calibration

        def one(words, lsb, bias, m):
            x = np.asarray(words, float) * lsb - bias
            out = np.empty(x.shape)
            for i in range(3):
                out[:, i] = x[:, 0] * m[i, 0] + x[:, 1] * m[i, 1] + x[:, 2] * m[i, 2]
            return out

        return (one(gyro_words, cal.gyro_lsb, cal.gyro_bias, cal.gyro_matrix),
                one(accel_words, cal.accel_lsb, cal.accel_bias, cal.accel_matrix))

    def _kernel(self, kinds, index, m0, m1, gyro_words, accel_words, baro_alt, baro_status,
                baro_r, log_every, logged, log):
        f = self.filter
        if self._cal is None:
            cal = self.setup.calibration
            self._cal = (np.array([cal.gyro_lsb, cal.accel_lsb], float),
                         np.array([cal.gyro_bias, cal.accel_bias], float),
                         np.array([cal.gyro_matrix, cal.accel_matrix], float))
        c = self._counts
        c[:] = 0
        c[eskf.C_SAMPLES] = self.samples
        c[eskf.C_LOGGED] = logged
        c[eskf.C_HAVE_GOOD] = f._have_good
        h_baro = np.full(1, np.inf)  # inf: no barometer record in the stretch
        out_nav, out_sigma, out_pne = self._no_log if log is None else log
        eskf.run_records(f.nav, f.bias_a, f.bias_g, f.p, f.last_good, kinds, index, m0, m1,
                         gyro_words, accel_words, *self._cal, baro_alt, baro_status,
                         float(baro_r), f.gate1, f.dt, f.q_diag, f.decay_a, f.decay_g, True,
                         log_every, out_nav, out_sigma, out_pne, c, h_baro)
        f._have_good = bool(c[eskf.C_HAVE_GOOD])
        n = int(c[eskf.C_SAMPLES]) - self.samples
        self.samples += n
        bad = int(c[eskf.C_IMU_BAD])
        f.imu_samples_rejected += bad
        self.imu_samples_rejected += bad
        for table, i in ((f.accepted, eskf.C_BARO_ACC), (f.rejected, eskf.C_BARO_REJ)):
            if c[i]:
                table["baro"] = table.get("baro", 0) + int(c[i])
        self.accepted, self.rejected = f.accepted, f.rejected
        f.raise_for(int(c[eskf.C_ERROR]), "baro")
        hb = float(h_baro[0])
        return n, int(c[eskf.C_LOGGED]), (None if hb == np.inf else hb), \
            int(c[eskf.C_BARO_INVALID])

    def propagate(self, gyro_words, accel_words) -> None:
        gyro_words, accel_words = check_imu_words(gyro_words, accel_words, finite=False)
        gyro_words = np.ascontiguousarray(gyro_words)
        accel_words = np.ascontiguousarray(accel_words)
        n = gyro_words.shape[0]
        self._kernel(np.zeros(n, np.uint8), np.arange(n), 0, n, gyro_words, accel_words,
                     self._no_baro[0], self._no_baro[1], 1.0, 1, 0, None)

    def run_records(self, stream, m0, m1, *, baro_sigma, log_every, logged, log):
        return self._kernel(stream.kind, stream.index, int(m0), int(m1), stream.gyro_words,
                            stream.accel_words, stream.baro_altitude, stream.baro_status,
                            float(baro_sigma) ** 2, int(log_every), int(logged), log)

    def _outcome(self, upd) -> UpdateOutcome:
        return UpdateOutcome(bool(upd.accepted), float(upd.nis), upd.correction,
                             "" if upd.accepted else "rejected by chi-square gate")

    def update_altitude(self, h_meas, sigma) -> UpdateOutcome:
        h_meas, sigma = check_altitude(h_meas, sigma)
        out = self._outcome(self.filter.update_altitude(h_meas, sigma))
        self.accepted, self.rejected = self.filter.accepted, self.filter.rejected
        return out

    def update_trn(self, y_ne, cov, lag_s) -> UpdateOutcome:
        y_ne, cov, lag_s = check_trn(y_ne, cov, lag_s)
        out = self._outcome(self.filter.update_position_offset(y_ne, cov, lag_s))
        self.accepted, self.rejected = self.filter.accepted, self.filter.rejected
        return out

    def inflate_p_horizontal(self, d_p) -> None:
        d = check_inflate(d_p)
        self.filter.p[:2, :2] += 0.5 * (d + d.T)

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
