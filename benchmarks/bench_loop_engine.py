"""Seed 000's programs on opflow's sequence machine (navgate.systems.ins_trn.pl.loop_engine):
cycles per entry and per segment on 1 to 4 lanes against issue 29's cycle targets, the
control store and the structure that costs logic (control bits, operand sources, delay-line
bits), and, with ``--synth``, the xc7z020 figures of the machine (Yosys, as
``benchmarks/bench_loop_machine.py --sequence-lanes`` does) against the engine targets
(<= 4,500 LUT, 6 DSP48E1, 3 BRAM36, logic path <= 4.0 ns).

    python benchmarks/bench_loop_engine.py [--lanes 1 2 3 4] [--synth 3 1] [--json out.json]

Each synthesis emits about 17 MB of Verilog and takes long on a loaded 2-core machine
(minutes to emit, much longer to synthesise). Prints tables and writes a JSON summary
(default ``bench_loop_engine.json``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from navgate.systems.ins_trn.pl import loop_engine as E

#: issue 29's cycle targets: entry -> (label, cycles)
TARGETS = {"propagate": ("IMU sample", 1000), "trn_apply": ("2-D update", 400),
           "alt_apply": ("1-D update", 250)}
ENGINE_TARGETS = "issue 29 engine targets: <= 4,500 LUT, 6 DSP48E1, 3 BRAM36, <= 4.0 ns"


def structure(sch) -> dict:
    """What the machine builds from the schedule, counted without elaborating it: delay-line
    bits (each unit output and read port feeds a line as long as its oldest tap; 32 bits a
    stage) and the distinct operand sources of each unit input."""
    age: dict = {}
    srcs: dict = {}
    for s in sch.schedules.values():
        by = {op.dst: op for op in s.nest.ops}
        for op in s.nest.ops:
            if op.kind in ("neg", "load"):
                continue
            for pos, x in enumerate(op.srcs):
                flip = False
                while x in by and by[x].kind == "neg":
                    x, flip = by[x].srcs[0], not flip
                src = (x, flip)  # a constant, or an accumulator (its own multiplexer)
                if not x.startswith("c:") and x in by:
                    d = s.time[op.dst] - s.ready[x]
                    if by[x].kind == "load":
                        d += s.units.load_latency - 1
                    key = s.resource[x]
                    age[key] = max(age.get(key, 0), d)
                    src = (key, d, flip)  # a tap of a delay line
                srcs.setdefault((s.resource[op.dst], pos), set()).add(src)
        for k, st in enumerate(s.nest.stores):
            x = st.src
            while x in by and by[x].kind == "neg":
                x = by[x].srcs[0]
            if x in by:
                d = s.time[("store", k)] - s.ready[x]
                if by[x].kind == "load":
                    d += s.units.load_latency - 1
                key = s.resource[x]
                age[key] = max(age.get(key, 0), d)
    # address generators: slot k of a segment is its k-th distinct address that moves from
    # iteration to iteration (a fixed one is a control-store constant), delayed to its use
    slots: dict = {}
    for s in sch.schedules.values():
        uses: dict = {}
        for op in s.nest.ops:
            if op.kind == "load" and (op.addr.table or any(op.addr.strides)):
                uses.setdefault(op.addr, []).append(s.time[op.dst])
        for k, st in enumerate(s.nest.stores):
            if st.addr.table or any(st.addr.strides):
                uses.setdefault(st.addr, []).append(s.time[("store", k)])
        for k, ts in enumerate(uses.values()):
            slots[k] = max(slots.get(k, 0), max(ts))
    return {"delay_line_bits": 32 * sum(age.values()),
            "address_slots": len(slots),
            "address_delay_stages": sum(max(0, t - 1) for t in slots.values()),
            "longest_line": max(age.values()),
            "unit_input_sources": max(len(v) for v in srcs.values())}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lanes", nargs="*", type=int, default=[1, 2, 3, 4])
    ap.add_argument("--synth", nargs="*", type=int, default=[],
                    help="lane counts of the machine to synthesise for the xc7z020")
    ap.add_argument("--json", default="bench_loop_engine.json")
    args = ap.parse_args()
    for n in args.lanes + args.synth:
        if not 1 <= n <= 4:
            raise SystemExit(f"lane counts are 1 to 4, got {n}")
    summary: dict = {"lanes": {}, "targets": {k: v[1] for k, v in TARGETS.items()}}
    print(f"{'lanes':>5s} " + " ".join(f"{TARGETS[k][0] if k in TARGETS else k:>11s}"
                                       for k in E.ENTRIES) + f" {'rows':>5s} "
          f"{'delay bits':>10s} {'longest':>7s} {'srcs':>5s}")
    for lanes in args.lanes:
        sch = E.engine_schedule(lanes)
        cyc = {k: sch.cycles(k) for k in E.ENTRIES}
        st = structure(sch)
        print(f"{lanes:5d} " + " ".join(f"{cyc[k]:11d}" for k in E.ENTRIES)
              + f" {sch.control_rows:5d} {st['delay_line_bits']:10d} {st['longest_line']:7d} "
              f"{st['unit_input_sources']:5d} {st['address_slots']:10d}")
        summary["lanes"][lanes] = {
            "cycles": cyc, "control_rows": sch.control_rows, **st,
            "segments": {n: {"iterations": s.nest.iterations, "ii": s.ii, "depth": s.depth,
                             "cycles": s.cycles} for n, s in sch.schedules.items()},
            "targets_met": {k: cyc[k] <= TARGETS[k][1] for k in TARGETS}}
    print("targets: " + ", ".join(f"{lab} <= {c}" for lab, c in TARGETS.values())
          + " cycles")
    print("(rows: control-store rows = the sum of the segments' II; delay bits: 32-bit "
          "delay-line stages; srcs: most distinct sources of one unit input; addr slots: "
          "address generators, for the addresses that move from iteration to iteration)")
    sch = E.engine_schedule()
    print(f"\ndefault machine ({E.DEFAULT_LANES} lanes), segments:")
    print(f"{'segment':14s} {'iters':>6s} {'II':>4s} {'depth':>5s} {'cycles':>7s}")
    for n, s in sch.schedules.items():
        print(f"{n:14s} {s.nest.iterations:6d} {s.ii:4d} {s.depth:5d} {s.cycles:7d}")
    if args.synth:
        from navgate.hw.synth import XC7_ROW_HEADER, print_xc7_row, xc7_summary
        from navgate.hw.verilog import emit_verilog
        from navgate.opflow.sequence import SequenceMachine

        summary["synth"] = {}
        for lanes in args.synth:
            t0 = time.time()
            dut = SequenceMachine(E.engine_schedule(lanes))
            text = emit_verilog(dut, "sequence_machine")
            t1 = time.time()
            print(f"\n{lanes} lanes: control store {dut.control_rows} rows x "
                  f"{dut.control_bits} bits; Verilog {len(text) / 1e6:.1f} MB "
                  f"({t1 - t0:.0f} s)", flush=True)
            row = xc7_summary(text, "sequence_machine")
            print("lanes" + XC7_ROW_HEADER[5:])
            print_xc7_row(f"{lanes}", row)
            print(f"cycles per step: {E.engine_schedule(lanes).cycles('propagate')} "
                  f"(IMU sample); synthesis {time.time() - t1:.0f} s")
            print(ENGINE_TARGETS, flush=True)
            summary["synth"][lanes] = {"control_rows": dut.control_rows,
                                       "control_bits": dut.control_bits, **row,
                                       "synth_s": time.time() - t1}
            Path(args.json).write_text(json.dumps(summary, indent=2, default=str) + "\n")
    Path(args.json).write_text(json.dumps(summary, indent=2, default=str) + "\n")
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
