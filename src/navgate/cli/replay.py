"""``navgate replay``: run seed 000's navigator on a sensor record log (``navgate fly --record``).

The log format is documented in :mod:`navgate.systems.ins_trn.ps.records`. Bad records
(truncated, unparsable, non-finite, int16 overflow) are counted by reason, skipped and
reported in summary.json; time order is resynchronised (one wrong stamp costs one record).
The fraction of the log's records used is in summary.json and on the table; below
``--min-used`` the log is not navigated (one line, exit 2). A header that does not describe a
usable navigator (NaN or indefinite P0, wrong shapes, a latitude off the Earth, ...) is one
line, exit 2. When the log holds truth records, both runs are scored exactly as ``navgate
fly`` scores them, each solution only against a truth record stamped at its own time
(:func:`stamp_tolerance`; a solution without one is not scored, the coverage and the gaps
are in summary.json and on the table) and ``trajectory.csv``,
``trn_fixes.csv``, ``track.png`` and ``errors.png`` are written as ``fly`` writes them;
without truth, ``trajectory.csv`` holds the solutions and ``trn_fixes.csv`` the fixes.
"""

from __future__ import annotations

import csv
import math
import time
from pathlib import Path
from types import SimpleNamespace

import click
import numpy as np

from navgate.cli.console import consoles, hardware_line
from navgate.cli.engines import engine_choice, load_engine_class
from navgate.cli.errors import CliError, simulation_errors
from navgate.cli.inputs import dem_input, regular_input
from navgate.cli.outputs import (
    check_out_dir,
    check_outputs_early,
    default_out_dir,
    out_option,
    staged_outputs,
)
from navgate.cli.summary import non_finite_keys, write_summary

#: the files replay writes into --out (the plots only for a log with truth)
OUTPUTS = ("summary.json", "trajectory.csv", "trn_fixes.csv", "track.png", "errors.png")


def _fraction(ctx, param, value):
    if not (math.isfinite(value) and 0.0 <= value <= 1.0):
        raise click.BadParameter(f"must be a fraction in [0, 1], got {value:g}")
    return value


@click.command()
@click.argument("log_path", type=click.Path(dir_okay=False))
@click.option("--engine", type=engine_choice(), default="reference", show_default=True,
              help="PL engine: float64 reference, float32 bit-true model, the ins_engines "
                   "gateware in Verilator, or the whole FPGA (ins_trn_top) in Verilator.")
@click.option("--dem", "dem_path", type=click.Path(dir_okay=True), default=None,
              help="DEM for TRN (default: the embedded Jacksboro fault DEM).")
@click.option("--no-trn", is_flag=True, help="Run INS-only (with baro) and skip TRN.")
@click.option("--min-used", type=float, default=0.95, show_default=True, callback=_fraction,
              help="Refuse a log of which less than this fraction of the records is usable.")
