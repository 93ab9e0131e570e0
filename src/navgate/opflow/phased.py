"""The phased list scheduler of opflow: a straight-line op program placed on one instance of
each unit kind, with flip-flop sources and sinks, result bypass and small register banks.

This is the scheduler of :mod:`navgate.opflow.phased_machine` (the datapath that executes
its schedules); :mod:`navgate.opflow.schedule` is the other one, for block-RAM banks.

Reference: resource-constrained list scheduling (Gajski et al., "High-Level Synthesis", 1992,
ch. 7) with the sequencing of a control FSM kept as phases, and left-edge register
allocation (interval colouring, ch. 8).

Model of the datapath:

* One unit of each kind the client declares (:class:`PhasedUnits`: the unit of every op kind,
  its latency, its issue interval and its operand ports); a pipelined unit accepts one
  operation per cycle, an iterative one every ``interval`` cycles.
* An operation issued in cycle ``c`` reads its operands combinationally in ``c``; its result
  leaves the unit in cycle ``c + L`` and is written (end of that cycle) either into a
  flip-flop register (state, outputs: "sinks") or into one of ``banks`` register banks
  (one write port each; the scheduler never lets two results want the same bank in the same
  cycle); it is readable from ``c + L + 1`` on, and in ``c + L`` itself through the bypass
  from the unit's output (``bypass=True``).
* Phases: tuples of op modules; the modules of one phase may start once every result of the
  previous phase has been written (a control FSM's ``finish`` handshakes), so the schedule
  keeps the client's sequencing; modules of one phase share the units.
* Priority: longest latency-weighted path to the end of the program, then program order.

Register allocation is interval colouring per bank (an address is reused from the cycle
its last reader issued). :func:`build_schedule` checks every constraint it relies on
(operand ready, unit free, bank write port free, a sink register's old value read before the
new one is written) and raises :class:`ScheduleError` otherwise. Operands are
:class:`navgate.opflow.ir.Op` sources: temporaries, source registers or named constants.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

from navgate.opflow.ir import Op

__all__ = ["ScheduleError", "PhasedUnits", "Placed", "Schedule", "build_schedule"]


class ScheduleError(RuntimeError):
    """The program cannot be placed under the datapath's rules."""


@dataclass(frozen=True)
class PhasedUnits:
    """The units of a phased datapath, one instance per unit kind."""

    unit_of: dict  #: op kind -> unit kind
    latency: dict  #: unit kind -> cycles from issue to the result leaving the unit
    ports: dict  #: unit kind -> operand port names (its keys: the units, in datapath order)
    interval: dict = field(default_factory=dict)  #: unit kind -> issue interval (default 1)
    #: kinds whose two operands may be swapped (bit-exact: x*y = y*x, x+y = y+x in IEEE
    #: arithmetic with one canonical NaN)
    commutative: tuple = ("mul", "add")

    def issue_interval(self, unit: str) -> int:
        return self.interval.get(unit, 1)


@dataclass(frozen=True)
class Placed:
    op: Op
    unit: str  #: the unit kind it runs on
    cycle: int  #: issue cycle
    done: int  #: cycle the result leaves the unit (written at its end)
    dest: tuple  #: ("ff", register) or ("bank", bank, address)


