"""``navgate gpsins``: seed 002's loosely coupled GPS/INS on a simulated aircraft flight with a
GPS outage; GPS-only and GPS/INS side by side.

Writes summary.json, trajectory.csv, gps.csv and errors.png into ``--out`` (same conventions
as ``navgate fly``). Bad option values end with one line on stderr and exit 2. ``--imu``
picks the IMU model (``navgate.systems.gpsins.scenario.config_for_imu``); ``--filter``
the full filter (navigation plus sensor error states, ``augmented.py``; default) or the
seed's 9-state filter; ``--smoother rts|fixed-lag --lag S`` adds a smoothed solution
(``gps_ins_smoothed``). summary.json carries both ratios to GPS-only (``ratio_whole_flight``,
outage included, and ``ratio_outage_excluded``) and the trajectory-exact bounds
(``bound_causal``, ``bound_rts``, ``trajectory_bound``; ``navgate.systems.gpsins.bound``),
plus the one-channel bound as a cross-check.
"""

from __future__ import annotations

import csv
import math
import time
from pathlib import Path

import click
import numpy as np

from navgate.cli.console import consoles, numba_note
from navgate.cli.errors import CliError
from navgate.cli.outputs import atomic_output_dir, check_out_dir, default_out_dir, out_option
from navgate.cli.summary import non_finite_keys, write_summary


def _finite(ctx, param, value):
    if value is not None and not math.isfinite(value):
        raise click.BadParameter(f"must be a finite number, got {value}")
    return value


@click.command()
@click.option("--duration", type=float, default=300.0, show_default=True, callback=_finite,
              help="Flight duration (s); at least 250 s as in the seed.")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@out_option(default_out_dir("gpsins"), "Output directory (written atomically).")
@click.option("--outage-start", type=float, default=240.0, show_default=True,
              callback=_finite, help="GPS outage start (s).")
@click.option("--outage-length", type=float, default=30.0, show_default=True,
              callback=_finite, help="GPS outage length (s); 0 for none.")
@click.option("--rate", "rate_hz", type=float, default=100.0, show_default=True,
              callback=_finite, help="INS / filter rate (Hz).")
@click.option("--gyro-noise", type=float, default=None, callback=_finite,
              help="Gyro white noise (deg/s/sqrt(Hz)) of the chosen IMU model; default the "
                   "model's own (Table 1: 0.015; the ADXRS652 data sheet: about 0.06).")
@click.option("--imu", type=click.Choice(["table1", "table1-uncalibrated", "tactical",
                                          "ideal"]), default="table1", show_default=True,
              help="IMU model: the Table-1 reading with calibrated scale factors, the same "
                   "uncalibrated, a tactical-grade MEMS IMU, or error-free.")
@click.option("--ideal-sensors", is_flag=True,
              help="Error-free IMU (and a filter tuned for it): the filter's own limit "
                   "(same as --imu ideal).")
@click.option("--filter", "filter_kind", type=click.Choice(["full", "seed"]), default="full",
              show_default=True,
              help="full: navigation plus the sensors' bias and scale-factor states, noise "
                   "from the sensor model; seed: the seed's 9-state filter.")
@click.option("--smoother", type=click.Choice(["none", "rts", "fixed-lag"]), default="none",
              show_default=True,
              help="Also smooth the full filter: rts (fixed interval, whole run) or fixed-lag.")
@click.option("--lag", "lag_s", type=float, default=None, callback=_finite,
              help="Fixed-lag smoother's lag (s, whole GPS periods; default 10).")
