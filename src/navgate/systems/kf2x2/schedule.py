"""Static schedule of seed 004's frame program onto shared, pipelined arithmetic units
(C0-C33).

Reference: seed 004, "34 周期时序甘特图" (the Gantt chart C0-C33) and its resource list
(4 multipliers, 2 adders, 4 subtractors, 1 divider). The frame program is
:func:`navgate.systems.kf2x2.model.frame_program`; this module assigns every operation an
issue cycle and a unit with a resource-constrained list scheduler.

Timing model (registered operands and products, docs/seed004-kf2x2.md "Timing"; the gateware
is :mod:`navgate.systems.kf2x2.modules`).
An operation *issued* in cycle c has its operands loaded into its unit's operand registers
at the end of c (from value registers, or forwarded from the unit that produces them in
that very cycle); the unit works from registers only:

* multiply (``MUL_LATENCY = 2``): c+1 the product of the operand registers goes into the
  raw product register (the DSP48E1 M/P register, 2N bits); c+2 truncation and saturation
  of that register, whose result is forwarded to operand loads in c+2 and written to the
  value register at the end of c+2;
* add / sub / |a - b| (``ALU_LATENCY = 1``): c+1 the unit computes from its operand
  registers and saturates; forwarded in c+1, value register at the end of c+1;
* the serial Goldschmidt reciprocal (``divider_latency = 2k + 5`` for k = 1 iteration,
  :class:`~navgate.systems.kf2x2.units.GoldschmidtSerial`): its multiplies are loaded on
  multiplier 3 at the offsets :func:`divider_mul_offsets` after its issue.

A result is *ready* in the cycle it is forwarded (issue + latency): consumers may issue
from that cycle on. Every committed value must be ready by C33 (``done``), where the
commit takes it forwarded or from its value register.

Priority: the longest latency-weighted path to the end of the frame (critical path), ties
broken by a deterministic jitter; :func:`build_schedule` tries jitter seeds 0, 1, 2, ... in
order and keeps the first schedule that fits (the result is a fixed function of the
program and parameters). The seed's per-module windows (:data:`SEED_WINDOWS`) are not
constraints any more: with two-cycle multiplies the modules overlap differently, and the
Q/R updates, which use the previous frame's values, move freely. ``Schedule.windows``
gives the windows the schedule produced; docs/seed004-kf2x2.md sets them against the seed's
chart.

:func:`build_schedule` raises ``ScheduleError`` if the program does not fit the frame.
"""

from __future__ import annotations

from dataclasses import dataclass

from navgate.systems.kf2x2.model import (
    FRAME_INPUTS,
    MODULES,
    STATE_NAMES,
    KfParams,
    Op,
    frame_program,
)

__all__ = ["ScheduleError", "Scheduled", "Schedule", "build_schedule", "SEED_WINDOWS",
           "MUL_UNITS", "ALU_UNITS", "FRAME_CYCLES", "DIV_MUL_UNIT", "divider_latency",
           "divider_mul_offsets", "MUL_LATENCY", "ALU_LATENCY", "min_frame_cycles"]

#: seed 004's Gantt chart: module -> (first cycle, last cycle)
SEED_WINDOWS = {
    "prior_state": (0, 7),
    "prior_cov": (0, 8),
    "est_output": (8, 11),
    "kalman_gain": (8, 24),
    "q_update": (10, 12),
    "r_update": (12, 14),
    "post_state": (25, 29),
    "post_cov": (25, 33),
}
FRAME_CYCLES = 34
MUL_UNITS = 4
ALU_UNITS = 6
DIV_MUL_UNIT = 3
MUL_LATENCY = 2
ALU_LATENCY = 1
UNIT_OF_KIND = {"mul": "mul", "add": "alu", "sub": "alu", "absdiff": "alu",
                "recip": "div"}
#: how many jitter seeds :func:`build_schedule` tries before giving up
SCHEDULE_TRIES = 512


class ScheduleError(RuntimeError):
    """The program does not fit the frame with the given units."""


