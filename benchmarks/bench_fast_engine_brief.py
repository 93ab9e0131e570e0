"""What a register-file engine would have to carry to run seed 000 at the lane machine's
speed (issue 29's fast engine; docs/opflow-register-machine.md section 7): the lifetimes
of the values in the 3-lane sequence-machine schedules that meet the cycle targets (fused
propagate 913, merged updates 205 / 337 cycles), and the register-file traffic they imply
when only values that live at most ``W`` cycles pass from unit to unit (forwarding or
short delay lines) and the others go through a register file; and the cycles of the same
programs when every unit result goes through a register file with P write ports; and
first the critical paths of the fp32 engine's programs with o extra cycles for every
operation that waits on another.

    python benchmarks/bench_fast_engine_brief.py [--lanes 3] [--json out.json]

Counted per entry over its segments' schedules (:func:`navgate.opflow.sequence.
schedule_sequence`, ``registered``, every array readable by every lane): a value's life is
from the cycle it is ready to its last read (an accumulator's update read ``distance``
iterations later; a sign flip is its source). Values a load brings from memory need no
register-file write: their readers read the register file (or memory) when they use them.
A nest's per-cycle figures are its steady state (the schedule folded modulo II), a
straight-line segment's its own cycles. Prints tables and writes a JSON summary (default
``bench_fast_engine_brief.json``).
"""

from __future__ import annotations

import argparse
import collections
import json
from pathlib import Path

from navgate.opflow.sequence import schedule_sequence
from navgate.systems.ins_trn.pl import loop_programs as L

#: entry -> the loop-program variant whose 3-lane schedule meets its cycle target
ENTRIES = {"propagate": "fused", "alt_apply": "merged", "trn_apply": "merged"}
LIFE_BINS = (1, 2, 4, 8, 16, 32, 64)
WINDOWS = (4, 8, 16)
#: register-file write ports of the what-if (0: no limit, the lane machine)
PORTS = (0, 6, 5, 4, 3, 2)


def lives(sch) -> list:
    """(value, ready offset, life, reader offsets, made by a load) of one segment's
    schedule."""
    nest = sch.nest
    alias = {op.dst: op.srcs[0] for op in nest.ops if op.kind == "neg"}

    def root(v):
        while v in alias:
            v = alias[v]
        return v

    accs = {a.name: a for a in nest.accs}
    readers = collections.defaultdict(list)
    for op in nest.ops:
        if op.kind == "neg":
            continue
        for x in map(root, op.srcs):
            if x in accs:
                a = accs[x]
                if nest.iterations > 1:  # (a straight line reads only the init)
                    readers[root(a.update)].append(sch.time[op.dst] + a.distance * sch.ii)
                if not a.init.startswith("c:"):
                    readers[root(a.init)].append(sch.time[op.dst])
            elif not x.startswith("c:"):
                readers[x].append(sch.time[op.dst])
    for k, st in enumerate(nest.stores):
        readers[root(st.src)].append(sch.time[("store", k)])
    out = []
    for op in nest.ops:
        if op.kind == "neg":
            continue
        r = sch.ready[op.dst]
        reads = readers.get(op.dst, [])
        out.append((op.dst, r, max(reads) - r if reads else 0, reads, op.kind == "load"))
    return out


def traffic(schedules: list, window: int) -> dict:
    """Register-file traffic of values living longer than ``window``: the most writes and
    reads in one cycle and the most such values live at once, over the segments."""
    worst = {"writes": 0, "reads": 0, "live": 0, "values": 0, "total_writes": 0}
    for sch in schedules:
        period = sch.ii if sch.nest.iterations > 1 else sch.depth + 1
        writes, reads, live = (collections.Counter() for _ in range(3))
        count = 0
        for _, ready, life, rd, loaded in lives(sch):
            if life <= window:
                continue
            count += sch.nest.iterations
            if not loaded:
                worst["total_writes"] += sch.nest.iterations
                writes[ready % period] += 1
                for t in range(ready, ready + life):
                    live[t % period] += 1
            for t in rd:
                reads[t % period] += 1
        worst["writes"] = max(worst["writes"], max(writes.values(), default=0))
        worst["reads"] = max(worst["reads"], max(reads.values(), default=0))
        worst["live"] = max(worst["live"], max(live.values(), default=0))
        worst["values"] += count
    return worst