@click.option("--quiet", is_flag=True, help="No progress or table.")
def gpsins(duration, seed, out, outage_start, outage_length, rate_hz, gyro_noise, imu,
           ideal_sensors, filter_kind, smoother, lag_s, quiet):
    """Seed 002: GPS/INS Kalman filter (and smoother) vs GPS alone, with a GPS outage."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from navgate.systems.gpsins import scenario

    table_console, console = consoles(quiet)
    if duration < 250:
        raise CliError(f"--duration must be at least 250 s (seed 002's flight), got {duration:g}")
    if duration > 3600:
        raise CliError(f"--duration {duration:g} s is longer than the 1 h this command supports")
    if seed < 0:
        raise CliError(f"--seed must be non-negative, got {seed}")
    if outage_length < 0 or outage_start < 0:
        raise CliError("--outage-start and --outage-length must be non-negative")
    if outage_length > 0 and outage_start + outage_length > duration:
        raise CliError(f"the outage ({outage_start:g} s + {outage_length:g} s) must end before "
                       f"the flight ({duration:g} s)")
    if not 20 <= rate_hz <= 1000:
        raise CliError(f"--rate must be between 20 and 1000 Hz, got {rate_hz:g}")
    if gyro_noise is not None and not 0 <= gyro_noise <= 1:
        raise CliError(f"--gyro-noise must be between 0 and 1 deg/s/sqrt(Hz), got {gyro_noise:g}")
    if ideal_sensors:
        if imu not in ("table1", "ideal"):
            raise CliError(f"--ideal-sensors and --imu {imu} exclude each other")
        imu = "ideal"
    if gyro_noise is not None and imu == "ideal":
        raise CliError("--gyro-noise and --ideal-sensors exclude each other")
    if smoother != "none" and filter_kind != "full":
        raise CliError(f"--smoother {smoother} needs --filter full")
    if lag_s is not None and smoother != "fixed-lag":
        raise CliError("--lag applies to --smoother fixed-lag only")
    if lag_s is None:
        lag_s = 10.0
    if not 1.0 <= lag_s <= duration:
        raise CliError(f"--lag must be between 1 s (one GPS period) and the flight's "
                       f"{duration:g} s, got {lag_s:g}")
    cfg = scenario.GpsInsConfig(duration_s=duration, seed=seed, outage_start_s=outage_start,
                                outage_s=outage_length, rate_hz=rate_hz, filter=filter_kind,
                                smoother=smoother, lag_s=lag_s)
    epochs = lag_s * cfg.gps_rate_hz
    if smoother == "fixed-lag" and abs(epochs - round(epochs)) > 1e-9 * max(1.0, epochs):
        period = 1.0 / cfg.gps_rate_hz
        raise CliError(f"--lag must be a whole number of GPS periods ({period:g} s), got "
                       f"{lag_s:g} s (the smoother lags by whole GPS epochs: "
                       f"{math.floor(epochs) * period:g} or {math.ceil(epochs) * period:g} s)")
    cfg = scenario.config_for_imu(cfg, imu)
    if gyro_noise is not None:
        cfg = scenario.with_gyro_noise(cfg, gyro_noise)
    check_out_dir(out)
    console.print(f"[bold]navgate gpsins[/]: {duration:g} s flight at {rate_hz:g} Hz, GPS 1 Hz "
                  f"(20 m), outage {outage_start:g}-{outage_start + outage_length:g} s, "
                  f"seed {seed}, IMU model {imu}")
    start = time.perf_counter()
    stages = ["trajectory", "sensors", "GPS/INS", "scoring", "smoothing", "writing report"]
    with numba_note(console), atomic_output_dir(out) as staging, Progress(
            TextColumn("{task.description}"), BarColumn(),
            TextColumn("{task.completed}/{task.total}"), TimeElapsedColumn(),
            console=console, disable=quiet) as bar:
        task = bar.add_task(stages[0], total=len(stages))

        def stage(name):
            bar.update(task, description=name, completed=stages.index(name))

        result = scenario.simulate(cfg, progress=stage)
        stage("writing report")
        summary = result.summary()
        summary["imu"] = imu
        summary["smoother"] = smoother
        summary["wall_time_s"] = time.perf_counter() - start
        files = [write_trajectory_csv(result, staging / "trajectory.csv"),
                 write_gps_csv(result, staging / "gps.csv"),
                 plot_errors(result, staging / "errors.png")]
        write_summary(staging, summary)
        bar.update(task, completed=len(stages))
    _print_table(table_console, summary)
    console.print(f"wrote summary.json, {', '.join(p.name for p in files)} in {out}",
                  highlight=False)
    bad = non_finite_keys(summary)
    if bad:
        raise CliError(f"the run produced non-finite results ({', '.join(bad[:4])}); "
                       f"files in {out}")


def write_trajectory_csv(result, path: Path) -> Path:
    t = result.truth.t
    st = result.states
    gi = result.gps_ins
    cols = {
        "t_s": t,
        "truth_lat_deg": np.degrees(result.truth.lat), "truth_lon_deg": np.degrees(
            result.truth.lon), "truth_h_m": result.truth.h,
        "ins_lat_deg": np.degrees(st[:, 0]), "ins_lon_deg": np.degrees(st[:, 1]),
        "ins_h_m": st[:, 2], "ins_vn_mps": st[:, 3], "ins_ve_mps": st[:, 4],
        "ins_vd_mps": st[:, 5],
        "err_north_m": gi.err_ned[:, 0], "err_east_m": gi.err_ned[:, 1],
        "err_down_m": gi.err_ned[:, 2], "horizontal_error_m": gi.horizontal_error,
        "sigma_north_m": gi.sigma_ned[:, 0], "sigma_east_m": gi.sigma_ned[:, 1],
        "sigma_down_m": gi.sigma_ned[:, 2], "nees_position": gi.nees,
        "gps_outage": result.outage_mask.astype(int),
    }
    if result.smoothed is not None:
        sm = result.smoothed
        cols.update({"smoothed_err_north_m": sm.err_ned[:, 0],
                     "smoothed_err_east_m": sm.err_ned[:, 1],
                     "smoothed_err_down_m": sm.err_ned[:, 2],
                     "smoothed_horizontal_error_m": sm.horizontal_error,
                     "smoothed_sigma_north_m": sm.sigma_ned[:, 0],
                     "smoothed_sigma_east_m": sm.sigma_ned[:, 1]})
    step = max(1, int(round(result.cfg.rate_hz / 10.0)))  # 10 Hz log
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols.keys())
        for k in range(0, len(t), step):
            w.writerow([f"{c[k]:.10g}" for c in cols.values()])
    return path


def write_gps_csv(result, path: Path) -> Path:
    g = result.gps
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["t_s", "lat_deg", "lon_deg", "h_m", "valid", "err_north_m", "err_east_m",
                    "err_down_m"])
        for k in range(len(g.t)):
            w.writerow([f"{g.t[k]:.3f}", f"{math.degrees(g.lla[k, 0]):.9f}",
                        f"{math.degrees(g.lla[k, 1]):.9f}", f"{g.lla[k, 2]:.3f}",
                        int(g.valid[k]), f"{g.noise_ned[k, 0]:.3f}",
                        f"{g.noise_ned[k, 1]:.3f}", f"{g.noise_ned[k, 2]:.3f}"])
    return path


def plot_errors(result, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    gi, go, cfg = result.gps_ins, result.gps_only, result.cfg
    t = result.truth.t
    fig, ax = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    v = result.gps.valid
    ax[0].plot(go.t[v], go.horizontal_error[v], ".", ms=3, color="0.6", label="GPS only")
    ax[0].plot(t, gi.horizontal_error, color="C0", lw=1.2, label="GPS/INS")
    if result.smoothed is not None:
        ax[0].plot(t, result.smoothed.horizontal_error, color="C2", lw=1.0,
                   label=f"GPS/INS smoothed ({result.cfg.smoother})")
    ax[0].plot(t, 3 * np.hypot(gi.sigma_ned[:, 0], gi.sigma_ned[:, 1]), "C3--", lw=1,
               label="GPS/INS 3-sigma (horizontal)")
    ax[0].set_ylabel("horizontal error (m)")
    ax[0].set_yscale("log")
    ax[0].legend(loc="upper left")
    for i, name in enumerate(("north", "east")):
        ax[1].plot(t, gi.err_ned[:, i], lw=1, color=f"C{i}", label=f"{name} error")
        ax[1].fill_between(t, -3 * gi.sigma_ned[:, i], 3 * gi.sigma_ned[:, i], color=f"C{i}",
                           alpha=0.12, label=f"{name} 3-sigma")
    ax[1].set_ylabel("GPS/INS error (m)")
    ax[1].set_xlabel("time (s)")
    ax[1].legend(loc="upper left", ncol=2)
    if cfg.outage_s > 0:
        for a in ax:
            a.axvspan(cfg.outage_start_s, cfg.outage_start_s + cfg.outage_s, color="0.85",
                      zorder=0)
    s = result.summary()
    fig.suptitle(f"seed 002 GPS/INS: RMS horizontal {s['gps_ins']['rms_horizontal_error_m']:.1f}"
                 f" m (GPS only {s['gps_only']['rms_horizontal_error_m']:.1f} m); outage shaded")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _print_table(console, s):
    from rich.table import Table

    gi, go = s["gps_ins"], s["gps_only"]
    table = Table(title=f"seed 002 GPS/INS, {s['duration_s']:.0f} s, outage "
                        f"{s['outage']['start_s']:.0f} s + {s['outage']['length_s']:.0f} s")
    table.add_column("solution")
    for col in ("RMS horiz. (m)", "RMS vert. (m)", "max horiz. in outage (m)",
                "in 3-sigma (outage)", "NEES mean (3 dof)"):
        table.add_column(col, justify="right")
    table.add_row("GPS only", f"{go['rms_horizontal_error_m']:.1f}",
                  f"{go['rms_vertical_error_m']:.1f}", "-", "-", "-")
    outage = gi["max_horizontal_error_during_outage_m"]
    frac = gi["outage_within_3sigma_per_axis_fraction"]
    table.add_row(f"GPS/INS ({s['filter']['kind']}, {s['filter']['n_states']} states)",
                  f"{gi['rms_horizontal_error_m']:.1f}",
                  f"{gi['rms_vertical_error_m']:.1f}",
                  "-" if outage is None else f"{outage:.1f}",
                  "-" if frac is None else f"{100 * frac:.0f} %",
                  f"{gi['nees_position_mean']:.2f}")
    sm = s.get("gps_ins_smoothed")
    if sm is not None:
        o = sm["max_horizontal_error_during_outage_m"]
        table.add_row(f"GPS/INS smoothed ({sm['smoother']})", f"{sm['rms_horizontal_error_m']:.1f}",
                      f"{sm['rms_vertical_error_m']:.1f}", "-" if o is None else f"{o:.1f}", "-",
                      f"{sm['nees_position_mean']:.2f}")
    console.print(table)
    tb = s["trajectory_bound"]
    one = s["optimal_filter_bound"]["rms_ratio_to_gps_only"]
    console.print(f"RMS ratio to GPS-only, whole flight (outage included) "
                  f"{s['ratio_whole_flight']:.3f}, outage excluded "
                  f"{s['ratio_outage_excluded']:.3f}; expected for the matched filter along "
                  f"this trajectory {tb['causal']['ratio_whole_flight']:.3f} / "
                  f"{tb['causal']['ratio_outage_excluded']:.3f} (one-channel cross-check "
                  f"{one:.3f})")
    if sm is not None:
        console.print(f"smoothed ({sm['smoother']}): whole flight {sm['ratio_whole_flight']:.3f}, "
                      f"outage excluded {sm['ratio_outage_excluded']:.3f}; bound "
                      f"{sm['bound']:.3f}")
    console.print(f"bounds: fixed lag {tb['fixed_lag']['lag_s']:g} s "
                  f"{tb['fixed_lag']['ratio_whole_flight']:.3f}, RTS "
                  f"{tb['rts']['ratio_whole_flight']:.3f} (expected ensemble ratios; one run "
                  f"scatters around them); wall time {s['wall_time_s']:.1f} s")
