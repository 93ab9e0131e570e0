"""Seed 003's attitude-solving circuit in gateware: ``INS_top`` and the per-module circuits.

Reference: seed 003 sections 2.1 (table 2-1, the top-level interface), 3.1.1 (figure 3-2, the
top FSM: IDLE, ACC_MAG, GYRO, QUAT, MATX, EULER, END) and 3.1.2-3.1.8 (the modules and their
port lists, tables 3-1 to 3-7); bit-true model :mod:`navgate.systems.attitude.mahony_fp32`
(operation order), program :mod:`navgate.systems.attitude.program`, units, phases and banks
:mod:`navgate.systems.attitude.datapath` (scheduled and built by :mod:`navgate.opflow.phased`
and :mod:`navgate.opflow.phased_machine`).

:class:`AttitudeTop` (``attitude_top``)
    Table 2-1's ports: ``in_accx..in_gyroz`` (float32 words, read in the cycle
    ``in_data_en`` is high while the circuit is idle: the sensor interface's FIFO has been
    read completely, section 3.1), ``out_c11..out_c33``, ``out_pitch/roll/yaw`` (degrees,
    yaw in [0, 360)), ``out_INS_finish`` (one cycle, state END). Extensions (marked so in
    docs/seed003-attitude-circuit.md): ``out_q0..out_q3`` (the quaternion state),
    ``out_state`` (FSM state code, :data:`STATES`), ``out_invalid`` (some output is NaN: a
    zero or non-finite accelerometer/magnetometer vector went through, as the model defines
    and flags it), ``out_saturated`` (an arctangent input did not fit Q2.13 in the last
    solve), and the parameter load: while idle, ``in_param_en`` loads ``in_kp``, ``in_ki``,
    ``in_t`` (float32) and the axis signs ``in_acc_neg`` (negate the accelerometer: the
    NED form) and ``in_mag_neg`` (3 bits, x = bit 0). Reset: C = I, q = (1, 0, 0, 0),
    integral 0 (section 3.1), Kp = 10, Ki = 0.5, T = 0.002 s, signs of the seed's circuit
    (magnetometer y negated): :data:`navgate.systems.attitude.mahony.SEED003`.

    One solve: ``in_data_en`` in cycle t; program cycles t+1 .. t+L on the shared units;
    END (``out_INS_finish``) in cycle t+L+1: ``SOLVE_CYCLES = L + 1`` cycles from
    ``in_data_en`` to ``out_INS_finish``. State registers are written as their new values
    leave the units (q in QUAT, C in MATX, the Euler angles in EULER); outputs are valid
    from END until the next solve's QUAT (q) / MATX (C) / EULER (angles) phase.

:class:`ModuleCircuit` (``attitude_acc`` ... ``attitude_euler``)
    One module alone with its own units, the seed's port names (``in_<port>``,
    ``out_<port>``, ``in_<module>_en``, ``out_<module>_finish``), the same microcode
    generator; used for the per-module tables 4-1 .. 4-6 and for per-module resources.
"""

from __future__ import annotations

from amaranth.hdl import Cat, Module, ResetInserter, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware.start_run import start_run_respond
from navgate.numerics.fp32 import f32_to_bits
from navgate.systems.attitude.datapath import make_datapath, make_schedule
from navgate.systems.attitude.mahony import SEED003
from navgate.systems.attitude.program import (
    MODULES,
    OUTPUTS,
    PARAMS,
    SENSORS,
    STATE,
    module_interface,
    solve_program,
)

__all__ = ["AttitudeTop", "AttitudeStream", "ModuleCircuit", "STATES", "PORT_NAME",
           "top_schedule", "solve_cycles"]

STATES = ("IDLE", "ACC_MAG", "GYRO", "QUAT", "MATX", "EULER", "END")
#: program value -> seed port name (without in_/out_)
PORT_NAME = {"ax": "accx", "ay": "accy", "az": "accz", "mx": "magx", "my": "magy",
             "mz": "magz", "gx": "gyrox", "gy": "gyroy", "gz": "gyroz", "dt": "t"}
