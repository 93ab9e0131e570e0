"""``navgate tinykalman``: seed 001's TinyKalman chip on an IMU log, and its UART decoder.

``navgate tinykalman LOG.csv --engine model|rtl --out DIR`` (the ``run`` sub-command is implied)
turns the log (the ``navgate ahrs`` CSV formats, :mod:`navgate.sim.imu_log`) into the words an
MPU-6500 would give (:mod:`navgate.systems.tinykalman.run`), runs them through the integer model
or through the chip's gateware at pin level (``rtl``: Verilator by default, ``--sim amaranth``
for short logs) and writes ``mpu6500_words.csv``, ``uart.bin`` (the byte stream on TX),
``roll_pitch.csv`` (the stream decoded) and ``summary.json``. With ``rtl`` the stream is also
compared byte for byte with the model's.

``navgate tinykalman decode FILE`` or ``... decode --serial PORT`` decodes a captured stream or a
live board (pyserial, imported only then) with the model's resynchronising decoder and reports
its counters.
"""

from __future__ import annotations

import csv
import dataclasses
import time
from pathlib import Path

import click
import numpy as np

from navgate.cli.console import consoles
from navgate.cli.errors import CliError
from navgate.cli.inputs import read_bounded, regular_input
from navgate.cli.outputs import (
    check_out_dir,
    check_outputs_early,
    default_out_dir,
    out_option,
    staged_outputs,
)
from navgate.cli.summary import write_summary


class _ImpliedRunGroup(click.Group):
    """A group whose first argument, when it is not a sub-command, goes to ``run``."""

    def parse_args(self, ctx, args):
        if args and args[0] not in self.commands and args[0] not in ("-h", "--help"):
            args = ["run", *args]
        return super().parse_args(ctx, args)


@click.group(cls=_ImpliedRunGroup)
def tinykalman() -> None:
    """Seed 001 TinyKalman: run an IMU log through the chip (LOG.csv, i.e. ``run``), or
    ``decode`` its UART stream."""


def _write_roll_pitch(path: Path, angles, t=None) -> None:
    from navgate.systems.tinykalman.model import bam_to_deg

    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["packet", "t", "roll_word", "pitch_word", "roll_deg", "pitch_deg"])
        for k, (r, p) in enumerate(angles):
            tk = "" if t is None or k >= len(t) else f"{t[k]:.6f}"
            w.writerow([k, tk, r, p, f"{float(bam_to_deg(r)):.5f}", f"{float(bam_to_deg(p)):.5f}"])


#: the files run and decode write into --out
RUN_OUTPUTS = ("mpu6500_words.csv", "uart.bin", "roll_pitch.csv", "summary.json")
DECODE_OUTPUTS = ("capture.bin", "roll_pitch.csv", "summary.json")


@tinykalman.command("run")
@click.argument("log_csv", type=click.Path(dir_okay=False))
@click.option("--engine", type=click.Choice(["model", "rtl"]), default="model", show_default=True,
              help="model: the integer bit-true model; rtl: the chip's gateware at pin level "
                   "(SPI device model, UART receiver), compared byte for byte with the model.")
@click.option("--sim", type=click.Choice(["verilator", "amaranth"]), default="verilator",
              show_default=True, help="Simulator for --engine rtl.")
@click.option("--axes", type=click.Choice(["auto", "flu", "frd"]), default="auto",
              show_default=True,
              help="Log axes: flu = the part's own (+1 g on z when level, x-io logs), frd (-1 g "
                   "on z); auto = flu for x-io headers, frd for plain ones.")
@click.option("--variant", type=click.Choice(["parallel", "serial"]), default="parallel",
              show_default=True,
              help="Chip for --engine rtl: parallel (word-parallel iterative CORDIC, 45 clocks "
                   "CS_N -> first start bit) or serial (bit-serial CORDIC and filter, 17.8k um2 "
                   "instead of 45.4k in SG13G2, 737 clocks). Same arithmetic, byte-identical "
                   "UART stream; the default keeps the chip earlier runs recorded and simulates "
                   "faster.")
