"""The gateware sensor emulators (issue 12): cycles per IMU sample through the pins in
SpiMasterImu's data-ready mode, and the resources of the emulators (yosys synth_xilinx,
xc7z020).

Cycles: Adis16500Emulator -> pins -> SpiMasterImu in the Amaranth simulator with ``-n``
samples pushed at once (the emulator's FIFO keeps the master busy), for each divider; prints
CS_N falling -> sample out (latency) and CS_N falling -> next CS_N falling (period).
Resources: the emulators, spi_master_imu and spi_master_baro synthesised from their emitted
Verilog. Prints tables and writes a JSON summary.

    python benchmarks/bench_sensor_emulators.py [-n 8] [--div 2 49] [--no-synth]
                                                [--out build/bench_sensor_emulators.json]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from navgate.systems.ins_trn.pl.sensors.adis16500_emulator import Adis16500Emulator
from navgate.systems.ins_trn.pl.sensors.bmp390_emulator import Bmp390Emulator
from navgate.systems.ins_trn.pl.sensors.sim_bench import run_imu_emulated
from navgate.systems.ins_trn.pl.sensors.spi_master_baro import SpiMasterBaro
from navgate.systems.ins_trn.pl.sensors.spi_master_imu import SpiMasterImu, burst_cycles
from navgate.systems.ins_trn.pl.sensors.tfluna_emulator import TfLunaEmulator

FIELDS = ("gx", "gy", "gz", "ax", "ay", "az", "temp", "diag")


def cycles(n: int, div: int, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    samples = [dict(zip(FIELDS, [int(x) for x in rng.integers(-32768, 32768, 7)]
                        + [int(rng.integers(0, 1 << 16))], strict=True)) for _ in range(n)]
    res = run_imu_emulated(samples, div=div, dr_sync=1,
                           cycles=n * (burst_cycles(div) + 20) + 100)
    ok = [{k: g[k] for k in FIELDS} for g in res["got"]] == samples
    lat = sorted({v - c for c, v in zip(res["cs_fall_at"], res["valid_at"], strict=True)})
    per = sorted({int(p) for p in np.diff(res["cs_fall_at"])})
    return {"div": div, "sclk_half_cycles": div + 1, "samples": n,
            "delivered_equal": ok, "latency_cycles": lat, "period_cycles": per,
            "underruns": res["underruns"], "master_errors": res["error_count"]}


def resources() -> dict:
    from navgate.gateware.verify import emit_verilog
    from navgate.hw.synth import synthesize

    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, comp in (("adis16500_emulator", Adis16500Emulator()),
                           ("tfluna_emulator", TfLunaEmulator()),
                           ("spi_master_imu", SpiMasterImu()),
                           ("bmp390_emulator", Bmp390Emulator()),
                           ("spi_master_baro", SpiMasterBaro())):
            r = synthesize(emit_verilog(comp, name), name, "xc7z020", Path(tmp) / name)
            out[name] = {k: r[k] for k in ("lut", "ff", "dsp", "carry4", "bram36")}
            out[name]["ram32m"] = r["cells"].get("RAM32M", 0)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-n", type=int, default=8)
    ap.add_argument("--div", type=int, nargs="+", default=[2, 49])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-synth", action="store_true")
    ap.add_argument("--out", default="build/bench_sensor_emulators.json")
    args = ap.parse_args()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    summary = {"n": args.n, "seed": args.seed, "cycles": [], "resources": None}
    print("| cfg_spi_div | SCLK half (cycles) | samples | delivered = pushed | latency (cycles) "
          "| period (cycles) | wall (s) |")
    print("|---|---|---|---|---|---|---|")
    for div in args.div:
        t0 = time.perf_counter()
        r = cycles(args.n, div, args.seed)
        r["wall_s"] = round(time.perf_counter() - t0, 1)
        summary["cycles"].append(r)
        out.write_text(json.dumps(summary, indent=2) + "\n")
        print(f"| {div} | {div + 1} | {r['samples']} | {r['delivered_equal']} | "
              f"{r['latency_cycles']} | {r['period_cycles']} | {r['wall_s']} |", flush=True)
    if not args.no_synth:
        summary["resources"] = resources()
        out.write_text(json.dumps(summary, indent=2) + "\n")
        print("\n| block | LUT | RAM32M | FF | CARRY4 | DSP | BRAM36 |")
        print("|---|---|---|---|---|---|---|")
        for name, r in summary["resources"].items():
            print(f"| {name} | {r['lut']} | {r['ram32m']} | {r['ff']} | {r['carry4']} | "
                  f"{r['dsp']} | {r['bram36']} |")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
