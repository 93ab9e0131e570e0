"""Seed 000's programs as segments + loop nests (navgate.systems.ins_trn.pl.loop_programs):
cycles per IMU sample, per 2-D (TRN) update and per 1-D (altitude) update on machines of
1 to 4 multiplier + adder lanes, step by step, for both variants (``plain``: every part in a
step of its own; ``fused``: work moved into the segments' free issue slots), against issue
29's targets; the control the steps need (segment microcode rows = their cycles, nest ROM
table words); and a bit-exactness check of every program against the fp32 engine.

    python benchmarks/bench_loop_programs.py [--lanes 1 2 3 4] [--checks 20] [--json out.json]

Cycles: segments by opflow's list scheduler (BankedUnits with ``lanes`` mul and add slots,
the shared misc slot with the iterative divider and square root, split read ports), nests by
opflow's modulo scheduler (LoopUnits with ``lanes`` mul and add units, every array readable
by every lane), a program's count the sum of its steps'. The 1-D and 2-D updates are the
``*_apply`` programs, which start with their gate (gate and apply fused). Prints tables and
writes a JSON summary (default ``bench_loop_programs.json``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from navgate.numerics.fp32 import float_to_bits
from navgate.opflow.execute import Machine
from navgate.opflow.loops import LoopNest
from navgate.systems.ins_trn.pl import fp32_program as fp
from navgate.systems.ins_trn.pl import loop_programs as L
from navgate.systems.ins_trn.pl.nav_engines import IMU_WORDS, random_registers

#: issue 29's targets: program -> (label, cycles)
TARGETS = {"propagate": ("IMU sample", 1000), "trn_apply": ("2-D update", 400),
           "alt_apply": ("1-D update", 250)}


def control(lps: dict) -> dict:
    """Microcode rows of the distinct segments (a row per cycle; programs that are the
    same ops counted once) and the ROM table words of the nests."""
    seen: dict = {}
    words = 0
    for lp in lps.values():
        for step in lp.steps:
            if isinstance(step, LoopNest):
                words += sum(len(t) for t in step.tables.values())
            else:
                key = tuple((op.kind, op.srcs) for op in step.prog.ops)
                if key and key not in seen:
                    seen[key] = step.name
    return {"segments": sorted(set(seen.values())), "table_words": words}


def check_bits(lps: dict, n: int, seed: int) -> int:
    """Random states through every program: registers and outputs that differ (0 expected)."""
    ref = Machine(fp.programs())
    rng = np.random.default_rng(seed)
    bad = 0
    for key, lp in lps.items():
        inputs_names = fp.programs()[key].inputs
        for _ in range(n):
            regs = random_registers(rng, list(fp.STATE_REGS) + list(inputs_names))
            state = {k: (float(w - (1 << 32) if w >= 1 << 31 else w) if k in IMU_WORDS
                         else float(np.uint32(w).view(np.float32))) for k, w in regs.items()}
            inputs = {k: state.pop(k) for k in inputs_names}
            for k, v in state.items():
                ref.set(k, v)
            want = ref.run(key, **inputs)
            got, out = L.run_program(lp, state, inputs)
            bad += sum(float_to_bits(got[k]) != float_to_bits(ref.get(k)) for k in fp.STATE_REGS)
            bad += sum(float_to_bits(out[k]) != float_to_bits(v) for k, v in want.items())
    return bad


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lanes", type=int, nargs="*", default=[1, 2, 3, 4])
    ap.add_argument("--checks", type=int, default=20, help="random states per program")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default="bench_loop_programs.json")
    args = ap.parse_args()
    if any(n < 1 for n in args.lanes):
        raise SystemExit("--lanes: lane counts must be >= 1")
    summary: dict = {"default_lanes": L.DEFAULT_LANES, "targets": TARGETS, "runs": {}}
    for variant in L.VARIANTS:
        for lanes in args.lanes:
            t0 = time.perf_counter()
            lps = L.loop_programs(lanes, variant)
            run = {"programs": {}, "control": control(lps)}
            print(f"\n{variant}, {lanes} lane(s)")
            print(f"  {'program':10s} {'step':16s} {'kind':8s} {'II':>3s} {'cycles':>7s}")
            for key, lp in lps.items():
                rows = L.program_cycles(lp, lanes)
                total = sum(r[2] for r in rows)
                for name, kind, cyc, ii in rows:
                    print(f"  {key:10s} {name:16s} {kind:8s} {ii or '':>3} {cyc:7d}")
                label, target = TARGETS.get(key, (key, None))
                mark = "" if target is None else (f" <= {target} met" if total <= target
                                                  else f" > {target} MISSED")
                print(f"  {key:10s} {'= ' + label:16s} {'':8s} {'':>3s} {total:7d}{mark}")
                run["programs"][key] = {"steps": [{"name": r[0], "kind": r[1], "cycles": r[2],
                                                   "ii": r[3]} for r in rows],
                                        "cycles": total, "target": target}
            seg = run["control"]
            rows_total = sum(next(r[2] for lp in lps.values()
                                  for r in L.program_cycles(lp, lanes) if r[0] == s)
                             for s in seg["segments"])
            seg["microcode_rows"] = rows_total
            print(f"  control: {rows_total} segment microcode rows ({', '.join(seg['segments'])}),"
                  f" {seg['table_words']} nest ROM table words")
            if args.checks:
                bad = check_bits(lps, args.checks, args.seed)
                run["bits_differing"] = bad
                print(f"  bits: {args.checks} random states per program against the fp32 "
                      f"programs: {bad} registers/outputs differ")
            seq = L.sequence_cycles(lanes, variant)
            run["sequence_machine"] = seq
            print("  on opflow's sequence machine (registered; segment II, cycles + 1):")
            for key in lps:
                steps = " + ".join(f"{n} {c} (II {ii})" for n, ii, c in seq[key]["steps"])
                label, target = TARGETS.get(key, (key, None))
                mark = "" if target is None else (f" <= {target} met"
                                                  if seq[key]["cycles"] <= target
                                                  else f" > {target} MISSED")
                print(f"    {label:11s} {seq[key]['cycles']:5d}{mark}: {steps}")
            print(f"    control rows (sum of IIs): {seq['control_rows']}")
            run["seconds"] = round(time.perf_counter() - t0, 2)
            summary["runs"][f"{variant}/{lanes}"] = run
    Path(args.json).write_text(json.dumps(summary, indent=1) + "\n")
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