def divider_mul_offsets(params: KfParams) -> list[int]:
    """Cycles after the divider's issue in which it loads multiplier 3's operand registers.

    k = 1: D0 = Dn x0 at 2, N = x0 (2 - D0) at 4 (``2 - D`` goes straight into the operand
    register). k > 1: D0 at 2; per middle iteration D G then N G on consecutive cycles, every
    operand from registers (period 3); the last N (2 - D) after the last N G.
    """
    from navgate.systems.kf2x2.units import divider_plan

    return divider_plan(params.div_iterations)[0]


def divider_latency(params: KfParams) -> int:
    """Cycles from the divider's issue to its result being forwarded (from its ``q``
    register): the last multiply's product is ready 2 cycles after its load, then one cycle
    of denormalising shift and rounding, one of saturation and sign into ``q``."""
    from navgate.systems.kf2x2.units import divider_plan

    return divider_plan(params.div_iterations)[1]


@dataclass(frozen=True)
class Scheduled:
    op: Op
    cycle: int  # global issue cycle
    unit: str  # "mul", "alu", "div"
    index: int  # unit index
    ready: int  # the cycle the result is forwarded (written to its register at its end)


@dataclass
class Schedule:
    params: KfParams
    ops: list[Scheduled]
    windows: dict  # module -> (first issue, last cycle that computes a result)
    seed: int = 0  # the jitter seed that produced it

    def module_ops(self, module: str) -> list[Scheduled]:
        return [s for s in self.ops if s.op.module == module]

    def usage(self) -> dict:
        """Peak number of units of each kind issued in one cycle (divider loads counted)."""
        per: dict[tuple[str, int], int] = {}
        for s in self.ops:
            per[(s.unit, s.cycle)] = per.get((s.unit, s.cycle), 0) + 1
            if s.unit == "div":
                for t in divider_mul_offsets(self.params):
                    per[("mul", s.cycle + t)] = per.get(("mul", s.cycle + t), 0) + 1
        peak = {"mul": 0, "alu": 0, "div": 0}
        for (unit, _), n in per.items():
            peak[unit] = max(peak[unit], n)
        return peak

    def table(self) -> str:
        """Gantt table: one row per cycle with the ops issued on each unit."""
        cells: dict[int, list[tuple[str, int, str]]] = {c: [] for c in range(FRAME_CYCLES)}
        for s in self.ops:
            cells[s.cycle].append((s.unit, s.index, s.op.name))
            if s.unit == "div":
                for t in divider_mul_offsets(self.params):
                    cells[s.cycle + t].append(("mul", DIV_MUL_UNIT, f"({s.op.name})"))
        return "\n".join(f"C{c:<3d} " + "  ".join(f"{u}{i}:{name}" for u, i, name in
                                                   sorted(cells[c]))
                         for c in range(FRAME_CYCLES))


def _latencies(prog: list[Op], params: KfParams, mul_latency: int) -> dict[str, int]:
    k = params.div_iterations
    if mul_latency == MUL_LATENCY:
        dl = divider_latency(params)
    else:  # trade-off analysis: divider multiplies at the same spacing
        dl = 4 + 2 * k * mul_latency
    return {o.name: (dl if o.kind == "recip" else mul_latency if o.kind == "mul" else 1)
            for o in prog}