@out_option(default_out_dir("replay"), "Output directory (written atomically).")
@click.option("--quiet", is_flag=True, help="No progress and no table.")
def replay(log_path, engine, dem_path, no_trn, min_used, out, quiet):
    """Navigate a recorded sensor stream; score it when the log carries truth."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from navgate.systems.ins_trn.ps.flight import fly_stream
    from navgate.systems.ins_trn.ps.records import LogError, check_header, read_log
    from navgate.trn.dem import DemError
    from navgate.trn.tiles import load_terrain

    table_console, console = consoles(quiet)
    if engine == "board":
        raise CliError("--engine board: a board's fabric reads its own sensors on its pins, "
                       "not a log's records; replay the log with --engine fpga-sim")
    check_out_dir(out)
    check_outputs_early(out, OUTPUTS, [log_path, dem_path])
    try:
        stream = read_log(regular_input(log_path))
        check_header(stream.header)
    except LogError as error:
        raise CliError(f"{log_path}: {error}" if str(log_path) not in str(error)
                       else str(error)) from None
    header = stream.header
    cfg, trn = _flight_config(header, log_path, no_trn)
    try:  # the engines' own checks of the initial state (p0, nav0, rate, ...), up front
        from navgate.systems.ins_trn.ps.navigator import engine_setup
        from navgate.systems.ins_trn.ps.pl_interface import check_setup

        check_setup(engine_setup(header, cfg))
    except (KeyError, TypeError, IndexError, ValueError) as error:
        raise CliError(f"{log_path}: the header's initial state is not usable ({error})"
                       ) from None
    if header.get("ideal") and load_engine_class(engine, "navgate replay").needs_imu_words:
        raise CliError(f"{log_path}: --engine {engine} needs the IMU's int16 output words; "
                       "this log has the ideal sensors' float words")
    used = stream.used_fraction
    bad_total = int(sum(stream.bad_records.values()))
    if used < min_used:
        reasons = ", ".join(f"{n} {r}" for r, n in sorted(stream.bad_records.items(),
                                                          key=lambda kv: -kv[1])[:3])
        raise CliError(f"{log_path}: only {100 * used:.1f} % of its {stream.records_read:,} "
                       f"records are usable ({reasons}), below --min-used {min_used:g}; "
                       "not navigated")
    log_dem = _log_dem(header, log_path, dem_path)
    try:
        dem = load_terrain(dem_input(dem_path))
    except DemError as error:
        raise CliError(str(error)) from None
    if log_dem is not None and dem.name != log_dem and cfg.trn:
        click.echo(f"navgate replay: warning: {log_path} was recorded over the DEM "
                   f"{log_dem!r}; navigating over {dem.name!r} (--dem)", err=True)
    console.print(f"[bold]navgate replay[/]: {log_path}, {stream.n_imu:,} IMU records "
                  f"({100 * used:.1f} % of the log used), engine {engine}", highlight=False)
    start = time.perf_counter()
    runs_n = 2 if cfg.trn else 1
    columns = (TextColumn("{task.description}"), BarColumn(),
               TextColumn("{task.percentage:>3.0f}%"), TimeElapsedColumn())
    with staged_outputs(out, inputs=[log_path, dem_path], names=OUTPUTS) as staging, \
            Progress(*columns, console=console, disable=quiet) as bar:
        task = bar.add_task("navigating", total=runs_n * stream.n_imu)
        try:
            runs = fly_stream(stream, dem, cfg, engine=engine,
                              progress=lambda n: bar.advance(task, n),
                              stage=lambda s: bar.update(task, description=s), trn=trn)
        except simulation_errors() as error:
            raise CliError(f"--engine {engine}: the co-simulation failed: {error}") from None
        except DemError as error:
            raise CliError(str(error)) from None
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as error:
            # the filter's own checks (a non-finite innovation or covariance, ...): the log's
            # calibration or records drove the navigation out of the numbers
            raise CliError(f"{log_path}: the navigation failed on this log ({error}); check "
                           "the header's calibration and configuration") from None
        bar.update(task, description="writing report", completed=runs_n * stream.n_imu)
        summary = {
            "log": str(log_path), "engine": engine, "dem": dem.name,
            "log_dem": header.get("dem"), "records": len(stream),
            "records_read": stream.records_read, "used_fraction": used,
            "min_used": min_used, "imu_records": stream.n_imu,
            "bad_records": dict(stream.bad_records), "bad_records_total": bad_total,
        }
        result = _Replayed(runs, stream, dem)
        n_sol = next(iter(runs.values())).t.size
        summary["scored"] = bool(result.scores)
        summary["truth"] = {
            "records": result.truth_records, "solutions": n_sol,
            "scored_solutions": result.scored, "coverage": result.scored / n_sol,
            "conflicting": result.conflicting,
            "first_scored_s": float(result.scored_times[0]) if result.scored else None,
            "last_scored_s": float(result.scored_times[-1]) if result.scored else None,
            "unscored_intervals_s": result.unscored_intervals[:20],
            "unscored_intervals_total": len(result.unscored_intervals)}
        for name, run in runs.items():
            s = {"wall_time_s": run.wall_time_s,
                 "baro_updates_accepted": run.accepted.get("baro", 0),
                 "baro_updates_rejected": run.rejected.get("baro", 0),
                 "baro_samples_invalid": run.rejected.get("baro invalid sample", 0),
                 "imu_samples_rejected": run.imu_samples_rejected,
                 "final_lat_deg": math.degrees(float(run.nav[-1, 0])),
                 "final_lon_deg": math.degrees(float(run.nav[-1, 1])),
                 "final_h_m": float(run.nav[-1, 2])}
            if result.scores:
                s.update(result.summaries[name])
            if name == "trn_aided":
                applied = [f for f in run.fixes if f["applied"]]
                s["fixes_attempted"] = len(run.fixes)
                s["fixes_accepted"] = len(applied)
                s["fixes_rejected"] = len(run.fixes) - len(applied)
                reasons = {}
                for f in run.fixes:
                    if not f["applied"]:
                        reasons[f["reason"]] = reasons.get(f["reason"], 0) + 1
                s["fix_rejection_reasons"] = reasons
            if run.hardware:
                s["hardware"] = run.hardware
            summary[name] = s
        summary["wall_time_s"] = time.perf_counter() - start
        files = _write_report(result, staging.dir)
        write_summary(staging.dir, summary)
    _print_table(table_console, summary, runs, engine, stream)
    if result.truth_records and summary["truth"]["coverage"] < 1.0:
        click.echo(f"navgate replay: warning: {_coverage_line(summary['truth'])}", err=True)
    console.print(f"wrote summary.json, {', '.join(files)} in {out}", highlight=False)
    bad = non_finite_keys(summary)
    if bad:
        raise CliError(f"the replay produced non-finite results ({', '.join(bad[:4])}); "
                       f"files in {out}")


def _log_dem(header, log_path, dem_path):
    """The DEM the log was recorded over (its header's ``dem``; None when the header does not
    say). Without --dem, a log recorded over another DEM than the embedded default is
    refused: the navigator would correlate against the wrong terrain."""
    from navgate.trn.dem import Dem

    name = header.get("dem")
    if name is None:
        return None
    if not isinstance(name, str) or not name:
        raise CliError(f"{log_path}: header dem is not a DEM name ({str(name)[:40]!r})")
    if dem_path is None and name != Dem.default().name:
        raise CliError(f"{log_path} was recorded over the DEM {name!r}, not the embedded "
                       f"default; pass --dem PATH to that DEM")
    return name


def _coverage_line(truth: dict) -> str:
    """How much of the replay the truth scored, and where it did not."""
    gaps = ", ".join(f"{a:g}-{b:g} s" if a != b else f"{a:g} s"
                     for a, b in truth["unscored_intervals_s"][:3])
    more = truth["unscored_intervals_total"] - 3
    return (f"truth scored {truth['scored_solutions']} of {truth['solutions']} solutions "
            f"({100 * truth['coverage']:.1f} %); no truth at {gaps}"
            + (f" and {more} more gaps" if more > 0 else "")
            + (f"; {truth['conflicting']} with conflicting truth records"
               if truth["conflicting"] else "")
            + (f"; figures over {truth['first_scored_s']:g}-{truth['last_scored_s']:g} s"
               if truth["scored_solutions"] else ""))


def _flight_config(header, log_path, no_trn):
    """The flight configuration and the navigator's TRN settings the log was recorded with
    (one line when unusable): the header's ``config`` and ``trn``, or, in a log written before
    they were split, the TRN keys inside ``config`` (trn_settings.from_header maps them)."""
    from dataclasses import fields, replace

    from navgate.sim.flight import FlightConfig
    from navgate.systems.ins_trn.ps.records import LogError
    from navgate.systems.ins_trn.ps.trn_settings import from_header

    try:
        conf = dict(header["config"])
        trn = from_header(header)
        known = {f.name for f in fields(FlightConfig)}
        conf = {k: v for k, v in conf.items() if k in known}
        _check_config_numbers(conf, header["calibration"])
        cfg = FlightConfig(**conf)
    except LogError as error:
        raise CliError(f"{log_path}: unusable flight configuration: {error}") from None
    except (KeyError, TypeError, ValueError, ArithmeticError) as error:
        raise CliError(f"{log_path}: header lacks a usable flight configuration "
                       f"({str(error)[:120]})") from None
    return (replace(cfg, trn=False) if no_trn else cfg), trn


#: the ranges ``navgate fly`` accepts for the configuration its options set (--imu-rate,
#: --speed, --duration: 4 h at most); a log's header is held to the same
FLY_RANGES = {"imu_rate_hz": (50.0, 4000.0), "speed_mps": (5.0, 400.0),
              "duration_s": (0.0, 4 * 3600.0)}
#: the largest magnitude of an int16 IMU word: a bias sigma beyond the IMU's full scale
#: (this many LSB) is no bias of that IMU
FULL_SCALE_LSB = 32767.0


def _check_config_numbers(conf: dict, calibration: dict) -> None:
    """LogError (one line naming the field) unless every number of the header's flight
    configuration is finite and in range: fly's ranges (:data:`FLY_RANGES`), rates positive
    and at most the IMU rate (the sensors and the log are sampled at IMU boundaries), spacing
    positive, sigmas >= 0 and the bias sigmas within the IMU's full scale."""
    from dataclasses import fields

    from navgate.sim.flight import FlightConfig
    from navgate.systems.ins_trn.ps.records import _number

    numeric = [f.name for f in fields(FlightConfig)
               if isinstance(f.default, float) and f.name in conf]
    for key in numeric:
        _number(conf[key], f"config.{key}")
    for key, (lo, hi) in FLY_RANGES.items():
        if key in conf:
            _number(conf[key], f"config.{key}", lo, hi, lo_open=(lo == 0.0))
    imu_rate = float(conf.get("imu_rate_hz", 400.0))
    for key in ("log_rate_hz", "baro_rate_hz", "ranger_rate_hz"):
        if key in conf:
            _number(conf[key], f"config.{key}", 0.0, imu_rate, lo_open=True)
    if "profile_spacing_m" in conf:
        _number(conf["profile_spacing_m"], "config.profile_spacing_m", 0.0, 1e5, lo_open=True)
    for key in numeric:
        if "sigma" in key:
            _number(conf[key], f"config.{key}", 0.0)
    for key, lsb in (("init_gyro_bias_sigma", "gyro_lsb"),
                     ("init_accel_bias_sigma", "accel_lsb")):
        if key in conf:
            _number(conf[key], f"config.{key}", 0.0,
                    FULL_SCALE_LSB * float(calibration[lsb]))


