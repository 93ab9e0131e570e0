"""Speed and accuracy of seed 002's GPS/INS: the full filter (navigation plus sensor error
states, augmented.py), its RTS and fixed-lag smoothers, and the seed's 9-state filter,
against the paper's 0.9 ms per iteration on a MicroBlaze (Virtex-6, 88 MHz, single-precision
FPU) and against the trajectory-exact bound.

Usage: python benchmarks/bench_gpsins.py [--iterations 200000] [--repeat 5] [--seed 0]
       python benchmarks/bench_gpsins.py --accuracy [--seeds 30] [--lag 10] [--models]

``--accuracy`` flies the default 300 s flight (Table-1 sensors, ``navgate gpsins``) for
seeds 0..N-1 with the full filter and smooths each run (RTS and a fixed lag of ``--lag`` s),
and prints the issue-14 targets: ratios to GPS-only pooled over the seeds,
sqrt(mean GPS/INS mean square / mean GPS-only mean square), whole flight (outage included)
and outage excluded on both sides, each against its trajectory bound
(navgate.systems.gpsins.bound.trajectory_bound, an expected mean square: the pooled ratio
estimates it); the seed's 9-state filter for comparison; and the NEES check: at each GPS
epoch the 3-dof position NEES averaged over the S seeds, S times which is chi-square with 3S
degrees of freedom for a consistent estimator, must lie in its two-sided 95 % band at about
95 % of the epochs. ``--models`` adds the per-IMU-model table (``--imu ...``) of both filters.

Timing rows: a Numba loop of ``--iterations`` calls (best of ``--repeat``; compilation
excluded) on a realistic state (a point of the default flight), microseconds per call on one
core:

* filter propagate: F, Phi = I + F dt, P <- Phi (P + G Q G' dt) Phi';
* filter update: GPS measurement (scaled rows), Kalman gain, Joseph-form P, closed-loop
  correction of the INS (and, full filter, of the sensor compensation);
* one filter iteration = propagate + update (the paper's "one iteration of Kalman filter");
* INS RK4 step (four derivative evaluations), for reference;
* the whole closed loop as the scenario runs it (100 Hz INS + propagate, 1 Hz update),
  per 100 Hz step;
* the smoothers' backward sweep (recomputing the covariances between epochs), per GPS epoch.

Both the wall clock and the process's CPU time are printed (and the load average): on the
shared development machine (2 cores, often a load of 10-30) the wall clock mostly measures
the wait for a core; the 20 us target is judged on the CPU time.
"""

from __future__ import annotations

import argparse
import math
import os
import time
from dataclasses import replace

import numpy as np
from numba import njit
from rich.console import Console
from rich.table import Table

from navgate.systems.gpsins import augmented, scenario
from navgate.systems.gpsins import filter as kf
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


@njit(cache=True)
def _loop_propagate_full(P0, x, f_c, w_c, dt, qa, qg, off, n):
    P = P0.copy()
    for _ in range(n):
        augmented.propagate(P, x, f_c, w_c, dt, qa, qg, off, EARTH_WGS84)
        P[:, :] = P0
    return P


@njit(cache=True)
def _loop_update_full(P0, x0, gps, sigma, off, n):
    P = P0.copy()
    x = x0.copy()
    comp = np.zeros(12)
    for _ in range(n):
        dx, z, S = augmented.gps_update(P, x, gps, sigma)
        augmented.apply_correction(x, comp, dx, off)
        P[:, :] = P0
        x[:] = x0
    return x


@njit(cache=True)
def _loop_iteration_full(P0, x0, f_c, w_c, dt, qa, qg, gps, sigma, off, n):
    P = P0.copy()
    x = x0.copy()
    comp = np.zeros(12)
    for _ in range(n):
        augmented.propagate(P, x, f_c, w_c, dt, qa, qg, off, EARTH_WGS84)
        dx, z, S = augmented.gps_update(P, x, gps, sigma)
        augmented.apply_correction(x, comp, dx, off)
        P[:, :] = P0
        x[:] = x0
    return x


