"""Seed 000's engines on the banked scheduled float32 datapath
(navgate.systems.ins_trn.pl.nav_engines):
exact cycle counts of every program per block (first issue to last write; a command adds
the ``start``/``done`` cycle), the lower bounds of fp32_program.schedule_bounds, register banks
and microcode sizes, and the Verilator simulation rate of ``ins_engines`` (native model of
navgate.gateware.native_stream; the first run builds it).

    python benchmarks/bench_engines.py [--samples 50] [--no-verilator] [--json out.json]

Prints tables and writes a JSON summary (default ``bench_engines.json`` in the current
directory).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from navgate.opflow.schedule import UNIT_LATENCY
from navgate.systems.ins_trn.pl.fp32_program import schedule_bounds
from navgate.systems.ins_trn.pl.nav_engines import (
    ENGINE_UNITS,
    IMU_WORDS,
    PROGRAM_SETS,
    command_vectors,
    engine_image,
    engine_programs,
    random_registers,
)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=50, help="propagate runs for the rate")
    ap.add_argument("--no-verilator", action="store_true")
    ap.add_argument("--json", default="bench_engines.json")
    args = ap.parse_args()
    summary: dict = {"units": ENGINE_UNITS.__dict__, "blocks": {}}
    lat = {u: UNIT_LATENCY[u] for u in ("add", "mul", "div", "sqrt", "cmp", "cvt")}
    counts = {"add": ENGINE_UNITS.add, "mul": ENGINE_UNITS.mul, "div": 1, "sqrt": 1, "cmp": 1,
              "cvt": 1}
    allp = engine_programs()
    print(f"units: {ENGINE_UNITS}")
    print(f"{'block':24s} {'program':14s} {'ops':>5s} {'cycles':>7s} {'bound':>6s} "
          f"{'movs':>5s}")
    for block in PROGRAM_SETS:
        img = engine_image(block)
        info = {"banks": img.layout.bank_depth, "persistent": img.layout.temp_base,
                "rom_rows": len(img.rom), "rom_width": img.fields.width, "programs": {}}
        for key, sp in img.programs.items():
            b = schedule_bounds(allp[key], lat, counts)["bound"]
            movs = sum(s.kind == "mov" for s in sp.ops)
            n = sum(s.kind != "mov" for s in sp.ops)
            print(f"{block:24s} {key:14s} {n:5d} {sp.cycles:7d} {b:6d} {movs:5d}")
            info["programs"][key] = {"ops": n, "cycles": sp.cycles, "bound": b, "movs": movs}
        print(f"{'':24s} register banks (words) {info['banks']} ({info['persistent']} "
              f"persistent), microcode {info['rom_rows']} x {info['rom_width']} bits")
        summary["blocks"][block] = info
    c = summary["blocks"]["ins_engines"]["programs"]
    print(f"per IMU sample (propagate + start): {c['propagate']['cycles'] + 1} cycles; "
          f"2-D update (gate + apply, each + start): "
          f"{c['trn_gate']['cycles'] + c['trn_apply']['cycles'] + 2}; 1-D update: "
          f"{c['alt_gate']['cycles'] + c['alt_apply']['cycles'] + 2}")
    if not args.no_verilator:
        import time

        from navgate.gateware.native_stream import NativeStreamServer
        from navgate.opflow.machine import ScheduledMachineStream

        img = engine_image("ins_engines")
        rng = np.random.default_rng(0)
        names = [n for n in img.layout.fixed if not n.startswith("c:")]
        regs = random_registers(rng, names)
        calls = [("propagate", random_registers(rng, IMU_WORDS)) for _ in range(args.samples)]
        vec = command_vectors(img, regs, calls)
        server = NativeStreamServer(ScheduledMachineStream(img))
        t0 = time.perf_counter()
        out = server.batch(vec)
        secs = time.perf_counter() - t0
        server.close()
        cycles = int(out["cycles"].sum()) + 3 * int(np.count_nonzero(vec["cmd"] != 2))
        rate = cycles / secs
        print(f"Verilator ins_engines (native model, {args.samples} propagate runs with "
              f"register writes and read-back): {cycles} cycles in {secs:.2f} s: "
              f"{rate:,.0f} cycles/s (build {server.build_seconds:.1f} s)")
        summary["verilator"] = {"cycles": cycles, "seconds": secs, "cycles_per_s": rate}
    with open(args.json, "w") as fh:
        json.dump(summary, fh, indent=1)


if __name__ == "__main__":
    main()