def critical_paths(overheads=(0, 1, 2, 3)) -> dict:
    """entry -> (operations, {o: the critical path with ``o`` extra cycles for every
    operation that waits on another}) of the fp32 engine's programs (the updates' gate and
    apply fused), with no resource limit: the units' latencies of navgate.gateware.fp32."""
    from navgate.gateware.fp32 import Fp32Add, Fp32Compare, Fp32DivIter, Fp32Mul, Fp32SqrtIter
    from navgate.systems.ins_trn.pl import fp32_program as fp

    lat = {"add": Fp32Add.LATENCY, "sub": Fp32Add.LATENCY, "mul": Fp32Mul.LATENCY,
           "div": Fp32DivIter.LATENCY, "sqrt": Fp32SqrtIter.LATENCY,
           "lt": Fp32Compare.LATENCY, "le": Fp32Compare.LATENCY}
    progs = fp.programs()
    entries = {"propagate": progs["propagate"],
               "alt_apply": L.fuse_programs(progs["alt_gate"], progs["alt_apply"], "alt"),
               "trn_apply": L.fuse_programs(progs["trn_gate"], progs["trn_apply"], "trn")}
    out = {}
    for name, prog in entries.items():
        paths = {}
        for o in overheads:
            ready: dict = {}
            for op in prog.ops:
                start = max([ready.get(x, 0) for x in op.srcs] + [0])
                # a sign flip costs nothing; a conversion of an input word one cycle
                ready[op.dst] = start if op.kind == "neg" else start + lat.get(op.kind, 1) + o
            paths[o] = max(ready.values(), default=0)
        out[name] = (len(prog.ops), paths)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lanes", type=int, default=3)
    ap.add_argument("--json", default="bench_fast_engine_brief.json")
    args = ap.parse_args()
    summary: dict = {"lanes": args.lanes, "entries": {}}
    print("critical paths of the fp32 engine's programs, o extra cycles a dependent operation:")
    cps = critical_paths()
    print(f"{'entry':10s} {'ops':>6s} " + " ".join(f"{'o=' + str(o):>6s}" for o in range(4)))
    for name, (ops, paths) in cps.items():
        print(f"{name:10s} {ops:6d} " + " ".join(f"{paths[o]:6d}" for o in range(4)))
    summary["critical_paths"] = {k: {"ops": v[0], **{str(o): c for o, c in v[1].items()}}
                                 for k, v in cps.items()}
    print()
    cache: dict = {}
    bins = " ".join(f"{'<=' + str(b):>6s}" for b in LIFE_BINS)
    print(f"{'entry':10s} {'variant':7s} {'cycles':>6s} {'values':>7s}  {bins} "
          f"{'>' + str(LIFE_BINS[-1]):>6s}")
    rows = []
    for entry, variant in ENTRIES.items():
        if variant not in cache:
            prog, _ = L.to_sequence(L.loop_programs(args.lanes, variant))
            cache[variant] = (prog, schedule_sequence(prog, args.lanes,
                                                      read_ports=max(2, args.lanes)))
        prog, s = cache[variant]
        schedules = [s.schedules[n] for n in prog.entries[entry]]
        hist = collections.Counter()
        for sch in schedules:
            for _, _, life, _, _ in lives(sch):
                b = next((b for b in LIFE_BINS if life <= b), None)
                hist[b] += sch.nest.iterations
        total = sum(hist.values())
        summary["entries"][entry] = {"variant": variant, "cycles": s.cycles(entry),
                                     "values": total,
                                     "lives": {str(b): hist[b] for b in LIFE_BINS}
                                     | {f">{LIFE_BINS[-1]}": hist[None]},
                                     "traffic": {}}
        print(f"{entry:10s} {variant:7s} {s.cycles(entry):6d} {total:7d}  "
              + " ".join(f"{hist[b]:6d}" for b in LIFE_BINS) + f" {hist[None]:6d}")
        for w in WINDOWS:
            t = traffic(schedules, w)
            summary["entries"][entry]["traffic"][str(w)] = t
            rows.append((entry, w, t))
    print("\nvalues living longer than W cycles (register-file traffic; loaded words need no "
          "write):")
    print(f"{'entry':10s} {'W':>3s} {'values':>7s} {'writes':>7s} {'mean/cycle':>10s} "
          f"{'most/cycle':>10s} {'reads most/cycle':>16s} {'live at once':>12s}")
    for entry, w, t in rows:
        cyc = summary["entries"][entry]["cycles"]
        print(f"{entry:10s} {w:3d} {t['values']:7d} {t['total_writes']:7d} "
              f"{t['total_writes'] / cyc:10.2f} {t['writes']:10d} {t['reads']:16d} "
              f"{t['live']:12d}")
    # every unit result through a register file of ``ports`` write ports (no forwarding):
    # the cycles of the same programs when at most that many results land in a cycle
    print("\nevery unit result written to a register file with P write ports (no forwarding), "
          "cycles:")
    print(f"{'P':>3s} " + " ".join(f"{e:>10s}" for e in ENTRIES))
    summary["result_ports"] = {}
    for ports in PORTS:
        got = {}
        for entry, variant in ENTRIES.items():
            prog, _ = cache[variant]
            sched = schedule_sequence(prog, args.lanes, read_ports=max(2, args.lanes),
                                      result_ports=ports)
            got[entry] = sched.cycles(entry)
        summary["result_ports"][str(ports)] = got
        print(f"{ports if ports else 'any':>3} " + " ".join(f"{got[e]:10d}" for e in ENTRIES))
    Path(args.json).write_text(json.dumps(summary, indent=1))
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
