"""Long sensor streams through the interfaces' emitted Verilog (Verilator + cocotb) against
the bit-level device models: lost / duplicated / altered samples and fault accounting.

Each interface runs n samples (default 4000, i.e. 10 s of the IMU at 400 Hz) with a fault of
every class every 97 samples; the TF-Luna receiver also gets a clean stream from
cocotbext-uart. Prints a table and writes a JSON summary.

    python benchmarks/bench_sensors.py [-n 4000] [--only imu baro lidar lidar_cocotbext]
                                       [--out build/bench_sensors.json]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from navgate.systems.ins_trn.pl.sensors.verilator_bench import STREAMS, long_streams


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-n", type=int, default=4000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--only", nargs="+", default=list(STREAMS), choices=STREAMS)
    ap.add_argument("--out", default="build/bench_sensors.json")
    args = ap.parse_args()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    summary = {"n": args.n, "seed": args.seed, "streams": {}}
    for name in args.only:
        t0, c0 = time.perf_counter(), time.process_time()
        res = long_streams(args.n, args.seed, only=(name,))[name]
        res["wall_s"] = round(time.perf_counter() - t0, 1)
        res["cpu_s_parent"] = round(time.process_time() - c0, 1)
        summary["streams"][name] = res
        out.write_text(json.dumps(summary, indent=2) + "\n")
        print(f"{name}: " + ", ".join(f"{k} {v}" for k, v in res.items()), flush=True)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