class _Replayed:
    """A replay shaped as navgate.systems.ins_trn.ps.report expects a flight: the runs, the
    DEM, and (with truth records) the truth, the truth row each solution is scored against
    (``truth_index``, -1 where none) and the scores.

    A solution is scored only against a truth record stamped at its own time: within
    :func:`stamp_tolerance` (the float64 rounding of two stamps ``t0 + k dt``), never the
    nearest record a log period away. Each truth record scores at most one solution; a
    solution with two different truth records at its time is not scored (``conflicting``).
    ``scores[name]`` holds full-length error arrays (NaN where unscored, for the report);
    ``summaries[name]`` the figures over the scored solutions."""

    def __init__(self, runs, stream, dem):
        from navgate.sim.flight import Score, score
        from navgate.systems.ins_trn.ps.records import TRUTH

        self.runs, self.dem, self.log_every = runs, dem, 1
        self.scores, self.summaries = {}, {}
        self.data = None
        rows = stream.truth
        t_truth = stream.t[stream.kind == TRUTH]
        t_sol = next(iter(runs.values())).t
        n = t_sol.size
        self.truth_index = np.full(n, -1, np.int64)
        self.conflicting = 0
        if rows.shape[0]:
            tol = stamp_tolerance(t_sol, float(stream.header.get("t0", 0.0)))
            lo = np.searchsorted(t_truth, t_sol - tol, side="left")
            hi = np.searchsorted(t_truth, t_sol + tol, side="right")
            used = np.zeros(t_truth.size, bool)
            for i in range(n):
                if hi[i] <= lo[i]:
                    continue
                if not np.all(rows[lo[i]:hi[i]] == rows[lo[i]]):  # two different truths
                    self.conflicting += 1
                    continue
                if not used[lo[i]]:
                    used[lo[i]] = True
                    self.truth_index[i] = lo[i]
        matched = self.truth_index >= 0
        self.truth_records = int(rows.shape[0])
        self.scored = int(np.count_nonzero(matched))
        self.scored_times = t_sol[matched]
        self.unscored_intervals = _intervals(t_sol, ~matched)
        if not self.scored:
            return
        self.data = SimpleNamespace(truth=_Truth(SimpleNamespace(
            t=t_truth, lat=rows[:, 0], lon=rows[:, 1], h=rows[:, 2])))
        j = self.truth_index[matched]
        truth = _Truth(SimpleNamespace(t=t_truth[j], lat=rows[j, 0], lon=rows[j, 1],
                                       h=rows[j, 2]))
        for name, run in runs.items():
            sub = SimpleNamespace(t=run.t[matched], nav=run.nav[matched],
                                  sigma=run.sigma[matched], p_ne=run.p_ne[matched])
            part = score(sub, truth, 1)
            self.summaries[name] = part.summary(sub.t)
            full = []
            for values in (part.horizontal_error, part.north_error, part.east_error,
                           part.nees):
                a = np.full(n, np.nan)
                a[matched] = values
                full.append(a)
            self.scores[name] = Score(*full)


