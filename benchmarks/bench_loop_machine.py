"""opflow's loop machine (navgate.opflow.loopmachine) on small generic float32 loop nests:
modulo schedules (II against its resource and recurrence bounds, iteration depth, exact
cycles) and the xc7z020 synthesis (Yosys ``synth_xilinx`` through navgate.hw.synth: LUT,
FF, DSP48E1, BRAM36, and the xc7 logic-only critical path) of chosen nests.

    python benchmarks/bench_loop_machine.py [--synth rank1_15 ...] [--json out.json]

Nests: ``rank1_15`` (P <- P + k k^T on the 120 stored elements of a symmetric 15 x 15
matrix, ROM row/column maps), ``rank1_15_scaled`` (P + (s k) k^T: two multiplies on one
multiplier), ``spmv_15`` (y <- A x, 15 x 15 with 45 non-zeros in a fixed pseudo-random
pattern, seed 0, ROM column/row maps and row flags), ``matvec_15`` (dense 15 x 15, two
levels, affine addresses), ``matvec_il_15`` (the same sums with the row loop inside: one
accumulator at distance 15). Each synthesis takes a minute or two on a quiet machine.

The sequence machine (navgate.opflow.sequence): ``--sequence-lanes 1 2`` synthesises the
machine of :func:`navgate.opflow.loop_kernels.chain_program` at n = 15 (the sparse pattern
above; segments prep, spmv, rank1, cmp, norm on one datapath with ``lanes`` multipliers and
adders, an iterative divider and square root, a comparator) once per lane count, and prints
its segment schedules, entry cycles, control-store size and the xc7z020 row beside issue 29's
engine targets (<= 4,500 LUT, 6 DSP48E1, 3 BRAM36, logic path <= 4.0 ns).
Prints tables and writes a JSON summary (default ``bench_loop_machine.json``).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from navgate.opflow import loop_kernels as K
from navgate.opflow.loops import LoopUnits, modulo_schedule


def nests() -> dict:
    rng = np.random.default_rng(0)
    flat = np.sort(rng.choice(15 * 15, 45, replace=False))
    return {"rank1_15": K.sym_rank1_update(15),
            "rank1_15_scaled": K.sym_rank1_update(15, 0.5),
            "spmv_15": K.sparse_matvec(flat // 15, flat % 15, 15, 15),
            "matvec_15": K.dense_matvec(15, 15),
            "matvec_il_15": K.dense_matvec_interleaved(15, 15)}


def sequence_rows(lanes_list) -> dict:
    from navgate.hw.synth import XC7_ROW_HEADER, print_xc7_row, xc7_summary
    from navgate.hw.verilog import emit_verilog
    from navgate.opflow.sequence import SequenceMachine, schedule_sequence

    rng = np.random.default_rng(0)
    flat = np.sort(rng.choice(15 * 15, 45, replace=False))
    prog = K.chain_program(15, flat // 15, flat % 15)
    out: dict = {}
    for lanes in lanes_list:
        sch = schedule_sequence(prog, lanes)
        print(f"\nsequence machine {prog.name}, lanes {lanes}")
        print(f"{'segment':10s} {'iters':>6s} {'II':>3s} {'ResMII':>6s} {'RecMII':>6s} "
              f"{'depth':>5s} {'cycles':>7s}")
        for name, s in sch.schedules.items():
            print(f"{name:10s} {s.nest.iterations:6d} {s.ii:3d} {s.res_mii:6d} {s.rec_mii:6d} "
                  f"{s.depth:5d} {s.cycles:7d}")
        cycles = {e: sch.cycles(e) for e in prog.entries}
        print("entry cycles (start to done):", cycles)
        dut = SequenceMachine(sch)
        text = emit_verilog(dut, "sequence_machine")
        print(f"control store: {dut.control_rows} rows x {dut.control_bits} bits")
        print("\nlanes" + XC7_ROW_HEADER[5:])
        row = xc7_summary(text, "sequence_machine")
        print_xc7_row(f"{lanes}", row)
        print("issue 29 engine targets: <= 4,500 LUT, 6 DSP48E1, 3 BRAM36, <= 4.0 ns")
        out[lanes] = {"cycles": cycles, "control_rows": dut.control_rows,
                      "control_bits": dut.control_bits, "synth": row,
                      "segments": {n: {"ii": s.ii, "depth": s.depth, "cycles": s.cycles}
                                   for n, s in sch.schedules.items()}}
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--synth", nargs="*", default=["rank1_15"], help="nests to synthesise")
    ap.add_argument("--sequence-lanes", nargs="*", type=int, default=[],
                    help="lane counts of the sequence machine to synthesise (1 to 4)")
    ap.add_argument("--json", default="bench_loop_machine.json")
    args = ap.parse_args()
    all_nests = nests()
    unknown = [n for n in args.synth if n not in all_nests]
    if unknown:
        raise SystemExit(f"unknown nest(s) {unknown}; known: {', '.join(all_nests)}")
    units = LoopUnits()
    summary: dict = {"units": vars(units) if hasattr(units, "__dict__") else str(units),
                     "nests": {}}
    print(f"units: {units}")
    print(f"{'nest':16s} {'iters':>6s} {'II':>3s} {'ResMII':>6s} {'RecMII':>6s} "
          f"{'depth':>5s} {'cycles':>7s}")
    scheds = {}
    for name, nest in all_nests.items():
        s = modulo_schedule(nest, units)
        scheds[name] = s
        print(f"{name:16s} {nest.iterations:6d} {s.ii:3d} {s.res_mii:6d} {s.rec_mii:6d} "
              f"{s.depth:5d} {s.cycles:7d}")
        summary["nests"][name] = {"iterations": nest.iterations, "ii": s.ii,
                                  "res_mii": s.res_mii, "rec_mii": s.rec_mii,
                                  "depth": s.depth, "cycles": s.cycles}
    if args.synth:
        from navgate.hw.synth import XC7_ROW_HEADER, print_xc7_row, xc7_summary
        from navgate.hw.verilog import emit_verilog
        from navgate.opflow.loopmachine import LoopMachine

        print("\nnest" + XC7_ROW_HEADER[4:])
        for name in args.synth:
            row = xc7_summary(emit_verilog(LoopMachine(scheds[name]), "loop_machine"),
                              "loop_machine")
            print_xc7_row(name, row)
            summary["nests"][name]["synth"] = row
    if args.sequence_lanes:
        summary["sequence"] = sequence_rows(args.sequence_lanes)
    Path(args.json).write_text(json.dumps(summary, indent=2, default=str) + "\n")
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
