"""``navgate ahrs``: run an attitude filter (seed 003's Mahony or a complementary filter) over a
real IMU log and write ``t qw qx qy qz roll_deg pitch_deg yaw_deg``.

Input formats and error handling: :mod:`navgate.sim.imu_log`; axes and filters:
:mod:`navgate.systems.attitude.estimate`. Bad input ends with one line on stderr and exit 2.
"""

from __future__ import annotations

import math
import time

import click
import numpy as np

from navgate.cli.common import CliError


def _run_circuit(log, engine, method, axes, kp, ki, no_mag, console):
    """``--engine fp32|rtl``: seed 003's circuit (bit-true model or gateware)."""
    from navgate.systems.attitude.circuit_engine import run_circuit

    if method != "mahony":
        raise CliError(f"--engine {engine} runs seed 003's Mahony circuit; use --filter mahony")
    if no_mag:
        raise CliError(f"--engine {engine}: the circuit always uses the magnetometer "
                       f"(drop --no-mag)")
    if engine == "fp32":
        console.print(f"running the float32 model over {len(log)} samples "
                      f"(about 50 ms a sample)")
    try:
        return run_circuit(log, engine, axes=axes, kp=kp, ki=ki)
    except ValueError as error:
        raise CliError(str(error)) from None
    except RuntimeError as error:  # a Verilator build or run failure
        raise CliError(f"--engine rtl: {str(error).splitlines()[0]}") from None


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
@click.option("--out", "out_csv", type=click.Path(dir_okay=False), default=None,
              help="Output CSV (t, qw..qz, roll/pitch/yaw in deg). Default: summary only.")
@click.option("--kp", type=float, default=1.0, show_default=True, callback=_nonneg,
              help="Mahony proportional gain (rad/s per unit error).")
@click.option("--ki", type=float, default=0.1, show_default=True, callback=_nonneg,
              help="Mahony integral gain.")
@click.option("--gain", type=float, default=0.02, show_default=True, callback=_nonneg,
              help="Complementary filter correction gain per sample (0..1).")
@click.option("--axes", type=click.Choice(["auto", "frd", "flu"]), default="auto",
              show_default=True,
              help="Sensor axes: frd (level accel reads -g on z), flu (+g on z, e.g. x-io); "
                   "auto = flu for x-io headers.")
@click.option("--no-mag", is_flag=True, help="Ignore magnetometer columns.")
@click.option("--init", type=click.Choice(["accel", "identity"]), default="accel",
              show_default=True, help="Initial attitude.")
@click.option("--engine", type=click.Choice(["reference", "fp32", "rtl"]), default="reference",
              show_default=True,
              help="mahony only: reference = float64 filter; fp32 = seed 003's float32 "
                   "bit-true circuit model; rtl = the circuit's gateware in Verilator "
                   "(fp32 and rtl give identical CSVs; docs/seed003-attitude-circuit.md).")
@click.option("--quiet", is_flag=True, help="No summary table.")
def ahrs(input_csv, method, out_csv, kp, ki, gain, axes, no_mag, init, engine, quiet):
    """Estimate attitude from an IMU log (CSV)."""
    from rich.console import Console
    from rich.table import Table

    from navgate.sim.imu_log import LogError, read_imu_csv, write_attitude_csv
    from navgate.systems.attitude.estimate import estimate_attitude

    if method == "complementary" and gain > 1:
        raise CliError(f"--gain must be between 0 and 1, got {gain:g}")
    console = Console(stderr=True, quiet=quiet)
    start = time.perf_counter()
    try:
        log = read_imu_csv(input_csv)
    except LogError as error:
        raise CliError(str(error)) from None
    if len(log) < 2:
        raise CliError(f"{input_csv}: need at least two samples")
    circuit = None
    if engine != "reference":
        circuit = _run_circuit(log, engine, method, axes, kp, ki, no_mag, console)
        res = circuit.result
    else:
        try:
            res = estimate_attitude(log, method, axes=axes, kp=kp, ki=ki, gain=gain,
                                    use_mag=not no_mag, init=init)
        except ValueError as error:
            raise CliError(str(error)) from None
    if not np.isfinite(res.q).all():
        raise CliError("the filter diverged (non-finite attitude); check units and --kp/--ki")
    elapsed = time.perf_counter() - start
    if out_csv is not None:
        try:
            write_attitude_csv(out_csv, res.t, res.q, res.roll_deg, res.pitch_deg, res.yaw_deg)
        except OSError as error:
            raise CliError(f"cannot write {out_csv}: {error.strerror}") from None
    dt = np.diff(res.t)
    table = Table(title=f"navgate ahrs: {method} on {input_csv}")
    table.add_column("item")
    table.add_column("value", justify="right")
    table.add_row("samples", f"{len(res.t)}")
    table.add_row("skipped rows", f"{log.skipped_rows}")
    table.add_row("duration", f"{res.t[-1] - res.t[0]:.2f} s")
    table.add_row("mean rate", f"{1.0 / float(np.mean(dt)):.1f} Hz")
    table.add_row("header style / axes", f"{log.style} / {res.axes}")
    table.add_row("magnetometer", "used" if res.used_mag else "not used")
    table.add_row("final roll / pitch / yaw",
                  f"{res.roll_deg[-1]:.2f} / {res.pitch_deg[-1]:.2f} / {res.yaw_deg[-1]:.2f} deg")
    if circuit is not None:
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
    console.print(table)
    if out_csv is not None:
        click.echo(f"wrote {len(res.t)} rows to {out_csv}")
