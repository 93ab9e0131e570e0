"""The eight computation modules of seed 004's 2x2 Kalman filter, generated from the schedule.

Reference: seed 004's module table (prior state, prior covariance, estimated output, Kalman
gain with the serial 2x2 inverse, posterior state, posterior covariance, Q update, R update)
and its Gantt chart. Each module is a :class:`KfModule`: the operations of
:func:`navgate.systems.kf2x2.model.frame_program` that belong to it, at the cycles that
:func:`navgate.systems.kf2x2.schedule.build_schedule` gave them, relative to the module's
``start`` pulse (its seed release cycle). A module owns one register per value it computes
(``o_<name>``), reads the values of other modules and the frame inputs on ``i_<name>``, and
issues its operations on the shared units through ports:

* ``mul<k>_a``, ``mul<k>_b`` -> multiplier k, result ``mul<k>_r`` (Q product, saturated);
* ``alu<k>_a``, ``alu<k>_b``, ``alu<k>_op`` -> adder/subtractor k, result ``alu<k>_r``;
* ``div_start``, ``div_d`` -> the Goldschmidt reciprocal, result ``div_q`` (Kalman gain only).

Operand ports are zero when the module does not issue (the top ORs them). A result is
written into its register at the end of the issue cycle. ``done`` is high in the cycle
whose end writes the module's last result.
"""

from __future__ import annotations

from amaranth import Module, Signal, signed
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from navgate.systems.kf2x2.schedule import SEED_WINDOWS, Schedule
from navgate.systems.kf2x2.units import ALU_ABSDIFF, ALU_ADD, ALU_SUB

__all__ = ["KfModule", "MODULE_CLASS_NAMES"]

_ALU_CODE = {"add": ALU_ADD, "sub": ALU_SUB, "absdiff": ALU_ABSDIFF}

#: seed file name of each module (for docs and reports)
MODULE_CLASS_NAMES = {
    "prior_state": "prior_state_serial", "prior_cov": "prior_cov_semipar",
    "est_output": "est_output_serial", "kalman_gain": "kg_semipar (+ inv2_serial)",
    "post_state": "post_state_serial", "post_cov": "post_cov_semipar",
    "q_update": "q_serial", "r_update": "r_serial (subsystem_eq1 x 2)",
}


class KfModule(wiring.Component):
    """One seed-004 module as scheduled; see the module docstring for its ports."""

    def __init__(self, schedule: Schedule, module: str):
        self.schedule = schedule
        self.module = module
        self.n = n = schedule.params.n
        self.release = SEED_WINDOWS[module][0]
        self.ops = schedule.module_ops(module)
        if not self.ops:
            raise ValueError(f"module {module!r} has no operations")
        self.produced = [s.op.name for s in self.ops]
        produced = set(self.produced)
        ext: list[str] = []
        for s in self.ops:
            for d in s.op.deps:
                if d not in produced and d not in ext:
                    ext.append(d)
        self.inputs = ext
        #: cycles from start to the cycle whose end writes the last result, plus one
        self.length = max(s.ready for s in self.ops) - self.release
        self.units = sorted({(s.unit, s.index) for s in self.ops})
        sig: dict = {"start": In(1), "done": Out(1)}
        for name in ext:
            sig[f"i_{name}"] = In(signed(n))
        for name in self.produced:
            sig[f"o_{name}"] = Out(signed(n))
        for unit, k in self.units:
            if unit == "mul":
                sig.update({f"mul{k}_a": Out(signed(n)), f"mul{k}_b": Out(signed(n)),
                            f"mul{k}_r": In(signed(n))})
            elif unit == "alu":
                sig.update({f"alu{k}_a": Out(signed(n)), f"alu{k}_b": Out(signed(n)),
                            f"alu{k}_op": Out(2), f"alu{k}_r": In(signed(n))})
            else:
                sig.update({"div_start": Out(1), "div_d": Out(signed(n)),
                            "div_q": In(signed(n))})
        super().__init__(sig)

    def elaborate(self, platform):
        m = Module()
        L = self.length
        cnt = Signal(range(L + 1))
        run = Signal()
        with m.If(self.start):
            m.d.sync += [run.eq(L > 1), cnt.eq(1)]
        with m.Elif(run):
            m.d.sync += cnt.eq(cnt + 1)
            with m.If(cnt == L - 1):
                m.d.sync += run.eq(0)
        m.d.comb += self.done.eq(self.start if L == 1 else (run & (cnt == L - 1)))

        values = {}
        for name in self.inputs:
            values[name] = getattr(self, f"i_{name}")
        for s in self.ops:
            if s.unit == "div":
                values[s.op.name] = self.div_q
                m.d.comb += getattr(self, f"o_{s.op.name}").eq(self.div_q)
            else:
                values[s.op.name] = getattr(self, f"o_{s.op.name}")

        def operand(src):
            if isinstance(src, str):
                return values[src]
            _, name, sh = src
            return values[name] >> sh

        for s in self.ops:
            local = s.cycle - self.release
            cond = self.start if local == 0 else (run & (cnt == local))
            srcs = [operand(x) for x in s.op.srcs]
            with m.If(cond):
                if s.unit == "mul":
                    k = s.index
                    m.d.comb += [getattr(self, f"mul{k}_a").eq(srcs[0]),
                                 getattr(self, f"mul{k}_b").eq(srcs[1])]
                    m.d.sync += values[s.op.name].eq(getattr(self, f"mul{k}_r"))
                elif s.unit == "alu":
                    k = s.index
                    m.d.comb += [getattr(self, f"alu{k}_a").eq(srcs[0]),
                                 getattr(self, f"alu{k}_b").eq(srcs[1] if len(srcs) > 1 else 0),
                                 getattr(self, f"alu{k}_op").eq(_ALU_CODE[s.op.kind])]
                    m.d.sync += values[s.op.name].eq(getattr(self, f"alu{k}_r"))
                else:
                    m.d.comb += [self.div_start.eq(1), self.div_d.eq(srcs[0])]
        return m
