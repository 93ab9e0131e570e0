"""Speed of the reference navigation: mechanization, mechanization + ESKF (P at every IMU
sample), the full `navgate fly` scenario; and, where python-ins (pyins) is installed, its
Integrator and feedback filter on the same data. Seed 000's float32 engine: its op counts per
IMU sample and per update (the op programs of navgate.systems.ins_trn.pl.fp32_program), its
throughput, and the default flight with ``--engine fp32`` against the reference engine in
the same run.

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

    from navgate.systems.ins_trn.ps import flight
    from navgate.trn.dem import Dem

    t_f32 = bench_fp32_engine(nav0, p0, cfg, gyro, accel, traj)

    dem = Dem.default()
    flight.fly(dem, flight.FlightConfig(duration_s=30.0), engine="fp32")  # warm caches
    t_fly = best(lambda: flight.fly(dem, flight.FlightConfig()), 1)
    res = flight.fly(dem, flight.FlightConfig(), engine="fp32")
    s32 = res.summary()

    rows = [
        ("navgate mechanization", n, t_mech),
        ("navgate mechanization + ESKF (P every sample)", n, t_filt),
        ("fp32 engine: calibration + mechanization + P (compiled)", n, t_f32),
        ("navgate fly default scenario (2 runs + TRN, 600 s)", 2 * 240_000, t_fly),
        ("navgate fly --engine fp32 (+ reference runs)", 4 * 240_000, res.wall_time_s),
    ]
    rows += pyins_rows(traj, args)
    print(f"\n{'what':58s} {'samples':>9s} {'time (s)':>9s} {'samples/s':>12s}")
    for name, count, t in rows:
        rate = count / t if t else float("nan")
        print(f"{name:58s} {count:9d} {t:9.3f} {rate:12,.0f}")
    print("\ntargets: mechanization >= 2,000,000/s; mechanization + ESKF >= 1,000,000/s; "
          "navgate fly < 30 s warm")
    print(f"\nfp32 vs reference, default flight (same run): engine wall "
          f"{s32['engine_wall_time_s']:.2f} s vs {s32['reference_engine_wall_time_s']:.2f} s "
          f"= {s32['engine_wall_time_ratio']:.2f} x (target <= 4 x); max position difference "
          f"{s32['fp32_vs_reference_max_position_difference_m']:.2f} m")
    for name in ("ins_only", "trn_aided"):
        r = s32[name]
        print(f"  {name:10s} fp32: final {r['final_horizontal_error_m']:.1f} m, RMS 2nd half "
              f"{r['rms_horizontal_error_second_half_m']:.1f} m, NEES "
              f"{r['nees_position_mean']:.2f}")
    print_op_counts()
    pyins = {r[0]: r for r in rows if r[0].startswith("pyins")}
    if pyins:
        for name, count, t in pyins.values():
            ours = t_mech / n if "Integrator" in name else t_filt / n  # ours: P every sample
            print(f"ratio {name}: navgate is {t / count / ours:,.0f}x faster per sample")


def bench_fp32_engine(nav0, p0, cfg, gyro, accel, traj):
    """The float32 engine on the same readings (identity calibration, float words)."""
    from navgate.nav.calibration import ImuCalibration
    from navgate.nav.earth import LocalTangent
    from navgate.systems.ins_trn.ps.engine import EngineSetup
    from navgate.systems.ins_trn.ps.fp32_engine import Fp32Engine

    cal = ImuCalibration(gyro_lsb=1.0, accel_lsb=1.0)
    setup = EngineSetup(cal, cfg, 400.0, nav0, p0, np.zeros(3), np.zeros(3),
                        LocalTangent(nav0[0], nav0[1], 0.0))
    Fp32Engine(setup).propagate(gyro[:10], accel[:10])  # compile / load cache
    return best(lambda: Fp32Engine(setup).propagate(gyro, accel), 1)


def print_op_counts():
    """Operations per IMU sample and per update, by module (neg is a sign flip: free)."""
    from navgate.systems.ins_trn.pl.fp32_program import programs

    progs = programs()
    print(f"\n{'fp32 op program':44s} {'mul':>6s} {'add/sub':>8s} {'div':>5s} {'sqrt':>5s} "
          f"{'cmp':>4s} {'cvt':>4s} {'total':>6s}")

    def line(label, c):
        tot = sum(v for k, v in c.items() if k != "neg")
        print(f"{label:44s} {c['mul']:6d} {c['add'] + c['sub']:8d} {c['div']:5d} "
              f"{c['sqrt']:5d} {c['le'] + c['lt']:4d} {c['cvt']:4d} {tot:6d}")

    for module, c in progs["propagate"].counts_by_module().items():
        line(f"  per IMU sample: {module}", c)
    line("per IMU sample (total)", progs["propagate"].counts())
    for key, label in (("alt_gate", "altitude update: gate"),
                       ("alt_apply", "altitude update: apply (K, Joseph, feedback)"),
                       ("trn_gate", "TRN 2-D update: gate"),
                       ("trn_apply", "TRN 2-D update: apply (K, Joseph, feedback)")):
        line(label, progs[key].counts())
    cov = progs["propagate"].counts_by_module()
    muls = cov["covariance_propagator"]["mul"] + cov["phi_q_generation"]["mul"]
    print(f"covariance propagation (Phi/Q + P): {muls} multiplies per sample (target <= 1500)")
    print_cycle_bounds(progs)


def print_cycle_bounds(progs, units=None):
    """Cycle lower bounds with the gateware/fp32 cores' latencies (pipelined units)."""
    from navgate.gateware.fp32.add import Fp32Add
    from navgate.gateware.fp32.compare import Fp32Compare
    from navgate.gateware.fp32.convert import Fp32FromInt
    from navgate.gateware.fp32.div import Fp32Div
    from navgate.gateware.fp32.mul import Fp32Mul
    from navgate.gateware.fp32.sqrt import Fp32Sqrt
    from navgate.systems.ins_trn.pl.fp32_program import schedule_bounds

    lat = {"add": Fp32Add.LATENCY, "mul": Fp32Mul.LATENCY, "div": Fp32Div.LATENCY,
           "sqrt": Fp32Sqrt.LATENCY, "cmp": Fp32Compare.LATENCY, "cvt": Fp32FromInt.LATENCY}
    units = units or {"add": 2, "mul": 2, "div": 1, "sqrt": 1, "cmp": 1, "cvt": 1}
    print(f"\ncycle lower bounds, units {units}, latencies {lat}:")
    for key in ("propagate", "alt_gate", "alt_apply", "trn_gate", "trn_apply"):
        b = schedule_bounds(progs[key], lat, units)
        print(f"  {key:10s} critical path {b['critical_path']:5d}  resource {b['resource']:5d}"
              f"  -> >= {b['bound']} cycles")


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
