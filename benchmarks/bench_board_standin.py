"""The board engine's code path over its stand-in (``navgate fly --engine board --board-bus
verilator``): the Verilated ``ins_trn_top`` behind DevMemBus's word window, one bus access per
round trip, as the PS reaches the real bank. Wall time, the bus accesses per IMU sample (what a
Python PS on the Zybo will have to make), interrupt polls, checked bit for bit against fp32.

    python benchmarks/bench_board_standin.py [--duration 5] [--seed 1] [--json out.json]

Prints a table and writes a JSON summary (default ``bench_board_standin.json`` in the current
directory). The first run builds the Verilator model fpga-sim uses (cached).
"""

from __future__ import annotations

import argparse
import json
import resource
import time

import numpy as np

from navgate.systems.ins_trn.ps import flight
from navgate.systems.ins_trn.ps.board_engine import (
    STANDIN_ACCESS_CYCLES,
    BoardSettings,
    open_board,
)
from navgate.systems.ins_trn.ps.navigator import Navigator, engine_setup
from navgate.systems.ins_trn.ps.pl_interface import make_engine
from navgate.trn.dem import Dem


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=5.0, help="flight seconds")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", default="bench_board_standin.json")
    args = ap.parse_args()
    dem = Dem.default()
    cfg = flight.FlightConfig(duration_s=args.duration, seed=args.seed)
    _, _, stream = flight.record_stream(dem, cfg)
    t0 = time.perf_counter()
    board = open_board(BoardSettings(bus="verilator"))
    setup_s = time.perf_counter() - t0
    runs = {}
    with board:
        for name, options in (("fp32", {}), ("board", {"board": board})):
            eng = make_engine(name, engine_setup(stream.header, cfg), **options)
            nav = Navigator(eng, cfg, t0=stream.header["t0"], dem=dem, use_trn=True)
            t1, cpu = time.perf_counter(), resource.getrusage(resource.RUSAGE_SELF).ru_utime
            runs[name] = nav.run(stream)
            wall = time.perf_counter() - t1
            cpu = resource.getrusage(resource.RUSAGE_SELF).ru_utime - cpu
        accesses = board.bus._words.accesses + board.dma.bus._words.window.accesses
        sim = board.standin.sim
        a, b = runs["fp32"], runs["board"]
        equal = bool(np.array_equal(a.nav, b.nav) and np.array_equal(a.sigma, b.sigma)
                     and np.array_equal(a.p_ne, b.p_ne) and a.accepted == b.accepted
                     and a.rejected == b.rejected)
        hw = b.hardware
        summary = {
            "duration_s": args.duration, "seed": args.seed, "imu_samples": eng.samples,
            "bit_identical_to_fp32": equal, "standin_setup_s": setup_s,
            "board_wall_s": wall, "board_python_cpu_s": cpu,
            "bus_accesses": accesses, "bus_accesses_per_imu_sample": accesses / eng.samples,
            "access_cycles": STANDIN_ACCESS_CYCLES, "simulated_cycles": sim.cycles,
            "update_interrupts": hw["update_interrupts"],
            "interrupt_polls": hw["interrupt_polls"], "profile_dmas": hw["profile_dmas"],
            "fixes": len(b.fixes),
        }
    print(f"board over its stand-in, {args.duration:g} s default mission INS+TRN "
          f"(seed {args.seed})")
    for k, v in summary.items():
        print(f"  {k:28s} {v:,.3f}" if isinstance(v, float) else f"  {k:28s} {v}")
    with open(args.json, "w") as f:
        json.dump(summary, f, indent=2)
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
