"""Seed 003's attitude circuit: resources (xc7z020), generic gate count, ECP5 proxy Fmax and
the ``rtl`` engine's speed on the x-io log. Prints a markdown table and writes a JSON summary
(docs/seed003-attitude-circuit.md carries the figures).

    python benchmarks/bench_attitude_circuit.py [--blocks attitude_top ...] [--gates]
        [--timing] [--log ../shared/data/fusion_sensor_data.csv] [--json OUT.json]

Gate count (the seed targets an ASIC, its sections 5-6): Yosys generic synthesis and ABC
mapping to a two-input NAND/NOR library (plus inverters),

    read_verilog attitude_top.v; synth -top attitude_top -flatten; abc -g NAND,NOR;
    opt_clean; stat

counting ``$_NAND_``, ``$_NOR_``, ``$_NOT_`` and flip-flops. The control ROM and the two
register banks are memories that ``synth`` turns into flip-flops and logic (no RAM macro).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from navgate.hw.blocks import get_block
from navgate.hw.synth import run_yosys, synthesize, timing_ecp5
from navgate.hw.verilog import emit_verilog


def gate_count(verilog_text: str, top: str, work: Path) -> dict:
    work.mkdir(parents=True, exist_ok=True)
    (work / f"{top}.v").write_text(verilog_text)
    run_yosys(f"read_verilog {top}.v\nsynth -top {top} -flatten\nabc -g NAND,NOR\n"
              "opt_clean\ntee -q -o gates.json stat -json\n", work, "yosys_gates.log")
    cells = json.loads((work / "gates.json").read_text())["design"]["num_cells_by_type"]
    cells = {str(k): int(v) for k, v in cells.items()}
    ff = sum(v for k, v in cells.items() if "DFF" in k or "SDFF" in k or "DLATCH" in k)
    return {"nand2": cells.get("$_NAND_", 0), "nor2": cells.get("$_NOR_", 0),
            "not": cells.get("$_NOT_", 0), "ff": ff, "cells": cells}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", nargs="*", default=["attitude_top"])
    ap.add_argument("--gates", action="store_true", help="generic NAND/NOR gate count")
    ap.add_argument("--timing", action="store_true", help="ECP5 nextpnr proxy Fmax")
    ap.add_argument("--log", default=None, help="x-io log for the rtl engine speed")
    ap.add_argument("--json", default="bench_attitude_circuit.json")
    args = ap.parse_args()
    summary: dict = {"blocks": {}}
    rows = []
    with tempfile.TemporaryDirectory(prefix="navgate-att-") as d:
        for name in args.blocks:
            comp = get_block(name).factory()
            text = emit_verilog(comp, name)
            t0 = time.perf_counter()
            use = synthesize(text, name, "xc7z020", Path(d) / name)
            rec = {k: use[k] for k in ("lut", "ff", "dsp", "carry4", "bram36")}
            rec["latency"] = int(comp.LATENCY)
            if args.gates:
                rec["gates"] = gate_count(text, name, Path(d) / f"{name}-gates")
            if args.timing:
                rec["ecp5_fmax_mhz"] = timing_ecp5(text, name, Path(d) / f"{name}-ecp5").get(
                    "fmax_mhz")
            rec["seconds"] = round(time.perf_counter() - t0, 1)
            summary["blocks"][name] = rec
            g = rec.get("gates", {})
            rows.append(f"| {name} | {rec['latency']} | {rec['lut']} | {rec['ff']} | "
                        f"{rec['dsp']} | {rec['carry4']} | {rec['bram36']} | "
                        f"{g.get('nand2', '')} | {g.get('nor2', '')} | {g.get('not', '')} | "
                        f"{g.get('ff', '')} | {rec.get('ecp5_fmax_mhz', '')} |")
    print("| block | latency | LUT | FF | DSP48E1 | CARRY4 | BRAM36 | NAND2 | NOR2 | NOT | "
          "gate-level FF | ECP5 fmax (MHz) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    if args.log:
        from navgate.sim.imu_log import read_imu_csv
        from navgate.systems.attitude.circuit_engine import run_circuit
        log = read_imu_csv(args.log)
        t0 = time.perf_counter()
        run = run_circuit(log, "rtl")
        wall = time.perf_counter() - t0
        summary["rtl_engine"] = {"samples": len(log), "wall_s": round(wall, 2),
                                 "sim_s": round(run.seconds, 2),
                                 "build_s": round(run.build_seconds, 1),
                                 "cycles": run.cycles,
                                 "samples_per_s_sim": round(len(log) / run.seconds, 1)}
        print(f"\nrtl engine on {args.log}: {len(log)} samples, {run.cycles} cycles, "
              f"simulation {run.seconds:.2f} s ({len(log) / run.seconds:.0f} samples/s), "
              f"wall {wall:.1f} s (Verilator build {run.build_seconds:.0f} s)")
    Path(args.json).write_text(json.dumps(summary, indent=1))
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