@click.option("--limit", type=int, default=None, help="Use only the first N samples.")
@out_option(default_out_dir("tinykalman"), "Output directory (written atomically).")
@click.option("--quiet", is_flag=True, help="No table.")
@click.pass_context
def run(ctx, log_csv, engine, sim, variant, axes, limit, out, quiet):
    """Run an IMU log (CSV) through TinyKalman; write words, uart.bin, roll/pitch, summary."""
    from navgate.cli.extras import SIMULATION, require_gateware

    if engine == "model":  # --sim and --variant choose the gateware run: say so, never ignore
        given = [f"--{name}" for name in ("sim", "variant")
                 if ctx.get_parameter_source(name) is not click.core.ParameterSource.DEFAULT]
        if given:
            raise CliError(f"{' and '.join(given)} choose{'s' if len(given) == 1 else ''} the "
                           "gateware run of --engine rtl; --engine model runs the integer "
                           "model only (drop the option or use --engine rtl)")

    # the chip's timing comes from its gateware module (Amaranth) even for --engine model
    require_gateware(f"navgate tinykalman --engine {engine}",
                     SIMULATION if engine == "rtl" and sim == "verilator" else ("amaranth",))
    from rich.table import Table

    from navgate.sim.imu_log import LogError, read_imu_csv
    from navgate.systems.attitude.estimate import GAP_PERIODS, gap_steps
    from navgate.systems.tinykalman.run import words_from_imu
    from navgate.systems.tinykalman.top import timing

    table_console, console = consoles(quiet)  # the table to stdout, progress to stderr
    if limit is not None and limit < 1:
        raise CliError(f"--limit must be positive, got {limit}")
    check_out_dir(out)
    check_outputs_early(out, RUN_OUTPUTS, [log_csv])
    t_start = time.perf_counter()
    try:
        log = read_imu_csv(regular_input(log_csv))
    except LogError as error:
        raise CliError(str(error)) from None
    frd = axes == "frd" or (axes == "auto" and log.style != "x-io")
    n = len(log) if limit is None else min(limit, len(log))
    # the chip assumes one fixed sample period: steps longer than GAP_PERIODS nominal periods
    # are counted and reported (the reference ahrs restarts its filter at them)
    gap_sizes = gap_steps(log.t[:n])
    gaps = int(gap_sizes.size)
    largest_gap = float(gap_sizes.max()) if gaps else None
    try:
        words = words_from_imu(log.acc[:n], log.gyro[:n], frd=frd)
    except ValueError as error:
        raise CliError(str(error)) from None
    with staged_outputs(out, inputs=[log_csv], names=RUN_OUTPUTS) as staging:
        rtl_info, stream, stats, angles, model_seconds = _run_chip(
            staging.dir, log, words, n, engine, sim, variant, console)
        wall = time.perf_counter() - t_start
        rate = (n - 1) / (log.t[n - 1] - log.t[0]) if n > 1 else None
        deg = [(r * 180 / 32768, p * 180 / 32768) for r, p in angles]
        summary = {
            "log": str(log_csv), "samples": n, "log_rate_hz": rate,
            "axes": "frd" if frd else "flu",
            "skipped_rows": log.skipped_rows, "implausible_rows": log.implausible_rows,
            "saturated_words": words.saturated,
            "time_gaps": gaps, "largest_time_gap_s": largest_gap,
            "engine": engine, "uart_bytes": len(stream), "packets": stats.packets,
            "skipped_bytes": stats.skipped_bytes, "trailing_bytes": stats.trailing_bytes,
            "final_roll_deg": deg[-1][0] if deg else None,
            "final_pitch_deg": deg[-1][1] if deg else None,
            "model_seconds": round(model_seconds, 3), "wall_seconds": round(wall, 3),
            "chip_timing_default": timing(), **({"rtl": rtl_info} if rtl_info else {}),
        }
        write_summary(staging.dir, summary)
    table = Table(title=f"tinykalman {engine}: {log_csv}")
    table.add_column("item")
    table.add_column("value")
    table.add_row("samples", str(n))
    table.add_row("packets", str(stats.packets))
    table.add_row("saturated words", str(words.saturated))
    if log.skipped_rows or log.implausible_rows:  # rows of the log not run (counted)
        table.add_row("rows dropped (non-finite / implausible)",
                      f"{log.skipped_rows} / {log.implausible_rows}")
    if gaps:
        table.add_row(f"time gaps (steps over {GAP_PERIODS:g} sample periods; the chip "
                      "assumes a fixed rate)", f"{gaps} (largest {largest_gap:.3g} s)")
    if deg:
        table.add_row("final roll / pitch (deg)", f"{deg[-1][0]:.2f} / {deg[-1][1]:.2f}")
    if rtl_info:
        table.add_row("rtl equal to model", str(rtl_info["equal_to_model"]))
        table.add_row("rtl wall time (s)", f"{rtl_info['rtl_seconds']:.1f}")
    table.add_row("wall time (s)", f"{wall:.2f}")
    table_console.print(table)
    if gaps:
        console.print(f"note: {gaps} time gaps in the log (largest {largest_gap:.3g} s); the "
                      "chip integrates every sample over its one fixed period, across the "
                      "gaps too", highlight=False)
    console.print(f"wrote {out}/mpu6500_words.csv, uart.bin, roll_pitch.csv, summary.json",
                  highlight=False)
    if rtl_info and not rtl_info["equal_to_model"]:
        raise CliError(f"the chip's stream differs from the model's at byte "
                       f"{rtl_info['first_differing_byte']}")


