"""``navgate ahrs``: run an attitude filter (seed 003's Mahony or a complementary filter) over a
real IMU log and write ``t qw qx qy qz roll_deg pitch_deg yaw_deg``.

Input formats and error handling: :mod:`navgate.sim.imu_log`; axes and filters:
:mod:`navgate.systems.attitude.estimate`. Bad input ends with one line on stderr and exit 2.

Every run writes a JSON summary through the staging path (:mod:`navgate.cli.outputs`):
``OUT_STEM.summary.json`` beside ``--out OUT``, else ``navgate-out/ahrs/summary.json``
(:func:`summary_path`). The circuit engines (``fp32``, ``rtl``) add an ``invalid`` column
to the CSV: a row the circuit flags (its ``invalid`` output: a zero-norm acceleration or
magnetic field makes its state NaN, and it never recovers) has 1 there and ``nan`` in every
attitude column; such a run writes its files, then exits 2 naming the first invalid sample.
"""

from __future__ import annotations

import math
import time

import click
import numpy as np
from rich.table import Table

from navgate.cli.console import consoles, numba_note
from navgate.cli.errors import CliError
from navgate.cli.inputs import fifo_guard
from navgate.cli.outputs import default_out_dir, out_option, staged_outputs
from navgate.cli.summary import non_finite_keys, write_summary


def _nonneg(ctx, param, value):
    if value is None:
        return value
    if not (math.isfinite(value) and value >= 0):
        raise click.BadParameter(f"must be a non-negative number, got {value}")
    return value


@click.command()
@click.argument("input_csv", type=click.Path(dir_okay=False))
@click.option("--filter", "method", type=click.Choice(["mahony", "complementary"]),
              default="mahony", show_default=True, help="Attitude filter.")
@out_option(None, "Output CSV (t, qw..qz, roll/pitch/yaw in deg; the circuit engines add an "
                  "'invalid' flag column), written atomically with OUT_STEM.summary.json "
                  "beside it; never the input. Default: no CSV, the JSON summary in "
                  "navgate-out/ahrs/summary.json.", kind="file")
@click.option("--kp", type=float, default=1.0, show_default=True, callback=_nonneg,
              help="Mahony proportional gain (rad/s per unit error); kp * dt must be < 1.")
@click.option("--ki", type=float, default=0.1, show_default=True, callback=_nonneg,
              help="Mahony integral gain; ki * dt^2 < 2 (1 - kp dt) keeps the loop stable "
                   "(checked, all engines).")
@click.option("--gain", type=float, default=0.02, show_default=True, callback=_nonneg,
              help="Complementary filter correction gain per sample (0..1).")
@click.option("--axes", type=click.Choice(["auto", "frd", "flu"]), default="auto",
              show_default=True,
              help="Sensor axes: frd (level accel reads -g on z), flu (+g on z, e.g. x-io); "
                   "auto = flu for x-io headers.")
@click.option("--gyro-unit", type=click.Choice(["rad/s", "deg/s"]), default=None,
              help="Unit of plain gx/gy/gz columns (default rad/s; a log that plainly holds "
                   "deg/s is rejected without this).")
@click.option("--no-mag", is_flag=True, help="Ignore magnetometer columns (rows kept).")
@click.option("--init", type=click.Choice(["accel", "identity"]), default="accel",
              show_default=True, help="Initial attitude (also after a time gap).")
@click.option("--engine", type=click.Choice(["reference", "fp32", "rtl"]), default="reference",
              show_default=True,
              help="mahony only: reference = float64 filter (streamed); fp32 = seed 003's "
                   "float32 bit-true circuit model; rtl = the circuit's gateware in Verilator "
                   "(fp32 and rtl give identical CSVs; docs/seed003-attitude-circuit.md). "
                   "The circuit runs at a fixed T through time gaps (counted) and cannot "
                   "recover from a zero-norm acceleration or magnetic field: its rows are "
                   "then flagged invalid (CSV column 'invalid', nan attitude), the summary "
                   "names the first one, and the run exits 2 after writing its files.")
