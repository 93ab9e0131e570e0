"""The whole FPGA in the loop (``navgate fly --engine fpga-sim``): wall time and simulation
rate of ``ins_trn_top`` in Verilator (native model, navgate.gateware.native_axi) flying the
default mission INS+TRN, checked bit for bit against the fp32 engine.

    python benchmarks/bench_fpga_sim.py [--duration 600] [--seed 0] [--json out.json]

Prints a table and writes a JSON summary (default ``bench_fpga_sim.json`` in the current
directory). The first run builds the Verilator model (a few minutes on 2 cores; cached).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from navgate.systems.ins_trn.ps import flight
from navgate.systems.ins_trn.ps.navigator import Navigator, engine_setup
from navgate.systems.ins_trn.ps.pl_interface import make_engine
from navgate.trn.dem import Dem


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=600.0, help="flight seconds")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--json", default="bench_fpga_sim.json")
    args = ap.parse_args()
    dem = Dem.default()
    cfg = flight.FlightConfig(duration_s=args.duration, seed=args.seed)
    _, _, stream = flight.record_stream(dem, cfg)
    runs, wall, build = {}, {}, {}
    eng = None
    for name in ("fp32", "fpga-sim"):
        t0 = time.perf_counter()
        eng = make_engine(name, engine_setup(stream.header, cfg))
        build[name] = time.perf_counter() - t0
        nav = Navigator(eng, cfg, t0=stream.header["t0"], dem=dem, use_trn=True)
        t1 = time.perf_counter()
        runs[name] = nav.run(stream)
        wall[name] = time.perf_counter() - t1
    a, b = runs["fp32"], runs["fpga-sim"]
    equal = bool(np.array_equal(a.nav, b.nav) and np.array_equal(a.sigma, b.sigma)
                 and np.array_equal(a.p_ne, b.p_ne) and a.accepted == b.accepted
                 and a.rejected == b.rejected)
    cycles = eng.cycles
    sim = eng.sim
    summary = {
        "duration_s": args.duration, "seed": args.seed, "imu_samples": eng.samples,
        "bit_identical_to_fp32": equal,
        "fp32_wall_s": wall["fp32"], "fpga_sim_wall_s": wall["fpga-sim"],
        "fpga_sim_setup_s": build["fpga-sim"],
        "cycles": cycles, "cycles_per_s": cycles / wall["fpga-sim"],
        "cycles_per_imu_sample": cycles / max(eng.samples, 1),
        "bus_batches": sim.batches, "bus_commands": sim.commands,
        "update_interrupts": eng.interrupts,
        "profile_dmas": eng.profile.fifo.dmas, "profile_entries_pushed": eng.profile.pushes,
        "updates_accepted": b.accepted, "updates_rejected": b.rejected,
        "fixes": len(b.fixes),
    }
    eng.close()
    print(f"fpga-sim, {args.duration:g} s default mission INS+TRN (seed {args.seed})")
    for k, v in summary.items():
        print(f"  {k:26s} {v:,.3f}" if isinstance(v, float) else f"  {k:26s} {v}")
    with open(args.json, "w") as f:
        json.dump(summary, f, indent=2)
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
