"""Running seed 003's attitude circuit against its bit-true model (thin adapter over
:mod:`navgate.gateware.verify`), and the ``rtl`` engine of ``navgate ahrs``.

:func:`sample_vectors` turns float32 sensor words into the input arrays of
:class:`~navgate.systems.attitude.top.AttitudeStream`; :func:`stream_model` is the matching
model, built on the per-module functions of :mod:`navgate.systems.attitude.mahony_fp32`
(not on the operation program the gateware is scheduled from, so the two are independent);
:func:`verify_samples` runs both on the Amaranth simulator or on Verilator; :func:`run_rtl`
returns the circuit's outputs for a whole log.
"""

from __future__ import annotations

import numpy as np

from navgate.gateware import verify as _verify
from navgate.numerics.fp32 import fp32_mul, is_nan
from navgate.systems.attitude import mahony_fp32 as bt
from navgate.systems.attitude.mahony import SEED003, MahonyParams
from navgate.systems.attitude.program import OUTPUTS, STATE
from navgate.systems.attitude.top import PORT_NAME, AttitudeStream

__all__ = ["sample_vectors", "stream_model", "verify_samples", "run_rtl", "param_bits",
           "lane_vectors", "lane_model"]

SENSOR_PORTS = [f"in_{PORT_NAME[v]}" for v in ("ax", "ay", "az", "mx", "my", "mz",
                                                "gx", "gy", "gz")]
OUT_FIELDS = [f"out_{v}" for v in list(STATE[:13]) + list(OUTPUTS)]


def param_bits(params: MahonyParams) -> dict:
    """The load fields of a parameter set (the circuit's gyro scale is fixed to deg/s)."""
    from navgate.numerics.fp32 import f32_to_bits
    if params.gyro_scale != SEED003.gyro_scale:
        raise ValueError("the circuit takes the gyro in deg/s (gyro_scale = pi/180)")
    return {"kp": int(f32_to_bits(params.kp)), "ki": int(f32_to_bits(params.ki)),
            "t": int(f32_to_bits(params.dt)), "acc_neg": int(params.accel_sign < 0),
            "mag_neg": sum(1 << i for i, s in enumerate(params.mag_sign) if s < 0)}


def sample_vectors(acc, mag, gyro, params: MahonyParams | None = None,
                   load_every: int | None = None) -> dict:
    """Input arrays: ``acc``, ``mag``, ``gyro`` are (N, 3) float32 bit patterns; the first
    sample (and every ``load_every``-th) loads ``params`` (default: none loaded, i.e. the
    reset values)."""
    acc, mag, gyro = (np.asarray(x, dtype=np.uint32).reshape(-1, 3) for x in (acc, mag, gyro))
    n = len(acc)
    cols = np.concatenate([acc, mag, gyro], axis=1)
    inputs = {p: cols[:, i].astype(np.int64) for i, p in enumerate(SENSOR_PORTS)}
    load = np.zeros(n, dtype=np.int64)
    pb = param_bits(params if params is not None else SEED003)
    if params is not None:
        load[0] = 1
        if load_every:
            load[::load_every] = 1
    inputs["load"] = load
    inputs["reset"] = np.zeros(n, dtype=np.int64)
    for k, v in pb.items():
        inputs[k] = np.full(n, v, dtype=np.int64)
    return inputs