@click.option("--quiet", is_flag=True, help="No summary table and no progress.")
def ahrs(input_csv, method, out, kp, ki, gain, axes, gyro_unit, no_mag, init, engine, quiet):
    """Estimate attitude from an IMU log (CSV), streamed in blocks (bounded memory)."""
    from rich.progress import BarColumn, DownloadColumn, Progress, TextColumn

    from navgate.sim.imu_log import ImuLogReader, LogError
    from navgate.systems.attitude.estimate import (
        GAP_PERIODS,
        AttitudeStream,
        euler_deg,
        resolve_axes,
    )

    if gain > 1:  # (whatever the filter: an option out of its range is never ignored)
        raise CliError(f"--gain must be between 0 and 1, got {gain:g}")
    table_console, console = consoles(quiet)
    if engine != "reference":
        _circuit_command(input_csv, engine, method, out, kp, ki, axes, gyro_unit, no_mag,
                         table_console, console)
        return
    start = time.perf_counter()
    try:
        reader = ImuLogReader(input_csv, use_mag=not no_mag, gyro_unit=gyro_unit,
                              fileobj=fifo_guard(input_csv))
    except LogError as error:
        raise CliError(str(error)) from None
    stats = {"rows": 0, "t0": None, "t1": None, "last": None}
    stream = None
    summary_file = summary_path(out)
    files = [p for p in (out, summary_file) if p is not None]
    columns = (TextColumn("{task.description}"), BarColumn(), DownloadColumn())
    try:
        with numba_note(console), staged_outputs(files=files, inputs=[input_csv]) as staging, \
                Progress(*columns, console=console, disable=quiet, transient=True) as bar:
            tmp = staging.file(out) if out is not None else None
            fh = open(tmp, "w") if tmp is not None else None  # noqa: SIM115
            try:
                task = bar.add_task(f"reading {input_csv}", total=reader.size or None)
                if fh is not None:
                    fh.write(HEADER + "\n")
                for block in reader:
                    if stream is None:
                        stream = _make_stream(AttitudeStream, reader, block, method, axes, kp,
                                              ki, gain, no_mag, init, GAP_PERIODS,
                                              resolve_axes)
                    q = stream.update(block.t, block.gyro, block.acc, block.mag)
                    if not np.isfinite(q).all():
                        raise CliError("the filter diverged (non-finite attitude); check "
                                       "units and --kp/--ki")
                    roll, pitch, yaw = euler_deg(q)
                    if fh is not None:
                        np.savetxt(fh, np.column_stack([block.t, q, roll, pitch, yaw]),
                                   delimiter=",", fmt=FMT)
                    stats["rows"] += len(block.t)
                    stats["t0"] = block.t[0] if stats["t0"] is None else stats["t0"]
                    stats["t1"] = block.t[-1]
                    stats["last"] = (roll[-1], pitch[-1], yaw[-1])
                    bar.update(task, completed=reader.bytes_read)
                if stats["rows"] < 2:
                    if stats["rows"] == 0 and not (reader.skipped_rows
                                                   or reader.implausible_rows):
                        raise CliError(f"{input_csv}: no data rows after the header")
                    raise CliError(f"{input_csv}: fewer than two usable data rows "
                                   f"({reader.skipped_rows} skipped, {reader.implausible_rows} "
                                   "implausible)")
            finally:
                if fh is not None:
                    fh.close()
            n, duration = stats["rows"], float(stats["t1"] - stats["t0"])
            roll, pitch, yaw = (float(v) for v in stats["last"])
            mag_state = "used" if stream.used_mag else "not used"
            summary = {
                "log": str(input_csv), "out": None if out is None else str(out),
                "engine": "reference", "filter": method, "kp": kp if method == "mahony" else None,
                "ki": ki if method == "mahony" else None,
                "gain": gain if method == "complementary" else None, "init": init,
                "samples": n, "skipped_rows": reader.skipped_rows,
                "implausible_rows": reader.implausible_rows,
                "time_gaps": stream.gaps, "time_gaps_handling": "filter restarted",
                "invalid_samples": 0,
                "duration_s": duration, "mean_rate_hz": (n - 1) / duration,
                "header_style": reader.style, "axes": stream.axes, "magnetometer": mag_state,
                "mag_held_rows": reader.mag_held_rows if stream.used_mag else None,
                "final_valid": True,
                "final_roll_deg": roll, "final_pitch_deg": pitch, "final_yaw_deg": yaw,
                "wall_seconds": round(time.perf_counter() - start, 3),
            }
            _write_summary(staging, summary_file, summary)
    except LogError as error:
        raise CliError(str(error)) from None
    except ValueError as error:
        raise CliError(str(error)) from None
    table = Table(title=f"navgate ahrs: {method} on {input_csv}")
    table.add_column("item")
    table.add_column("value", justify="right")
    table.add_row("samples", f"{n}")
    table.add_row("skipped rows", f"{reader.skipped_rows}")
    table.add_row("implausible rows (beyond sensor range, dropped)",
                  f"{reader.implausible_rows}")
    table.add_row("time gaps (filter restarted)", f"{stream.gaps}")
    table.add_row("duration", f"{duration:.2f} s")
    table.add_row("mean rate", f"{(n - 1) / duration:.1f} Hz")
    table.add_row("header style / axes", f"{reader.style} / {stream.axes}")
    if stream.used_mag and reader.mag_held_rows:
        mag_state += f" (held over {reader.mag_held_rows} rows)"
    table.add_row("magnetometer", mag_state)
    table.add_row("final roll / pitch / yaw",
                  f"{roll:.2f} / {pitch:.2f} / {yaw:.2f} deg")
    table.add_row("wall time", f"{summary['wall_seconds']:.2f} s")
    table_console.print(table)
    _wrote(console, out, n, summary_file)
    _check_finite(summary)


