"""Static schedule of seed 004's frame program onto shared arithmetic units (C0-C33).

Reference: seed 004, "34 周期时序甘特图" (the Gantt chart C0-C33) and its resource list
(4 multipliers, 2 adders, 4 subtractors, 1 divider). The frame program is
:func:`navgate.systems.kf2x2.model.frame_program`; this module assigns every operation a cycle
and a unit with a resource-constrained list scheduler (priority: longest latency-weighted
slack: as-late-as-possible issue cycle under the
module windows, then program order), honouring the seed's module release
cycles:

=============== ======= =====================================================
module          release seed window
=============== ======= =====================================================
prior_state     C0      C0-C7
prior_cov       C0      C0-C8
est_output      C8      C8-C11
kalman_gain     C8      C8-C24
q_update        C10     C10-C12
r_update        C12     C12-C14
post_state      C25     C25-C29
post_cov        C25     C25-C33
=============== ======= =====================================================

Units and timing: every ``mul`` / ``add`` / ``sub`` / ``abs`` reads its operands from
registers in cycle c and writes its result register at the end of c (readable in c+1): the
seed's combinational fixed units between registers. Units: ``MUL_UNITS`` = 4 multipliers;
``ALU_UNITS`` = 6 adder/subtractors (the seed's 2 adders + 4 subtractors, each able to add,
subtract or take the absolute value, so that the scheduler may use any of them); one
Goldschmidt divider whose multiplies run on multiplier 3 (reserved for it at offsets 2 ..
2k+1 after its start), result readable ``2k + 4`` cycles after its start.

:func:`build_schedule` raises ``ScheduleError`` if an operation would leave its module's
seed window or the frame; the schedule is therefore verified at construction, and the
tests assert the per-module windows and the frame length.
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
           "min_frame_cycles"]

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
UNIT_OF_KIND = {"mul": "mul", "add": "alu", "sub": "alu", "absdiff": "alu",
                "recip": "div"}


class ScheduleError(RuntimeError):
    """The program does not fit the seed's windows with the given units."""


def divider_latency(params: KfParams) -> int:
    """Cycles from the divider's start to its result being readable: normalise, seed,
    2k multiplies, denormalise/round, saturate/sign."""
    return 2 * params.div_iterations + 4


@dataclass(frozen=True)
class Scheduled:
    op: Op
    cycle: int  # global issue cycle
    unit: str  # "mul", "alu", "div"
    index: int  # unit index
    ready: int  # first cycle the result is readable


@dataclass
class Schedule:
    params: KfParams
    ops: list[Scheduled]
    windows: dict  # module -> (first issue, last issue)

    def module_ops(self, module: str) -> list[Scheduled]:
        return [s for s in self.ops if s.op.module == module]

    def usage(self) -> dict:
        """Peak number of units of each kind busy in one cycle (divider multiplies counted)."""
        per: dict[tuple[str, int], int] = {}
        for s in self.ops:
            per[(s.unit, s.cycle)] = per.get((s.unit, s.cycle), 0) + 1
        peak = {"mul": 0, "alu": 0, "div": 0}
        for (unit, _), n in per.items():
            peak[unit] = max(peak[unit], n)
        return peak

    def table(self) -> str:
        """Gantt table: one row per cycle with the ops issued on each unit."""
        k = self.params.div_iterations
        cells: dict[int, list[tuple[str, int, str]]] = {c: [] for c in range(FRAME_CYCLES)}
        for s in self.ops:
            cells[s.cycle].append((s.unit, s.index, s.op.name))
            if s.unit == "div":
                for t in range(2 * k):
                    cells[s.cycle + 2 + t].append(("mul", DIV_MUL_UNIT, f"({s.op.name})"))
        return "\n".join(f"C{c:<3d} " + "  ".join(f"{u}{i}:{name}" for u, i, name in
                                                   sorted(cells[c]))
                         for c in range(FRAME_CYCLES))


