"""Speed of the reference navigation: mechanization, mechanization + ESKF (P at every IMU
sample), the full `navgate fly` scenario and where its time goes by stage; and, where
python-ins (pyins) is installed, its Integrator and feedback filter on the same data. Seed
000's float32 engine: its op counts per IMU sample and per update (the op programs of
navgate.systems.ins_trn.pl.fp32_program), its throughput, and the default flight with
``--engine fp32`` against the reference engine in the same run.

    python benchmarks/bench_navigation.py [--seconds 600] [--repeat 3] [--skip-fp32]

Every figure is given per CPU-second of this process (``time.process_time``: load from other
processes on the machine cancels) beside wall time; the kernels' figures are medians of
interleaved repetitions after Numba's cache is warm. The `navgate fly` line runs the command
itself (a child process, warm caches); its stage table runs the same steps in this process:

- scenario: route planning, sensor simulation, initial estimate, record stream;
- IMU input: the INS-only run over the stream's IMU records alone (calibration, mechanization,
  covariance propagation, logging);
- barometer updates: the INS-only run over the whole stream, less the IMU input;
- TRN: the INS+TRN run, less the INS-only run (ranger records, profile, correlation, fixes);
- scoring; CSV files; plots (track.png, errors.png);
- imports: a child process importing what the command imports;
- the rest: the command's CPU time less all of the above (DEM loading, Numba's cache loads,
  writing the output directory).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from navgate.nav import eskf, strapdown
from navgate.sim import trajectory as tr


def timed(fn):
    """(wall s, CPU s of this process) of one call."""
    w0, c0 = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - w0, time.process_time() - c0


def interleaved(fns, repeat):
    """Median (wall, CPU) of each function, the repetitions interleaved."""
    got = {name: [] for name in fns}
    for _ in range(repeat):
        for name, fn in fns.items():
            got[name].append(timed(fn))
    return {name: (statistics.median(w for w, _ in v), statistics.median(c for _, c in v))
            for name, v in got.items()}


def child_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_fly_command(out_dir, repeat):
    """`navgate fly --quiet` as a user runs it: median (wall, CPU) of ``repeat`` warm runs."""
    cmd = [sys.executable, "-m", "navgate.cli", "fly", "--quiet", "--out", str(out_dir)]
    subprocess.run(cmd, check=True, capture_output=True)  # warm Numba's cache
    got = []
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), child_cpu()
        subprocess.run(cmd, check=True, capture_output=True)
        got.append((time.perf_counter() - w0, child_cpu() - c0))
    return statistics.median(w for w, _ in got), statistics.median(c for _, c in got)


def imports_cpu(repeat):
    """Median (wall, CPU) of a child process that imports what `navgate fly` imports."""
    code = ("import navgate.cli, navgate.cli.fly, matplotlib.pyplot; "
            "from navgate.systems.ins_trn.ps import flight, report, engine")
    got = []
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), child_cpu()
        subprocess.run([sys.executable, "-c", code], check=True, capture_output=True)
        got.append((time.perf_counter() - w0, child_cpu() - c0))
    return statistics.median(w for w, _ in got), statistics.median(c for _, c in got)


def fly_stages(repeat):
    """The default flight's steps in this process: stage -> median (wall, CPU)."""
    from navgate.sim.flight import initial_estimate, score, simulate_sensors
    from navgate.systems.ins_trn.ps import flight, report
    from navgate.systems.ins_trn.ps.flight import flight_stream
    from navgate.systems.ins_trn.ps.navigator import navigate
    from navgate.systems.ins_trn.ps.records import IMU
    from navgate.trn.dem import Dem

    dem = Dem.default()
    cfg = flight.FlightConfig()
    box = {}

    def scenario():
        route = flight.plan_route(dem, cfg)
        data = simulate_sensors(route, dem, cfg)
        box["route"], box["data"] = route, data
        box["stream"] = flight_stream(data, dem, cfg, initial_estimate(data, cfg))

    scenario()
    stream = box["stream"]
    keep = stream.kind == IMU
    imu_only = dataclasses.replace(stream, kind=stream.kind[keep], t=stream.t[keep],
                                   index=stream.index[keep])

    def ins_only():
        box["ins_only"] = navigate(stream, cfg, dem=None, use_trn=False, name="ins_only")

    def trn_aided():
        box["trn_aided"] = navigate(stream, cfg, dem=dem, use_trn=True, name="trn_aided")

    def imu_input():
        navigate(imu_only, cfg, dem=None, use_trn=False)

    ins_only()
    trn_aided()
    log_every = max(1, int(round(cfg.imu_rate_hz / cfg.log_rate_hz)))

    def scoring():
        box["scores"] = {k: score(box[k], box["data"].truth, log_every)
                         for k in ("ins_only", "trn_aided")}

    scoring()
    result = flight.FlightResult(cfg, dem, box["route"], box["data"],
                                 {k: box[k] for k in ("ins_only", "trn_aided")}, box["scores"],
                                 log_every, 0.0, "reference", None, stream)
    tmp = Path(tempfile.mkdtemp(prefix="bench_nav_"))

    def csv_files():
        report.write_trajectory_csv(result, tmp / "trajectory.csv")
        report.write_fixes_csv(result, tmp / "trn_fixes.csv")

    def plots():
        report.plot_track(result, tmp / "track.png")
        report.plot_errors(result, tmp / "errors.png")

    plots()  # first-use costs of matplotlib are start-up's
    t = interleaved({"scenario": scenario, "imu": imu_input, "ins_only": ins_only,
                     "trn_aided": trn_aided, "scoring": scoring, "csv": csv_files,
                     "plots": plots}, repeat)

    def minus(a, b):
        return (max(a[0] - b[0], 0.0), max(a[1] - b[1], 0.0))

    return {
        "scenario (route, sensors, initial estimate, records)": t["scenario"],
        "IMU input (calibration, mechanization, P; 2 runs)": tuple(2 * x for x in t["imu"]),
        "barometer updates (2 runs)": tuple(2 * x for x in minus(t["ins_only"], t["imu"])),
        "TRN (rangers, profile, correlation, fixes)": minus(t["trn_aided"], t["ins_only"]),
        "scoring": t["scoring"],
        "CSV files": t["csv"],
        "plots": t["plots"],
    }, stream.n_imu


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=600.0, help="flight length (s) at 400 Hz")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--pyins-seconds", type=float, default=10.0,
                    help="flight length for the (slower) pyins comparison")
    ap.add_argument("--skip-fp32", action="store_true",
                    help="leave out the float32 engine's figures (the fp32 flight is slow)")
    args = ap.parse_args()
    print(f"machine: {os.cpu_count()} CPUs, load average "
          f"{', '.join(f'{x:.1f}' for x in os.getloadavg())} (1, 5, 15 min)")

    segs = [tr.straight(40), tr.turn(90, 3), tr.climb(150, 5), tr.speed_change(75, 40),
            tr.turn(-135, 4), tr.straight(30)]
    traj = tr.generate(segs, lat0=math.radians(36.6), lon0=math.radians(-84.2), h0=1200.0,
                       heading0=0.4, speed0=60.0, rate_hz=400.0, duration_s=args.seconds)
    gyro, accel = traj.imu()
    n = gyro.shape[0]
    nav0 = traj.states[0]
    cfg = eskf.FilterConfig(1e-3, 1e-4, 1e-3, 3600.0, 1e-5, 3600.0)
    p0 = eskf.initial_covariance(pos_sigma=5, vel_sigma=0.1, att_sigma=1e-3,
                                 accel_bias_sigma=1e-2, gyro_bias_sigma=1e-4)

    def mech():
        strapdown.integrate_final(nav0, gyro, accel, traj.dt)

    def run_filter():
        f = eskf.ErrorStateFilter(nav0, p0, cfg)
        f.propagate(gyro, accel, 0, n)

    mech()  # compile / load cache
    run_filter()
    k = interleaved({"mech": mech, "filter": run_filter}, args.repeat)

    rows = [("navgate mechanization", n, *k["mech"]),
            ("navgate mechanization + ESKF (P every sample)", n, *k["filter"])]
    s32 = None
    if not args.skip_fp32:
        from navgate.systems.ins_trn.ps import flight
        from navgate.trn.dem import Dem

        rows.append(("fp32 engine: calibration + mechanization + P (compiled)", n,
                     *bench_fp32_engine(nav0, p0, cfg, gyro, accel, traj)))
        dem = Dem.default()
        flight.fly(dem, flight.FlightConfig(duration_s=30.0), engine="fp32")  # warm caches
        res = flight.fly(dem, flight.FlightConfig(), engine="fp32")
        s32 = res.summary()
        rows.append(("navgate fly --engine fp32 (+ reference runs), in process", 4 * 240_000,
                     res.wall_time_s, float("nan")))
    with tempfile.TemporaryDirectory(prefix="bench_fly_") as tmp:
        fly_wall, fly_cpu = run_fly_command(Path(tmp) / "fly", args.repeat)
    rows.append(("navgate fly default scenario (command: 2 runs + TRN + plots)", 2 * 240_000,
                 fly_wall, fly_cpu))
    rows += pyins_rows(traj, args)
    print(f"\n{'what':62s} {'samples':>9s} {'wall (s)':>9s} {'CPU (s)':>8s} "
          f"{'samples/wall-s':>15s} {'samples/CPU-s':>14s}")
    for name, count, wall, cpu in rows:
        print(f"{name:62s} {count:9d} {wall:9.3f} {cpu:8.3f} {count / wall:15,.0f} "
              f"{count / cpu if cpu else float('nan'):14,.0f}")
    print("\ntargets (issue 32, per CPU-second): mechanization >= 10,000,000/s; mechanization + "
          "ESKF >= 1,500,000/s; navgate fly <= 8 s wall warm on 2 idle cores")

    stages, n_imu = fly_stages(args.repeat)
    total_cpu = sum(c for _, c in stages.values())
    print(f"\nnavgate fly by stage (default flight, {n_imu} IMU samples a run; medians of "
          f"{args.repeat} interleaved repetitions in this process):")
    print(f"  {'stage':54s} {'wall (s)':>9s} {'CPU (s)':>8s} {'CPU share':>10s}")
    imp_wall, imp_cpu = imports_cpu(args.repeat)
    rest = max(fly_cpu - total_cpu - imp_cpu, 0.0)
    for name, (wall, cpu) in list(stages.items()) + [
            ("imports (NumPy, Numba, SciPy, Matplotlib, navgate)", (imp_wall, imp_cpu)),
            ("the rest: DEM, Numba cache loads, outputs (difference)",
             (float("nan"), rest))]:
        print(f"  {name:54s} {wall:9.3f} {cpu:8.3f} {cpu / fly_cpu:10.1%}")
    print(f"  {'the command (child process)':54s} {fly_wall:9.3f} {fly_cpu:8.3f}")

    if s32 is not None:
        print(f"\nfp32 vs reference, default flight (same run): engine wall "
              f"{s32['engine_wall_time_s']:.2f} s vs {s32['reference_engine_wall_time_s']:.2f} s"
              f" = {s32['engine_wall_time_ratio']:.2f} x (target <= 4 x); max position "
              f"difference {s32['fp32_vs_reference_max_position_difference_m']:.2f} m")
        for name in ("ins_only", "trn_aided"):
            r = s32[name]
            print(f"  {name:10s} fp32: final {r['final_horizontal_error_m']:.1f} m, RMS 2nd "
                  f"half {r['rms_horizontal_error_second_half_m']:.1f} m, NEES "
                  f"{r['nees_position_mean']:.2f}")
        print_op_counts()
    pyins = {r[0]: r for r in rows if r[0].startswith("pyins")}
    if pyins:
        t_mech, t_filt = k["mech"][1], k["filter"][1]
        for name, count, _, cpu in pyins.values():
            ours = t_mech / n if "Integrator" in name else t_filt / n  # ours: P every sample
            print(f"ratio {name}: navgate is {cpu / count / ours:,.0f}x faster per CPU-second"
                  " per sample")


