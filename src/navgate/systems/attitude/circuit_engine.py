"""The seed 003 circuit as an attitude engine for ``navgate ahrs --engine fp32|rtl``.

``fp32`` runs the float32 bit-true model compiled
(:class:`navgate.systems.attitude.compiled.CompiledSolve`, bit-identical to
:class:`navgate.systems.attitude.mahony_fp32.MahonyCircuitFP32`) over the whole log; ``rtl``
runs the gateware
(:class:`navgate.systems.attitude.top.AttitudeStream`) compiled by Verilator
(:mod:`navgate.systems.attitude.native_sim`). Both see the same float32 words and the same
parameters, so they produce the same bits (the tests check it), and the same CSV.

Mapping a log onto the circuit (docs/seed003-attitude-circuit.md):

* axes as the float64 engine (:func:`navgate.systems.attitude.estimate.resolve_axes`:
  x-io's z-up axes turned to FRD), the NED form of the equations (``accel_sign = -1``,
  magnetometer signs +1); the gyro enters in deg/s (the circuit multiplies by pi/180), the
  accelerometer and magnetometer in the log's units (both are normalised);
* T is fixed (a circuit parameter): the median sample interval of the log, as float32;
* the circuit starts from its reset state (q = 1, C = I, integral 0) and row k of the
  output is the state after the solve of sample k; ``--init`` does not apply;
* yaw is the circuit's [0, 360) angle moved to (-180, 180] (the CSV's convention), the
  other columns are the circuit's float32 words as they are.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from navgate.numerics.fp32 import bits_to_f32, f32_to_bits
from navgate.sim.imu_log import ImuLog
from navgate.systems.attitude.estimate import (
    FLU_TO_FRD,
    AttitudeResult,
    check_run,
    resolve_axes,
)
from navgate.systems.attitude.mahony import SEED003, MahonyParams

__all__ = ["CircuitRun", "circuit_inputs", "run_circuit", "ENGINES"]

ENGINES = ("fp32", "rtl")


@dataclass
class CircuitRun:
    result: AttitudeResult
    params: MahonyParams
    invalid: int  #: samples whose outputs are NaN (zero / non-finite vectors), flagged
    saturated: int  #: samples with a saturated arctangent input
    seconds: float  #: time in the engine (model or simulation, without the build)
    build_seconds: float = 0.0
    cycles: int = 0  #: simulated clock cycles (rtl)
    #: (N,) bool, the circuit's ``invalid`` indication of each sample (``invalid`` counts them)
    invalid_rows: np.ndarray | None = None


def circuit_inputs(log: ImuLog, axes: str, kp: float, ki: float):
    """float32 words (N, 3) x 3 and the circuit parameters for a log."""
    if log.mag is None:
        raise ValueError("the seed 003 circuit needs magnetometer columns")
    axes = resolve_axes(log, axes)
    s = FLU_TO_FRD if axes == "flu" else np.ones(3)
    gyro = np.degrees(log.gyro * s)
    acc, mag = log.acc * s, log.mag * s
    dts = np.diff(log.t)
    dt = float(np.float32(np.median(dts))) if len(dts) else SEED003.dt
    # the reference engine's checks (estimate.check_run), on the period the circuit uses
    check_run(method="mahony", dt=dt, kp=kp, ki=ki, acc0=acc[0] if len(acc) else None)
    params = replace(SEED003, kp=kp, ki=ki, dt=dt, mag_sign=(1.0, 1.0, 1.0), accel_sign=-1.0)
    words = [f32_to_bits(np.asarray(x, dtype=np.float32)) for x in (acc, mag, gyro)]
    return words, params, axes


def _result(log, axes, q, pitch, roll, yaw):
    yaw = np.where(yaw > 180.0, yaw - 360.0, yaw)
    return AttitudeResult(log.t, q, roll, pitch, yaw, axes, True)


def _f(bits):
    return bits_to_f32(np.asarray(bits, dtype=np.uint32)).astype(np.float64)


def run_circuit(log: ImuLog, engine: str, *, axes: str = "auto", kp: float = 1.0,
                ki: float = 0.1) -> CircuitRun:
    """Run the circuit's ``engine`` ("fp32" or "rtl") over ``log``."""
    if engine not in ENGINES:
        raise ValueError(f"engine must be one of {ENGINES}, got {engine!r}")
    (acc, mag, gyro), params, axes = circuit_inputs(log, axes, kp, ki)
    if engine == "fp32":
        from navgate.systems.attitude.compiled import CompiledSolve
        circ = CompiledSolve(params)
        t0 = time.perf_counter()
        out, flags = circ.run(acc, mag, gyro)
        bad, sat = int(np.sum(flags[:, 0])), int(np.sum(flags[:, 1]))
        secs = time.perf_counter() - t0
        res = _result(log, axes, _f(out[:, :4]), _f(out[:, 4]), _f(out[:, 5]), _f(out[:, 6]))
        return CircuitRun(res, params, bad, sat, secs,
                          invalid_rows=np.asarray(flags[:, 0], dtype=bool))
    from navgate.systems.attitude.native_sim import simulate_native
    from navgate.systems.attitude.rtl_sim import sample_vectors
    from navgate.systems.attitude.top import AttitudeStream
    inputs = sample_vectors(acc, mag, gyro, params)
    # AttitudeStream takes no parameters: its Verilog is cached by the source version alone
    o, run = simulate_native(AttitudeStream(), inputs, top="attitude_stream",
                             design="AttitudeStream", params={})
    q = np.column_stack([_f(o[f"out_q{i}"]) for i in range(4)])
    res = _result(log, axes, q, _f(o["out_pitch"]), _f(o["out_roll"]), _f(o["out_yaw"]))
    invalid = np.asarray(o["invalid"], dtype=bool)
    return CircuitRun(res, params, int(np.sum(invalid)), int(np.sum(o["saturated"])),
                      run.seconds, run.build_seconds, run.cycles, invalid_rows=invalid)
