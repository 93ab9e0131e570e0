"""Top level of seed 004's 2x2 adaptive fixed-point Kalman filter (``top_kf.v``), 34 cycles a
frame, and a stream wrapper for the shared verification harness.

:class:`Kf2x2`: start/done handshake. ``start`` (while not busy) is cycle C0; the frame's
operations run at the cycles of :func:`~navgate.systems.kf2x2.schedule.build_schedule` on
the datapath of :func:`~navgate.systems.kf2x2.modules.build_datapath` (registered one-hot
control, operand registers, registered raw products, pipelined flags); ``done`` is high in
C33, exactly 34 cycles after start, and at the end of C33 the state is committed: x <- x+,
P <- P+, Q <- Q_next (if ``adapt_q``), R <- R_next (if ``adapt_r``), plus the previous
correction, innovation and (H Pp H^T) diagonal used by next frame's Q/R updates. A new
``start`` is accepted from C34 on. The frame inputs (A, B, H, u, z, ``adapt_q``,
``adapt_r``) must be held from C0 to C33 (the seed's testbench does the same;
:class:`Kf2x2Stream` registers them). ``init`` (while not busy, priority over ``start``)
loads x, P, Q, R from the ``init_*`` ports and clears the adaptation memory.

Flags: ``div_zero`` (det(S) was 0: 1/det saturated) and ``div_overflow`` are valid from C34,
``overflow`` (some operation of the frame saturated; sticky, pipelined) from C35, each until
the next frame's.

Resources: 4 multipliers (multiplier 3 also serves the Goldschmidt divider, so it is
(N+2) x (N+2) bits), 6 adder/subtractors, one divider sequencer, operand registers per unit
and a register for every intermediate value that is read after its ready cycle.
``LATENCY = 34``, ``THROUGHPUT = 1/34``.
"""

from __future__ import annotations

from fractions import Fraction

from amaranth import Module, Mux, Signal, signed
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware.parameters import CheckedParameters
from navgate.gateware.start_run import start_run_respond
from navgate.systems.kf2x2.model import COMMIT, FRAME_INPUTS, STATE_NAMES, KfParams
from navgate.systems.kf2x2.modules import ModulePlan, build_datapath
from navgate.systems.kf2x2.schedule import FRAME_CYCLES, build_schedule
from navgate.systems.kf2x2.units import Control

__all__ = ["Kf2x2", "Kf2x2Stream", "ModuleHarness", "INIT_NAMES", "GAIN_NAMES"]

#: state words loaded by ``init`` (the others are cleared)
INIT_NAMES = ("x0", "x1", "P00", "P01", "P11", "Q00", "Q01", "Q11", "R00", "R01", "R11")
GAIN_NAMES = ("k00", "k01", "k10", "k11")


def _params_kw(n, frac, q_shift, r_shift, div_iterations, div_seed_bits):
    return KfParams(n=n, frac=frac, q_shift=q_shift, r_shift=r_shift,
                    div_iterations=div_iterations, div_seed_bits=div_seed_bits)


class Kf2x2(CheckedParameters, wiring.Component):
    """Seed 004 2x2 adaptive fixed-point Kalman filter, 34 cycles a frame (start/done)."""

    LATENCY = FRAME_CYCLES
    THROUGHPUT = Fraction(1, FRAME_CYCLES)

    @classmethod
    def check_parameters(cls, n, frac, q_shift, r_shift, div_iterations, div_seed_bits) -> None:
        """The filter's parameter checks (:class:`KfParams`), before the component exists."""
        _params_kw(n, frac, q_shift, r_shift, div_iterations, div_seed_bits)

    def __init__(self, n: int = 20, frac: int = 10, q_shift: int = 5, r_shift: int = 5,
                 div_iterations: int = 1, div_seed_bits: int = 8):
        self.params = _params_kw(n, frac, q_shift, r_shift, div_iterations, div_seed_bits)
        self.n, self.frac = n, frac
        self.schedule = build_schedule(self.params)
        sig = {"start": In(1), "init": In(1), "adapt_q": In(1), "adapt_r": In(1),
               "busy": Out(1), "done": Out(1),
               "overflow": Out(1), "div_zero": Out(1), "div_overflow": Out(1)}
        for name in FRAME_INPUTS:
            sig[name] = In(signed(n))
        for name in INIT_NAMES:
            sig[f"init_{name}"] = In(signed(n))
        for name in STATE_NAMES:
            sig[name] = Out(signed(n))
        for name in GAIN_NAMES:
            sig[name] = Out(signed(n))
        super().__init__(sig)

    def elaborate(self, platform):
        m = Module()
        last = FRAME_CYCLES - 1
        go = Signal()
        m.d.comb += go.eq(self.start & ~self.busy & ~self.init)
        ctl = Control(m, go, FRAME_CYCLES)
        m.d.comb += self.done.eq(ctl.phase[last])
        with m.If(go):
            m.d.sync += self.busy.eq(1)
        with m.Elif(self.done):
            m.d.sync += self.busy.eq(0)
        env = {name: getattr(self, name) for name in FRAME_INPUTS + STATE_NAMES}
        dp = build_datapath(m, self.schedule.ops, self.params, ctl, env)
        for name in GAIN_NAMES:
            m.d.comb += getattr(self, name).eq(dp.values[name])

        # pipelined sticky overflow: per-unit flag registers, OR-ed one cycle later
        any_flag = Signal()
        acc = 0
        for f in dp.flags:
            acc = acc | f
        m.d.comb += any_flag.eq(acc)
        ovf = Signal()
        with m.If(go):
            m.d.sync += ovf.eq(0)
        with m.Else():
            m.d.sync += ovf.eq(ovf | any_flag)
        done_d = Signal()
        m.d.sync += done_d.eq(self.done)
        with m.If(done_d):
            m.d.sync += self.overflow.eq(ovf | any_flag)

        with m.If(~self.busy & self.init):
            for name in STATE_NAMES:
                src = getattr(self, f"init_{name}") if name in INIT_NAMES else 0
                m.d.sync += getattr(self, name).eq(src)
        with m.If(self.done):
            for reg, src in COMMIT.items():
                value = dp.final(src, last)
                if reg.startswith("Q"):
                    value = Mux(self.adapt_q, value, getattr(self, reg))
                elif reg.startswith("R"):
                    value = Mux(self.adapt_r, value, getattr(self, reg))
                m.d.sync += getattr(self, reg).eq(value)
            m.d.sync += [self.div_zero.eq(dp.divider.div_zero),
                         self.div_overflow.eq(dp.divider.overflow)]
        return m