def _circuit_command(input_csv, engine, method, out, kp, ki, axes, gyro_unit, no_mag,
                     table_console, console):
    """``--engine fp32|rtl``: seed 003's circuit (bit-true model or gateware) over the whole
    log (read at once: the circuit engines run the log as one batch)."""
    from navgate.sim.imu_log import LogError, read_imu_csv
    from navgate.systems.attitude.circuit_engine import run_circuit

    if method != "mahony":
        raise CliError(f"--engine {engine} runs seed 003's Mahony circuit; use --filter mahony")
    if engine == "rtl":
        from navgate.cli.extras import SIMULATION, require_gateware

        require_gateware("navgate ahrs --engine rtl", SIMULATION)
    if no_mag:
        raise CliError(f"--engine {engine}: the circuit always uses the magnetometer "
                       f"(drop --no-mag)")
    start = time.perf_counter()
    try:
        log = read_imu_csv(input_csv, gyro_unit=gyro_unit, fileobj=fifo_guard(input_csv))
    except LogError as error:
        raise CliError(str(error)) from None
    if len(log) < 2:
        raise CliError(f"{input_csv}: need at least two samples")
    from navgate.systems.attitude.circuit_engine import circuit_inputs
    from navgate.systems.attitude.estimate import gap_steps

    try:  # the checks every engine shares (estimate.check_run), before any message or build
        words, _, _ = circuit_inputs(log, axes, kp, ki)
    except ValueError as error:
        raise CliError(str(error)) from None
    # the reference engine's gaps; the circuit has a fixed T and no restart, so it runs
    # through them: counted and reported only
    gaps = int(gap_steps(log.t).size)
    summary_file = summary_path(out)
    files = [p for p in (out, summary_file) if p is not None]
    with staged_outputs(files=files, inputs=[input_csv]) as staging:
        if engine == "fp32":
            console.print(f"running the float32 model over {len(log)} samples "
                          f"(about 50 ms a sample)")
        try:
            circuit = run_circuit(log, engine, axes=axes, kp=kp, ki=ki)
        except ValueError as error:
            raise CliError(str(error)) from None
        except RuntimeError as error:  # a Verilator build or run failure
            raise CliError(f"--engine rtl: {str(error).splitlines()[0]}") from None
        res = circuit.result
        att = np.column_stack([res.q, res.roll_deg, res.pitch_deg, res.yaw_deg])
        # the circuit's own flag, and any non-finite word it did not flag
        invalid = ~np.isfinite(att).all(axis=1)
        if circuit.invalid_rows is not None:
            invalid |= circuit.invalid_rows
        # a flagged row's Euler words are the arctangent of NaN (a saturated constant, not an
        # angle): every attitude column of it is written as nan, and flagged
        att[invalid] = np.nan
        n, n_bad = len(res.t), int(invalid.sum())
        first = int(np.argmax(invalid)) if n_bad else None
        valid_rows = np.flatnonzero(~invalid)
        last = int(valid_rows[-1]) if valid_rows.size else None
        if out is not None:
            with open(staging.file(out), "w") as fh:
                fh.write(HEADER + ",invalid\n")
                np.savetxt(fh, np.column_stack([res.t, att, invalid.astype(int)]),
                           delimiter=",", fmt=[*FMT, "%d"])
        duration = float(res.t[-1] - res.t[0])
        summary = {
            "log": str(input_csv), "out": None if out is None else str(out),
            "engine": engine, "filter": method, "kp": kp, "ki": ki,
            "samples": n, "skipped_rows": log.skipped_rows,
            "implausible_rows": log.implausible_rows,
            "time_gaps": gaps, "time_gaps_handling": "run through at the fixed period T",
            "invalid_samples": n_bad,
            "first_invalid_sample": first,
            "first_invalid_t_s": None if first is None else float(res.t[first]),
            "first_invalid_reason": None if first is None else _invalid_reason(words, first),
            "saturated_samples": circuit.saturated,
            "duration_s": duration, "mean_rate_hz": (n - 1) / duration,
            "header_style": log.style, "axes": res.axes, "magnetometer": "used",
            "mag_held_rows": log.mag_held_rows, "circuit_dt_s": circuit.params.dt,
            "final_valid": not bool(invalid[-1]),
            **({} if invalid[-1] else {"final_roll_deg": float(res.roll_deg[-1]),
                                       "final_pitch_deg": float(res.pitch_deg[-1]),
                                       "final_yaw_deg": float(res.yaw_deg[-1])}),
            **({} if last is None or not invalid[-1] else {
                "last_valid_sample": last, "last_valid_t_s": float(res.t[last]),
                "last_valid_roll_deg": float(res.roll_deg[last]),
                "last_valid_pitch_deg": float(res.pitch_deg[last]),
                "last_valid_yaw_deg": float(res.yaw_deg[last])}),
            "simulated_cycles": circuit.cycles if engine == "rtl" else None,
            "build_seconds": round(circuit.build_seconds, 3) if engine == "rtl" else None,
            "engine_seconds": round(circuit.seconds, 3),
            "wall_seconds": round(time.perf_counter() - start, 3),
        }
        _write_summary(staging, summary_file, summary)
    table = Table(title=f"navgate ahrs: seed 003 circuit ({engine}) on {input_csv}")
    table.add_column("item")
    table.add_column("value", justify="right")
    table.add_row("samples", f"{n}")
    table.add_row("skipped rows", f"{log.skipped_rows}")
    table.add_row("implausible rows (beyond sensor range, dropped)", f"{log.implausible_rows}")
    table.add_row("time gaps (run through at fixed T)", f"{gaps}")
    table.add_row("duration", f"{duration:.2f} s")
    table.add_row("header style / axes", f"{log.style} / {res.axes}")
    if invalid[-1]:
        table.add_row("final roll / pitch / yaw", "INVALID")
        if last is not None:
            table.add_row(f"last valid roll / pitch / yaw (t = {res.t[last]:.3f} s)",
                          f"{res.roll_deg[last]:.2f} / {res.pitch_deg[last]:.2f} / "
                          f"{res.yaw_deg[last]:.2f} deg")
    else:
        table.add_row("final roll / pitch / yaw",
                      f"{res.roll_deg[-1]:.2f} / {res.pitch_deg[-1]:.2f} / "
                      f"{res.yaw_deg[-1]:.2f} deg")
    table.add_row("engine", f"{engine} (seed 003 circuit, T = {circuit.params.dt:.6g} s, "
                            f"starts from reset)")
    table.add_row("invalid samples (flagged, nan in the CSV)", f"{n_bad}")
    if first is not None:
        table.add_row("first invalid sample",
                      f"{first} (t = {res.t[first]:.3f} s): {summary['first_invalid_reason']}")
    table.add_row("atan saturated samples", f"{circuit.saturated}")
    if engine == "rtl":
        table.add_row("simulated cycles", f"{circuit.cycles}")
        table.add_row("Verilator build", f"{circuit.build_seconds:.1f} s")
    table.add_row("engine time / samples per s",
                  f"{circuit.seconds:.2f} s / {n / max(circuit.seconds, 1e-9):.0f}")
    table.add_row("wall time", f"{summary['wall_seconds']:.2f} s")
    table_console.print(table)
    _wrote(console, out, n, summary_file)
    if first is not None:
        where = f"flagged in {out} (column invalid) and {summary_file}" if out is not None \
            else f"see {summary_file}"
        raise CliError(f"--engine {engine}: the circuit's output became invalid at sample "
                       f"{first}, t = {res.t[first]:.6f} s: {summary['first_invalid_reason']}; "
                       f"{n_bad} of {n} samples invalid, {where}")
    _check_finite(summary)