def bench_fp32_engine(nav0, p0, cfg, gyro, accel, traj):
    """The float32 engine on the same readings (identity calibration, float words)."""
    from navgate.nav.calibration import ImuCalibration
    from navgate.nav.earth import LocalTangent
    from navgate.systems.ins_trn.ps.fp32_engine import Fp32Engine
    from navgate.systems.ins_trn.ps.pl_interface import EngineSetup

    cal = ImuCalibration(gyro_lsb=1.0, accel_lsb=1.0)
    setup = EngineSetup(cal, cfg, 400.0, nav0, p0, np.zeros(3), np.zeros(3),
                        LocalTangent(nav0[0], nav0[1], 0.0))
    Fp32Engine(setup).propagate(gyro[:10], accel[:10])  # compile / load cache
    return timed(lambda: Fp32Engine(setup).propagate(gyro, accel))


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
    w, c = timed(lambda: pstrap.Integrator(pva0).integrate(increments))
    rows.append(("pyins Integrator", len(increments), w, c))
    w, c = timed(lambda: filters.run_feedback_filter(
        pva0, 5, 0.1, 0.05, 0.3, increments, measurements=[fixes], time_step=1 / 400))
    rows.append(("pyins run_feedback_filter (P every sample)", len(increments), w, c))
    w, c = timed(lambda: filters.run_feedback_filter(pva0, 5, 0.1, 0.05, 0.3, increments,
                                                     measurements=[fixes]))
    rows.append(("pyins run_feedback_filter (P every 0.1 s, its default)", len(increments),
                 w, c))
    del pd
    return rows


if __name__ == "__main__":
    main()