def stream_model(solve_cycles: int):
    """Bit-true model of :class:`AttitudeStream` (state from reset, parameters loaded where
    ``load`` is set), built from ``mahony_fp32``'s module functions."""

    def model(seen: dict) -> dict:
        n = len(seen["load"])
        one = np.uint32(0x3F800000)
        z = np.uint32(0)
        q = (one, z, z, z)
        c = tuple(one if i in (0, 4, 8) else z for i in range(9))
        integ = (z, z, z)
        kp, ki, dt = (np.uint32(int(v)) for v in (bt.f32_to_bits(SEED003.kp),
                                                  bt.f32_to_bits(SEED003.ki),
                                                  bt.f32_to_bits(SEED003.dt)))
        acc_neg, mag_neg = SEED003.accel_sign < 0, 0b010
        rows = {k: np.zeros(n, dtype=np.int64) for k in OUT_FIELDS + ["invalid", "saturated",
                                                                      "cycles"]}
        for j in range(n):
            if seen["reset"][j]:
                q = (one, z, z, z)
                c = tuple(one if i in (0, 4, 8) else z for i in range(9))
                integ = (z, z, z)
                kp, ki, dt = (np.uint32(int(v)) for v in (bt.f32_to_bits(SEED003.kp),
                                                          bt.f32_to_bits(SEED003.ki),
                                                          bt.f32_to_bits(SEED003.dt)))
                acc_neg, mag_neg = SEED003.accel_sign < 0, 0b010
            if seen["load"][j]:
                kp, ki, dt = (np.uint32(int(seen[k][j])) for k in ("kp", "ki", "t"))
                acc_neg, mag_neg = bool(seen["acc_neg"][j]), int(seen["mag_neg"][j])
            w = [np.uint32(int(seen[p][j])) for p in SENSOR_PORTS]
            ea = bt.acc_error(*w[0:3], c[2], c[5], c[8], -1.0 if acc_neg else 1.0)
            em = bt.mag_error(*w[3:6], c, tuple(-1.0 if (mag_neg >> i) & 1 else 1.0
                                                for i in range(3)))
            om, integ = bt.gyro_correction(tuple(w[6:9]), ea, em, integ, kp, ki, dt)
            q = bt.quat_update(q, om, fp32_mul(dt, bt.HALF))
            c = bt.dcm_from_quat(q)
            eu = bt.euler_from_dcm(c[0], c[1], c[2], c[5], c[8])
            vals = list(q) + list(c) + [eu.pitch, eu.roll, eu.yaw]
            for k, v in zip(OUT_FIELDS, vals, strict=True):
                rows[k][j] = int(v)
            rows["invalid"][j] = int(any(bool(is_nan(v)) for v in vals))
            rows["saturated"][j] = int(bool(eu.saturated))
            rows["cycles"][j] = solve_cycles
        return rows

    return model


def verify_samples(acc, mag, gyro, params: MahonyParams | None = None, *,
                   backend: str = "amaranth", keep_outputs: bool = False, **kwargs):
    """Run samples through the circuit (``backend`` "amaranth" or "verilator") and the
    model; returns the harness's ``VerifyResult``."""
    dut = AttitudeStream()
    inputs = sample_vectors(acc, mag, gyro, params)
    return _verify.verify(dut, stream_model(dut.core.SOLVE_CYCLES), inputs, backend=backend,
                          name="attitude_top", keep_outputs=keep_outputs,
                          formatters={k: _verify.f32_formatter for k in OUT_FIELDS}, **kwargs)


def run_rtl(acc, mag, gyro, params: MahonyParams, backend: str = "verilator", **kwargs):
    """The circuit's outputs (per-field arrays) for a whole log, and the harness's run."""
    dut = AttitudeStream()
    inputs = sample_vectors(acc, mag, gyro, params)
    return _verify.simulate(dut, inputs, backend=backend, **kwargs)


def lane_vectors(acc, mag, gyro, params: MahonyParams) -> dict:
    """``L`` independent runs ("lanes") of ``T`` samples in one vector file: ``acc``,
    ``mag``, ``gyro`` are (L, T, 3) bit patterns; each lane starts with ``reset`` and a
    parameter load. Lane-major order."""
    acc, mag, gyro = (np.asarray(x, dtype=np.uint32) for x in (acc, mag, gyro))
    n_lanes, t = acc.shape[:2]
    inputs = sample_vectors(acc.reshape(-1, 3), mag.reshape(-1, 3), gyro.reshape(-1, 3),
                            params)
    start = np.zeros(n_lanes * t, dtype=np.int64)
    start[::t] = 1
    inputs["reset"] = start
    inputs["load"] = start.copy()
    return inputs


def lane_model(acc, mag, gyro, params: MahonyParams, solve_cycles: int) -> dict:
    """The model of :func:`lane_vectors`' runs: all lanes in lock-step through one batched
    :class:`~navgate.systems.attitude.mahony_fp32.MahonyCircuitFP32` (same per-module
    functions, vectorised over lanes). Returns the stream's output fields, lane-major."""
    acc, mag, gyro = (np.asarray(x, dtype=np.uint32) for x in (acc, mag, gyro))
    n_lanes, t = acc.shape[:2]
    circ = bt.MahonyCircuitFP32(params, batch=n_lanes)
    out = {k: np.zeros((n_lanes, t), dtype=np.int64) for k in OUT_FIELDS + ["invalid",
                                                                           "saturated"]}
    for j in range(t):
        r = circ.solve([acc[:, j, i] for i in range(3)], [mag[:, j, i] for i in range(3)],
                       [gyro[:, j, i] for i in range(3)])
        vals = list(r.q) + list(r.c) + [r.euler.pitch, r.euler.roll, r.euler.yaw]
        for k, v in zip(OUT_FIELDS, vals, strict=True):
            out[k][:, j] = v
        out["invalid"][:, j] = r.invalid
        out["saturated"][:, j] = r.euler.saturated
    res = {k: v.reshape(-1) for k, v in out.items()}
    res["cycles"] = np.full(n_lanes * t, solve_cycles, dtype=np.int64)
    return res