def summary_path(out):
    """Where a run's JSON summary goes: ``OUT_STEM.summary.json`` beside ``--out OUT``, else
    ``navgate-out/ahrs/summary.json``."""
    from pathlib import Path

    if out is None:
        return Path(default_out_dir("ahrs")) / "summary.json"
    out = Path(out)
    return out.with_name(f"{out.stem}.summary.json")


def _write_summary(staging, summary_file, summary):
    staged = staging.file(summary_file)
    write_summary(staged.parent, summary, name=staged.name)


def _wrote(console, out, n, summary_file):
    if out is not None:
        console.print(f"wrote {n} rows to {out} and the summary {summary_file}",
                      highlight=False)
    else:
        console.print(f"wrote the summary {summary_file}", highlight=False)


def _check_finite(summary):
    bad = non_finite_keys(summary)
    if bad:
        raise CliError(f"the run produced non-finite results ({', '.join(bad[:4])})")


def _invalid_reason(words, k):
    """Why the circuit's output is NaN at sample ``k``: the float32 vectors it normalises
    (a zero norm is 0/0 in its arithmetic), else its arithmetic."""
    from navgate.numerics.fp32 import bits_to_f32

    acc, mag, _ = words
    for name, vec in (("acceleration (free fall or a dead accelerometer)", acc),
                      ("magnetic field", mag)):
        v = bits_to_f32(np.asarray(vec[k], dtype=np.uint32)).astype(np.float32)
        with np.errstate(all="ignore"):
            norm2 = np.float32(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        if not np.isfinite(v).all():
            return f"non-finite {name.split(' (')[0]}"
        if norm2 == 0:
            return f"zero-norm {name}"
        if not np.isfinite(norm2):
            return f"{name.split(' (')[0]} too large for float32 normalisation"
    return "NaN in the circuit's arithmetic"


HEADER = "t,qw,qx,qy,qz,roll_deg,pitch_deg,yaw_deg"
FMT = ["%.6f"] + ["%.9f"] * 4 + ["%.5f"] * 3


def _make_stream(cls, reader, block, method, axes, kp, ki, gain, no_mag, init, gap_periods,
                 resolve_axes):
    """The filter for this log: axes resolved, gap threshold and the kp*dt check from the
    log's nominal period."""
    from navgate.systems.attitude.estimate import check_run

    dt = reader.nominal_dt
    if not (math.isfinite(dt) and dt > 0):
        dt = 0.01
    if method == "mahony" and kp * dt >= 1.0:
        raise CliError(f"--kp {kp:g} with a {dt:g} s sample period gives kp * dt = {kp * dt:.3g};"
                       f" the discrete filter needs kp * dt < 1 (here kp < {1 / dt:.4g})")
    # the checks every engine shares (the circuit engines run the same in circuit_inputs)
    check_run(method=method, dt=dt, kp=kp, ki=ki, gain=gain,
              acc0=block.acc[0] if init == "accel" and len(block.acc) else None,
              use_mag=not no_mag and block.mag is not None)
    return cls(method, axes=resolve_axes(block, axes), kp=kp, ki=ki, gain=gain,
               use_mag=not no_mag, init=init, gap_s=gap_periods * dt)
