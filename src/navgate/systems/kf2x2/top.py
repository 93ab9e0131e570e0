"""Top level of seed 004's 2x2 adaptive fixed-point Kalman filter (``top_kf.v``), 34 cycles a
frame, and a stream wrapper for the shared verification harness.

:class:`Kf2x2`: start/done handshake. ``start`` (while not busy) is cycle C0; the eight
:class:`~navgate.systems.kf2x2.modules.KfModule` receive their start pulses at their seed
release cycles (C0, C0, C8, C8, C10, C12, C25, C25); ``done`` is high in C33, exactly 34
cycles after start, and at the end of C33 the state is committed: x <- x+, P <- P+,
Q <- Q_next (if ``adapt_q``), R <- R_next (if ``adapt_r``), plus the previous correction,
innovation and (H Pp H^T) diagonal used by next frame's Q/R updates. A new ``start`` is
accepted from C34 on. The frame inputs (A, B, H, u, z, ``adapt_q``, ``adapt_r``) must be held
from C0 to C33 (the seed's testbench does the same; :class:`Kf2x2Stream` registers them).
``init`` (while not busy, priority over ``start``) loads x, P, Q, R from the ``init_*``
ports and clears the adaptation memory.

Flags, valid from C34 until the next done: ``overflow`` (some operation of the frame
saturated), ``div_zero`` (det(S) was 0: 1/det saturated), ``div_overflow``.

Resources: 4 multipliers (multiplier 3 also serves the Goldschmidt divider, so it is
(N+3) x (N+3) bits), 6 adder/subtractors, one divider sequencer, registers for every
intermediate value. ``LATENCY = 34``, ``THROUGHPUT = 1/34``.
"""

from __future__ import annotations

from fractions import Fraction

from amaranth import Module, Mux, Signal, signed
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.systems.kf2x2.model import COMMIT, FRAME_INPUTS, MODULES, STATE_NAMES, KfParams
from navgate.systems.kf2x2.modules import KfModule
from navgate.systems.kf2x2.schedule import (
    ALU_UNITS,
    DIV_MUL_UNIT,
    FRAME_CYCLES,
    MUL_UNITS,
    SEED_WINDOWS,
    build_schedule,
)
from navgate.systems.kf2x2.units import GoldschmidtSerial, q_alu, q_mul

__all__ = ["Kf2x2", "Kf2x2Stream", "ModuleHarness", "INIT_NAMES", "attach_units"]

#: state words loaded by ``init`` (the others are cleared)
INIT_NAMES = ("x0", "x1", "P00", "P01", "P11", "Q00", "Q01", "Q11", "R00", "R01", "R11")
GAIN_NAMES = ("k00", "k01", "k10", "k11")


def _or(values, shape):
    out = Signal(shape)
    acc = 0
    for v in values:
        acc = acc | v
    return out, acc


