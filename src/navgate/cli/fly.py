"""``navgate fly``: a GPS-denied flight over real terrain, INS-only and INS+TRN side by side.

Runs :func:`navgate.systems.ins_trn.ps.flight.fly` (the scenario of :mod:`navgate.sim.flight`
flown by seed 000's navigator) and writes summary.json, trajectory.csv, trn_fixes.csv,
track.png and errors.png into ``--out``. Bad input (missing/unreadable/non-DEM files, a DEM
too small for the route, bad option values) ends with one line on stderr and exit 2.
"""

from __future__ import annotations

import contextlib
import math
import time
from pathlib import Path

import click

from navgate.cli.console import consoles, hardware_line, numba_note
from navgate.cli.engines import engine_choice, load_engine_class
from navgate.cli.errors import CliError, simulation_errors
from navgate.cli.inputs import dem_input
from navgate.cli.outputs import (
    check_not_input,
    check_out_dir,
    check_outputs_early,
    check_writable_file,
    default_out_dir,
    out_option,
    reject_empty,
    staged_outputs,
)
from navgate.cli.summary import non_finite_keys, write_summary


def _positive_float(ctx, param, value):
    if value is None:
        return value
    if not (math.isfinite(value) and value > 0):
        raise click.BadParameter(f"must be a positive number, got {value}")
    return value


@click.command()
@click.option("--dem", "dem_path", type=click.Path(dir_okay=True), default=None,
              help="DEM file (GeoTIFF, DTED .dt0/.dt1/.dt2, SRTM .hgt; geographic CRS) or a "
                   "directory of such tiles (navgate tiles split makes one). "
                   "Default: the embedded Jacksboro fault DEM.")
@click.option("--tile-cache-mb", type=float, default=None, callback=_positive_float,
              help="With a tile directory: the tile cache's cap (MiB; default no cap).")
@click.option("--tile-priority", type=click.Choice(["check", "first", "last"]),
              default="check", show_default=True,
              help="With a tile directory: where overlapping tiles disagree, stop (check) or "
                   "let the first / last tile in file-name order win.")
@click.option("--duration", type=float, default=600.0, show_default=True,
              callback=_positive_float, help="Flight duration after GPS loss (s).")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@out_option(default_out_dir("fly"), "Output directory (written atomically).")
@click.option("--ideal-sensors", is_flag=True, help="No sensor errors and no quantisation.")
@click.option("--no-trn", is_flag=True, help="Run INS-only (with baro) and skip TRN.")
@click.option("--imu-rate", type=float, default=400.0, show_default=True,
              callback=_positive_float, help="IMU rate (Hz).")
@click.option("--ranger", type=click.Choice(["long-range", "tf-luna"]), default="long-range",
              show_default=True, help="AGL ranger preset.")
@click.option("--speed", type=float, default=60.0, show_default=True, callback=_positive_float,
              help="Cruise speed (m/s).")
@click.option("--trn", "trn_method", type=click.Choice(["pmf", "tercom"]), default="pmf",
              show_default=True,
              help="TRN method: point-mass filter or batch TERCOM (docs/trn.md compares them).")
@click.option("--engine", type=engine_choice(), default="reference", show_default=True,
              help="PL engine: float64 reference, the float32 bit-true model, the "
                   "ins_engines gateware in Verilator, or the whole FPGA (ins_trn_top, IMU on "
                   "its SPI pins, the PS through AXI registers) in Verilator; rtl and "
                   "fpga-sim equal fp32 bit for bit; fp32-plain is fp32 without its float32 "
                   "remedies (an ablation, docs/seed000-navigator.md); board flies the real "
                   "ins_trn_top in the Zynq's PL from its PS (the --board-* options, "
                   "docs/deploy.md). With any engine but reference the reference "
                   "flies too, for the comparison in summary.json.")
