"""Static schedule of seed 003's solve program onto shared float32 units, with register
allocation and the microcode that the gateware's control ROM holds.

Reference: seed 003 section 3.1.1 (figure 3-2: the top FSM runs ACC_MAG, GYRO, QUAT, MATX,
EULER, END, each state waiting for its modules' ``*_finish``) and the precedent of seed 004's
scheduled datapath (:mod:`navgate.systems.kf2x2.schedule`).

Model of the datapath (:mod:`navgate.systems.attitude.datapath` implements exactly this):

* One unit of each kind: ``mul`` (:class:`~navgate.gateware.fp32.Fp32Mul`), ``add``
  (:class:`~navgate.gateware.fp32.Fp32Add`, add or subtract), ``div``, ``sqrt``, the
  one-cycle ``misc`` unit and the ``atan`` unit (iterative CORDIC, one issue every
  ``ATAN_II`` cycles); the pipelined cores accept one operation per cycle.
* An operation issued in cycle ``c`` reads its operands combinationally in ``c``; its result
  leaves the unit in cycle ``c + L`` and is written (end of that cycle) either into a
  flip-flop register (state, outputs: "sinks") or into one of ``BANKS`` register banks
  (one write port each; the scheduler never lets two results want the same bank in the same
  cycle); it is readable from ``c + L + 1`` on.
* Phases: the modules of one FSM state may start once every result of the previous state
  has been written (the seed's ``*_finish`` handshakes), so the schedule keeps the seed's
  sequencing: ACC_MAG (acc and mag side by side, sharing units), GYRO, QUAT, MATX, EULER.
* Priority: longest latency-weighted path to the end of the program, then program order.

Register allocation is interval colouring per bank (an address is reused from the cycle
its last reader issued). :func:`build_schedule` checks every constraint it relies on
(operand ready, unit free, bank write port free, a sink register's old value read before the
new one is written) and raises :class:`ScheduleError` otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from navgate.gateware.fp32 import Fp32Add, Fp32Div, Fp32Mul, Fp32Sqrt
from navgate.systems.attitude.program import CONSTANTS, Op

__all__ = ["ScheduleError", "Placed", "Schedule", "build_schedule", "LATENCY", "ATAN_II",
           "PHASES", "BANKS", "PORTS"]

ATAN_LATENCY = 26  #: see units.AtanUnit
ATAN_II = 16
LATENCY = {"mul": Fp32Mul.LATENCY, "add": Fp32Add.LATENCY, "div": Fp32Div.LATENCY,
           "sqrt": Fp32Sqrt.LATENCY, "misc": 1, "atan": ATAN_LATENCY}
II = {"mul": 1, "add": 1, "div": 1, "sqrt": 1, "misc": 1, "atan": ATAN_II}
#: operand ports of each unit
PORTS = {"mul": ("a", "b"), "add": ("a", "b"), "div": ("a", "b"), "sqrt": ("a",),
         "misc": ("a", "b"), "atan": ("a", "b")}
UNITS = tuple(PORTS)
PHASES = (("acc", "mag"), ("gyro",), ("quat",), ("matx",), ("euler",))
BANKS = 2
BANK_DEPTH = 32
MISC_CODES = {"neg": 0, "dbl": 1, "clampneg": 2, "yawsel": 3}


class ScheduleError(RuntimeError):
    """The program cannot be placed under the datapath's rules."""


@dataclass(frozen=True)
class Placed:
    op: Op
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
            out[p.op.unit] = out.get(p.op.unit, 0) + 1
        return out

    def table(self) -> str:
        rows = []
        for c in range(self.length):
            here = [f"{p.op.unit}:{p.op.name}" for p in self.ops if p.cycle == c]
            if here:
                rows.append(f"{c:4d} " + "  ".join(here))
        return "\n".join(rows)


def _paths(program: list[Op]) -> dict:
    users: dict[str, list[Op]] = {o.name: [] for o in program}
    for o in program:
        for a in o.args:
            if a in users:
                users[a].append(o)
    tail: dict[str, int] = {}
    for o in reversed(program):
        lat = LATENCY[o.unit] + 1
        tail[o.name] = lat + max([tail[u.name] for u in users[o.name]], default=0)
    return tail


def build_schedule(program: list[Op], sources, sinks: dict, phases=PHASES,
                   banks: int = BANKS, bank_depth: int = BANK_DEPTH,
                   max_cycles: int = 2000, bypass: bool = True,
                   latency: dict | None = None) -> Schedule:
    """Place ``program``. ``sources``: values held in flip-flops before the solve (inputs,
    state, parameters; constants are added); ``sinks``: value -> flip-flop register the
    result goes to (new state, outputs)."""
    global LATENCY
    saved = LATENCY
    if latency is not None:
        LATENCY = {**LATENCY, **latency}
    try:
        return _build(program, sources, sinks, phases, banks, bank_depth, max_cycles, bypass)
    finally:
        LATENCY = saved


