"""The float32 PL engine of seed 000: the op programs of
:mod:`navgate.systems.ins_trn.pl.fp32_program` on the compiled machine of
:mod:`navgate.systems.ins_trn.pl.fp32_exec`, behind the :class:`PlEngine` interface.

Registers as the seed holds them (float32): position as NED metres about the reference point
the PS set (the TRN map frame: the DEM's local tangent, :class:`navgate.nav.earth.LocalTangent`
coordinates, i.e. north = (lat - lat0)(R_N(lat0) + h0), east = (lon - lon0)(R_E(lat0) + h0)
cos lat0), with a Kahan compensation word per horizontal axis; height, NED velocity,
quaternion, biases, the 120 stored elements of P. The PS recovers the geodetic position in
float64 as lat = lat0 + (pN - cN) / m_lat, lon = lon0 + (pE - cE) / m_lon
(:meth:`Fp32Engine.read_nav`). The mechanization integrates exactly these coordinates: the
position increments are scaled by kN = m_lat / (R_N + h) and kE = m_lon / ((R_E + h) cos lat).

The PS writes float64 values into float32 registers rounded to nearest (subnormals
flushed): calibration (:func:`navgate.nav.calibration.calibration_to_fp32`), initial state,
P0, noise, measurement, R, lag and gate. A measurement update runs in two programs: the gate
half (innovation, S, NIS, compare) and, when the sequencer sees ``accept`` and a positive
S (or det S), the apply half (K, Joseph covariance update, closed-loop feedback).
"""

from __future__ import annotations

import math

import numpy as np

from navgate.nav import eskf
from navgate.nav.calibration import calibration_to_fp32
from navgate.nav.earth import radii
from navgate.numerics.fp32 import bits_to_float, float_to_bits
from navgate.systems.ins_trn.pl import fp32_program as fp
from navgate.systems.ins_trn.pl.fp32_exec import Machine, run_samples
from navgate.systems.ins_trn.pl.fp32_program import programs
from navgate.systems.ins_trn.ps.pl_interface import (
    EngineSetup,
    PlEngine,
    UpdateOutcome,
    check_altitude,
    check_imu_words,
    check_inflate,
    check_trn,
    nav_from_ned,
)
from navgate.systems.ins_trn.ps.pl_profile import PlProfileBuffer, ProfileFifoModel
from navgate.trn.profile import PROFILE_DEPTH


