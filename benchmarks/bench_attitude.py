"""Throughput of navgate's attitude filters, and a cross-check against the ``ahrs`` package.

Usage: python benchmarks/bench_attitude.py [--n 2000000] [--repeat 3] [--seed 0]
                                           [--log ../shared/data/fusion_sensor_data.csv]

Table 1, speed (one core, best of ``--repeat``; the first call's Numba compilation is
excluded): the float64 Mahony filter (seed 003 equations, :func:`mahony_batch`) and the
complementary filter over ``--n`` synthetic samples (random gyro/accel/mag drawn from
``--seed``), the seed-003 float32 bit-true model (solves per second with 4096 circuits in
lock-step), and the TinyKalman integer pipeline (samples per second).

Table 2, where the ``ahrs`` package is installed (it is a benchmark-only dependency): its
``Mahony`` filter and navgate's on the same real log (x-io 100 Hz), same gains (its defaults
Kp = 1, Ki = 0.3), same fixed step 1/100 s, same start. IMU-only (accelerometer + gyro) the
two filters are the same equations, so the outputs agree to rounding. With the magnetometer,
``ahrs`` puts the horizontal reference field on its y axis (east-north-up), seed 003 on x
(north): the two navigation frames differ by a 90 deg turn about the vertical, and navgate's
start attitude is turned by -90 deg to match; roll and pitch agree, yaw differs by 90 deg.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

from navgate.nav.rotations import dcm_to_euler_array, quat_to_dcm_array
from navgate.numerics.fp32 import f32_to_bits
from navgate.systems.attitude import mahony as ref
from navgate.systems.attitude import mahony_fp32 as bt
from navgate.systems.attitude.complementary import complementary_batch
from navgate.systems.tinykalman import model as tk

DEFAULT_LOG = Path(__file__).resolve().parents[2] / "shared" / "data" / "fusion_sensor_data.csv"


def _best(fn, repeat):
    best = math.inf
    out = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return best, out


def speed_table(n, repeat, seed, console):
    rng = np.random.default_rng(seed)
    gyro = rng.normal(0, 0.5, (n, 3))
    acc = rng.normal(0, 0.5, (n, 3)) + [0, 0, -9.8]
    mag = rng.normal(0, 0.05, (n, 3)) + [0.4, 0.0, 0.9]
    dt = np.full(n, 0.01)
    q0 = np.array([1.0, 0, 0, 0])
    p = ref.NED_SI
    ms = np.asarray(p.mag_sign, dtype=np.float64)

    def mahony():
        return ref.mahony_batch(gyro, acc, mag, dt, q0, p.kp, p.ki, p.gyro_scale, ms,
                                p.accel_sign, True)

    def mahony_imu():
        return ref.mahony_batch(gyro, acc, mag, dt, q0, p.kp, p.ki, p.gyro_scale, ms,
                                p.accel_sign, False)

    def compl():
        return complementary_batch(gyro, acc, mag, dt, q0, 0.02, True)

    rows = []
    for name, fn in (("Mahony float64 (MARG)", mahony), ("Mahony float64 (IMU only)", mahony_imu),
                     ("complementary float64 (MARG)", compl)):
        fn_small = fn  # compile once outside the timing
        ref.mahony_batch(gyro[:10], acc[:10], mag[:10], dt[:10], q0, p.kp, p.ki, p.gyro_scale,
                         ms, p.accel_sign, True)
        complementary_batch(gyro[:10], acc[:10], mag[:10], dt[:10], q0, 0.02, True)
        t, _ = _best(fn_small, repeat)
        rows.append((name, n, t, n / t))

    batch, solves = 4096, 5
    circuit = bt.MahonyCircuitFP32(ref.SEED003, batch=batch)
    ins = [f32_to_bits(rng.normal(0, 1, batch).astype(np.float32)) for _ in range(9)]

    def bittrue():
        for _ in range(solves):
            circuit.solve(ins[0:3], ins[3:6], ins[6:9])

    t, _ = _best(bittrue, repeat)
    rows.append(("seed-003 float32 bit-true (4096 lanes)", batch * solves, t,
                 batch * solves / t))

    m = min(n, 200000)
    words = rng.integers(-16384, 16384, (5, m))
    words[2] += 16384

    def tiny():
        return tk.run_sequence(*words)

    t, _ = _best(tiny, repeat)
    rows.append(("seed-001 TinyKalman integer model", m, t, m / t))

    table = Table(title="attitude filters: throughput (one core)")
    for col in ("filter", "samples", "best time (s)", "samples/s"):
        table.add_column(col, justify="right" if col != "filter" else "left")
    for name, k, t, rate in rows:
        table.add_row(name, f"{k}", f"{t:.4f}", f"{rate:,.0f}")
    console.print(table)
    return rows


def ahrs_table(log_path, console):
    try:
        from ahrs.filters import Mahony
    except ImportError:
        console.print("ahrs package not installed: comparison skipped")
        return None
    from navgate.sim.imu_log import read_imu_csv

    if not Path(log_path).exists():
        console.print(f"{log_path} not found: comparison skipped")
        return None
    log = read_imu_csv(log_path)
    gyro, acc, mag = log.gyro, log.acc, log.mag  # raw x-io axes: z up (as ahrs expects)
    n = len(log)
    hz = 100.0
    kp, ki = 1.0, 0.3
    params = ref.MahonyParams(kp=kp, ki=ki, dt=1.0 / hz, gyro_scale=1.0,
                              mag_sign=(1.0, 1.0, 1.0), accel_sign=1.0)
    q_enu = np.array([1.0, 0.0, 0.0, 0.0])
    c45 = math.sqrt(0.5)
    q_nwu = np.array([c45, 0.0, 0.0, -c45])  # the same start, seen from seed 003's frame
    results = []
    for mode, use_mag in (("IMU only", False), ("MARG", True)):
        t0 = time.perf_counter()
        theirs = Mahony(gyr=gyro, acc=acc, mag=mag if use_mag else None, frequency=hz, k_P=kp,
                        k_I=ki, q0=q_enu).Q
        t_theirs = time.perf_counter() - t0
        q0 = q_nwu if use_mag else q_enu
        ref.run_mahony(gyro[:5], acc[:5], mag[:5] if use_mag else None, params=params, q0=q0)
        t0 = time.perf_counter()
        ours = ref.run_mahony(gyro, acc, mag if use_mag else None, params=params, q0=q0)
        t_ours = time.perf_counter() - t0
        e_t = np.degrees(np.column_stack(dcm_to_euler_array(quat_to_dcm_array(theirs))))
        e_o = np.degrees(np.column_stack(dcm_to_euler_array(quat_to_dcm_array(ours))))
        d = e_o - e_t
        if use_mag:
            d[:, 2] += 90.0
        d[:, 2] = (d[:, 2] + 180.0) % 360.0 - 180.0
        qd = np.min([np.abs(ours - theirs).max(axis=1), np.abs(ours + theirs).max(axis=1)],
                    axis=0) if not use_mag else None
        results.append((mode, n, t_theirs, t_ours, np.abs(d).max(axis=0),
                        None if qd is None else float(qd.max())))
    table = Table(title=f"navgate Mahony vs ahrs.filters.Mahony on {Path(log_path).name} "
                        f"({n} samples)")
    for col in ("mode", "ahrs samples/s", "navgate samples/s", "speed ratio",
                "max |d roll| (deg)", "max |d pitch| (deg)", "max |d yaw| (deg)",
                "max |d q|"):
        table.add_column(col, justify="right")
    for mode, k, tt, to, dmax, qd in results:
        yaw_note = " (after -90)" if mode == "MARG" else ""
        table.add_row(mode, f"{k / tt:,.0f}", f"{k / to:,.0f}", f"{tt / to:,.0f}x",
                      f"{dmax[0]:.2e}", f"{dmax[1]:.2e}", f"{dmax[2]:.2e}{yaw_note}",
                      "-" if qd is None else f"{qd:.2e}")
    console.print(table)
    return results


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=2_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--log", type=Path, default=DEFAULT_LOG)
    args = ap.parse_args(argv)
    console = Console(width=150)
    speed_table(args.n, args.repeat, args.seed, console)
    ahrs_table(args.log, console)


if __name__ == "__main__":
    main()
