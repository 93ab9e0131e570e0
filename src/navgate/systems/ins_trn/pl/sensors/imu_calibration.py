"""Seed 000 ``imu_calibration``: int16 ADIS16500 words -> float32 SI (rad/s, m/s^2) with LSB
scaling, bias, scale factor and misalignment, on one shared float32 adder/multiplier/converter.

The bit-true specification is :func:`navgate.nav.calibration.apply_calibration_fp32` (the same
function the float32 navigation engine uses); :data:`PROGRAM` is its operation order, written
out for the :class:`~.fp32_sequencer.Fp32Sequencer`, and the tests check the gateware against that
function bit for bit. Parameters (26 float32 words: gyro LSB, accel LSB, 3+3 biases, two 3x3
matrices row-major) are the seed's CAL_* registers, written through ``par_*`` while idle; their
initial values are the seed-000 LSBs with zero bias and identity matrices.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
from amaranth.hdl import Module, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from .fp32_sequencer import Fp32Sequencer, Program

AXES = ("x", "y", "z")
SENSORS = ("g", "a")  # gyro, accel
IN_FIELDS = tuple(f"{s}{ax}" for s in SENSORS for ax in AXES)
PARAMS = (("g_lsb", "a_lsb") + tuple(f"{s}_bias{j}" for s in SENSORS for j in range(3))
          + tuple(f"{s}_m{i}{j}" for s in SENSORS for i in range(3) for j in range(3)))


def _program():
    prog = []
    for s in SENSORS:
        for j, ax in enumerate(AXES):
            prog += [("i2f", f"{s}_t", f"{s}{ax}"), ("mul", f"{s}_t", f"{s}_t", f"{s}_lsb"),
                     ("sub", f"{s}_x{j}", f"{s}_t", f"{s}_bias{j}")]
        for i in range(3):
            prog += [("mul", "p0", f"{s}_m{i}0", f"{s}_x0"), ("mul", "p1", f"{s}_m{i}1", f"{s}_x1"),
                     ("add", "acc", "p0", "p1"), ("mul", "p2", f"{s}_m{i}2", f"{s}_x2"),
                     ("add", f"o_{s}{AXES[i]}", "acc", "p2")]
    return tuple(prog)


PROGRAM = _program()
OUT_FIELDS = tuple(f"o_{f}" for f in IN_FIELDS)
#: cycles per calibrated sample, back to back (load 6, 48 operations, unload 6)
CYCLES = Program(PROGRAM, IN_FIELDS, OUT_FIELDS, PARAMS).cycles
#: cycles from the raw sample accepted to the calibrated sample valid
LATENCY = Program(PROGRAM, IN_FIELDS, OUT_FIELDS, PARAMS).latency


def param_words(cal=None) -> dict[str, int]:
    """The 26 parameter words (float32 bit patterns) of an ImuCalibration (default: identity)."""
    from navgate.nav.calibration import ImuCalibration, calibration_to_fp32

    c = calibration_to_fp32(cal if cal is not None else ImuCalibration())
    out = {"g_lsb": int(c.gyro_lsb), "a_lsb": int(c.accel_lsb)}
    for s, bias, mat in (("g", c.gyro_bias, c.gyro_matrix), ("a", c.accel_bias, c.accel_matrix)):
        for j in range(3):
            out[f"{s}_bias{j}"] = int(bias[j])
            for i in range(3):
                out[f"{s}_m{i}{j}"] = int(np.asarray(mat)[i, j])
    return out


class ImuCalibrationBlock(wiring.Component):
    """Seed 000 imu_calibration: int16 gyro/accel words -> float32 rad/s and m/s^2.

    ``i`` {gx, gy, gz, ax, ay, az} (int16) -> ``o`` {gx..az} (float32 bit patterns).
    """

    def __init__(self, cal=None):
        self.program = Program(PROGRAM, IN_FIELDS, OUT_FIELDS, PARAMS,
                               param_init=param_words(cal))
        self.LATENCY = self.program.latency
        self.THROUGHPUT = Fraction(1, self.program.cycles)
        super().__init__({
            "i": In(stream.Signature(data.StructLayout({f: signed(16) for f in IN_FIELDS}))),
            "o": Out(stream.Signature(data.StructLayout({f: unsigned(32) for f in IN_FIELDS}))),
            "par_we": In(1), "par_addr": In(5), "par_data": In(32), "par_ready": Out(1),
        })

    def elaborate(self, platform):
        m = Module()
        m.submodules.engine = eng = Fp32Sequencer(self.program)
        for f in IN_FIELDS:  # sign-extend to the engine's int32 inputs
            m.d.comb += getattr(eng.i.payload, f).eq(getattr(self.i.payload, f).as_signed())
        for f in IN_FIELDS:
            m.d.comb += getattr(self.o.payload, f).eq(getattr(eng.o.payload, f"o_{f}"))
        m.d.comb += [eng.i.valid.eq(self.i.valid), self.i.ready.eq(eng.i.ready),
                     self.o.valid.eq(eng.o.valid), eng.o.ready.eq(self.o.ready),
                     eng.par_we.eq(self.par_we), eng.par_addr.eq(self.par_addr),
                     eng.par_data.eq(self.par_data), self.par_ready.eq(eng.par_ready)]
        return m
