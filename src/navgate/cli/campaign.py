"""``navgate campaign``: Monte Carlo over seeds x terrains x options on Dask.

Runs :mod:`navgate.systems.ins_trn.ps.campaign` and writes ``summary.json`` (a
``configurations`` list and every failed run), ``results.csv`` (one row per run),
``error_cdf.png`` and ``nees_hist.png`` into ``--out``; prints a results table per
configuration. Bad input ends with one line on stderr and exit 2.
"""

from __future__ import annotations

import math

import click

from navgate.cli.console import consoles
from navgate.cli.errors import CliError
from navgate.cli.extras import require
from navgate.cli.inputs import dem_input
from navgate.cli.outputs import (
    atomic_output_dir,
    check_out_dir,
    check_outputs_early,
    default_out_dir,
    out_option,
)
from navgate.cli.summary import non_finite_keys, write_summary

#: the files campaign writes into --out
OUTPUTS = ("summary.json", "results.csv", "error_cdf.png", "nees_hist.png")
#: the most runs (seeds x configurations) one campaign takes
MAX_RUNS = 100_000


@click.command()
@click.option("--seeds", default="0-9", show_default=True,
              help="Seeds: a range A-B, a list, or both (0-49, 3,7,9-12).")
@click.option("--dem", "dems", multiple=True,
              help="DEM file (repeat for several terrains); 'default' is the embedded "
                   "Jacksboro DEM. Default: the embedded DEM.")
@click.option("--trn", "trns", multiple=True,
              help="TRN method (repeat to compare: tercom, pmf). Default: pmf.")
@click.option("--ranger", "rangers", multiple=True,
              help="AGL ranger preset (repeat to compare). Default: long-range.")
@click.option("--duration", type=float, default=600.0, show_default=True,
              help="Flight duration after GPS loss (s).")
@click.option("--workers", type=int, default=2, show_default=True,
              help="Worker processes of the LocalCluster (ignored with --scheduler).")
@click.option("--scheduler", default=None,
              help="Address of an existing Dask scheduler (tcp://host:8786) instead of a "
                   "LocalCluster; its workers must have navgate installed.")