def _list_schedule(prog, params, lat, div_offsets, frame_cycles, jitter_seed):
    import random

    producers = {o.name: o for o in prog}
    users: dict[str, list[Op]] = {o.name: [] for o in prog}
    for o in prog:
        for d in o.deps:
            if d in users:
                users[d].append(o)
    tail: dict[str, int] = {}
    for o in reversed(prog):
        tail[o.name] = lat[o.name] + max([tail[u.name] for u in users[o.name]] + [0])
    rnd = random.Random(jitter_seed)
    jitter = {o.name: (rnd.random() if jitter_seed else 0.0) for o in prog}
    order = {o.name: i for i, o in enumerate(prog)}
    ready_at: dict[str, int] = {}
    busy: set[tuple[str, int, int]] = set()
    placed: list[Scheduled] = []
    todo = list(prog)
    for c in range(frame_cycles):
        cands = [o for o in todo
                 if all(ready_at.get(d, 0 if d not in producers else 10**9) <= c
                        for d in o.deps)]
        cands.sort(key=lambda o: (-tail[o.name] - jitter[o.name], order[o.name]))
        for o in cands:
            if c + lat[o.name] > frame_cycles - 1:
                continue
            unit = UNIT_OF_KIND[o.kind]
            if unit == "div":
                need = [("mul", DIV_MUL_UNIT, c + t) for t in div_offsets]
                if ("div", 0, c) in busy or any(n in busy for n in need):
                    continue
                for t in range(lat[o.name]):
                    busy.add(("div", 0, c + t))
                busy.update(need)
                index = 0
            else:
                count = MUL_UNITS if unit == "mul" else ALU_UNITS
                free = [i for i in range(count) if (unit, i, c) not in busy]
                if not free:
                    continue
                index = free[0]
                busy.add((unit, index, c))
            ready_at[o.name] = c + lat[o.name]
            placed.append(Scheduled(o, c, unit, index, c + lat[o.name]))
            todo.remove(o)
    return placed, todo


def build_schedule(params: KfParams | None = None, program: list[Op] | None = None,
                   mul_latency: int = MUL_LATENCY,
                   frame_cycles: int = FRAME_CYCLES, tries: int = SCHEDULE_TRIES) -> Schedule:
    """Schedule the frame program (every result ready by cycle ``frame_cycles - 1``).

    ``mul_latency`` other than :data:`MUL_LATENCY` is for the trade-off analysis of
    :func:`min_frame_cycles` only; the gateware implements :data:`MUL_LATENCY`.
    """
    params = KfParams() if params is None else params
    prog = frame_program(params) if program is None else program
    producers = {o.name for o in prog}
    for o in prog:
        for d in o.deps:
            if d not in producers and d not in FRAME_INPUTS and d not in STATE_NAMES:
                raise ScheduleError(f"{o.name}: unknown operand {d}")
    lat = _latencies(prog, params, mul_latency)
    if mul_latency == MUL_LATENCY:
        div_offsets = divider_mul_offsets(params)
    else:
        div_offsets = [2 + i * mul_latency for i in range(2 * params.div_iterations)]
    for seed in range(tries):
        placed, todo = _list_schedule(prog, params, lat, div_offsets, frame_cycles, seed)
        if not todo:
            break
    else:
        raise ScheduleError(f"{len(todo)} operations do not fit in {frame_cycles} cycles: "
                            f"{', '.join(o.name for o in todo[:8])}")
    got = {}
    for module in MODULES:
        mine = [s for s in placed if s.op.module == module]
        if mine:
            got[module] = (min(s.cycle for s in mine), max(s.ready for s in mine))
    placed.sort(key=lambda s: (s.cycle, s.unit, s.index))
    return Schedule(params, placed, got, seed)


def min_frame_cycles(params: KfParams | None = None, mul_latency: int = MUL_LATENCY) -> int:
    """Shortest frame (cycles from start to done, every result ready by done) that the list
    scheduler finds (64 jitter seeds per length, from the critical-path bound up) with the
    same units, for multipliers ``mul_latency`` deep."""
    params = KfParams() if params is None else params
    prog = frame_program(params)
    lat = _latencies(prog, params, mul_latency)
    users: dict[str, list[Op]] = {o.name: [] for o in prog}
    for o in prog:
        for d in o.deps:
            if d in users:
                users[d].append(o)
    tail: dict[str, int] = {}
    for o in reversed(prog):
        tail[o.name] = lat[o.name] + max([tail[u.name] for u in users[o.name]] + [0])
    bound = max(tail.values()) + 1  # the critical path, last result ready in the last cycle
    for cycles in range(bound, 200):
        try:
            build_schedule(params, mul_latency=mul_latency, frame_cycles=cycles, tries=64)
        except ScheduleError:
            continue
        return cycles
    raise ScheduleError("no schedule under 200 cycles")