def stamp_tolerance(t, t0: float) -> np.ndarray:
    """How far apart two float64 stamps of the same instant may be: a stamp is ``t0 + k dt``
    (or ``t0 + k / rate``) of an exact integer k, one rounded product and one rounded sum,
    each within half an ulp of ``|t0| + |t|``; two stamps so made differ by at most two
    ulps (a log's ``repr`` stamps read back exactly). Four ulps: the bound with a factor two
    to spare, microseconds below a log period for any flight shorter than 10^9 s."""
    return 4.0 * np.spacing(np.abs(np.asarray(t, float)) + abs(t0))


def _intervals(t, mask) -> list:
    """The [first, last] times of each run of consecutive ``mask`` rows."""
    out, start = [], None
    for i, m in enumerate(mask):
        if m and start is None:
            start = i
        if start is not None and (not m or i == len(mask) - 1):
            last = i if m else i - 1
            out.append([float(t[start]), float(t[last])])
            start = None
    return out


class _Truth:
    """Truth rows (t, lat, lon, h), shaped for navgate.sim.flight.score and the report."""

    def __init__(self, rows):
        self.t, self.lat, self.lon, self.h = rows.t, rows.lat, rows.lon, rows.h

    def __len__(self):
        return self.lat.size


def _write_report(result, out: Path) -> list[str]:
    """fly's report files for a log with truth; the solutions and fixes without truth."""
    from navgate.systems.ins_trn.ps import report

    if result.data is not None:
        return [p.name for p in report.write_report(result, out).values()]
    tan = report._tangent(result)
    cols = {"t_s": next(iter(result.runs.values())).t}
    for name, run in result.runs.items():
        n, e = tan.to_ned(run.nav[:, 0], run.nav[:, 1])
        cols[f"{name}_lat_deg"] = np.degrees(run.nav[:, 0])
        cols[f"{name}_lon_deg"] = np.degrees(run.nav[:, 1])
        cols[f"{name}_h_m"] = run.nav[:, 2]
        cols[f"{name}_north_m"], cols[f"{name}_east_m"] = n, e
        cols[f"{name}_sigma_north_m"] = run.sigma[:, 0]
        cols[f"{name}_sigma_east_m"] = run.sigma[:, 1]
    with open(out / "trajectory.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols.keys())
        for row in zip(*cols.values(), strict=True):
            w.writerow([f"{v:.9g}" for v in row])
    report.write_fixes_csv(result, out / "trn_fixes.csv")
    return ["trajectory.csv", "trn_fixes.csv"]


def _print_table(console, s, runs, engine, stream):
    from rich.table import Table

    table = Table(title=f"replay of {s['log']} ({engine} engine)")
    truth = s["truth"]
    no_truth = "- (no truth)" if not truth["records"] else "- (no truth at its times)"
    table.add_column("solution")
    for col in ("final error (m)", "RMS 2nd half (m)", "NEES mean (2 dof)", "final position",
                "TRN fixes acc/rej"):
        table.add_column(col, justify="right")
    for name, label in (("ins_only", "INS only (+baro)"), ("trn_aided", "INS + TRN")):
        if name not in s:
            continue
        r = s[name]
        scored = "final_horizontal_error_m" in r
        fixes = f"{r['fixes_accepted']}/{r['fixes_rejected']}" if name == "trn_aided" else "-"
        table.add_row(label,
                      f"{r['final_horizontal_error_m']:.1f}" if scored else no_truth,
                      f"{r['rms_horizontal_error_second_half_m']:.1f}" if scored else "-",
                      f"{r['nees_position_mean']:.2f}" if scored else "-",
                      f"{r['final_lat_deg']:.6f}, {r['final_lon_deg']:.6f}, "
                      f"{r['final_h_m']:.1f} m", fixes)
    console.print(table)
    reasons = ", ".join(f"{n} {k}" for k, n in s["bad_records"].items())
    console.print(f"used {100 * s['used_fraction']:.2f} % of the log's {s['records_read']:,} "
                  f"records ({s['imu_records']:,} IMU); {s['bad_records_total']} bad"
                  + (f": {reasons}" if reasons else ""), highlight=False)
    if truth["records"]:
        console.print(_coverage_line(truth) if truth["coverage"] < 1.0 else
                      f"truth scored all {truth['solutions']} solutions", highlight=False)
    for name in runs:
        if "hardware" in s[name]:
            console.print(f"{name}: {hardware_line(s[name]['hardware'])}", highlight=False)
