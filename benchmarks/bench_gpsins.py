"""Speed of seed 002's 9-state GPS/INS filter, against the paper's 0.9 ms per iteration on a
MicroBlaze (Virtex-6, 88 MHz, single-precision FPU).

Usage: python benchmarks/bench_gpsins.py [--iterations 200000] [--repeat 5] [--seed 0]
       python benchmarks/bench_gpsins.py --accuracy [--seeds 10]

``--accuracy`` instead flies the default 300 s flight for seeds 0..N-1 with each IMU model
(``navgate gpsins --imu ...``) and prints the accuracy table of docs/seed002-gpsins.md:
horizontal RMS of GPS-only and GPS/INS, their ratio (target <= 1/3), the pooled ratio
sqrt(mean GPS/INS MS / mean GPS-only MS) over the seeds (the quantity the optimal-filter
bound of navgate.systems.gpsins.bound predicts: an expected mean square), the outage error, the
3-sigma containment and NEES.

Each row times a Numba loop of ``--iterations`` calls (best of ``--repeat``; compilation
excluded) on a realistic state (a point of the default flight) and reports microseconds per
call on one core:

* filter propagate: F, Phi = I + F dt, P <- Phi (P + G Q G' dt) Phi';
* filter update: GPS measurement (scaled rows), Kalman gain, Joseph-form P, closed-loop
  correction of the INS;
* one filter iteration = propagate + update (the paper's "one iteration of Kalman filter");
* INS RK4 step (four derivative evaluations), for reference;
* the whole closed loop as the scenario runs it (100 Hz INS + propagate, 1 Hz update),
  per 100 Hz step.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from numba import njit
from rich.console import Console
from rich.table import Table

from navgate.systems.gpsins import filter as kf
from navgate.systems.gpsins import scenario
from navgate.systems.gpsins.ins import EARTH_WGS84, rk4_step


@njit(cache=True)
def _loop_propagate(P0, x, f_b, dt, qa, qg, n):
    P = P0.copy()
    for _ in range(n):
        kf.propagate(P, x, f_b, dt, qa, qg, EARTH_WGS84)
        P[:, :] = P0
    return P


@njit(cache=True)
def _loop_update(P0, x0, gps, sigma, n):
    P = P0.copy()
    x = x0.copy()
    for _ in range(n):
        dx, z, S = kf.gps_update(P, x, gps, sigma)
        kf.apply_correction(x, dx)
        P[:, :] = P0
        x[:] = x0
    return x


@njit(cache=True)
def _loop_iteration(P0, x0, f_b, dt, qa, qg, gps, sigma, n):
    P = P0.copy()
    x = x0.copy()
    for _ in range(n):
        kf.propagate(P, x, f_b, dt, qa, qg, EARTH_WGS84)
        dx, z, S = kf.gps_update(P, x, gps, sigma)
        kf.apply_correction(x, dx)
        P[:, :] = P0
        x[:] = x0
    return x


@njit(cache=True)
def _loop_rk4(x0, f_b, w_b, dt, n):
    x = x0.copy()
    for _ in range(n):
        x = rk4_step(x0, f_b, w_b, dt, EARTH_WGS84)
    return x


def _best(fn, repeat):
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def accuracy(n_seeds: int):
    """The seeds table: one row per IMU model, means over seeds (extremes in brackets)."""
    models = [("table1", lambda c: c), ("table1-uncalibrated", scenario.uncalibrated_config),
              ("table1, --gyro-noise 0.06", lambda c: scenario.with_gyro_noise(c, 0.06)),
              ("tactical", scenario.tactical_config), ("ideal", scenario.ideal_config)]
    table = Table(title=f"seed 002 GPS/INS accuracy, default flight, seeds 0..{n_seeds - 1}")
    for col in ("IMU", "GPS-only RMS (m)", "GPS/INS RMS (m)", "ratio mean [min, max]",
                "seeds <= 1/3", "seed 0", "pooled ratio", "max outage err (m) mean [max]",
                "outage in 3-sigma (min)", "NEES mean [min, max]", "bound"):
        table.add_column(col, justify="right")
    for name, make in models:
        rows = []
        for seed in range(n_seeds):
            cfg = make(scenario.GpsInsConfig(seed=seed))
            s = scenario.simulate(cfg).summary()
            gi = s["gps_ins"]
            rows.append((s["gps_only"]["rms_horizontal_error_m"], gi["rms_horizontal_error_m"],
                         gi["rms_ratio_to_gps_only"], gi["max_horizontal_error_during_outage_m"],
                         gi["outage_within_3sigma_per_axis_fraction"],
                         gi["nees_position_mean"],
                         s["optimal_filter_bound"]["rms_ratio_to_gps_only"]))
        a = np.array(rows)
        r = a[:, 2]
        table.add_row(name, f"{a[:, 0].mean():.1f}", f"{a[:, 1].mean():.1f}",
                      f"{r.mean():.3f} [{r.min():.3f}, {r.max():.3f}]",
                      f"{int((r <= 1 / 3).sum())}/{n_seeds}", f"{r[0]:.3f}",
                      f"{math.sqrt(np.mean(a[:, 1] ** 2) / np.mean(a[:, 0] ** 2)):.3f}",
                      f"{a[:, 3].mean():.0f} [{a[:, 3].max():.0f}]", f"{100 * a[:, 4].min():.0f} %",
                      f"{a[:, 5].mean():.2f} [{a[:, 5].min():.2f}, {a[:, 5].max():.2f}]",
                      f"{a[0, 6]:.3f}")
    Console(width=200).print(table)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--iterations", type=int, default=200_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--accuracy", action="store_true",
                    help="print the accuracy table over seeds instead of timings")
    ap.add_argument("--seeds", type=int, default=10)
    args = ap.parse_args(argv)
    if args.accuracy:
        accuracy(args.seeds)
        return
    n = args.iterations

    cfg = scenario.GpsInsConfig(seed=args.seed)
    res = scenario.simulate(cfg)  # also compiles the scenario loop
    k = len(res.truth.t) // 2
    x = res.states[k].copy()
    gyro, accel = res.truth.imu()
    f_b, w_b = accel[k].copy(), gyro[k].copy()
    dt = 1.0 / cfg.rate_hz
    P0 = np.ascontiguousarray(np.diag([1e-12, 1e-12, 100.0, 0.1, 0.1, 0.1, 1e-5, 1e-5, 1e-4]))
    qa = np.array([cfg.q_accel**2, cfg.q_accel**2, cfg.q_accel_z**2])
    qg = np.full(3, cfg.q_gyro**2)
    gps = res.truth.states[k, :3].copy()
    sigma = np.full(3, 20.0)

    for fn in (lambda m: _loop_propagate(P0, x, f_b, dt, qa, qg, m),
               lambda m: _loop_update(P0, x, gps, sigma, m),
               lambda m: _loop_iteration(P0, x, f_b, dt, qa, qg, gps, sigma, m),
               lambda m: _loop_rk4(x, f_b, w_b, dt, m)):
        fn(10)  # compile

    rows = [
        ("filter propagate (F, Phi, P)", _best(lambda: _loop_propagate(
            P0, x, f_b, dt, qa, qg, n), args.repeat) / n),
        ("filter update (GPS fix) + correction", _best(lambda: _loop_update(
            P0, x, gps, sigma, n), args.repeat) / n),
        ("one filter iteration (propagate + update)", _best(lambda: _loop_iteration(
            P0, x, f_b, dt, qa, qg, gps, sigma, n), args.repeat) / n),
        ("INS RK4 step", _best(lambda: _loop_rk4(x, f_b, w_b, dt, n), args.repeat) / n),
    ]
    sig = np.full(3, cfg.table1.gps_sigma_m)
    gyro_m = np.ascontiguousarray(gyro)
    accel_m = np.ascontiguousarray(accel)
    x0, p0 = scenario.initial_state(res.truth, cfg, np.random.default_rng(0))

    def loop():
        scenario._run(x0, p0, gyro_m, accel_m, dt, res.gps.index.astype(np.int64),
                      res.gps.lla, res.gps.valid, sig, qa, qg, cfg.q_sf_accel,
                      cfg.q_sf_gyro, cfg.q_tau_s)

    steps = gyro.shape[0]
    rows.append((f"closed loop per 100 Hz step ({steps} steps)", _best(loop, args.repeat)
                 / steps))

    table = Table(title="seed 002 GPS/INS: time per call (one core)")
    table.add_column("operation")
    table.add_column("microseconds", justify="right")
    table.add_column("vs 0.9 ms (MicroBlaze)", justify="right")
    for name, t in rows:
        table.add_row(name, f"{t * 1e6:.2f}", f"{900e-6 / t:,.0f}x faster")
    Console(width=120).print(table)
    it = rows[2][1] * 1e6
    print(f"target: one filter iteration <= 20 us: {'met' if it <= 20 else 'NOT met'} "
          f"({it:.2f} us)")


if __name__ == "__main__":
    main()
