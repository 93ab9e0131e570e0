"""BMP390 ``compensation_engine`` (seed 000 ``spi_master_baro``): raw 24-bit pressure and
temperature + the 21-byte calibration NVM -> float32 pressure (Pa) and temperature (degC).

Float32, on the shared float32 cores, running :data:`navgate.devices.bmp390.FP32_PROGRAM`
(the data sheet's floating-point formulas, operation for operation), rather than the data
sheet's 64-bit integer form: the navigation side consumes float32 anyway, the float32 units
already exist in the design (no 64-bit multiplier), and the float32 error is bounded
rigorously per sample by :func:`navgate.devices.bmp390.compensate_fp32_bound` (at most about
0.12 Pa, 1 cm of altitude, over 300-1250 hPa and -40..85 degC; the part's own RMS noise is
0.9 Pa). Bit-true model: :func:`navgate.devices.bmp390.compensate_fp32`.
"""

from __future__ import annotations

from fractions import Fraction

from amaranth.hdl import Module, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.devices import bmp390

from ..shared_units import forward_units, unit_members
from .fp32_sequencer import Fp32Sequencer, Program

IN_LAYOUT = data.StructLayout({"up": unsigned(24), "ut": unsigned(24),
                               "nvm": unsigned(8 * bmp390.NVM_LEN)})
OUT_LAYOUT = data.StructLayout({"p": unsigned(32), "t": unsigned(32)})


class BaroCompensation(wiring.Component):
    """BMP390 compensation in float32: {up, ut, nvm} -> {p (Pa), t (degC)} float32."""

    def __init__(self, shared_units: bool = False):
        self.program = Program(bmp390.FP32_PROGRAM, bmp390.FP32_INPUTS, bmp390.FP32_OUTPUTS,
                               consts=bmp390.FP32_CONSTANTS)
        self.LATENCY = self.program.latency
        self.THROUGHPUT = Fraction(1, self.program.cycles)
        #: True: the adder and multiplier are outside (:mod:`..shared_units`); a sample is
        #: taken only while ``grant`` is high, and ``busy`` covers the whole computation
        self.shared_units = shared_units
        shared = ({"grant": In(1), "busy": Out(1), **unit_members()} if shared_units else {})
        super().__init__({"i": In(stream.Signature(IN_LAYOUT)),
                          "o": Out(stream.Signature(OUT_LAYOUT)), **shared})

    def elaborate(self, platform):
        m = Module()
        m.submodules.engine = eng = Fp32Sequencer(self.program, shared_units=self.shared_units)
        ip = self.i.payload
        m.d.comb += [eng.i.payload.up.eq(ip.up), eng.i.payload.ut.eq(ip.ut)]
        for name, off, signed_, size in bmp390.NVM_FIELDS:
            raw = ip.nvm[8 * off:8 * (off + size)]
            m.d.comb += getattr(eng.i.payload, f"n_{name}").eq(
                raw.as_signed() if signed_ else raw)
        m.d.comb += [self.o.payload.p.eq(eng.o.payload.p), self.o.payload.t.eq(eng.o.payload.t),
                     self.o.valid.eq(eng.o.valid), eng.o.ready.eq(self.o.ready),
                     eng.par_we.eq(0)]
        if self.shared_units:
            m.d.comb += [eng.i.valid.eq(self.i.valid & self.grant),
                         self.i.ready.eq(eng.i.ready & self.grant), self.busy.eq(eng.busy)]
            forward_units(m, eng, self)
        else:
            m.d.comb += [eng.i.valid.eq(self.i.valid), self.i.ready.eq(eng.i.ready)]
        return m