@dataclass
class Schedule:
    ops: list[Placed]
    phases: tuple
    phase_windows: list[tuple[int, int]]  #: per phase: (first issue cycle, last write cycle)
    length: int  #: cycles 0 .. length-1 hold the program (every result written)
    sources: tuple  #: flip-flop registers read (inputs, state, params, constants)
    sinks: dict  #: value -> flip-flop register it is written to
    units: PhasedUnits | None = None
    constants: dict = field(default_factory=dict)  #: constant name -> bits
    port_sources: dict = field(default_factory=dict)  #: (unit, port) -> list of sources
    bank_depth: list = field(default_factory=list)

    def read_source(self, value: str, cycle: int):
        """Where ``value`` is read in ``cycle``: ("unit", u) in the cycle it leaves unit u
        (bypass), else ("ff", reg) or ("bank", k, addr)."""
        d = self._done.get(value)
        if d is not None and d[0] == cycle:
            return ("unit", d[1])
        return self._loc[value]

    def module_cycles(self) -> dict:
        """module -> (first issue, last result written) cycle."""
        out = {}
        for p in self.ops:
            lo, hi = out.get(p.op.module, (10**9, -1))
            out[p.op.module] = (min(lo, p.cycle), max(hi, p.done))
        return out

    def unit_use(self) -> dict:
        """unit -> number of operations."""
        out: dict[str, int] = {}
        for p in self.ops:
            out[p.unit] = out.get(p.unit, 0) + 1
        return out

    def table(self) -> str:
        rows = []
        for c in range(self.length):
            here = [f"{p.unit}:{p.op.dst}" for p in self.ops if p.cycle == c]
            if here:
                rows.append(f"{c:4d} " + "  ".join(here))
        return "\n".join(rows)


def _paths(program: list[Op], units: PhasedUnits) -> dict:
    users: dict[str, list[Op]] = {o.dst: [] for o in program}
    for o in program:
        for a in o.srcs:
            if a in users:
                users[a].append(o)
    tail: dict[str, int] = {}
    for o in reversed(program):
        lat = units.latency[units.unit_of[o.kind]] + 1
        tail[o.dst] = lat + max([tail[u.dst] for u in users[o.dst]], default=0)
    return tail


