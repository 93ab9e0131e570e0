"""``navgate ahrs``: run an attitude filter (seed 003's Mahony or a complementary filter) over a
real IMU log and write ``t qw qx qy qz roll_deg pitch_deg yaw_deg``.

Input formats and error handling: :mod:`navgate.sim.imu_log`; axes and filters:
:mod:`navgate.systems.attitude.estimate`. Bad input ends with one line on stderr and exit 2.
"""

from __future__ import annotations

import contextlib
import math
import time

import click
import numpy as np
from rich.table import Table

from navgate.cli.console import consoles, numba_note
from navgate.cli.errors import CliError
from navgate.cli.inputs import fifo_guard
from navgate.cli.outputs import atomic_output_file, out_option


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
@out_option(None, "Output CSV (t, qw..qz, roll/pitch/yaw in deg), written atomically; never "
                  "the input. Default: summary only.", kind="file")
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
                   "(fp32 and rtl give identical CSVs; docs/seed003-attitude-circuit.md).")
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
    out_ctx = (atomic_output_file(out, inputs=[input_csv]) if out is not None
               else contextlib.nullcontext(None))
    columns = (TextColumn("{task.description}"), BarColumn(), DownloadColumn())
    try:
        with numba_note(console), out_ctx as tmp, Progress(
                *columns, console=console, disable=quiet, transient=True) as bar:
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
    except LogError as error:
        raise CliError(str(error)) from None
    except ValueError as error:
        raise CliError(str(error)) from None
    elapsed = time.perf_counter() - start
    n, duration = stats["rows"], float(stats["t1"] - stats["t0"])
    roll, pitch, yaw = stats["last"]
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
    mag_state = "used" if stream.used_mag else "not used"
    if stream.used_mag and reader.mag_held_rows:
        mag_state += f" (held over {reader.mag_held_rows} rows)"
    table.add_row("magnetometer", mag_state)
    table.add_row("final roll / pitch / yaw",
                  f"{roll:.2f} / {pitch:.2f} / {yaw:.2f} deg")
    table.add_row("wall time", f"{elapsed:.2f} s")
    table_console.print(table)
    if out is not None:
        console.print(f"wrote {n} rows to {out}", highlight=False)


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

    try:  # the checks every engine shares (estimate.check_run), before any message or build
        circuit_inputs(log, axes, kp, ki)
    except ValueError as error:
        raise CliError(str(error)) from None
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
    if out is not None:
        with atomic_output_file(out, inputs=[input_csv]) as tmp:
            with open(tmp, "w") as fh:
                fh.write(HEADER + "\n")
                np.savetxt(fh, np.column_stack([res.t, res.q, res.roll_deg, res.pitch_deg,
                                                res.yaw_deg]), delimiter=",", fmt=FMT)
    elapsed = time.perf_counter() - start
    table = Table(title=f"navgate ahrs: seed 003 circuit ({engine}) on {input_csv}")
    table.add_column("item")
    table.add_column("value", justify="right")
    table.add_row("samples", f"{len(res.t)}")
    table.add_row("skipped rows", f"{log.skipped_rows}")
    table.add_row("duration", f"{res.t[-1] - res.t[0]:.2f} s")
    table.add_row("header style / axes", f"{log.style} / {res.axes}")
    table.add_row("final roll / pitch / yaw",
                  f"{res.roll_deg[-1]:.2f} / {res.pitch_deg[-1]:.2f} / {res.yaw_deg[-1]:.2f} deg")
    table.add_row("engine", f"{engine} (seed 003 circuit, T = {circuit.params.dt:.6g} s, "
                            f"starts from reset)")
    table.add_row("flagged samples (invalid / atan saturated)",
                  f"{circuit.invalid} / {circuit.saturated}")
    if engine == "rtl":
        table.add_row("simulated cycles", f"{circuit.cycles}")
        table.add_row("Verilator build", f"{circuit.build_seconds:.1f} s")
    table.add_row("engine time / samples per s",
                  f"{circuit.seconds:.2f} s / {len(res.t) / max(circuit.seconds, 1e-9):.0f}")
    table.add_row("wall time", f"{elapsed:.2f} s")
    table_console.print(table)
    if out is not None:
        console.print(f"wrote {len(res.t)} rows to {out}", highlight=False)


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