@click.option("--board-bus", type=click.Choice(["devmem", "pynq", "verilator"]), default=None,
              help="With --engine board: the way to the register bank. devmem (the default) "
                   "maps /dev/mem (root; any Zynq Linux); pynq uses pynq.MMIO (a PYNQ image); "
                   "verilator is the stand-in, the Verilated ins_trn_top with its sensor "
                   "emulators, to check the board's code path without a board.")
@click.option("--board-base", type=str, default=None, metavar="ADDR",
              help="With --engine board: the register bank's physical address (default "
                   "0x40000000, where the Vivado block design puts it on M_AXI_GP0).")
@click.option("--board-dma", type=str, default=None, metavar="ADDR",
              help="With --engine board --board-bus devmem: the profile DMA's buffer in DDR "
                   "(default 0x3FF00000, the last MiB of the Zybo's 1 GiB; keep Linux off it "
                   "with mem=1023M). pynq allocates its own.")
@click.option("--board-irq", type=str, default=None, metavar="poll|/dev/uioN",
              help="With --engine board: wait for the PL's interrupt by polling IRQ_STATUS "
                   "(default) or on a UIO device bound to IRQ_F2P[0].")
@click.option("--board-mem", type=str, default=None, metavar="PATH",
              help="With --engine board --board-bus devmem: the memory device (default "
                   "/dev/mem).")
@click.option("--record", "record_path", type=click.Path(dir_okay=False), default=None,
              callback=reject_empty,
              help="Also write the sensor record stream to this log file (navgate replay).")
@click.option("--trn-service", "trn_service", default=None,
              metavar="tcp://HOST:PORT|serial:PORT[@BAUD]|spawn",
              help="Correlate on a TRN service (navgate trn-serve, seed 000's Pi 5) instead of "
                   "in this process; spawn starts one on a pseudo-terminal.")
@click.option("--trn-timeout", type=float, default=5.0, show_default=True,
              callback=_positive_float,
              help="With --trn-service: seconds to wait for each fix before a retry.")
@click.option("--trn-heartbeat", type=float, default=1.0, show_default=True,
              help="With --trn-service: send a heartbeat after this many seconds without "
                   "traffic; a missed reply marks the link down and reconnecting starts at "
                   "once. 0: no heartbeats.")
@click.option("--trn-latency", type=float, default=0.0, show_default=True,
              help="Apply each TRN fix this many seconds after its request (simulated link "
                   "and Pi time; deterministic). 0: at the request's time.")
@click.option("--link-flip-rate", type=float, default=0.0, show_default=True,
              help="With --trn-service: flip bits in the PS's outgoing bytes at this rate per "
                   "byte (fault injection; every bad frame is counted).")
@click.option("--realtime", type=float, is_flag=False, flag_value=1.0, default=None,
              metavar="[SPEED]",
              help="Pace the INS+TRN run to the wall clock (SPEED times real time, default 1): "
                   "TRN requests go out on a worker thread and each fix is applied when it "
                   "arrives, at its own time tag. NOT deterministic (thread and link timing); "
                   "the default, simulated time, is.")