def _best(fn, repeat):
    """Best of ``repeat`` calls: (wall-clock s, process CPU s) as an array (so that dividing
    by the call count gives both per call). On a shared, oversubscribed machine the wall
    clock also counts the time the process waits for a core; the CPU time does not."""
    best = np.array([math.inf, math.inf])
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        best = np.minimum(best, [time.perf_counter() - t0, time.process_time() - c0])
    return best


def _pooled(ms, ms_go):
    return math.sqrt(np.mean(ms) / np.mean(ms_go))


def _nees_band(nees, n_seeds):
    """(fraction of epochs whose seed-mean NEES is inside the 95 % band, below, above, band,
    mean): ``nees`` (S, epochs), 3 dof each."""
    from scipy.stats import chi2

    lo, hi = (chi2.ppf(p, 3 * n_seeds) / n_seeds for p in (0.025, 0.975))
    m = nees.mean(axis=0)
    return (float(np.mean((m >= lo) & (m <= hi))), float(np.mean(m < lo)),
            float(np.mean(m > hi)), (lo, hi), float(m.mean()))


def accuracy_targets(n_seeds: int, lag_s: float):
    """The issue-14 targets for the Table-1 sensors, pooled over seeds 0..n_seeds-1."""
    cfg0 = scenario.GpsInsConfig(lag_s=lag_s)
    L = cfg0.lag_epochs
    tb = scenario.trajectory_bound(cfg0)
    keys = ("go", "filter", "filter_x", "fl", "fl_x", "rts", "rts_x", "seed", "seed_x")
    ms = {k: [] for k in keys}
    nees = {"filter": [], "fl": [], "rts": []}
    t_smooth = []
    epochs = None
    for seed in range(n_seeds):
        res = scenario.simulate(replace(cfg0, seed=seed))
        t0 = time.perf_counter()
        rts, fl = res.smooth((None, L))
        t_smooth.append(time.perf_counter() - t0)
        seed9 = scenario.simulate(replace(cfg0, seed=seed, filter="seed"))
        out = res.outage_mask
        ms["go"].append(np.mean(res.gps_only.horizontal_error[res.gps.valid] ** 2))
        epochs = res.gps.index
        for key, sol in (("filter", res.gps_ins), ("fl", fl), ("rts", rts),
                         ("seed", seed9.gps_ins)):
            ms[key].append(np.mean(sol.horizontal_error ** 2))
            ms[key + "_x"].append(np.mean(sol.horizontal_error[~out] ** 2))
            if key in nees:
                nees[key].append(sol.nees[epochs])
    go = ms["go"]
    table = Table(title=f"seed 002 GPS/INS, Table-1 sensors, default flight: ratio to GPS-only "
                        f"pooled over seeds 0..{n_seeds - 1}")
    for col in ("estimator", "ratio whole flight", "trajectory bound", "ratio / bound",
                "ratio outage excluded", "bound (outage excl.)", "target", "met"):
        table.add_column(col, justify="right")
    rows = [
        ("full filter (causal)", "filter", tb.ratio_causal, tb.ratio_causal_outage_excluded,
         "<= 0.45 and <= 1.08 x bound"),
        (f"fixed-lag smoother, {L / cfg0.gps_rate_hz:g} s", "fl", tb.ratio_smoothed(L),
         tb.ratio_smoothed(L, True), "<= 0.30"),
        ("RTS smoother", "rts", tb.ratio_smoothed(None), tb.ratio_smoothed(None, True),
         "<= 0.20"),
        ("seed's 9-state filter", "seed", tb.ratio_causal, tb.ratio_causal_outage_excluded,
         "-"),
    ]
    verdict = {}
    for name, key, b, bx, target in rows:
        r = _pooled(ms[key], go)
        rx = _pooled(ms[key + "_x"], go)
        if key == "filter":
            ok = r <= 0.45 and r <= 1.08 * b
        elif key == "fl":
            ok = r <= 0.30
        elif key == "rts":
            ok = r <= 0.20
        else:
            ok = None
        verdict[key] = ok
        table.add_row(name, f"{r:.3f}", f"{b:.3f}", f"{r / b:.3f}", f"{rx:.3f}", f"{bx:.3f}",
                      target, "-" if ok is None else ("met" if ok else "NOT met"))
    Console(width=200).print(table)
    per_seed = np.sqrt(np.array(ms["filter"]) / np.array(go))
    print(f"full filter per-seed whole-flight ratio: mean {per_seed.mean():.3f}, "
          f"min {per_seed.min():.3f}, max {per_seed.max():.3f}; GPS-only RMS pooled "
          f"{math.sqrt(np.mean(go)):.2f} m (expected {math.sqrt(2) * 20:.2f} m)")
    nt = Table(title=f"position NEES (3 dof) at the {len(epochs)} GPS epochs, mean over "
                     f"{n_seeds} seeds: 95 % chi-square band")
    for col in ("estimator", "band", "epochs inside", "below", "above", "mean NEES"):
        nt.add_column(col, justify="right")
    for name, key in (("full filter", "filter"), (f"fixed-lag {L / cfg0.gps_rate_hz:g} s",
                                                  "fl"), ("RTS", "rts")):
        inside, below, above, (lo, hi), mean = _nees_band(np.array(nees[key]), n_seeds)
        nt.add_row(name, f"[{lo:.2f}, {hi:.2f}]", f"{100 * inside:.1f} %",
                   f"{100 * below:.1f} %", f"{100 * above:.1f} %", f"{mean:.2f}")
    Console(width=200).print(nt)
    print(f"smoother backward sweep (RTS and fixed lag together, covariances recomputed "
          f"between epochs): {1e3 * np.mean(t_smooth) / len(epochs):.2f} ms per GPS epoch "
          f"(mean over the runs, {len(epochs)} epochs each)")


