"""Seed 000 on opflow's register machine (navgate.systems.ins_trn.pl.register_engine): cycles
per entry against the 400 Hz budget (250,000 cycles a sample at 100 MHz) and issue 29's
cycle targets, the sizes of its memories, and with ``--synth`` the xc7z020 figures (Yosys
``synth_xilinx`` and the logic-only path of ``navgate.hw.synth.timing_xc7``) against the
engine targets (<= 4,500 LUT, 6 DSP48E1, 3 BRAM36, logic path <= 4.0 ns).

    python benchmarks/bench_register_machine.py [--synth] [--json out.json]

Prints tables and writes a JSON summary (default ``bench_register_machine.json``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from navgate.opflow.regmachine import RegisterMachine
from navgate.systems.ins_trn.pl.register_engine import register_engine

#: issue 29's cycle targets (for the default lane machine): entry -> (label, cycles)
TARGETS = {"propagate": ("IMU sample", 1000), "trn_apply": ("2-D update", 400),
           "alt_apply": ("1-D update", 250), "alt_gate": ("1-D gate", None),
           "trn_gate": ("2-D gate", None)}
SAMPLE_CYCLES = 250_000  # one 400 Hz sample at 100 MHz


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--synth", action="store_true", help="synthesise for the xc7z020")
    ap.add_argument("--json", default="bench_register_machine.json")
    args = ap.parse_args()
    t0 = time.time()
    rp, _, _ = register_engine()
    dut = RegisterMachine(rp)
    summary: dict = {"compile_s": time.time() - t0, "entries": {}, "blocks": {}}
    print(f"compiled in {summary['compile_s']:.2f} s\n")
    print(f"{'entry':12s} {'what':12s} {'cycles':>8s} {'us @100MHz':>10s} "
          f"{'of a 400 Hz sample':>18s} {'lane target':>11s}")
    for e in rp.entries:
        c = rp.cycles(e)
        label, target = TARGETS.get(e, (e, None))
        summary["entries"][e] = {"cycles": c, "target": target}
        print(f"{e:12s} {label:12s} {c:8d} {c / 100:10.1f} {100 * c / SAMPLE_CYCLES:17.1f}% "
              f"{target if target else '':>11}")
    worst = rp.cycles("propagate") + max(rp.cycles("trn_apply"), rp.cycles("alt_apply"))
    print(f"\nIMU sample + an update: {worst} cycles = {100 * worst / SAMPLE_CYCLES:.1f} % of "
          "a 400 Hz sample at 100 MHz")
    print("\n(a software-pipelined block: its kernel of II cycles runs iterations + stages - 1 "
          "times, then the tail drains)")
    print(f"\n{'block':12s} {'iters':>6s} {'kernel':>6s} {'rows':>5s} {'issues':>6s} "
          f"{'II/cycles':>9s} {'stages':>6s} {'tail':>4s} {'total':>7s}")
    for b in rp.blocks.values():
        total = b.run_cycles
        summary["blocks"][b.name] = {"iterations": b.valid_trips, "kernel_runs": b.trips,
                                     "rows": len(b.rows), "issues": b.ops, "cycles": b.cycles,
                                     "stages": b.stages, "tail": b.tail, "total": total,
                                     "pipelined": b.overlapped}
        print(f"{b.name:12s} {b.valid_trips:6d} {b.trips:6d} {len(b.rows):5d} {b.ops:6d} "
              f"{b.cycles:9d} {b.stages:6d} {b.tail:4d} {total:7d}")
    sizes = {"instruction_rows": dut.instruction_rows, "table_entries": len(rp.table),
             "data_words": rp.data_words, "registers": rp.registers}
    summary["sizes"] = sizes
    print(f"\ninstruction ROM {sizes['instruction_rows']} x 36 bits (identical blocks once), "
          f"table ROM {sizes['table_entries']} x 9 bits, data memory {sizes['data_words']} "
          f"words, register file {sizes['registers']} words")
    if args.synth:
        from navgate.hw.synth import XC7_ROW_HEADER, print_xc7_row, xc7_summary
        from navgate.hw.verilog import emit_verilog

        t1 = time.time()
        text = emit_verilog(dut, "register_machine")
        row = xc7_summary(text, "register_machine")
        print("\n" + "machine" + XC7_ROW_HEADER[7:])
        print_xc7_row("register_machine", row)
        print(f"synthesis {time.time() - t1:.0f} s; issue 29 engine targets: <= 4,500 LUT, "
              "6 DSP48E1, 3 BRAM36, <= 4.0 ns")
        summary["synth"] = {**row, "synth_s": time.time() - t1}
    Path(args.json).write_text(json.dumps(summary, indent=2, default=str) + "\n")
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