_RESET = {"q0": 0x3F800000, "c11": 0x3F800000, "c22": 0x3F800000, "c33": 0x3F800000}
_SCHEDULES: dict = {}


def _port(value: str) -> str:
    base = value[:-2] if value.endswith("_n") else value
    return PORT_NAME.get(base, base)


def top_schedule():
    if "top" not in _SCHEDULES:
        sinks = {f"{k}_n": k for k in STATE}
        sinks.update({k: k for k in OUTPUTS})
        _SCHEDULES["top"] = make_schedule(solve_program().ops, SENSORS + STATE + PARAMS, sinks)
    return _SCHEDULES["top"]


def solve_cycles() -> int:
    """Cycles from ``in_data_en`` to ``out_INS_finish`` of :class:`AttitudeTop`."""
    return top_schedule().length + 1


def _nan(x):
    return (x[23:31] == 0xFF) & (x[0:23] != 0)


class AttitudeTop(wiring.Component):
    """Seed 003's INS_top (see the module docstring)."""

    def __init__(self):
        self.schedule = top_schedule()
        self.LATENCY = self.SOLVE_CYCLES = self.schedule.length + 1
        self.THROUGHPUT = 1 / (self.schedule.length + 2)
        sig = {}
        for v in SENSORS:
            sig[f"in_{PORT_NAME[v]}"] = In(32)
        sig.update({"in_data_en": In(1), "in_param_en": In(1), "in_kp": In(32),
                    "in_ki": In(32), "in_t": In(32), "in_acc_neg": In(1), "in_mag_neg": In(3)})
        for c in STATE[4:13]:
            sig[f"out_{c}"] = Out(32)
        for v in OUTPUTS:
            sig[f"out_{v}"] = Out(32)
        for q in STATE[:4]:
            sig[f"out_{q}"] = Out(32)
        sig.update({"out_INS_finish": Out(1), "out_state": Out(range(len(STATES))),
                    "out_invalid": Out(1), "out_saturated": Out(1)})
        super().__init__(sig)

    def elaborate(self, platform):
        m = Module()
        m.submodules.dp = dp = make_datapath(self.schedule)
        p = SEED003
        regs = {}
        for v in SENSORS:
            regs[v] = Signal(32, name=f"r_{v}")
        for v in STATE + OUTPUTS:
            regs[v] = Signal(32, name=f"r_{v}", init=_RESET.get(v, 0))
        regs["kp"] = Signal(32, name="r_kp", init=int(f32_to_bits(p.kp)))
        regs["ki"] = Signal(32, name="r_ki", init=int(f32_to_bits(p.ki)))
        regs["dt"] = Signal(32, name="r_dt", init=int(f32_to_bits(p.dt)))
        acc_neg = Signal(init=int(p.accel_sign < 0))
        mag_neg = Signal(3, init=sum(1 << i for i, s in enumerate(p.mag_sign) if s < 0))
        end = Signal()
        sat = Signal()
        idle = ~dp.busy & ~end
        go = idle & self.in_data_en
        m.d.comb += dp.start.eq(go)
        m.d.sync += end.eq(dp.last)
        with m.If(go):
            for i, v in enumerate(SENSORS):
                word = getattr(self, f"in_{PORT_NAME[v]}")
                if v[0] == "a":
                    flip = acc_neg
                elif v[0] == "m":
                    flip = mag_neg[i - 3]
                else:
                    flip = 0
                # a raw sign flip: its only readers (mul, div) treat it as fp32_neg would
                m.d.sync += regs[v].eq(Cat(word[0:31], word[31] ^ flip))
            m.d.sync += sat.eq(0)
        with m.Elif(dp.atan_sat):
            m.d.sync += sat.eq(1)
        with m.If(idle & ~self.in_data_en & self.in_param_en):
            m.d.sync += [regs["kp"].eq(self.in_kp), regs["ki"].eq(self.in_ki),
                         regs["dt"].eq(self.in_t), acc_neg.eq(self.in_acc_neg),
                         mag_neg.eq(self.in_mag_neg)]
        for name in dp.src_names:
            m.d.comb += getattr(dp, f"src_{name}").eq(regs[name])
        for r in dp.sink_regs:
            with m.If(getattr(dp, f"we_{r}")):
                m.d.sync += regs[r].eq(getattr(dp, f"wd_{r}"))
        outs = list(STATE[:13]) + list(OUTPUTS)
        for v in outs:
            m.d.comb += getattr(self, f"out_{v}").eq(regs[v])
        inval = 0
        for v in outs:
            inval = inval | _nan(regs[v])
        m.d.comb += [self.out_INS_finish.eq(end), self.out_invalid.eq(inval),
                     self.out_saturated.eq(sat)]
        with m.If(end):
            m.d.comb += self.out_state.eq(STATES.index("END"))
        with m.Elif(dp.busy):
            m.d.comb += self.out_state.eq(dp.phase + 1)
        return m