def accuracy_models(n_seeds: int):
    """The seeds table: one row per IMU model and filter, means over seeds (extremes in
    brackets)."""
    models = [("table1", lambda c: c), ("table1-uncalibrated", scenario.uncalibrated_config),
              ("table1, --gyro-noise 0.06", lambda c: scenario.with_gyro_noise(c, 0.06)),
              ("tactical", scenario.tactical_config), ("ideal", scenario.ideal_config)]
    table = Table(title=f"seed 002 GPS/INS accuracy, default flight, seeds 0..{n_seeds - 1}")
    for col in ("IMU", "filter", "GPS-only RMS (m)", "GPS/INS RMS (m)", "ratio mean [min, max]",
                "seeds <= 1/3", "seed 0", "pooled ratio", "trajectory bound",
                "max outage err (m) mean [max]", "outage in 3-sigma (min)",
                "NEES mean [min, max]", "one-channel bound"):
        table.add_column(col, justify="right")
    for name, make in models:
        for kind in ("full", "seed"):
            rows = []
            for seed in range(n_seeds):
                cfg = make(scenario.GpsInsConfig(seed=seed, filter=kind))
                s = scenario.simulate(cfg).summary()
                gi = s["gps_ins"]
                rows.append((s["gps_only"]["rms_horizontal_error_m"],
                             gi["rms_horizontal_error_m"], gi["rms_ratio_to_gps_only"],
                             gi["max_horizontal_error_during_outage_m"],
                             gi["outage_within_3sigma_per_axis_fraction"],
                             gi["nees_position_mean"],
                             s["optimal_filter_bound"]["rms_ratio_to_gps_only"],
                             s["bound_causal"]))
            a = np.array(rows)
            r = a[:, 2]
            table.add_row(name, kind, f"{a[:, 0].mean():.1f}", f"{a[:, 1].mean():.1f}",
                          f"{r.mean():.3f} [{r.min():.3f}, {r.max():.3f}]",
                          f"{int((r <= 1 / 3).sum())}/{n_seeds}", f"{r[0]:.3f}",
                          f"{math.sqrt(np.mean(a[:, 1] ** 2) / np.mean(a[:, 0] ** 2)):.3f}",
                          f"{a[0, 7]:.3f}",
                          f"{a[:, 3].mean():.0f} [{a[:, 3].max():.0f}]",
                          f"{100 * a[:, 4].min():.0f} %",
                          f"{a[:, 5].mean():.2f} [{a[:, 5].min():.2f}, {a[:, 5].max():.2f}]",
                          f"{a[0, 6]:.3f}")
    Console(width=220).print(table)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--iterations", type=int, default=200_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--accuracy", action="store_true",
                    help="print the accuracy table over seeds instead of timings")
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--lag", type=float, default=10.0, help="fixed-lag smoother's lag (s)")
    ap.add_argument("--models", action="store_true",
                    help="with --accuracy: also the per-IMU-model table of both filters")
    args = ap.parse_args(argv)
    if args.accuracy:
        if args.seeds < 2:
            ap.error("--seeds must be at least 2")
        accuracy_targets(args.seeds, args.lag)
        if args.models:
            accuracy_models(args.seeds)
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
    rows = [(f"seed 9-state: {name}", t) for name, t in rows]

    # the full filter (21 states with the Table-1 model)
    full = res_full = res
    fw = full.forward
    off = fw["off"]
    P0f = np.ascontiguousarray(fw["p_post"][len(fw["p_post"]) // 2])
    xf = full.states[k].copy()
    f_c, w_c = fw["fcs"][k].copy(), fw["wcs"][k].copy()
    qaf, qgf = fw["qas"][k].copy(), fw["qgs"][k].copy()
    for fn in (lambda m: _loop_propagate_full(P0f, xf, f_c, w_c, dt, qaf, qgf, off, m),
               lambda m: _loop_update_full(P0f, xf, gps, sigma, off, m),
               lambda m: _loop_iteration_full(P0f, xf, f_c, w_c, dt, qaf, qgf, gps, sigma,
                                              off, m)):
        fn(10)
    nf = fw["n"]
    rows += [
        (f"full {nf}-state: filter propagate", _best(lambda: _loop_propagate_full(
            P0f, xf, f_c, w_c, dt, qaf, qgf, off, n), args.repeat) / n),
        (f"full {nf}-state: filter update + correction", _best(lambda: _loop_update_full(
            P0f, xf, gps, sigma, off, n), args.repeat) / n),
        (f"full {nf}-state: one filter iteration (propagate + update)", _best(
            lambda: _loop_iteration_full(P0f, xf, f_c, w_c, dt, qaf, qgf, gps, sigma, off, n),
            args.repeat) / n),
    ]
    ep_idx = fw["ep_idx"]
    qa0 = fw["qas"][0].copy()
    qg0 = fw["qgs"][0].copy()

    def loop_full():
        augmented.run(x0, fw["p_post"][0], gyro_m, accel_m, dt, ep_idx, res.gps.lla,
                      res.gps.valid, sig, qa0, qg0, 0.0, 0.0, cfg.q_tau_s, off)

    rows.append((f"full {nf}-state: closed loop per 100 Hz step", _best(loop_full, args.repeat)
                 / steps))
    epochs = len(ep_idx) - 1
    for lags, name in (((None,), "RTS"), ((cfg.lag_epochs,), f"fixed lag {cfg.lag_s:g} s")):
        res_full.smooth(lags)  # warm
        rows.append((f"full {nf}-state: {name} smoother, per GPS epoch", _best(
            lambda lags=lags: res_full.smooth(lags), max(1, args.repeat // 2)) / epochs))

    load = os.getloadavg()[0]
    table = Table(title=f"seed 002 GPS/INS: time per call (one core; load average {load:.1f} "
                        f"on {os.cpu_count()} CPUs)")
    table.add_column("operation")
    table.add_column("us (wall clock)", justify="right")
    table.add_column("us (CPU time)", justify="right")
    table.add_column("vs 0.9 ms (MicroBlaze), CPU", justify="right")
    for name, t in rows:
        table.add_row(name, f"{t[0] * 1e6:.2f}", f"{t[1] * 1e6:.2f}",
                      f"{900e-6 / t[1]:,.0f}x faster")
    Console(width=130).print(table)
    for label in ("seed 9-state: one filter iteration", f"full {nf}-state: one filter"):
        wall, cpu = next(t for name, t in rows if name.startswith(label)) * 1e6
        print(f"target: {label.split(':')[0]} filter iteration <= 20 us: "
              f"{'met' if cpu <= 20 else 'NOT met'} ({cpu:.2f} us CPU time, {wall:.2f} us "
              f"wall clock{'' if wall <= 20 else ' (over 20: waiting for a core)'})")


if __name__ == "__main__":
    main()