def build_schedule(params: KfParams | None = None, program: list[Op] | None = None,
                   windows: dict | None = None, check: bool = True, mul_latency: int = 1,
                   frame_cycles: int = FRAME_CYCLES) -> Schedule:
    """Schedule the frame program. ``mul_latency`` > 1 (pipelined multipliers, one issue
    per cycle) and ``frame_cycles`` are for the trade-off analysis of
    :func:`min_frame_cycles` only; the gateware implements ``mul_latency = 1``."""
    params = KfParams() if params is None else params
    prog = frame_program(params) if program is None else program
    windows = SEED_WINDOWS if windows is None else windows
    k = params.div_iterations
    dl = 4 + 2 * k * mul_latency
    div_offsets = [2 + i * mul_latency for i in range(2 * k)]
    lat = {o.name: (dl if o.kind == "recip" else mul_latency if o.kind == "mul" else 1)
           for o in prog}
    producers = {o.name: o for o in prog}
    for o in prog:
        for d in o.deps:
            if d not in producers and d not in FRAME_INPUTS and d not in STATE_NAMES:
                raise ScheduleError(f"{o.name}: unknown operand {d}")
    # priority: least slack first. alap = latest issue cycle that still meets the module
    # windows of the op and of every op that uses its result (as-late-as-possible times)
    users: dict[str, list[Op]] = {o.name: [] for o in prog}
    for o in prog:
        for d in o.deps:
            if d in users:
                users[d].append(o)
    alap: dict[str, int] = {}
    for o in reversed(prog):
        due = min([windows[o.module][1] + 1] + [alap[u.name] for u in users[o.name]])
        alap[o.name] = due - lat[o.name]
    order = {o.name: i for i, o in enumerate(prog)}
    ready_at: dict[str, int] = {}
    busy: set[tuple[str, int, int]] = set()
    placed: list[Scheduled] = []
    todo = list(prog)
    for c in range(frame_cycles):
        cands = [o for o in todo
                 if windows[o.module][0] <= c
                 and all(ready_at.get(d, 0 if d not in producers else 10**9) <= c
                         for d in o.deps)]
        cands.sort(key=lambda o: (alap[o.name], order[o.name]))
        for o in cands:
            unit = UNIT_OF_KIND[o.kind]
            if unit == "div":
                need = [("mul", DIV_MUL_UNIT, c + t) for t in div_offsets]
                if ("div", 0, c) in busy or any(n in busy for n in need):
                    continue
                for t in range(dl):
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
    if todo:
        raise ScheduleError(f"{len(todo)} operations do not fit in {frame_cycles} cycles: "
                            f"{', '.join(o.name for o in todo[:8])}")
    got = {}
    for module in MODULES:
        mine = [s for s in placed if s.op.module == module]
        first = min(s.cycle for s in mine)
        last = max(s.ready for s in mine) - 1  # the cycle whose end writes the last result
        got[module] = (first, last)
        lo, hi = windows[module]
        if check and (first < lo or last > hi):
            raise ScheduleError(f"{module} occupies C{first}-C{last}, outside its window "
                                f"C{lo}-C{hi}")
    if max(s.ready for s in placed) > frame_cycles:
        raise ScheduleError(f"results are not ready within {frame_cycles} cycles")
    placed.sort(key=lambda s: (s.cycle, s.unit, s.index))
    return Schedule(params, placed, got)


def min_frame_cycles(params: KfParams | None = None, mul_latency: int = 1) -> int:
    """Shortest frame (cycles from start to the last result, done included) that the list
    scheduler finds with the same units and no module windows, for multipliers pipelined
    ``mul_latency`` deep: the cost in cycles of a faster clock (docs/seed004-kf2x2.md)."""
    params = KfParams() if params is None else params
    for cycles in range(8, 200):
        windows = {m: (0, cycles - 1) for m in SEED_WINDOWS}
        try:
            build_schedule(params, windows=windows, mul_latency=mul_latency,
                           frame_cycles=cycles)
        except ScheduleError:
            continue
        return cycles
    raise ScheduleError("no schedule under 200 cycles")
