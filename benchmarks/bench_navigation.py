"""Speed of the reference navigation: mechanization, mechanization + ESKF (P at every IMU
sample), the full `navgate fly` scenario; and, where python-ins (pyins) is installed, its
Integrator and feedback filter on the same data.

    python benchmarks/bench_navigation.py [--seconds 600] [--repeat 3]

Prints a table; numbers are best-of-repeat wall time on one core, after Numba's cache is warm.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from navgate.nav import eskf, strapdown
from navgate.sim import trajectory as tr


def best(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=600.0, help="flight length (s) at 400 Hz")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--pyins-seconds", type=float, default=10.0,
                    help="flight length for the (slower) pyins comparison")
    args = ap.parse_args()

    segs = [tr.straight(40), tr.turn(90, 3), tr.climb(150, 5), tr.speed_change(75, 40),
            tr.turn(-135, 4), tr.straight(30)]
    traj = tr.generate(segs, lat0=math.radians(36.6), lon0=math.radians(-84.2), h0=1200.0,
                       heading0=0.4, speed0=60.0, rate_hz=400.0, duration_s=args.seconds)
    gyro, accel = traj.imu()
    n = gyro.shape[0]
    nav0 = traj.states[0]
    strapdown.integrate_final(nav0, gyro[:10], accel[:10], traj.dt)  # compile / load cache
    t_mech = best(lambda: strapdown.integrate_final(nav0, gyro, accel, traj.dt), args.repeat)

    cfg = eskf.FilterConfig(1e-3, 1e-4, 1e-3, 3600.0, 1e-5, 3600.0)
    p0 = eskf.initial_covariance(pos_sigma=5, vel_sigma=0.1, att_sigma=1e-3,
                                 accel_bias_sigma=1e-2, gyro_bias_sigma=1e-4)

    def run_filter():
        f = eskf.ErrorStateFilter(nav0, p0, cfg)
        f.propagate(gyro, accel, 0, n)

    run_filter()
    t_filt = best(run_filter, args.repeat)

    from navgate.systems.ins_trn import flight
    from navgate.trn.dem import Dem

    dem = Dem.default()
    flight.fly(dem, flight.FlightConfig(duration_s=30.0))  # warm caches
    t_fly = best(lambda: flight.fly(dem, flight.FlightConfig()), 1)

    rows = [
        ("navgate mechanization", n, t_mech),
        ("navgate mechanization + ESKF (P every sample)", n, t_filt),
        ("navgate fly default scenario (2 runs + TRN, 600 s)", 2 * 240_000, t_fly),
    ]
    rows += pyins_rows(traj, args)
    print(f"\n{'what':58s} {'samples':>9s} {'time (s)':>9s} {'samples/s':>12s}")
    for name, count, t in rows:
        rate = count / t if t else float("nan")
        print(f"{name:58s} {count:9d} {t:9.3f} {rate:12,.0f}")
    print("\ntargets: mechanization >= 2,000,000/s; mechanization + ESKF >= 300,000/s; "
          "navgate fly < 30 s warm")
    pyins = {r[0]: r for r in rows if r[0].startswith("pyins")}
    if pyins:
        for name, count, t in pyins.values():
            ours = t_mech / n if "Integrator" in name else t_filt / n  # ours: P every sample
            print(f"ratio {name}: navgate is {t / count / ours:,.0f}x faster per sample")


def pyins_rows(traj, args):
    try:
        import pandas as pd
        from pyins import filters, measurements, sim
        from pyins import strapdown as pstrap
    except ImportError:
        print("pyins (python-ins) not installed: skipping the comparison "
              "(pip install -e '.[bench]')")
        return []
    n = int(args.pyins_seconds * 400) + 1
    t = traj.t[:n]
    lla = np.column_stack([np.degrees(traj.lat[:n]), np.degrees(traj.lon[:n]), traj.h[:n]])
    rph = np.column_stack([np.degrees(traj.roll[:n]), np.degrees(traj.pitch[:n]),
                           np.degrees(traj.yaw[:n])])
    ref, imu = sim.generate_imu(t, lla, rph, sensor_type="increment")
    increments = pstrap.compute_increments_from_imu(imu, "increment")
    pva0 = ref.iloc[0]
    fixes = measurements.Position(sim.generate_position_measurements(ref.iloc[::4000], 10.0, 0),
                                  10.0)
    # warm-up: pyins compiles its own Numba kernels on first use
    pstrap.Integrator(pva0).integrate(increments.iloc[:50])
    filters.run_feedback_filter(pva0, 5, 0.1, 0.05, 0.3, increments.iloc[:50],
                                measurements=[fixes], time_step=1 / 400)
    rows = []
    t0 = time.perf_counter()
    pstrap.Integrator(pva0).integrate(increments)
    rows.append(("pyins Integrator", len(increments), time.perf_counter() - t0))
    t0 = time.perf_counter()
    filters.run_feedback_filter(pva0, 5, 0.1, 0.05, 0.3, increments, measurements=[fixes],
                                time_step=1 / 400)
    rows.append(("pyins run_feedback_filter (P every sample)", len(increments),
                 time.perf_counter() - t0))
    t0 = time.perf_counter()
    filters.run_feedback_filter(pva0, 5, 0.1, 0.05, 0.3, increments, measurements=[fixes])
    rows.append(("pyins run_feedback_filter (P every 0.1 s, its default)", len(increments),
                 time.perf_counter() - t0))
    del pd
    return rows


if __name__ == "__main__":
    main()