@click.option("--quiet", is_flag=True, help="No progress bar and no table.")
def fly(dem_path, tile_cache_mb, tile_priority, duration, seed, out, ideal_sensors, no_trn,
        imu_rate, ranger, speed, trn_method, engine, record_path, trn_service, trn_timeout,
        trn_heartbeat, trn_latency, link_flip_rate, realtime, board_bus, board_base, board_dma,
        board_irq, board_mem, quiet):
    """Fly a GPS-denied route over a DEM; compare INS-only with INS+TRN."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from navgate.systems.ins_trn.ps import flight, report
    from navgate.trn.dem import DemError
    from navgate.trn.tiles import load_terrain

    table_console, console = consoles(quiet)
    if duration > 4 * 3600:
        raise CliError(f"--duration {duration:g} s is longer than the 4 h this command supports")
    if not 50 <= imu_rate <= 4000:
        raise CliError(f"--imu-rate must be between 50 and 4000 Hz, got {imu_rate:g}")
    if not 5 <= speed <= 400:
        raise CliError(f"--speed must be between 5 and 400 m/s, got {speed:g}")
    if seed < 0:
        raise CliError(f"--seed must be non-negative, got {seed}")
    # imported now, before any work: on a slim install (the boards) an engine that needs the
    # gateware extra is one line naming it
    engine_cls = load_engine_class(engine, "navgate fly")
    board_settings = _board_settings(engine, board_bus, board_base, board_dma, board_irq,
                                     board_mem)
    if ideal_sensors and engine_cls.needs_imu_words:
        raise CliError(f"--engine {engine} needs the IMU's int16 output words, which "
                       "--ideal-sensors does not produce")
    try:
        dem = load_terrain(dem_input(dem_path), cache_mb=tile_cache_mb, priority=tile_priority)
    except DemError as error:
        raise CliError(str(error)) from None
    if (tile_cache_mb is not None or tile_priority != "check") and not hasattr(dem, "stats"):
        raise CliError("--tile-cache-mb and --tile-priority need --dem to be a tile directory")
    try:
        cfg = flight.FlightConfig(duration_s=duration, imu_rate_hz=imu_rate, seed=seed,
                                  ideal_sensors=ideal_sensors, trn=not no_trn, ranger=ranger,
                                  speed_mps=speed)
        trn = flight.TrnSettings(method=trn_method)
    except ValueError as error:
        raise CliError(str(error).replace("duration_s", "--duration")) from None
    try:
        route = flight.plan_route(dem, cfg)
    except (flight.RouteError, DemError) as error:
        raise CliError(str(error)) from None
    check_out_dir(out)
    check_outputs_early(out, REPORT_FILES, [dem_path])
    if record_path is not None:
        _check_record(record_path, out, dem_path)
    if not (math.isfinite(trn_latency) and 0.0 <= trn_latency <= 60.0):
        raise CliError(f"--trn-latency must lie in [0, 60] s, got {trn_latency:g}")
    if not (math.isfinite(link_flip_rate) and 0.0 <= link_flip_rate <= 1.0):
        raise CliError(f"--link-flip-rate must lie in [0, 1], got {link_flip_rate:g}")
    if not trn_timeout <= 3600.0:  # (positive and finite: its callback) 1e10 s overflowed
        raise CliError(f"--trn-timeout must lie in (0, 3600] s, got {trn_timeout:g}")
    if not (math.isfinite(trn_heartbeat) and 0.0 <= trn_heartbeat <= 3600.0):
        raise CliError(f"--trn-heartbeat must lie in [0, 3600] s, got {trn_heartbeat:g}")
    if realtime is not None:
        if not (math.isfinite(realtime) and 0.0 < realtime <= 1000.0):
            raise CliError(f"--realtime SPEED must lie in (0, 1000], got {realtime:g}")
        if no_trn:
            raise CliError("--realtime paces the INS+TRN run; it cannot go with --no-trn")
        if trn_latency:
            raise CliError("--trn-latency sets a simulated latency; --realtime measures "
                           "the real one: give one of them")
    if trn_service is None and link_flip_rate:
        raise CliError("--link-flip-rate needs --trn-service")
    trn_link = None
    if trn_service is not None and not no_trn:
        from navgate.systems.ins_trn.link.faults import FaultInjector
        from navgate.systems.ins_trn.ps.trn_link import LinkError, TrnLink

        faults = FaultInjector(seed=seed, flip_rate=link_flip_rate) if link_flip_rate else None
        try:
            trn_link = TrnLink(trn_service, terrain_path=dem_path, cache_mb=tile_cache_mb,
                               timeout_s=trn_timeout, faults=faults,
                               heartbeat_s=trn_heartbeat)
        except LinkError as error:
            raise CliError(str(error)) from None
    engine_options = None
    board = None
    if board_settings is not None:
        from navgate.systems.ins_trn.ps.board_engine import BoardError, open_board

        try:
            board = open_board(board_settings)
        except BoardError as error:
            if trn_link is not None:
                trn_link.close()
            raise CliError(f"--engine board: {error}") from None
        engine_options = {"board": board}
    # the link and the board (if any) stay open for the flight and are closed whatever happens
    with trn_link if trn_link is not None else contextlib.nullcontext(), \
            board if board is not None else contextlib.nullcontext():
        console.print(f"[bold]navgate fly[/]: {duration:g} s at {imu_rate:g} Hz over {dem.name} "
                      f"({dem.shape[0]} x {dem.shape[1]} posts), seed {seed}"
                      + (", ideal sensors" if ideal_sensors else ", ADIS16500/BMP390 errors")
                      + ("" if no_trn else f", TRN {trn_method}"))
        runs = 1 if no_trn else 2
        total = runs * int(round(duration * imu_rate))
        start = time.perf_counter()
        columns = (TextColumn("{task.description}"), BarColumn(),
                   TextColumn("{task.percentage:>3.0f}%"))
        records = [] if record_path is None else [record_path]
        with numba_note(console), staged_outputs(out, files=records, inputs=[dem_path],
                                                 names=REPORT_FILES) as staging, Progress(
                *columns, TimeElapsedColumn(), console=console, disable=quiet,
                transient=False) as bar:
            stage = staging.dir
            task = bar.add_task("simulating sensors", total=total)
            try:
                result = flight.fly(dem, cfg, progress=lambda n: bar.advance(task, n),
                                    stage=lambda s: bar.update(task, description=s), route=route,
                                    engine=engine, trn_link=trn_link, trn_latency_s=trn_latency,
                                    realtime=realtime, trn=trn, engine_options=engine_options)
            except simulation_errors() as error:
                what = "the board" if board is not None and board.standin is None \
                    else "the co-simulation"
                raise CliError(f"--engine {engine}: {what} failed: {error}") from None
            except DemError as error:
                raise CliError(str(error)) from None
            bar.update(task, description="writing report", completed=total)
            summary = result.summary()
            summary["wall_time_s"] = time.perf_counter() - start
            summary["trn_latency_s"] = trn_latency
            if trn_link is not None:
                summary["trn_link"] = trn_link.stats()
                summary["trn_link"]["service_status"] = trn_link.status()
            files = report.write_report(result, stage)
            if record_path is not None:
                from navgate.systems.ins_trn.ps.records import write_log

                bar.update(task, description="writing the record log")
                write_log(result.stream, staging.file(record_path))
                summary["record_log"] = str(record_path)
            write_summary(stage, summary)
        _print_table(table_console, summary)
        console.print(f"wrote summary.json, {', '.join(p.name for p in files.values())} in {out}",
                      highlight=False)
        if record_path is not None:
            console.print(f"wrote the sensor record log {record_path} "
                          f"({len(result.stream):,} records; navgate replay {record_path})",
                          highlight=False)
        bad = non_finite_keys(summary)
        if bad:
            raise CliError(f"the run produced non-finite results ({', '.join(bad[:4])}); "
                           f"check the DEM heights and options (files in {out})")


#: the files fly writes into --out (navgate.systems.ins_trn.ps.report.write_report)
REPORT_FILES = ("summary.json", "trajectory.csv", "trn_fixes.csv", "track.png", "errors.png")


def _address(option: str, text: str | None, default: int) -> int:
    if text is None:
        return default
    try:
        value = int(text, 0)
    except ValueError:
        raise CliError(f"{option} {text!r} is not an address (0x40000000 or 1073741824)") \
            from None
    if not 0 <= value <= 0xFFFF_FFFF:
        raise CliError(f"{option} {text} is not a 32-bit address")
    return value


def _board_settings(engine, bus, base, dma, irq, mem):
    """The --board-* options as BoardSettings for --engine board (None for another engine,
    which refuses them)."""
    given = [name for name, value in (("--board-bus", bus), ("--board-base", base),
                                      ("--board-dma", dma), ("--board-irq", irq),
                                      ("--board-mem", mem)) if value is not None]
    if engine != "board":
        if given:
            raise CliError(f"{given[0]} goes with --engine board, not --engine {engine}")
        return None
    from navgate.systems.ins_trn.pl.registers import BASE_ADDRESS
    from navgate.systems.ins_trn.ps.board_engine import (
        DMA_ADDRESS,
        BoardError,
        BoardSettings,
    )

    settings = BoardSettings(bus=bus or "devmem",
                             base=_address("--board-base", base, BASE_ADDRESS),
                             dma=_address("--board-dma", dma, DMA_ADDRESS),
                             irq=irq or "poll", mem=mem or "/dev/mem")
    if mem is not None and settings.bus != "devmem":
        raise CliError("--board-mem goes with --board-bus devmem")
    try:
        settings.check()
    except BoardError as error:
        raise CliError(str(error)) from None
    return settings


def _check_record(record_path, out, dem_path) -> None:
    """--record FILE, checked before the flight: a regular file or absent (never a FIFO,
    device or directory), in a directory that exists, not the DEM, not one of the files the
    run writes into --out."""
    record = Path(record_path)
    check_writable_file(record)
    check_not_input(record, [dem_path])
    if record.parent.resolve() == Path(out).resolve() and record.name in REPORT_FILES:
        raise CliError(f"--record {record_path} is one of the files this run writes into "
                       f"--out {out}; choose another name")


def _print_table(console, s):
    from rich.table import Table

    title = f"GPS-denied flight: {s['duration_s']:.0f} s, {s['route']['distance_km']:.1f} km"
    table = Table(title=title)
    table.add_column("solution")
    for col in ("final error (m)", "RMS error (m)", "RMS 2nd half (m)", "NEES mean (2 dof)",
                "TRN fixes acc/rej"):
        table.add_column(col, justify="right")
    for name, label in (("ins_only", "INS only (+baro)"), ("trn_aided", "INS + TRN")):
        if name not in s:
            continue
        r = s[name]
        fixes = f"{r['fixes_accepted']}/{r['fixes_rejected']}" if name == "trn_aided" else "-"
        if name == "trn_aided" and r["fixes_accepted"] + r["fixes_rejected"] == 0:
            fixes = "0 (no fix attempted)"
        table.add_row(label, f"{r['final_horizontal_error_m']:.1f}",
                      f"{r['rms_horizontal_error_m']:.1f}",
                      f"{r['rms_horizontal_error_second_half_m']:.1f}",
                      f"{r['nees_position_mean']:.2f}", fixes)
    console.print(table)
    ranger = s.get("sensors", {})
    if "trn_aided" in s and ranger.get("ranger_valid_fraction", 1.0) < 0.5:
        console.print(f"ranger {ranger.get('ranger')}: only "
                      f"{100 * ranger['ranger_valid_fraction']:.0f} % of its samples were valid "
                      f"(out of range at this height above ground): TRN had "
                      f"{s['trn_aided']['fixes_accepted']} accepted fixes", highlight=False)
    console.print(f"wall time {s['wall_time_s']:.1f} s, engine {s.get('engine', 'reference')}")
    for name, label in (("ins_only", "INS only"), ("trn_aided", "INS + TRN")):
        hw = s.get(name, {}).get("hardware")
        if hw:
            console.print(f"{label}: {hardware_line(hw)}", highlight=False)
    engine = s.get("engine", "reference")
    key = f"{engine.replace('-', '_')}_vs_reference_max_position_difference_m"
    if key in s:
        console.print(f"{engine} vs reference: max position difference {s[key]:.2f} m; "
                      f"{engine} wall time {s['engine_wall_time_s']:.1f} s vs "
                      f"{s['reference_engine_wall_time_s']:.1f} s", highlight=False)