def attach_units(m: Module, modules: list[KfModule], params: KfParams, active) -> Signal:
    """Instantiate the shared units used by ``modules`` and wire them (AND-OR operand
    multiplexing). Returns a signal that is high when an operation issued in this cycle
    saturated (``active`` gates it)."""
    n, frac = params.n, params.frac
    flags = []
    used = {u for mod in modules for u in mod.units}
    div = None
    if ("div", 0) in used:
        div = GoldschmidtSerial(n, frac, params.div_iterations, params.div_seed_bits)
        m.submodules.div = div
        users = [mod for mod in modules if ("div", 0) in mod.units]
        start, d = Signal(), Signal(signed(n))
        m.d.comb += [start.eq(_or([u.div_start for u in users], 1)[1]),
                     d.eq(_or([u.div_d for u in users], signed(n))[1])]
        m.d.comb += [div.start.eq(start), div.d.eq(d)]
        for u in users:
            m.d.comb += u.div_q.eq(div.q)
    for k in range(MUL_UNITS):
        users = [mod for mod in modules if ("mul", k) in mod.units]
        if not users and not (div is not None and k == DIV_MUL_UNIT):
            continue
        a = Signal(signed(n), name=f"mul{k}_a")
        b = Signal(signed(n), name=f"mul{k}_b")
        m.d.comb += [a.eq(_or([getattr(u, f"mul{k}_a") for u in users], signed(n))[1]),
                     b.eq(_or([getattr(u, f"mul{k}_b") for u in users], signed(n))[1])]
        if div is not None and k == DIV_MUL_UNIT:
            wide = params.n + 3
            a2 = Signal(signed(wide), name=f"mul{k}_a_wide")
            b2 = Signal(signed(wide), name=f"mul{k}_b_wide")
            m.d.comb += [a2.eq(Mux(div.mul_en, div.mul_a, a)),
                         b2.eq(Mux(div.mul_en, div.mul_b, b))]
            p = Signal(signed(2 * wide), name=f"mul{k}_p")
            m.d.comb += p.eq(a2 * b2)
            m.d.comb += div.mul_p.eq((p >> params.n)[:params.n + 2])
            r, f = q_mul(p, n, frac)
            f = f & ~div.mul_en
        else:
            p = Signal(signed(2 * n), name=f"mul{k}_p")
            m.d.comb += p.eq(a * b)
            r, f = q_mul(p, n, frac)
        rs = Signal(signed(n), name=f"mul{k}_r")
        m.d.comb += rs.eq(r)
        for u in users:
            m.d.comb += getattr(u, f"mul{k}_r").eq(rs)
        flags.append(f)
    for k in range(ALU_UNITS):
        users = [mod for mod in modules if ("alu", k) in mod.units]
        if not users:
            continue
        a = Signal(signed(n), name=f"alu{k}_a")
        b = Signal(signed(n), name=f"alu{k}_b")
        op = Signal(2, name=f"alu{k}_op")
        m.d.comb += [a.eq(_or([getattr(u, f"alu{k}_a") for u in users], signed(n))[1]),
                     b.eq(_or([getattr(u, f"alu{k}_b") for u in users], signed(n))[1]),
                     op.eq(_or([getattr(u, f"alu{k}_op") for u in users], 2)[1])]
        r, f = q_alu(m, a, b, op, n, f"alu{k}")
        rs = Signal(signed(n), name=f"alu{k}_r")
        m.d.comb += rs.eq(r)
        for u in users:
            m.d.comb += getattr(u, f"alu{k}_r").eq(rs)
        flags.append(f)
    any_flag = Signal()
    acc = 0
    for f in flags:
        acc = acc | f
    m.d.comb += any_flag.eq(active & acc)
    return any_flag, div


def _params_kw(n, frac, q_shift, r_shift, div_iterations, div_seed_bits):
    return KfParams(n=n, frac=frac, q_shift=q_shift, r_shift=r_shift,
                    div_iterations=div_iterations, div_seed_bits=div_seed_bits)


