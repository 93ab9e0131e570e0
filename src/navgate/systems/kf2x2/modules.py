"""The datapath of seed 004's 2x2 Kalman filter, generated from the schedule, and the eight
modules as views of it.

Reference: seed 004's module table (prior state, prior covariance, estimated output, Kalman
gain with the serial 2x2 inverse, posterior state, posterior covariance, Q update, R update)
and its Gantt chart, re-timed so that every unit works from registers (docs/seed004-kf2x2.md,
"Timing").

:func:`build_datapath` turns scheduled operations (:mod:`navgate.systems.kf2x2.schedule`)
into hardware in which every arithmetic unit works from registers only:

* **registered one-hot control**: :class:`Control` is a shift register of phase bits (one
  per cycle of the frame, phase 0 = the start pulse); every control word (an operand
  select, an ALU op code, a write enable, a flag enable) is a register loaded with the OR
  of the phase bits one cycle earlier, so no counter is decoded in the datapath;
* **operand registers written by the producer**: each unit has operand registers (the
  DSP48E1 A/B registers for a multiplier) loaded, in an operation's issue cycle, through an
  AND-OR multiplexer from value registers or directly from the unit that computes the
  operand in that cycle (forwarding);
* **raw product registered**: a multiplier registers the full 2N-bit product (DSP48E1 M/P
  register); truncation and saturation happen in the next cycle, on the way to the value
  register and the consumers' operand registers;
* **pipelined, sticky overflow flag**: each unit's saturation flag is registered (gated by
  the cycles in which the unit delivers a scheduled result), and the frame's sticky flag
  ORs those registers one cycle later.
* **adders without an op code** (so the Nexus carry chains map one-to-one): an
  adder/subtractor adds and subtracts on one carry chain ``a + b + cin`` (a subtraction
  loads the complemented subtrahend, and
  ``cin`` is a registered control word), ``|a - b|`` has its own chains; the operand
  multiplexers merge the terms that are the same bits (one producing unit's result, one
  register) under one select.

A module (:class:`ModulePlan`) is the subset of the frame's operations that the seed assigns
to it; :class:`~navgate.systems.kf2x2.top.ModuleHarness` builds one module alone with
private units, :class:`~navgate.systems.kf2x2.top.Kf2x2` builds the whole frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from amaranth import Module, Mux, Signal, signed
from amaranth.hdl import Value

from navgate.systems.kf2x2.model import KfParams
from navgate.systems.kf2x2.schedule import DIV_MUL_UNIT, Schedule, Scheduled
from navgate.systems.kf2x2.units import Control, GoldschmidtSerial, alu_results, q_mul

__all__ = ["Control", "Datapath", "ModulePlan", "build_datapath", "MODULE_CLASS_NAMES"]

#: seed file name of each module (for docs and reports)
MODULE_CLASS_NAMES = {
    "prior_state": "prior_state_serial", "prior_cov": "prior_cov_semipar",
    "est_output": "est_output_serial", "kalman_gain": "kg_semipar (+ inv2_serial)",
    "post_state": "post_state_serial", "post_cov": "post_cov_semipar",
    "q_update": "q_serial", "r_update": "r_serial (subsystem_eq1 x 2)",
}


def _alu_result(kind: str) -> str:
    """Which result of an adder/subtractor unit an operation kind uses."""
    return "absdiff" if kind == "absdiff" else "addsub"


@dataclass
class Datapath:
    """What :func:`build_datapath` built: value registers, forwarded results, flags."""

    values: dict[str, Value]  # name -> value register (the divider's: its q register)
    forwarded: dict[str, Value]  # name -> the result in its ready cycle (combinational)
    ready: dict[str, int]  # name -> ready cycle (relative to the datapath's cycle 0)
    flags: list[Signal]  # registered per-unit saturation flags
    divider: GoldschmidtSerial | None = None
    length: int = 0  # last ready cycle + 1

    def final(self, name: str, cycle: int) -> Value:
        """``name`` as seen in ``cycle`` (forwarded in its ready cycle, else its register)."""
        if self.ready[name] > cycle:
            raise ValueError(f"{name} is not ready in cycle {cycle}")
        return self.forwarded[name] if self.ready[name] == cycle else self.values[name]


def build_datapath(m: Module, ops: list[Scheduled], params: KfParams, ctl: Control,
                   env: dict[str, Value], base: int = 0, prefix: str = "") -> Datapath:
    """Units, operand registers, value registers and control for ``ops`` (cycles relative to
    ``base``); operands not produced by ``ops`` come from ``env``."""
    n, frac = params.n, params.frac
    ready = {s.op.name: s.ready - base for s in ops}
    has_div = any(s.unit == "div" for s in ops)
    mul_ids = sorted({s.index for s in ops if s.unit == "mul"} | ({DIV_MUL_UNIT} if has_div
                                                                    else set()))
    alu_ids = sorted({s.index for s in ops if s.unit == "alu"})

    # --- units -------------------------------------------------------------------------
    mul_a, mul_b, mul_r, mul_f = {}, {}, {}, {}
    for k in mul_ids:
        wide = has_div and k == DIV_MUL_UNIT
        # the divider's operands are unsigned and below 2**(F+1) (F = n): signed n+2 bits
        w = n + 2 if wide else n
        a = Signal(signed(w), name=f"{prefix}mul{k}_a", reset_less=True)
        b = Signal(signed(w), name=f"{prefix}mul{k}_b", reset_less=True)
        p = Signal(signed(2 * w), name=f"{prefix}mul{k}_p", reset_less=True)
        m.d.sync += p.eq(a * b)
        r, f = q_mul(p, n, frac)
        rs = Signal(signed(n), name=f"{prefix}mul{k}_r")
        m.d.comb += rs.eq(r)
        mul_a[k], mul_b[k], mul_r[k], mul_f[k] = a, b, rs, f
        if wide:
            mul_p_wide = p
    # an adder/subtractor adds and subtracts on one chain (a + b + cin: a subtraction loads
    # the complemented subtrahend and sets cin, a registered control word high in its
    # compute cycle) and takes |a - b| on its own chains; a forwarded result is (unit,
    # "addsub" or "absdiff"), selected by the consumer's operand select
    alu_a, alu_b, alu_r = {}, {}, {}
    for k in alu_ids:
        a = Signal(signed(n), name=f"{prefix}alu{k}_a", reset_less=True)
        b = Signal(signed(n), name=f"{prefix}alu{k}_b", reset_less=True)
        mine = [s for s in ops if s.unit == "alu" and s.index == k]
        sub_cycles = {s.cycle - base + 1 for s in mine if s.op.kind == "sub"}
        cin = ctl.at(sub_cycles) if sub_cycles else 0
        kinds = sorted({s.op.kind for s in mine})
        results = alu_results(m, a, b, cin, kinds, n, f"{prefix}alu{k}")
        alu_r[k] = {}
        for result, (r, f) in results.items():
            rs = Signal(signed(n), name=f"{prefix}alu{k}_{result}")
            m.d.comb += rs.eq(r)
            alu_r[k][result] = (rs, f)
        alu_a[k], alu_b[k] = a, b
    div = None
    if has_div:
        div = GoldschmidtSerial(params.n, params.frac, params.div_iterations,
                                params.div_seed_bits)
        m.submodules[f"{prefix}div"] = div
        m.d.comb += div.mul_p.eq((mul_p_wide >> div.F)[:div.F + 2])

    # --- results: forwarded in the ready cycle, then in a value register ---------------
    forwarded: dict[str, Value] = {}
    producer: dict[str, tuple] = {}  # name -> the hardware that forwards it
    values: dict[str, Value] = {}
    for s in ops:
        name = s.op.name
        if s.unit == "div":
            forwarded[name] = div.q_next
            producer[name] = ("div",)
            values[name] = div.q
            continue
        if s.unit == "mul":
            forwarded[name] = mul_r[s.index]
            producer[name] = ("mul", s.index)
        else:
            result = _alu_result(s.op.kind)
            forwarded[name] = alu_r[s.index][result][0]
            producer[name] = ("alu", s.index, result)
        reg = Signal(signed(n), name=f"{prefix}v_{name}", reset_less=True)
        with m.If(ctl.at({ready[name]})):
            m.d.sync += reg.eq(forwarded[name])
        values[name] = reg

    def source(src, cycle: int) -> tuple[tuple, Value]:
        """(key, value) of an operand: equal keys are the same bits, so their selects merge
        into one control word (a unit's forwarded result of one kind is one term however
        many operations it delivers)."""
        name, shift = (src, 0) if isinstance(src, str) else (src[1], src[2])
        if name in ready:
            if cycle < ready[name]:
                raise ValueError(f"{name} used in cycle {cycle} before it is ready")
            if cycle == ready[name]:
                key, value = ("fwd", *producer[name], shift), forwarded[name]
            else:
                key, value = ("reg", name, shift), values[name]
        else:
            key, value = ("env", name, shift), env[name]
        return key, (value >> shift if shift else value)

    # --- operand multiplexers: AND-OR under registered one-hot selects -----------------
    regs: dict[str, Signal] = {}
    ports: dict[str, dict[tuple, tuple[set, Value]]] = {}

    def load(reg, key, value, cycle):
        regs[reg.name] = reg
        entry = ports.setdefault(reg.name, {}).setdefault(key, (set(), value))
        entry[0].add(cycle)

    div_start = None
    for s in ops:
        c = s.cycle - base
        srcs = [source(x, c) for x in s.op.srcs]
        if s.unit == "mul":
            load(mul_a[s.index], *srcs[0], c)
            load(mul_b[s.index], *srcs[1], c)
        elif s.unit == "alu":
            load(alu_a[s.index], *srcs[0], c)
            if len(srcs) > 1:
                key, value = srcs[1]
                if s.op.kind == "sub":  # a - b = a + ~b + 1 (cin)
                    key, value = (*key, "complement"), ~value
                load(alu_b[s.index], key, value, c)
        else:
            div_start = c
            key, value = srcs[0]
            m.d.comb += [div.start.eq(ctl.at({c})), div.d.eq(value)]
    extra: dict[str, list[Value]] = {}
    if has_div:
        for reg, value in ((mul_a[DIV_MUL_UNIT], div.mul_a), (mul_b[DIV_MUL_UNIT], div.mul_b)):
            regs[reg.name] = reg
            extra[reg.name] = [Mux(div.mul_load, value, 0)]
    for reg_name, reg in regs.items():
        terms = [Mux(ctl.at(cycles), value, 0)
                 for cycles, value in ports.get(reg_name, {}).values()]
        terms += extra.get(reg_name, [])
        acc = 0
        for term in terms:
            acc = acc | term
        m.d.sync += reg.eq(acc)
    assert not has_div or div_start is not None

    # --- flags: registered per unit, enabled in the cycles of scheduled results ---------
    flags: list[Signal] = []
    for k in mul_ids:
        cycles = {ready[s.op.name] for s in ops if s.unit == "mul" and s.index == k}
        if cycles:
            reg = Signal(name=f"{prefix}mul{k}_ovf")
            m.d.sync += reg.eq(mul_f[k] & ctl.at(cycles))
            flags.append(reg)
    for k in alu_ids:
        acc = 0
        for result, (_, flag) in alu_r[k].items():
            cycles = {ready[s.op.name] for s in ops
                      if s.unit == "alu" and s.index == k and _alu_result(s.op.kind) == result}
            acc = acc | (flag & ctl.at(cycles))
        reg = Signal(name=f"{prefix}alu{k}_ovf")
        m.d.sync += reg.eq(acc)
        flags.append(reg)
    return Datapath(values, forwarded, ready, flags, div, max(ready.values()) + 1)


@dataclass
class ModulePlan:
    """One seed module in the schedule: its operations, inputs and timing."""

    schedule: Schedule
    module: str
    ops: list[Scheduled] = field(init=False)
    produced: list[str] = field(init=False)
    inputs: list[str] = field(init=False)
    release: int = field(init=False)  # first issue cycle in the frame
    length: int = field(init=False)  # cycles from release to the last result, inclusive

    def __post_init__(self):
        self.ops = self.schedule.module_ops(self.module)
        if not self.ops:
            raise ValueError(f"module {self.module!r} has no operations")
        self.produced = [s.op.name for s in self.ops]
        produced = set(self.produced)
        self.inputs = []
        for s in self.ops:
            for d in s.op.deps:
                if d not in produced and d not in self.inputs:
                    self.inputs.append(d)
        self.release = min(s.cycle for s in self.ops)
        self.length = max(s.ready for s in self.ops) - self.release + 1