# ------------------------------------------------------------------------ stream wrapper

def stream_layouts():
    li = {f"in_{PORT_NAME[v]}": 32 for v in SENSORS}
    li.update({"reset": 1, "load": 1, "kp": 32, "ki": 32, "t": 32, "acc_neg": 1, "mag_neg": 3})
    lo = {f"out_{v}": 32 for v in list(STATE[:13]) + list(OUTPUTS)}
    lo.update({"invalid": 1, "saturated": 1, "cycles": 10})
    return data.StructLayout(li), data.StructLayout(lo)


class AttitudeStream(wiring.Component):
    """:class:`AttitudeTop` behind one input and one output stream (for the verification
    harness and ``navgate ahrs --engine rtl``): an input payload is one sample (with
    ``load`` set, the parameters are loaded first); the output payload is the state after
    the solve, the flags and ``cycles``, counted from ``in_data_en`` to ``out_INS_finish``
    (the wrapper measures it; it is ``SOLVE_CYCLES``). ``reset`` set: the core is reset
    (one cycle of its domain reset, as ``rst_n``) before the sample, so that one vector file
    can hold many independent runs ("lanes")."""

    def __init__(self):
        self.core = AttitudeTop()
        self.LATENCY = self.core.SOLVE_CYCLES + 3
        self.THROUGHPUT = 1 / (self.core.SOLVE_CYCLES + 3)
        li, lo = stream_layouts()
        super().__init__({"i": In(stream.Signature(li)), "o": Out(stream.Signature(lo))})

    def elaborate(self, platform):
        m = Module()
        core = self.core
        core_rst = Signal()
        m.submodules.core = ResetInserter(core_rst)(core)
        held, cycles = start_run_respond(
            m, self.i, self.o, start=core.in_data_en, done=core.out_INS_finish, width=10,
            steps=(("reset", core_rst), ("load", core.in_param_en)))
        for v in SENSORS:
            n = f"in_{PORT_NAME[v]}"
            m.d.comb += getattr(core, n).eq(getattr(held, n))
        m.d.comb += [core.in_kp.eq(held.kp), core.in_ki.eq(held.ki), core.in_t.eq(held.t),
                     core.in_acc_neg.eq(held.acc_neg), core.in_mag_neg.eq(held.mag_neg)]
        for v in list(STATE[:13]) + list(OUTPUTS):
            m.d.comb += getattr(self.o.payload, f"out_{v}").eq(getattr(core, f"out_{v}"))
        m.d.comb += [self.o.payload.invalid.eq(core.out_invalid),
                     self.o.payload.saturated.eq(core.out_saturated),
                     self.o.payload.cycles.eq(cycles)]
        return m


# ------------------------------------------------------------------------ module circuits

def module_ports(module: str):
    """(inputs, outputs, sink map) of one module's standalone circuit."""
    prog = solve_program()
    ins, outs = module_interface(prog, module)
    sinks = {}
    for v in outs:
        base = v[:-2] if v.endswith("_n") else v
        sinks[v] = base if base in ins else v
    return ins, outs, sinks


