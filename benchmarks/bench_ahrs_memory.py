"""Peak memory and speed of ``navgate ahrs`` on a large IMU log (issue 17: at most 500 MB for a
10 M-row log), and byte-identity of its streamed output with the in-memory API.

Generates a synthetic plain-header log (t, gx gy gz, ax ay az, mx my mz: a slowly swinging
sensor with noise, 100 Hz) of ``--rows`` rows, written block by block; runs
``navgate ahrs LOG --out OUT --quiet`` in a child process and reads its peak resident set
size (``ru_maxrss`` of the child); then, for the first ``--compare-rows`` rows (all of them
with ``--compare-rows 0``), runs the in-memory path (``read_imu_csv`` + ``estimate_attitude``
+ ``write_attitude_csv``) and compares the two output files byte for byte.

Usage: ``python benchmarks/bench_ahrs_memory.py [--rows 10000000] [--compare-rows 1000000]``
(the 10 M-row log is about 0.9 GB; its in-memory comparison needs about 3 GB).
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

G0 = 9.80665


def write_log(path: Path, rows: int, seed: int = 0, block: int = 1_000_000) -> None:
    rng = np.random.default_rng(seed)
    with open(path, "w") as fh:
        fh.write("t,gx,gy,gz,ax,ay,az,mx,my,mz\n")
        for k0 in range(0, rows, block):
            k = np.arange(k0, min(rows, k0 + block))
            t = k / 100.0
            roll = 0.3 * np.sin(0.5 * t)
            gyro = np.column_stack([0.15 * np.cos(0.5 * t), np.zeros(k.size), np.zeros(k.size)])
            gyro += rng.normal(0, 0.01, gyro.shape)
            acc = np.column_stack([np.zeros(k.size), -G0 * np.sin(roll), -G0 * np.cos(roll)])
            acc += rng.normal(0, 0.05, acc.shape)
            mag = np.column_stack([np.full(k.size, 20.0), 40 * np.sin(roll), 40 * np.cos(roll)])
            np.savetxt(fh, np.column_stack([t, gyro, acc, mag]), delimiter=",",
                       fmt=["%.2f"] + ["%.6f"] * 9)


def head(src: Path, dst: Path, rows: int) -> None:
    with open(src) as fi, open(dst, "w") as fo:
        for i, line in enumerate(fi):
            if i > rows:
                break
            fo.write(line)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=10_000_000)
    ap.add_argument("--compare-rows", type=int, default=1_000_000,
                    help="rows compared with the in-memory path (0: all)")
    ap.add_argument("--dir", default=None, help="scratch directory (default: a temp dir)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(dir=args.dir) as scratch:
        scratch = Path(scratch)
        log = scratch / "imu.csv"
        t0 = time.perf_counter()
        write_log(log, args.rows)
        t_gen = time.perf_counter() - t0
        size_mb = log.stat().st_size / 1e6
        out = scratch / "att.csv"
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "navgate.cli", "ahrs", str(log), "--out",
                               str(out), "--quiet"], capture_output=True, text=True)
        t_run = time.perf_counter() - t0
        if proc.returncode != 0:
            sys.exit(f"navgate ahrs failed: {proc.stderr.strip()}")
        peak_mb = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
        n_cmp = args.rows if args.compare_rows in (0, None) else min(args.rows,
                                                                     args.compare_rows)
        from navgate.sim.imu_log import read_imu_csv, write_attitude_csv
        from navgate.systems.attitude.estimate import estimate_attitude

        cmp_log = log if n_cmp == args.rows else scratch / "head.csv"
        if cmp_log != log:
            head(log, cmp_log, n_cmp)
            proc = subprocess.run([sys.executable, "-m", "navgate.cli", "ahrs", str(cmp_log),
                                   "--out", str(scratch / "att_head.csv"), "--quiet"],
                                  capture_output=True, text=True)
            streamed = scratch / "att_head.csv"
        else:
            streamed = out
        t0 = time.perf_counter()
        res = estimate_attitude(read_imu_csv(cmp_log), "mahony", kp=1.0, ki=0.1)
        mem_out = scratch / "att_mem.csv"
        write_attitude_csv(mem_out, res.t, res.q, res.roll_deg, res.pitch_deg, res.yaw_deg)
        t_mem = time.perf_counter() - t0
        identical = mem_out.read_bytes() == streamed.read_bytes()
    print("| rows | log size (MB) | navgate ahrs wall (s) | peak RSS (MB) | bytes/row at peak "
          "| compared rows | identical to in-memory | in-memory wall (s) | log generation (s) |")
    print("|---:|---:|---:|---:|---:|---:|---|---:|---:|")
    print(f"| {args.rows} | {size_mb:.0f} | {t_run:.1f} | {peak_mb:.0f} | "
          f"{peak_mb * 1e6 / args.rows:.1f} | {n_cmp} | {identical} | {t_mem:.1f} | {t_gen:.1f} |")
    print(f"cpu count {os.cpu_count()}; target: peak RSS <= 500 MB for 10 M rows")


if __name__ == "__main__":
    main()