class Kf2x2(wiring.Component):
    """Seed 004 2x2 adaptive fixed-point Kalman filter, 34 cycles a frame (start/done)."""

    LATENCY = FRAME_CYCLES
    THROUGHPUT = Fraction(1, FRAME_CYCLES)

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
        cyc = Signal(range(FRAME_CYCLES))
        go = Signal()
        m.d.comb += go.eq(self.start & ~self.busy & ~self.init)
        with m.If(go):
            m.d.sync += [self.busy.eq(1), cyc.eq(1)]
        with m.Elif(self.busy):
            m.d.sync += cyc.eq(cyc + 1)
            with m.If(cyc == last):
                m.d.sync += [self.busy.eq(0), cyc.eq(0)]
        m.d.comb += self.done.eq(self.busy & (cyc == last))

        mods = {}
        for name in MODULES:
            mod = KfModule(self.schedule, name)
            m.submodules[name] = mod
            mods[name] = mod
            rel = SEED_WINDOWS[name][0]
            m.d.comb += mod.start.eq(go if rel == 0 else (self.busy & (cyc == rel)))
        producer = {o: mod for mod in mods.values() for o in mod.produced}
        for mod in mods.values():
            for name in mod.inputs:
                if name in producer:
                    src = getattr(producer[name], f"o_{name}")
                else:
                    src = getattr(self, name)  # frame input or state register
                m.d.comb += getattr(mod, f"i_{name}").eq(src)
        flag, div = attach_units(m, list(mods.values()), self.params, go | self.busy)
        ovf = Signal()
        with m.If(go):
            m.d.sync += ovf.eq(flag)
        with m.Elif(self.busy):
            m.d.sync += ovf.eq(ovf | flag)
        for name in GAIN_NAMES:
            m.d.comb += getattr(self, name).eq(getattr(producer[name], f"o_{name}"))

        with m.If(~self.busy & self.init):
            for name in STATE_NAMES:
                src = getattr(self, f"init_{name}") if name in INIT_NAMES else 0
                m.d.sync += getattr(self, name).eq(src)
        with m.If(self.done):
            for reg, src in COMMIT.items():
                value = getattr(producer[src], f"o_{src}")
                if reg.startswith("Q"):
                    value = Mux(self.adapt_q, value, getattr(self, reg))
                elif reg.startswith("R"):
                    value = Mux(self.adapt_r, value, getattr(self, reg))
                m.d.sync += getattr(self, reg).eq(value)
            m.d.sync += [self.overflow.eq(ovf | flag), self.div_zero.eq(div.div_zero),
                         self.div_overflow.eq(div.overflow)]
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
    inclusive (34), measured by the wrapper."""

    def __init__(self, **kw):
        self.core = Kf2x2(**kw)
        self.params = self.core.params
        self.LATENCY = FRAME_CYCLES + 2
        self.THROUGHPUT = Fraction(1, FRAME_CYCLES + 2)
        li, lo = stream_layouts(self.params.n)
        super().__init__({"i": In(stream.Signature(li)), "o": Out(stream.Signature(lo))})

    def elaborate(self, platform):
        m = Module()
        core = self.core
        m.submodules.core = core
        held = Signal(self.i.payload.shape())
        cycles = Signal(8)
        counting = Signal(8)
        with m.FSM():
            with m.State("IDLE"):
                m.d.comb += self.i.ready.eq(1)
                with m.If(self.i.valid):
                    m.d.sync += held.eq(self.i.payload)
                    with m.If(self.i.payload.init):
                        m.next = "INIT"
                    with m.Else():
                        m.next = "START"
            with m.State("INIT"):
                m.d.comb += core.init.eq(1)
                m.next = "START"
            with m.State("START"):
                m.d.comb += core.start.eq(1)
                m.d.sync += counting.eq(1)
                m.next = "RUN"
            with m.State("RUN"):
                m.d.sync += counting.eq(counting + 1)
                with m.If(core.done):
                    m.d.sync += cycles.eq(counting + 1)
                    m.next = "OUT"
            with m.State("OUT"):
                m.d.comb += self.o.valid.eq(1)
                with m.If(self.o.ready):
                    m.next = "IDLE"
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
    """One module alone with private shared units (for per-module tests): the module's
    ports ``start``, ``done``, ``i_*``, ``o_*`` plus ``overflow`` (an issued operation
    saturated in this cycle)."""

    def __init__(self, module: str, params: KfParams | None = None):
        self.params = params = KfParams() if params is None else params
        self.schedule = build_schedule(params)
        self.mod = KfModule(self.schedule, module)
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
        m.submodules.mod = mod
        m.d.comb += [mod.start.eq(self.start), self.done.eq(mod.done)]
        for name in mod.inputs:
            m.d.comb += getattr(mod, f"i_{name}").eq(getattr(self, f"i_{name}"))
        for name in mod.produced:
            m.d.comb += getattr(self, f"o_{name}").eq(getattr(mod, f"o_{name}"))
        flag, _ = attach_units(m, [mod], self.params, 1)
        m.d.comb += self.overflow.eq(flag)
        return m