class ModuleCircuit(wiring.Component):
    """One seed module alone (see the module docstring): ``in_<port>`` read while
    ``in_<module>_en`` is high and the circuit idle; ``out_<module>_finish`` one cycle after
    the last result is written; ``out_<port>`` hold the results."""

    def __init__(self, module: str):
        if module not in MODULES:
            raise ValueError(f"unknown module {module!r}")
        self.module = module
        ins, outs, sinks = module_ports(module)
        self.ins, self.outs, self.sinks = ins, outs, sinks
        key = f"mod_{module}"
        if key not in _SCHEDULES:
            prog = [o for o in solve_program().ops if o.module == module]
            _SCHEDULES[key] = make_schedule(prog, ins, sinks)
        self.schedule = _SCHEDULES[key]
        self.LATENCY = self.schedule.length + 1
        self.THROUGHPUT = 1 / (self.schedule.length + 2)
        sig = {f"in_{_port(v)}": In(32) for v in ins}
        sig.update({f"out_{_port(v)}": Out(32) for v in outs})
        sig[f"in_{module}_en"] = In(1)
        sig[f"out_{module}_finish"] = Out(1)
        super().__init__(sig)

    def elaborate(self, platform):
        m = Module()
        m.submodules.dp = dp = make_datapath(self.schedule)
        regs = {v: Signal(32, name=f"r_{v}") for v in self.ins}
        for r in self.sinks.values():
            regs.setdefault(r, Signal(32, name=f"r_{r}"))
        end = Signal()
        go = ~dp.busy & ~end & getattr(self, f"in_{self.module}_en")
        m.d.comb += dp.start.eq(go)
        m.d.sync += end.eq(dp.last)
        with m.If(go):
            for v in self.ins:
                word = getattr(self, f"in_{_port(v)}")
                if self.module == "mag" and v == "my":  # the seed's mirrored y axis
                    word = Cat(word[0:31], ~word[31])
                m.d.sync += regs[v].eq(word)
        for name in dp.src_names:
            m.d.comb += getattr(dp, f"src_{name}").eq(regs[name])
        for r in dp.sink_regs:
            with m.If(getattr(dp, f"we_{r}")):
                m.d.sync += regs[r].eq(getattr(dp, f"wd_{r}"))
        for v in self.outs:
            m.d.comb += getattr(self, f"out_{_port(v)}").eq(regs[self.sinks[v]])
        m.d.comb += getattr(self, f"out_{self.module}_finish").eq(end)
        return m


def attitude_acc():
    return ModuleCircuit("acc")


def attitude_mag():
    return ModuleCircuit("mag")


def attitude_gyro():
    return ModuleCircuit("gyro")


def attitude_quat():
    return ModuleCircuit("quat")


def attitude_matx():
    return ModuleCircuit("matx")


def attitude_euler():
    return ModuleCircuit("euler")


class ModuleStream(wiring.Component):
    """:class:`ModuleCircuit` behind one input and one output stream (for the verification
    harness): input payload = the module's ``in_*`` words, output payload = its ``out_*``
    words and ``cycles`` (``in_<module>_en`` to ``out_<module>_finish``)."""

    def __init__(self, module: str):
        self.core = ModuleCircuit(module)
        self.module = module
        self.LATENCY = self.core.LATENCY + 3
        self.THROUGHPUT = 1 / (self.core.LATENCY + 3)
        li = data.StructLayout({f"in_{_port(v)}": 32 for v in self.core.ins})
        lo = {f"out_{_port(v)}": 32 for v in self.core.outs}
        lo["cycles"] = 10
        super().__init__({"i": In(stream.Signature(li)),
                          "o": Out(stream.Signature(data.StructLayout(lo)))})

    def elaborate(self, platform):
        m = Module()
        m.submodules.core = core = self.core
        held, cycles = start_run_respond(
            m, self.i, self.o, start=getattr(core, f"in_{self.module}_en"),
            done=getattr(core, f"out_{self.module}_finish"), width=10)
        for v in core.ins:
            n = f"in_{_port(v)}"
            m.d.comb += getattr(core, n).eq(getattr(held, n))
        for v in core.outs:
            n = f"out_{_port(v)}"
            m.d.comb += getattr(self.o.payload, n).eq(getattr(core, n))
        m.d.comb += self.o.payload.cycles.eq(cycles)
        return m