def build_schedule(program: list[Op], sources, sinks: dict, units: PhasedUnits,
                   phases: tuple, constants: dict | None = None, banks: int = 2,
                   bank_depth: int = 32, max_cycles: int = 2000,
                   bypass: bool = True) -> Schedule:
    """Place ``program`` (ops in program order). ``sources``: values held in flip-flops
    before the program (inputs, state, parameters; the names of ``constants`` are added);
    ``sinks``: value -> flip-flop register the result goes to (new state, outputs);
    ``phases``: tuples of op modules, run one after the other."""
    constants = dict(constants or {})
    unknown = sorted({o.kind for o in program if o.kind not in units.unit_of})
    if unknown:
        raise ScheduleError(f"op kinds without a unit: {', '.join(unknown)}")
    sources = tuple(sources) + tuple(k for k in constants if k not in sources)
    produced = {o.dst for o in program}
    for o in program:
        for a in o.srcs:
            if a not in produced and a not in sources:
                raise ScheduleError(f"{o.dst}: operand {a} is neither produced nor a source")
    phases = tuple(tuple(m for m in ph if any(o.module == m for o in program))
                   for ph in phases)
    phases = tuple(ph for ph in phases if ph)
    phase_of = {m: i for i, ph in enumerate(phases) for m in ph}
    missing = sorted({o.module for o in program if o.module not in phase_of})
    if missing:
        raise ScheduleError(f"modules in no phase: {', '.join(missing)}")
    unit_of = {o.dst: units.unit_of[o.kind] for o in program}
    tail = _paths(program, units)
    order = {o.dst: i for i, o in enumerate(program)}
    ready: dict[str, int] = {s: 0 for s in sources}
    unit_busy: dict[tuple[str, int], bool] = {}
    bank_write: set[tuple[int, int]] = set()
    placed: dict[str, Placed] = {}
    windows = []
    release = 0
    for pi, ph in enumerate(phases):
        todo = [o for o in program if phase_of[o.module] == pi]
        c = release
        first = None
        while todo:
            if c > max_cycles:
                raise ScheduleError(f"phase {ph} does not fit in {max_cycles} cycles")
            cands = [o for o in todo if all(ready.get(a, 10**9) <= c for a in o.srcs)]
            cands.sort(key=lambda o: (-tail[o.dst], order[o.dst]))
            for o in cands:
                u = unit_of[o.dst]
                ii = units.issue_interval(u)
                if any(unit_busy.get((u, c + t)) for t in range(ii)):
                    continue
                done = c + units.latency[u]
                if o.dst in sinks:
                    bank = None
                else:
                    free = [k for k in range(banks) if (k, done) not in bank_write]
                    if not free:
                        continue
                    bank = free[0]
                    bank_write.add((bank, done))
                for t in range(ii):
                    unit_busy[(u, c + t)] = True
                placed[o.dst] = Placed(o, u, c, done, ("ff", sinks[o.dst]) if bank is None
                                       else ("bank", bank, -1))
                ready[o.dst] = done if bypass else done + 1
                first = c if first is None else first
                todo.remove(o)
            c += 1
        last = max(placed[o.dst].done for o in program if phase_of[o.module] == pi)
        windows.append((first, last))
        release = last + 1
    length = release

    # last read of every value
    last_read: dict[str, int] = {}
    for p in placed.values():
        for a in p.op.srcs:
            last_read[a] = max(last_read.get(a, -1), p.cycle)
    # sink registers: the old value (a source of the same register name) must be read
    # before the new one is written
    for v, reg in sinks.items():
        if v not in placed:
            raise ScheduleError(f"sink {v} is not produced by the program")
        if reg in sources and last_read.get(reg, -1) > placed[v].done:
            raise ScheduleError(f"{v} overwrites {reg} in cycle {placed[v].done} before its "
                                f"last read in cycle {last_read[reg]}")
    # interval colouring per bank
    depth = []
    for k in range(banks):
        vals = sorted((p for p in placed.values() if p.dest[0] == "bank" and p.dest[1] == k),
                      key=lambda p: p.done)
        free_at: list[int] = []  # address -> cycle from which it may be written again
        for p in vals:
            if p.op.dst not in last_read:
                raise ScheduleError(f"{p.op.dst} is never read")
            addr = next((a for a, t in enumerate(free_at) if t <= p.done), None)
            if addr is None:
                addr = len(free_at)
                free_at.append(0)
            free_at[addr] = last_read[p.op.dst]
            placed[p.op.dst] = replace(p, dest=("bank", k, addr))
        if len(free_at) > bank_depth:
            raise ScheduleError(f"bank {k} needs {len(free_at)} registers > {bank_depth}")
        depth.append(len(free_at))
    ops = sorted(placed.values(), key=lambda p: (p.cycle, order[p.op.dst]))
    sched = Schedule(ops, phases, windows, length, sources, dict(sinks), units, constants,
                     bank_depth=depth)
    loc = {s: ("ff", s) for s in sources}
    for p in ops:
        loc[p.op.dst] = p.dest
    sched._loc = loc
    sched._done = {p.op.dst: (p.done, p.unit) for p in ops}
    sched.ops, sched.port_sources = _assign_ports(sched, ops)
    return sched


def _assign_ports(sched: Schedule, ops: list[Placed]):
    """Operand sources per port, in first-use order. A commutative op takes the operand order
    that adds the fewest new sources to its unit's two port multiplexers (greedy)."""
    units = sched.units
    ps: dict[tuple[str, str], list] = {}

    def key(a, cycle):
        src = sched.read_source(a, cycle)
        return src[:2] if src[0] == "bank" else src

    final = []
    for p in ops:
        u = p.unit
        args = p.op.srcs
        if p.op.kind in units.commutative and args[0] != args[1]:
            pa, pb = units.ports[u][:2]
            la, lb = ps.get((u, pa), []), ps.get((u, pb), [])
            k0, k1 = key(args[0], p.cycle), key(args[1], p.cycle)
            keep = (k0 not in la) + (k1 not in lb)
            swap = (k1 not in la) + (k0 not in lb)
            if swap < keep:
                p = replace(p, op=replace(p.op, srcs=(args[1], args[0])))
        for port, a in zip(units.ports[u], p.op.srcs, strict=False):
            lst = ps.setdefault((u, port), [])
            if key(a, p.cycle) not in lst:
                lst.append(key(a, p.cycle))
        final.append(p)
    return final, ps