@out_option(default_out_dir("campaign"), "Output directory (written atomically).")
@click.option("--quiet", is_flag=True, help="No progress bar and no table.")
def campaign(seeds, dems, trns, rangers, duration, workers, scheduler, out, quiet):
    """Monte Carlo campaign of GPS-denied flights: seeds x DEMs x TRN options, on Dask."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
    )

    from navgate.sim.sensors import RANGER_PRESETS
    from navgate.systems.ins_trn.ps import campaign as camp
    from navgate.systems.ins_trn.ps.flight import FlightConfig, RouteError, plan_route
    from navgate.trn.correlators import METHODS
    from navgate.trn.dem import DemError

    try:
        seed_list = camp.parse_seeds(seeds)
    except ValueError as error:
        raise CliError(f"--seeds: {error}") from None
    if not (math.isfinite(duration) and 0 < duration <= 4 * 3600):
        raise CliError(f"--duration must be in (0, 14400] s, got {duration:g}")
    if workers < 1 or workers > 256:
        raise CliError(f"--workers must be between 1 and 256, got {workers}")
    require("dask.distributed", "navgate campaign")  # the campaign extra; one line if absent
    trns = tuple(dict.fromkeys(trns)) or ("pmf",)
    for t in trns:
        if t not in METHODS:
            raise CliError(f"--trn: unknown method {t!r}; choose from {', '.join(METHODS)}")
    rangers = tuple(dict.fromkeys(rangers)) or ("long-range",)
    for r in rangers:
        if r not in RANGER_PRESETS:
            raise CliError(f"--ranger: unknown preset {r!r}; choose from "
                           f"{', '.join(RANGER_PRESETS)}")
    # the flight's own checks (a duration too short for the scenario), as fly makes them
    for r in rangers:
        try:
            FlightConfig(duration_s=duration, ranger=r)
        except ValueError as error:
            raise CliError(str(error).replace("duration_s", "--duration")) from None
    if scheduler is not None:
        _check_scheduler(scheduler)
    dems = tuple(dict.fromkeys(dems)) or ("default",)
    n_planned = len(seed_list) * len(dems) * len(trns) * len(rangers)
    if n_planned > MAX_RUNS:
        raise CliError(f"{len(seed_list)} seeds x {len(dems) * len(trns) * len(rangers)} "
                       f"configurations = {n_planned:,} runs, more than the {MAX_RUNS:,} one "
                       "campaign runs")
    check_out_dir(out)
    check_outputs_early(out, OUTPUTS, [d for d in dems if d != "default"])
    # every DEM must load and hold the route before any worker starts
    for d in dems:
        try:
            dem = camp._load_dem(dem_input(d))
            plan_route(dem, FlightConfig(duration_s=duration))
        except (DemError, RouteError) as error:
            raise CliError(str(error)) from None
    spec = camp.Campaign.build(seed_list, dems, trns, rangers, duration_s=duration)
    table_console, console = consoles(quiet)
    n_runs = len(spec.tasks())
    console.print(f"[bold]navgate campaign[/]: {len(seed_list)} seeds x "
                  f"{len(spec.configurations)} configurations = {n_runs} runs of {duration:g} s, "
                  + (f"scheduler {scheduler}" if scheduler else f"LocalCluster, {workers} workers"))
    failures = []
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TimeElapsedColumn())
    with Progress(*columns, console=console, disable=quiet) as bar:
        task = bar.add_task("running", total=n_runs)

        done = [0]

        def progress(row):
            bar.advance(task)
            done[0] += 1
            if not console.is_terminal and row["status"] == "ok":  # a log: one line per run
                console.print(f"[{done[0]}/{n_runs}] {row['dem']} / {row['trn']} seed "
                              f"{row['seed']}: RMS 2nd half {row['rms_second_half_m']:.1f} m, "
                              f"final {row['final_error_m']:.1f} m, {row['wall_s']:.0f} s")
            if row["status"] != "ok":
                failures.append(row)
                bar.console.print(f"run failed: {row['dem']} / {row['trn']} seed {row['seed']}: "
                                  f"{row['error']}", style="red")

        try:
            result = camp.run_campaign(spec, workers=workers, scheduler=scheduler,
                                       progress=progress)
        except OSError as error:
            raise CliError(f"cannot reach the Dask scheduler {scheduler}: {error}") from None
    summary = result.summary()
    with atomic_output_dir(out, inputs=[d for d in dems if d != "default"]) as stage:
        files = camp.write_report(result, stage)
        write_summary(stage, summary)
    if not quiet:
        _print_table(_table_console(table_console), summary)
    console.print(f"wrote summary.json and {', '.join(p.name for p in files.values())} in "
                  f"{out}", highlight=False)
    bad = non_finite_keys(summary)
    if bad:
        raise CliError(f"the campaign produced non-finite results ({', '.join(bad[:4])})")


def _check_scheduler(address: str) -> None:
    """One line for a scheduler address Dask could not parse: [tcp|tls|ws|wss://]HOST:PORT."""
    from distributed.comm.addressing import parse_address, parse_host_port

    shape = "[tcp://]HOST:PORT, e.g. tcp://10.0.0.5:8786"
    if not address.strip():
        raise CliError(f"--scheduler must not be empty; give {shape}")
    try:
        scheme, location = parse_address(address)
        if scheme not in ("tcp", "tls", "ws", "wss"):
            raise ValueError(f"unknown protocol {scheme!r}")
        host, port = parse_host_port(location)
    except (ValueError, TypeError) as error:
        raise CliError(f"--scheduler {address!r} is not a scheduler address ({error}); give "
                       f"{shape}") from None
    if not host or not 0 < port < 65536:
        raise CliError(f"--scheduler {address!r} is not a scheduler address (host "
                       f"{host!r}, port {port}); give {shape}")


#: the table's width when stdout is not a terminal (a file, a pipe): rich wraps the headers
TABLE_WIDTH_REDIRECTED = 120


def _table_console(console):
    """The console for the results table: the terminal's own width on a terminal, else
    :data:`TABLE_WIDTH_REDIRECTED` columns (never the 200 that a log file had to take)."""
    from rich.console import Console

    return console if console.is_terminal else Console(width=TABLE_WIDTH_REDIRECTED)


def _fmt(v, spec=".1f"):
    return "-" if v is None else format(v, spec)


def _print_table(console, s):
    from rich.table import Table

    table = Table(title=f"Monte Carlo: {s['runs']} runs, {s['duration_s']:.0f} s flights, "
                        f"wall {s['wall_time_s']:.0f} s on {s['workers']} workers")
    for col in ("configuration", "runs (failed)", "RMS 2nd half mean/max (m)", "CEP50 (m)",
                "CEP95 (m)", "final mean (m)", "INS-only final (m)", "TRN worse",
                "first fix (s)", "NEES mean [95% band]", "outside 3-sigma"):
        table.add_column(col, justify="right" if col != "configuration" else "left")
    for c in s["configurations"]:
        band = c.get("nees_band_95")
        nees = "-" if c["nees_mean"] is None else (
            f"{c['nees_mean']:.2f} [{band[0]:.2f}, {band[1]:.2f}]")
        table.add_row(
            c["label"], f"{c['runs']} ({c['failed']})",
            f"{_fmt(c['rms_second_half_m_mean'])} / {_fmt(c['rms_second_half_m_max'])}",
            _fmt(c["cep50_m"]), _fmt(c["cep95_m"]), _fmt(c["final_error_m_mean"]),
            _fmt(c["ins_only_final_error_m_mean"]), _fmt(c["runs_trn_worse_than_ins_only"], "d"),
            _fmt(c["time_to_first_fix_s_mean"]), nees,
            "-" if c["outside_3sigma_fraction"] is None
            else f"{100 * c['outside_3sigma_fraction']:.2f} %")
    console.print(table)
    for f in s["failed_runs"]:
        console.print(f"failed: {f['dem']} / {f['trn']} / {f['ranger']} seed {f['seed']}: "
                      f"{f['error']}", style="red")
    console.print(f"wall time {s['wall_time_s']:.1f} s; mean run {s['run_wall_s_mean']:.1f} s; "
                  f"scaling ratio {s['scaling_ratio']:.2f} (1.0 = runs x mean run / workers)")