def stream_layouts(n: int):
    """Payload layouts of :class:`Kf2x2Stream` (input: one frame; output: state after it)."""
    fi = {name: signed(n) for name in FRAME_INPUTS}
    fi.update({f"init_{name}": signed(n) for name in INIT_NAMES})
    fi.update({"init": 1, "adapt_q": 1, "adapt_r": 1})
    fo = {name: signed(n) for name in STATE_NAMES + GAIN_NAMES}
    fo.update({"overflow": 1, "div_zero": 1, "div_overflow": 1, "cycles": 8})
    return data.StructLayout(fi), data.StructLayout(fo)


class Kf2x2Stream(wiring.Component):
    """:class:`Kf2x2` behind a stream interface: one input payload = one frame (with an
    optional ``init`` of the state first), one output payload = the committed state, the
    gains, the flags and ``cycles``, the number of cycles from ``start`` to ``done``
    inclusive (34), measured by the wrapper. The result is offered from C35 (the overflow
    flag is pipelined)."""

    def __init__(self, **kw):
        self.core = Kf2x2(**kw)
        self.params = self.core.params
        self.LATENCY = FRAME_CYCLES + 3
        self.THROUGHPUT = Fraction(1, FRAME_CYCLES + 3)
        li, lo = stream_layouts(self.params.n)
        super().__init__({"i": In(stream.Signature(li)), "o": Out(stream.Signature(lo))})

    def elaborate(self, platform):
        m = Module()
        core = self.core
        m.submodules.core = core
        # cycles from start to done inclusive; one settle cycle: the pipelined overflow flag
        # settles in C34
        held, cycles = start_run_respond(
            m, self.i, self.o, start=core.start, done=core.done, width=8,
            steps=(("init", core.init),), inclusive=True, settle=1)
        for name in FRAME_INPUTS:
            m.d.comb += getattr(core, name).eq(getattr(held, name))
        for name in INIT_NAMES:
            m.d.comb += getattr(core, f"init_{name}").eq(getattr(held, f"init_{name}"))
        m.d.comb += [core.adapt_q.eq(held.adapt_q), core.adapt_r.eq(held.adapt_r)]
        for name in STATE_NAMES + GAIN_NAMES:
            m.d.comb += getattr(self.o.payload, name).eq(getattr(core, name))
        m.d.comb += [self.o.payload.overflow.eq(core.overflow),
                     self.o.payload.div_zero.eq(core.div_zero),
                     self.o.payload.div_overflow.eq(core.div_overflow),
                     self.o.payload.cycles.eq(cycles)]
        return m


class ModuleHarness(wiring.Component):
    """One module alone with private units (for per-module tests), its operations at their
    scheduled cycles relative to the module's first issue: ports ``start``, ``done`` (high
    in the cycle of the module's last result), ``i_*``, ``o_*`` (value registers) plus
    ``overflow`` (registered: an operation saturated in the previous cycle)."""

    def __init__(self, module: str, params: KfParams | None = None):
        self.params = params = KfParams() if params is None else params
        self.schedule = build_schedule(params)
        self.mod = ModulePlan(self.schedule, module)
        n = params.n
        sig = {"start": In(1), "done": Out(1), "overflow": Out(1)}
        for name in self.mod.inputs:
            sig[f"i_{name}"] = In(signed(n))
        for name in self.mod.produced:
            sig[f"o_{name}"] = Out(signed(n))
        super().__init__(sig)

    def elaborate(self, platform):
        m = Module()
        mod = self.mod
        ctl = Control(m, self.start, mod.length, "mph")
        env = {name: getattr(self, f"i_{name}") for name in mod.inputs}
        dp = build_datapath(m, mod.ops, self.params, ctl, env, base=mod.release)
        m.d.comb += self.done.eq(ctl.phase[mod.length - 1] if mod.length > 1 else self.start)
        for name in mod.produced:
            m.d.comb += getattr(self, f"o_{name}").eq(dp.values[name])
        acc = 0
        for f in dp.flags:
            acc = acc | f
        m.d.comb += self.overflow.eq(acc)
        return m
