"""What a register-file engine would have to carry to run seed 000 at the lane machine's
speed (issue 29's fast engine; docs/opflow-register-machine.md section 7): the lifetimes
of the values in the 3-lane sequence-machine schedules that meet the cycle targets (fused
propagate 913, merged updates 205 / 337 cycles), and the register-file traffic they imply
when only values that live at most ``W`` cycles pass from unit to unit (forwarding or
short delay lines) and the others go through a register file; and the cycles of the same
programs when every unit result goes through a register file with P write ports; and
first the critical paths of the fp32 engine's programs with o extra cycles for every
operation that waits on another.

    python benchmarks/bench_fast_engine_brief.py [--lanes 3] [--synth] [--json out.json]

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


def banks(schedules: list) -> dict:
    """The register file the schedules would need with one bank per producer (each unit
    instance, each memory read port: one write port each, so writes never conflict) and,
    where the schedules keep lanes as clusters (``units.transfers``), one transfer bank per
    lane for the values sent to it: per bank the most values live at once and the most
    distinct values read in one cycle (a transfer reads its value's bank too), and per
    operand point (unit instance and operand, a store's data, a lane's transfer input) the
    banks it reads. A read in the cycle the value lands takes it from the unit or the bus (a
    bypass) and reads no bank. With clusters, also the writes a cycle into each lane's banks
    taken as one (the values a bank holds: read after the cycle they land), the most and
    the mean. Values as :func:`lives` (a sign flip is its source); nests folded modulo
    II."""
    live_most: collections.Counter = collections.Counter()
    read_most: collections.Counter = collections.Counter()
    point_banks: dict = collections.defaultdict(set)
    bank_points: dict = collections.defaultdict(set)
    lane_most: collections.Counter = collections.Counter()
    lane_total: collections.Counter = collections.Counter()
    reads = bypassed = cycles = 0
    for sch in schedules:
        nest = sch.nest
        lanes = sch.units.lanes if sch.units.transfers else 0
        period = sch.ii if nest.iterations > 1 else sch.depth + 1
        alias = {op.dst: op.srcs[0] for op in nest.ops if op.kind == "neg"}

        def root(v, alias=alias):
            while v in alias:
                v = alias[v]
            return v

        bank = {}
        for op in nest.ops:
            if op.kind != "neg":
                res, inst = sch.resource[op.dst]
                bank[op.dst] = ("load" if res[0] == "read" else res[0],
                                inst % lanes if lanes and res[0] == "read" else inst)

        def lane_of(b):
            return b[1] if b[0] in ("mul", "add", "load", "xfer") else 0

        accs = {a.name: a for a in nest.accs}
        uses = []  # (value, transfer key, read offset, operand point, its lane or None)
        for op in nest.ops:
            if op.kind in ("neg", "load"):
                continue
            res, inst = sch.resource[op.dst]
            lane = inst if res[0] in ("mul", "add") else 0
            for pos, x in enumerate(map(root, op.srcs)):
                point = (res[0], inst, pos)
                if x in accs:
                    a = accs[x]
                    if nest.iterations > 1:
                        uses.append((root(a.update), a.name,
                                     sch.time[op.dst] + a.distance * sch.ii, point, lane))
                    if not a.init.startswith("c:"):
                        uses.append((root(a.init), root(a.init), sch.time[op.dst], point,
                                     lane))
                elif not x.startswith("c:"):
                    uses.append((x, x, sch.time[op.dst], point, lane))
        for k, st in enumerate(nest.stores):
            uses.append((root(st.src), None, sch.time[("store", k)], ("store", 0, 0), None))
        copies = []  # (bank, value, ready, read offset, operand point)
        for v, key, t, point, lane in uses:
            home = bank[v]
            if lanes and lane is not None and lane != lane_of(home):
                x = sch.transfers[(key, lane)]
                copies.append((("xfer", lane), v, x + 1, t, point))
                copies.append((home, v, sch.ready[v], x, ("bus", lane, 0)))
            else:
                copies.append((home, v, sch.ready[v], t, point))
        live, rd = collections.defaultdict(collections.Counter), collections.defaultdict(
            lambda: collections.defaultdict(set))
        last: dict = {}
        for b, v, r, t, point in copies:
            reads += nest.iterations
            if t == r:
                bypassed += nest.iterations
                continue
            point_banks[point].add(b)
            bank_points[b].add(point)
            rd[b][t % period].add(v)
            last[(b, v)] = (r, max(last.get((b, v), (r, t))[1], t))
        lane_writes: collections.Counter = collections.Counter()
        for (b, _), (r, t) in last.items():
            for c in range(r, t):
                live[b][c % period] += 1
            if lanes:  # the banks of a lane as one: its writes a cycle (without the loaded
                # words too, which could be read from memory again instead)
                for with_loads in ((True,) if b[0] == "load" else (True, False)):
                    lane_writes[(lane_of(b), with_loads, r % period)] += 1
                    lane_total[(lane_of(b), with_loads)] += nest.iterations
        for (lane, with_loads, _), n in lane_writes.items():
            lane_most[(lane, with_loads)] = max(lane_most[(lane, with_loads)], n)
        cycles += sch.cycles
        for b, c in live.items():
            live_most[b] = max(live_most[b], max(c.values()))
        for b, c in rd.items():
            read_most[b] = max(read_most[b], max(len(x) for x in c.values()))
    return {"banks": {f"{b[0]}{b[1]}": {"live": live_most[b], "reads": read_most[b],
                                        "points": len(bank_points[b])}
                      for b in sorted(set(live_most) | set(read_most))},
            "points": {f"{p[0]}{p[1]}.{p[2]}": len(b) for p, b in sorted(point_banks.items())},
            "lane_writes": {f"{k[0]}{' with loads' if k[1] else ''}": {
                "most": lane_most[k], "mean": round(lane_total[k] / max(1, cycles), 2)}
                for k in sorted(lane_most)},
            "reads": reads, "bypassed": bypassed}


def bank_cost(depth: int, reads: int) -> dict:
    """LUT RAM of one bank of ``depth`` 32-bit words, one write port and ``reads``
    combinational read ports (outputs registered), as Yosys ``synth_xilinx`` maps Amaranth
    memories of that shape (pieces of at most 64 words and a multiplexer per read port):
    cells and LUT sites (4 a RAM32M or RAM64M)."""
    from amaranth.back import verilog
    from amaranth.hdl import Array, Module
    from amaranth.lib import wiring
    from amaranth.lib.memory import Memory
    from amaranth.lib.wiring import In, Out

    from navgate.hw.synth import xc7_summary

    bits = max(1, (depth - 1).bit_length())

    class Bank(wiring.Component):
        def __init__(self):
            sig = {"we": In(1), "waddr": In(bits), "wdata": In(32)}
            for r in range(reads):
                sig[f"raddr{r}"] = In(bits)
                sig[f"rdata{r}"] = Out(32)
            super().__init__(sig)

        def elaborate(self, platform):
            m = Module()
            # pieces of at most 64 words (Yosys would put a deeper memory with registered
            # reads in block RAM), the read port's word chosen by its upper address bits
            pieces = max(1, depth // 64)
            low = bits - (pieces - 1).bit_length()
            data = [[] for _ in range(reads)]
            for k in range(pieces):
                mem = Memory(shape=32, depth=depth // pieces, init=[])
                m.submodules[f"mem{k}"] = mem
                w = mem.write_port()
                m.d.comb += [w.en.eq(self.we & (self.waddr[low:] == k) if pieces > 1
                                     else self.we),
                             w.addr.eq(self.waddr[:low]), w.data.eq(self.wdata)]
                for r in range(reads):
                    p = mem.read_port(domain="comb")
                    m.d.comb += p.addr.eq(getattr(self, f"raddr{r}")[:low])
                    data[r].append(p.data)
            for r in range(reads):
                addr = getattr(self, f"raddr{r}")
                m.d.sync += getattr(self, f"rdata{r}").eq(
                    Array(data[r])[addr[low:]] if pieces > 1 else data[r][0])
            return m

    row = xc7_summary(verilog.convert(Bank(), name="bank", emit_src=False), "bank")
    cells = row["memory_cells"]
    return {"lut": row["lut"], "cells": cells,
            "lut_ram": 4 * sum(v for k, v in cells.items() if k in ("RAM32M", "RAM64M")),
            "other_ram": {k: v for k, v in cells.items() if k not in ("RAM32M", "RAM64M")}}


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


def program_text(lanes: int) -> dict:
    """variant -> (the operations and stores of its program text, every segment once;
    {entry: cycles on the lane machine}): what an instruction store would hold against what
    the text buys, for the variants of :func:`navgate.systems.ins_trn.pl.loop_programs.
    loop_programs` (``plain``: nests for every vector part; ``fused``: long straight lines
    around the propagation's nests and the Joseph nests; ``merged``: each update one
    straight line)."""
    out = {}
    for variant in L.VARIANTS:
        prog, _ = L.to_sequence(L.loop_programs(lanes, variant))
        sched = schedule_sequence(prog, lanes, read_ports=max(2, lanes))
        text = sum(len([o for o in nest.ops if o.kind != "neg"]) + len(nest.stores)
                   for nest in prog.segments.values())
        out[variant] = (text, {e: sched.cycles(e) for e in ENTRIES})
    return out


def beside(lanes: int) -> dict:
    """entry -> cycles of the ``plain`` update with its Joseph nest and its correction side
    by side (:func:`navgate.opflow.loops.schedule_beside`), against one after the other."""
    from navgate.opflow.loops import schedule_beside

    prog, _ = L.to_sequence(L.loop_programs(lanes, "plain"))
    sched = schedule_sequence(prog, lanes, read_ports=max(2, lanes))
    out = {}
    for entry, pre in (("alt_apply", "alt"), ("trn_apply", "trn")):
        nest, line = prog.segments[f"{pre}_joseph"], prog.segments[f"{pre}_corr"]
        looped, straight, both = schedule_beside(nest, line, sched.units)
        before = sum(sched.schedules[n].cycles for n in prog.entries[entry]
                     if n not in (nest.name, line.name))
        out[entry] = {"nest": looped.cycles, "line_alone": sched.schedules[line.name].cycles,
                      "line": straight.depth, "both": both, "plain": sched.cycles(entry),
                      "entry": before + both + 1}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lanes", type=int, default=3)
    ap.add_argument("--json", default="bench_fast_engine_brief.json")
    ap.add_argument("--synth", action="store_true",
                    help="synthesise the register-file banks the schedules need (minutes)")
    args = ap.parse_args()
    summary: dict = {"lanes": args.lanes, "entries": {}}
    print("critical paths of the fp32 engine's programs, o extra cycles a dependent operation:")
    cps = critical_paths()
    print(f"{'entry':10s} {'ops':>6s} " + " ".join(f"{'o=' + str(o):>6s}" for o in range(4)))
    for name, (ops, paths) in cps.items():
        print(f"{name:10s} {ops:6d} " + " ".join(f"{paths[o]:6d}" for o in range(4)))
    summary["critical_paths"] = {k: {"ops": v[0], **{str(o): c for o, c in v[1].items()}}
                                 for k, v in cps.items()}
    print("\nprogram text (operations and stores, every segment once) and the cycles it buys "
          "on the lane machine:")
    print(f"{'variant':8s} {'text':>6s} " + " ".join(f"{e:>10s}" for e in ENTRIES))
    summary["program_text"] = {}
    for variant, (text, cycles) in program_text(args.lanes).items():
        summary["program_text"][variant] = {"text": text, **cycles}
        print(f"{variant:8s} {text:6d} " + " ".join(f"{cycles[e]:10d}" for e in ENTRIES))
    print("\nthe plain updates with the Joseph nest and the correction side by side "
          "(schedule_beside: the correction in the slots the nest leaves):")
    summary["beside"] = {}
    for entry, got in beside(args.lanes).items():
        summary["beside"][entry] = got
        print(f"  {entry}: nest {got['nest']} + correction alone {got['line_alone']} -> "
              f"beside {got['both']} (the correction {got['line']}); the entry "
              f"{got['plain']} -> {got['entry']}")
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
    # lanes as clusters (each lane reads what it made; transfers between lanes), and the
    # ops moved as late as their reads allow: the cycles
    print("\nlanes as clusters, T transfers into a lane a cycle (one cycle long); the "
          "propagation's chained sums over 27 (the default) or 30 tracks; ops as placed or "
          "as late as their reads allow (cycles):")
    print(f"{'T':>2s} {'tracks':>6s} {'late':>5s} " + " ".join(f"{e:>10s}" for e in ENTRIES))
    summary["clusters"] = []
    progs30 = L.to_sequence(L.loop_programs(args.lanes, "fused", tracks=30))[0]
    for transfers, tracks, late in ((1, 27, ""), (2, 27, ""), (1, 30, ""), (2, 30, ""),
                                    (1, 30, "all")):
        got = {}
        for entry, variant in ENTRIES.items():
            prog = progs30 if entry == "propagate" and tracks == 30 else cache[variant][0]
            sched = schedule_sequence(prog, args.lanes, read_ports=max(2, args.lanes),
                                      transfers=transfers, late=late)
            got[entry] = sched.cycles(entry)
        summary["clusters"].append({"transfers": transfers, "tracks": tracks,
                                    "late": late or "no", **got})
        print(f"{transfers:2d} {tracks:6d} {late or 'no':>5s} "
              + " ".join(f"{got[e]:10d}" for e in ENTRIES))
    # the register file those schedules need, one bank per producer (no write conflicts)
    designs = {"lane machine": {}, "lane machine, ops late": {"late": "all"},
               "clusters": {"transfers": 1, "late": "all"}}
    summary["banks"] = {}
    shapes: dict = {}
    for design, opts in designs.items():
        clustered = bool(opts.get("transfers"))
        print(f"\n{design}{' (T = 1, 30 tracks, ops late)' if clustered else ''}: one register-"
              "file bank per producer (unit instance, read port; a lane's transfers): "
              "most values live / most distinct values read a cycle / operand points reading "
              "it; the most banks a point reads:")
        summary["banks"][design] = {}
        for entry, variant in ENTRIES.items():
            prog = progs30 if entry == "propagate" and clustered else cache[variant][0]
            sched = (schedule_sequence(prog, args.lanes, read_ports=max(2, args.lanes), **opts)
                     if opts else cache[variant][1])
            b = banks([sched.schedules[n] for n in prog.entries[entry]])
            summary["banks"][design][entry] = b
            print(f"  {entry}: {b['reads']} reads, {b['bypassed']} in the cycle the value "
                  f"lands (a bypass); a point reads at most {max(b['points'].values())} banks")
            print("    " + "  ".join(f"{k} {v['live']}/{v['reads']}/{v['points']}"
                                     for k, v in b["banks"].items()))
            if b["lane_writes"]:
                print("    writes a cycle into a lane's banks, most / mean: " + "  ".join(
                    f"lane {k} {v['most']} / {v['mean']}" for k, v in b["lane_writes"].items()))
            for k, v in b["banks"].items():
                shape = (max(32, 1 << max(0, v["live"] - 1).bit_length()), max(1, v["reads"]))
                old = shapes.setdefault(design, {}).get(k, (0, 0))
                shapes[design][k] = (max(old[0], shape[0]), max(old[1], shape[1]))
    if args.synth:
        costs: dict = {}
        summary["bank_lut_sites"] = {}
        for design, banked in shapes.items():
            print(f"\n{design}: those banks in LUT RAM (depth: the most live over the "
                  "entries, to a power of two >= 32; read ports: the most reads), Yosys "
                  "synth_xilinx:")
            total = 0
            for k, (depth, reads) in sorted(banked.items()):
                if (depth, reads) not in costs:
                    costs[(depth, reads)] = bank_cost(depth, reads)
                c = costs[(depth, reads)]
                total += c["lut_ram"] + c["lut"]
                print(f"  {k:6s} {depth:4d} x 32, {reads} read ports: {c['lut_ram']:4d} LUT as "
                      f"RAM + {c['lut']:3d} LUT {c['cells']}")
            print(f"  all banks: {total} LUT sites (the operand multiplexers not counted)")
            summary["bank_lut_sites"][design] = total
        summary["bank_costs"] = {f"{d}x{r}": c for (d, r), c in costs.items()}
    Path(args.json).write_text(json.dumps(summary, indent=1))
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
