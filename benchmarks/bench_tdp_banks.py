"""True-dual-port register banks for seed 000's ``ins_engines``
(``BankedUnits(shared_write_port=...)`` of navgate.opflow, docs/seed000-engines.md §7):
exact cycle counts of every program, the 1-D and 2-D update and the IMU sample, microcode
size and bank depths for separate write ports (the default), every bank true-dual-port, and
each single bank true-dual-port; optionally the xc7z020 synthesis (navgate.hw.synth, Yosys
``synth_xilinx``) and the xc7 logic-only critical path of chosen configurations (minutes
each).

    python benchmarks/bench_tdp_banks.py [--synth all 0 ...] [--json out.json]

``--synth`` takes configuration names as printed (``separate``, ``all``, or a bank number).
Prints tables and writes a JSON summary (default ``bench_tdp_banks.json``).
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

from navgate.systems.ins_trn.pl.nav_engines import ENGINE_UNITS, engine_image


def configs() -> dict:
    out = {"separate": False, "all": True}
    out.update({str(b): (b,) for b in range(ENGINE_UNITS.banks)})
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--synth", nargs="*", default=[], help="configurations to synthesise")
    ap.add_argument("--json", default="bench_tdp_banks.json")
    args = ap.parse_args()
    cfg = configs()
    unknown = [c for c in args.synth if c not in cfg]
    if unknown:
        raise SystemExit(f"unknown configuration(s) {unknown}; known: {', '.join(cfg)}")
    summary: dict = {"units": ENGINE_UNITS.__dict__, "configs": {}}
    print(f"{'shared banks':12s} {'propagate':>9s} {'alt g+a':>9s} {'trn g+a':>9s} "
          f"{'1-D':>5s} {'2-D':>5s} {'rom rows x bits':>16s} {'kbit':>6s}  bank words")
    for name, sw in cfg.items():
        img = engine_image("ins_engines",
                           replace(ENGINE_UNITS, split_ports=False, shared_write_port=sw))
        c = {k: img.cycles(k) for k in img.programs}
        one_d = c["alt_gate"] + c["alt_apply"] + 2
        two_d = c["trn_gate"] + c["trn_apply"] + 2
        rows, width = len(img.rom), img.fields.width
        print(f"{name:12s} {c['propagate']:9d} {c['alt_gate']:4d}+{c['alt_apply']:<4d} "
              f"{c['trn_gate']:4d}+{c['trn_apply']:<4d} {one_d:5d} {two_d:5d} "
              f"{rows:7d} x {width:3d}  {rows * width / 1000:6.1f}  {img.layout.bank_depth}")
        summary["configs"][name] = {"shared_write_port": sw, "cycles": c, "update_1d": one_d,
                                    "update_2d": two_d, "imu_sample": c["propagate"] + 1,
                                    "rom_rows": rows, "rom_width": width,
                                    "bank_depth": img.layout.bank_depth}
    if args.synth:
        from navgate.hw.synth import XC7_ROW_HEADER, print_xc7_row, xc7_summary
        from navgate.hw.verilog import emit_verilog
        from navgate.opflow.machine import ScheduledMachineStream

        print("\nshared banks" + XC7_ROW_HEADER[12:])
        for name in args.synth:
            img = engine_image("ins_engines",
                               replace(ENGINE_UNITS, split_ports=False,
                                       shared_write_port=cfg[name]))
            row = xc7_summary(emit_verilog(ScheduledMachineStream(img), "ins_engines"),
                              "ins_engines")
            print_xc7_row(name, row)
            summary["configs"][name]["synth"] = row
    Path(args.json).write_text(json.dumps(summary, indent=2, default=list) + "\n")
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