def _build(program, sources, sinks, phases, banks, bank_depth, max_cycles, bypass):
    sources = tuple(sources) + tuple(k for k in CONSTANTS if k not in sources)
    produced = {o.name for o in program}
    for o in program:
        for a in o.args:
            if a not in produced and a not in sources:
                raise ScheduleError(f"{o.name}: operand {a} is neither produced nor a source")
    phases = tuple(tuple(m for m in ph if any(o.module == m for o in program))
                   for ph in phases)
    phases = tuple(ph for ph in phases if ph)
    phase_of = {m: i for i, ph in enumerate(phases) for m in ph}
    tail = _paths(program)
    order = {o.name: i for i, o in enumerate(program)}
    ready: dict[str, int] = {s: 0 for s in sources}
    unit_busy: dict[tuple[str, int], bool] = {}
    bank_write: set[tuple[int, int]] = set()
    placed: dict[str, Placed] = {}
    bank_of: dict[str, int] = {}
    windows = []
    release = 0
    for pi, ph in enumerate(phases):
        todo = [o for o in program if phase_of[o.module] == pi]
        c = release
        first = None
        while todo:
            if c > max_cycles:
                raise ScheduleError(f"phase {ph} does not fit in {max_cycles} cycles")
            cands = [o for o in todo if all(ready.get(a, 10**9) <= c for a in o.args)]
            cands.sort(key=lambda o: (-tail[o.name], order[o.name]))
            for o in cands:
                u = o.unit
                if any(unit_busy.get((u, c + t)) for t in range(II[u])):
                    continue
                done = c + LATENCY[u]
                if o.name in sinks:
                    bank = None
                else:
                    free = [k for k in range(banks) if (k, done) not in bank_write]
                    if not free:
                        continue
                    bank = free[0]
                    bank_write.add((bank, done))
                    bank_of[o.name] = bank
                for t in range(II[u]):
                    unit_busy[(u, c + t)] = True
                placed[o.name] = Placed(o, c, done, ("ff", sinks[o.name]) if bank is None
                                        else ("bank", bank, -1))
                ready[o.name] = done if bypass else done + 1
                first = c if first is None else first
                todo.remove(o)
            c += 1
        last = max(placed[o.name].done for o in program if phase_of[o.module] == pi)
        windows.append((first, last))
        release = last + 1
    length = release

    # last read of every value
    last_read: dict[str, int] = {}
    for p in placed.values():
        for a in p.op.args:
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
            if p.op.name not in last_read:
                raise ScheduleError(f"{p.op.name} is never read")
            addr = next((a for a, t in enumerate(free_at) if t <= p.done), None)
            if addr is None:
                addr = len(free_at)
                free_at.append(0)
            free_at[addr] = last_read[p.op.name]
            placed[p.op.name] = Placed(p.op, p.cycle, p.done, ("bank", k, addr))
        if len(free_at) > bank_depth:
            raise ScheduleError(f"bank {k} needs {len(free_at)} registers > {bank_depth}")
        depth.append(len(free_at))
    ops = sorted(placed.values(), key=lambda p: (p.cycle, order[p.op.name]))
    sched = Schedule(ops, phases, windows, length, sources, dict(sinks), bank_depth=depth)
    loc = {s: ("ff", s) for s in sources}
    for p in ops:
        loc[p.op.name] = p.dest
    sched._loc = loc
    sched._done = {p.op.name: (p.done, p.op.unit) for p in ops}
    # operand sources per port, in first-use order. Multiplications and additions are
    # commutative bit for bit (IEEE results, canonical NaN), so each one takes the operand
    # order that adds the fewest new sources to the two port multiplexers (greedy).
    ps: dict[tuple[str, str], list] = {}

    def key(a, cycle):
        src = sched.read_source(a, cycle)
        return src[:2] if src[0] == "bank" else src

    final = []
    for p in ops:
        u = p.op.unit
        args = p.op.args
        if p.op.kind in ("mul", "add") and args[0] != args[1]:
            la, lb = ps.get((u, "a"), []), ps.get((u, "b"), [])
            k0, k1 = key(args[0], p.cycle), key(args[1], p.cycle)
            keep = (k0 not in la) + (k1 not in lb)
            swap = (k1 not in la) + (k0 not in lb)
            if swap < keep:
                p = Placed(Op(p.op.name, p.op.kind, (args[1], args[0]), p.op.module),
                           p.cycle, p.done, p.dest)
        for port, a in zip(PORTS[u], p.op.args, strict=False):
            lst = ps.setdefault((u, port), [])
            if key(a, p.cycle) not in lst:
                lst.append(key(a, p.cycle))
        final.append(p)
    sched.ops = final
    sched.port_sources = ps
    return sched