class Fp32Engine(PlEngine):
    """Bit-true float32 model of seed 000's PL engines."""

    name = "fp32"
    compensated = True

    def __init__(self, setup: EngineSetup, *, check_pd: bool = False):
        super().__init__(setup)
        self.profile = PlProfileBuffer(self._profile_fifo(), self.sample_time,
                                       min_spacing_m=setup.profile_spacing_m)
        self.m = Machine(programs(self.compensated))
        self._baro_cache: dict = {}
        self.check_pd = check_pd
        self.pd_stats = np.zeros(2, np.int64)  #: [not positive definite, non-finite]
        self._write_config(setup)
        self._write_state(setup)
        self._gate = {1: eskf.chi2_gate(setup.filter.gate_probability, 1),
                      2: eskf.chi2_gate(setup.filter.gate_probability, 2)}

    # -- PS register writes -------------------------------------------------------------------
    def _write_config(self, s: EngineSetup):
        m = self.m
        cal = calibration_to_fp32(s.calibration)
        for sensor, lsb, bias, mat in (("g", cal.gyro_lsb, cal.gyro_bias, cal.gyro_matrix),
                                       ("a", cal.accel_lsb, cal.accel_bias, cal.accel_matrix)):
            m.regs[m.index[f"cal_{sensor}_lsb"]] = bits_to_float(lsb)
            for j in range(3):
                m.regs[m.index[f"cal_{sensor}_b{j}"]] = bits_to_float(bias[j])
                for i in range(3):
                    m.regs[m.index[f"cal_{sensor}_m{i}{j}"]] = bits_to_float(mat[i, j])
        dt = 1.0 / s.rate_hz
        c = s.filter
        decay_a = math.exp(-dt / c.accel_bias_tau)
        decay_g = math.exp(-dt / c.gyro_bias_tau)
        ref = s.reference
        values = {
            "dt": dt, "half_dt": 0.5 * dt,
            "q_vel": c.accel_vrw**2 * dt, "q_att": c.gyro_arw**2 * dt,
            "q_ba": c.accel_bias_sigma**2 * (1.0 - decay_a**2),
            "q_bg": c.gyro_bias_sigma**2 * (1.0 - decay_g**2),
            "eps_a": -math.expm1(-dt / c.accel_bias_tau),
            "eps_g": -math.expm1(-dt / c.gyro_bias_tau),
            "e2_a": -math.expm1(-2.0 * dt / c.accel_bias_tau),
            "e2_g": -math.expm1(-2.0 * dt / c.gyro_bias_tau),
            "sin_lat0": math.sin(ref.lat0), "cos_lat0": math.cos(ref.lat0),
            "inv_mlat": 1.0 / ref.m_per_rad_lat, "m_lat": ref.m_per_rad_lat,
            "m_lon": ref.m_per_rad_lon,
        }
        for k, v in values.items():
            m.set(k, v)

    def _write_state(self, s: EngineSetup):
        m = self.m
        nav = s.nav0
        pn, pe = s.reference.to_ned(nav[0], nav[1])
        for name, v in zip(fp.NAV_REGS, [pn, pe, *nav[2:]], strict=True):
            m.set(name, float(v))
        for name in ("cN", "cE", "cD", "cvN", "cvE", "cvD", "cq0", "cq1", "cq2", "cq3"):
            m.set(name, 0.0)
        rn, re = radii(nav[0])
        m.set("kN", s.reference.m_per_rad_lat / (rn + nav[2]))
        m.set("kE", s.reference.m_per_rad_lon / ((re + nav[2]) * math.cos(nav[0])))
        for i in range(3):
            m.set(f"ba{i}", s.bias_a0[i])
            m.set(f"bg{i}", s.bias_g0[i])
        p = 0.5 * (s.p0 + s.p0.T)
        for i in range(15):
            for j in range(i, 15):
                m.set(fp.p_reg(i, j), p[i, j])
                m.set("c" + fp.p_reg(i, j), 0.0)

    # -- engine calls ---------------------------------------------------------------------------
    def propagate(self, gyro_words, accel_words) -> None:
        gw, aw = check_imu_words(gyro_words, accel_words)
        c = self.m.compiled["propagate"]
        run_samples(self.m.regs, c.ops, c.table, c.inputs, gw, aw, self.check_pd,
                    self.m.p_idx, self.pd_stats)
        self.samples += gw.shape[0]

    def _update(self, kind, gate_key, apply_key, dof, **inputs) -> UpdateOutcome:
        m = self.m
        out = m.run(gate_key, gate=self._gate[dof], **inputs)
        nis = out["nis"]
        if out["positive"] != 1.0:
            self._count(self.rejected, kind)
            return UpdateOutcome(False, nis, np.zeros(15), "innovation covariance not positive")
        if out["accept"] != 1.0:
            self._count(self.rejected, kind)
            return UpdateOutcome(False, nis, np.zeros(15), "rejected by chi-square gate")
        res = m.run(apply_key, **{k: v for k, v in inputs.items()})
        self._count(self.accepted, kind)
        if self.check_pd:
            p = self.read_cov()
            try:
                np.linalg.cholesky(p)
            except np.linalg.LinAlgError:
                self.pd_stats[0] += 1
            if not np.all(np.isfinite(p)):
                self.pd_stats[1] += 1
        return UpdateOutcome(True, nis, np.array([res[f"dx{i}"] for i in range(15)]))

    def update_altitude(self, h_meas, sigma) -> UpdateOutcome:
        h_meas, sigma = check_altitude(h_meas, sigma)
        return self._update("baro", "alt_gate", "alt_apply", 1, h_meas=h_meas, r=sigma**2)

    def update_trn(self, y_ne, cov, lag_s) -> UpdateOutcome:
        y_ne, cov, lag_s = check_trn(y_ne, cov, lag_s)
        return self._update("trn", "trn_gate", "trn_apply", 2, y0=y_ne[0], y1=y_ne[1],
                            r00=cov[0, 0], r01=0.5 * (cov[0, 1] + cov[1, 0]), r11=cov[1, 1],
                            lag=lag_s)

    # -- the altitude profile in the PL ------------------------------------------------------------
    def _profile_fifo(self):
        """The PL's profile FIFO: here its model (the fpga-sim engine pushes into the PL and
        reads back by DMA)."""
        return ProfileFifoModel(PROFILE_DEPTH)

    def sample_time(self, k: int) -> float:
        """The time (s) of IMU sample count k: ``t0 + k dt``, the record stream's stamps."""
        return self.setup.t0 + int(k) * (1.0 / float(self.setup.rate_hz))

    def correlated_sample(self) -> tuple:
        """What the PL's timestamp correlator latches at a ranger frame: the pN and pE words
        and the IMU samples propagated (the profile entry's position and time)."""
        g = self.m.get
        return float_to_bits(g("pN")), float_to_bits(g("pE")), self.samples

    def profile_push(self, **entry) -> str:
        return self.profile.add(sample=self.correlated_sample(), **entry)

    def profile_read(self):
        """The profile as the PL's FIFO holds it now (time stamps against the samples
        propagated so far)."""
        return self.profile.snapshot(self.samples)

    # -- sensors through the PL ------------------------------------------------------------------
    pl_sensors = True

    def prepare_baro(self, uncomp_press, uncomp_temp) -> None:
        """Compensate a whole flight's barometer words at once (the model is a pure function
        of the words; :meth:`read_baro` then looks the result up)."""
        from navgate.devices import bmp390

        up = np.asarray(uncomp_press, np.int64)
        ut = np.asarray(uncomp_temp, np.int64)
        if up.size:
            p, _ = bmp390.compensate_fp32(up, ut)
            self._baro_cache.update(zip(zip(up.tolist(), ut.tolist(), strict=True),
                                        np.asarray(p, np.uint32).view(np.float32).tolist(),
                                        strict=True))

    def read_baro(self, uncomp_press: int, uncomp_temp: int) -> float:
        """baro_compensation's float32 result (navgate.devices.bmp390.compensate_fp32, which
        the gateware equals bit for bit)."""
        key = (int(uncomp_press), int(uncomp_temp))
        if key not in self._baro_cache:
            self.prepare_baro([key[0]], [key[1]])
        return self._baro_cache[key]

    def read_ranger(self, dist: int, strength: int) -> tuple[int, int]:
        """uart_rx_lidar delivers the frame's words as sent (a frame with a good checksum)."""
        return int(dist), int(strength)

    # -- register reads ---------------------------------------------------------------------------
    def inflate_p_horizontal(self, d_p) -> None:
        """P00, P01, P11 += d (float32 adds, as the PS's register writes would be summed in
        the PL); the compensation words are left as they are."""
        d = check_inflate(d_p)
        d = 0.5 * (d + d.T)
        for i, j in ((0, 0), (0, 1), (1, 1)):
            name = fp.p_reg(i, j)
            self.m.set(name, self.m.get(name) + float(np.float32(d[i, j])))

    def read_position_ned(self):
        g = self.m.get
        return g("pN") - g("cN"), g("pE") - g("cE")

    def read_nav(self):
        g = self.m.get
        pn, pe = self.read_position_ned()
        return nav_from_ned(self.setup.reference, pn, pe, g("h") - g("cD"),
                            [g(v) - g(f"c{v}") for v in ("vN", "vE", "vD")],
                            [g(f"q{i}") - g(f"cq{i}") for i in range(4)])

    def read_bias(self):
        g = self.m.get
        return (np.array([g(f"ba{i}") for i in range(3)]),
                np.array([g(f"bg{i}") for i in range(3)]))

    def read_cov(self):
        v = self.m.regs[self.m.p_idx] - self.m.regs[self.m.cp_idx]
        p = np.empty((15, 15))
        k = 0
        for i in range(15):
            for j in range(i, 15):
                p[i, j] = p[j, i] = v[k]
                k += 1
        return p

    def _p(self, i, j):
        name = fp.p_reg(i, j)
        return self.m.get(name) - self.m.get("c" + name)

    def read_cov_diag(self):
        return np.array([self._p(i, i) for i in range(15)])

    def read_p_horizontal(self):
        return np.array([[self._p(0, 0), self._p(0, 1)], [self._p(0, 1), self._p(1, 1)]])


class Fp32EngineUncompensated(Fp32Engine):
    """The float32 engine without the Kahan position compensation (for the measurements of
    docs/seed000-navigator.md)."""

    name = "fp32-plain"
    compensated = False