def _run_chip(out: Path, log, words, n, engine, sim, variant, console):
    """Write the words, run the model (and the chip with ``rtl``) and write the stream and
    its decoding into ``out`` (a staging directory)."""
    from navgate.systems.tinykalman.model import decode_stream
    from navgate.systems.tinykalman.run import model_stream
    from navgate.systems.tinykalman.top import timing

    with open(out / "mpu6500_words.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["sample", "t", "ax", "ay", "az", "temp", "gx", "gy", "gz"])
        for k in range(n):
            w.writerow([k, f"{log.t[k]:.6f}", *(int(v) for v in words.words[k])])

    t0 = time.perf_counter()
    model_bytes = model_stream(words)
    model_seconds = time.perf_counter() - t0
    rtl_info = {}
    stream = model_bytes
    if engine == "rtl":
        from navgate.gateware.verify import VerifyError
        from navgate.systems.tinykalman.rtl_sim import (
            FAST,
            expected_stream,
            run_amaranth,
            run_verilator,
        )

        cfg = dataclasses.replace(FAST, variant=variant)
        console.print(f"running {n} samples through the {variant} chip ({sim}) ...")
        runner = run_verilator if sim == "verilator" else run_amaranth
        try:
            res = runner(words.bursts(), n, cfg)
        except VerifyError as error:
            raise CliError(str(error).splitlines()[0]) from None
        stream = res.uart
        dev_log = res.extra["log"] if sim == "verilator" else res.device.log
        from_log, whos = expected_stream(dev_log, n)
        first_bad = next((i for i, (a, b) in enumerate(zip(stream, model_bytes, strict=False))
                          if a != b), None)
        if first_bad is None and len(stream) != len(model_bytes):
            first_bad = min(len(stream), len(model_bytes))
        rtl_info = {
            "simulator": sim, "variant": variant, "config": cfg.params(),
            "timing": timing(**cfg.params()),
            "rtl_seconds": round(res.seconds, 3), "clock_cycles": res.cycles,
            "equal_to_model": stream == model_bytes, "first_differing_byte": first_bad,
            "equal_to_model_on_words_read": stream == from_log,
            "who_am_i_failures": int(sum(1 for v in whos if v != 0x70)),
            "latency_cycles": sorted(set(res.latencies)),
            "uart_receiver": "cocotbext-uart UartSink" if sim == "verilator"
            else "cycle-sampled 8N1 receiver",
        }
    (out / "uart.bin").write_bytes(stream)
    angles, stats = decode_stream(stream)
    _write_roll_pitch(out / "roll_pitch.csv", angles, log.t[:n])
    return rtl_info, stream, stats, angles, model_seconds


def _read_serial(port: str, baud: int, seconds: float) -> bytes:
    try:
        import serial  # pyserial
    except ImportError:
        raise CliError("--serial needs pyserial (pip install pyserial)") from None
    try:
        dev = serial.serial_for_url(port, baudrate=baud, timeout=0.1)
    except (serial.SerialException, ValueError, OSError) as error:
        raise CliError(f"cannot open {port}: {error}") from None
    data = bytearray()
    end = time.monotonic() + seconds
    try:
        while time.monotonic() < end and len(data) <= MAX_STREAM_BYTES:
            data += dev.read(256)
    finally:
        dev.close()
    return bytes(data)


#: the fastest UART --baud names (as trn-serve's --baud)
MAX_BAUD = 12_000_000
#: the longest --serial capture (a day) and the largest captured stream read (at 9600 baud a
#: TinyKalman sends about 1 kB/s: 64 MiB is some 18 hours)
MAX_CAPTURE_S = 86_400.0
MAX_STREAM_BYTES = 64 << 20
#: how long reading a FILE that is a FIFO or a device may take before it is an error
MAX_READ_S = 10.0


@tinykalman.command("decode")
@click.argument("file", required=False, type=click.Path(dir_okay=False))
@click.option("--serial", "port", default=None, help="Read a live board on this serial port "
              "(pyserial URL or device, e.g. /dev/ttyUSB0).")
@click.option("--baud", type=int, default=9600, show_default=True)
@click.option("--seconds", type=float, default=10.0, show_default=True,
              help=f"Capture time with --serial (at most {MAX_CAPTURE_S:g} s).")
@out_option(default_out_dir("tinykalman-decode"), "Output directory (written atomically).")
@click.option("--quiet", is_flag=True)
def decode(file, port, baud, seconds, out, quiet):
    """Decode a TinyKalman UART stream (FILE) or a live board (--serial PORT)."""
    table_console, console = consoles(quiet)  # results to stdout, notes to stderr
    if (file is None) == (port is None):
        raise CliError("give exactly one of FILE or --serial PORT")
    if baud <= 0 or not seconds > 0:
        raise CliError("--baud and --seconds must be positive")
    if baud > MAX_BAUD:
        raise CliError(f"--baud must be at most {MAX_BAUD:,} (a UART), got {baud}")
    if not seconds <= MAX_CAPTURE_S:  # also NaN
        raise CliError(f"--seconds must be at most {MAX_CAPTURE_S:g} s "
                       f"({MAX_CAPTURE_S / 3600:g} h), got {seconds:g}")
    check_out_dir(out)
    check_outputs_early(out, DECODE_OUTPUTS, [file])
    if file is not None:
        data = read_bounded(file, MAX_STREAM_BYTES, MAX_READ_S)
        source = str(file)
    else:
        data = _read_serial(port, baud, seconds)
        source = f"serial:{port}"
    with staged_outputs(out, inputs=[file], names=DECODE_OUTPUTS) as staging:
        if port is not None:
            (staging.dir / "capture.bin").write_bytes(data)
        angles, st = _decode_into(staging.dir, data)
        if not angles:  # nothing decoded: an error, and nothing is committed
            raise CliError(f"{source}: no TinyKalman packet in {len(data)} bytes "
                           f"({st.skipped_bytes} skipped, {st.trailing_bytes} trailing); "
                           "nothing written")
        summary = {"source": source, "bytes": len(data), "packets": st.packets,
                   "skipped_bytes": st.skipped_bytes, "trailing_bytes": st.trailing_bytes}
        write_summary(staging.dir, summary)
    table_console.print(f"{source}: {len(data)} bytes, {st.packets} packets, "
                        f"{st.skipped_bytes} skipped, {st.trailing_bytes} trailing",
                        highlight=False)
    if angles:
        r, p = angles[-1]
        table_console.print(f"last roll {r * 180 / 32768:.2f} deg, pitch "
                            f"{p * 180 / 32768:.2f} deg", highlight=False)
    console.print(f"wrote {out}/roll_pitch.csv, summary.json", highlight=False)
    return np.asarray(angles)


def _decode_into(out: Path, data: bytes):
    from navgate.systems.tinykalman.model import PacketDecoder

    dec = PacketDecoder()
    angles = []
    for k in range(0, len(data), 4096):  # a live stream arrives in chunks
        angles += dec.feed(data[k:k + 4096])
    dec.close()
    _write_roll_pitch(out / "roll_pitch.csv", angles)
    return angles, dec.stats
