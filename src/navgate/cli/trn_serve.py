"""``navgate trn-serve``: the Raspberry Pi 5's TRN service of seed 000 (docs/seed000-link.md).

Holds the terrain (``--tiles``: a tile directory, one DEM file, or the embedded DEM when
omitted) and answers profile requests with fixes over TCP (``--listen tcp://HOST:PORT``), a
serial port (``--serial PORT --baud N``), or an inherited file descriptor (``--fd N``, used by
``navgate fly --trn-service spawn``). One client at a time; one log line per request on
stderr; SIGTERM or Ctrl-C stops it cleanly. It writes no files.
"""

from __future__ import annotations

import math
import os

import click

from navgate.cli.errors import CliError
from navgate.cli.inputs import dem_input


def _cache(ctx, param, value):
    if value is not None and not (math.isfinite(value) and value > 0):
        raise click.BadParameter(f"must be a positive number of MiB, got {value}")
    return value


@click.command("trn-serve")
@click.option("--tiles", "tiles_path", type=click.Path(), default=None,
              help="Tile directory (DTED/SRTM/GeoTIFF) or one DEM file; default: the "
                   "embedded Jacksboro DEM.")
@click.option("--cache-mb", type=float, default=None, callback=_cache,
              help="Tile cache cap (MiB) for a tile directory (default: no cap).")
@click.option("--listen", default=None, metavar="tcp://HOST:PORT",
              help="Serve over TCP (e.g. tcp://127.0.0.1:7700; port 0 picks a free one).")
@click.option("--serial", "serial_port", default=None, help="Serve over this serial port.")
@click.option("--baud", type=click.IntRange(1200, 12_000_000), default=921600,
              show_default=True, help="Serial baud rate.")
@click.option("--fd", type=click.IntRange(0, 2**31 - 1), default=None, hidden=True,
              help="Serve over this inherited file descriptor (fly --trn-service spawn).")
@click.option("--max-requests", type=click.IntRange(1), default=None,
              help="Stop after answering this many profile requests.")
@click.option("--silent-periods", type=click.IntRange(0, 1000), default=5, show_default=True,
              help="Drop a PS that sends nothing for this many of its heartbeat periods (the "
                   "period its hello gives), so the next one can connect. 0: never.")
def trn_serve(tiles_path, cache_mb, listen, serial_port, baud, fd, max_requests,
              silent_periods):
    """Serve terrain correlation to the PS over TCP or a serial link (seed 000's Pi 5)."""
    from navgate.systems.ins_trn.link.transport import Transport, open_serial, parse_tcp
    from navgate.systems.ins_trn.pi.service import TrnService
    from navgate.trn.dem import DemError
    from navgate.trn.tiles import load_terrain

    chosen = [x for x in (listen, serial_port, fd) if x is not None]
    if len(chosen) != 1:
        raise CliError("give exactly one of --listen tcp://HOST:PORT, --serial PORT, --fd N")
    host = port = None
    if listen is not None:
        address = parse_tcp(listen)
        if address is None:
            raise CliError(f"--listen must be tcp://HOST:PORT, got {listen!r}")
        host, port = address
    if cache_mb is not None and (tiles_path is None or not os.path.isdir(tiles_path)):
        raise CliError("--cache-mb needs --tiles to be a tile directory")
    try:
        terrain = load_terrain(dem_input(tiles_path), cache_mb=cache_mb)
    except DemError as error:
        raise CliError(str(error)) from None
    service = TrnService(terrain, silent_periods=silent_periods)
    service.stop_on_signals()
    if fd is not None:
        try:
            os.fstat(fd)
        except OSError:
            raise CliError(f"--fd {fd} is not an open file descriptor") from None
        link = Transport(fd, closer=lambda: os.close(fd))
        try:
            service.serve(link, max_requests)
        finally:
            link.close()
    elif serial_port is not None:
        try:
            link = open_serial(serial_port, baud)
        except ImportError:
            raise CliError('--serial needs pyserial: pip install "navgate[serial]"') from None
        except (OSError, ValueError) as error:
            raise CliError(f"cannot open serial port {serial_port}: "
                           f"{getattr(error, 'strerror', None) or error}") from None
        service.log(f"trn-serve: serving on {serial_port} at {baud} baud")
        try:
            # a silent PS is dropped; the line then waits for the next one's hello
            while service.serve(link, max_requests) and not service.stop.is_set():
                pass
        finally:
            link.close()
    else:
        try:
            service.serve_tcp(host, port, max_requests=max_requests)
        except OSError as error:
            raise CliError(f"cannot listen on {listen}: {error.strerror or error}") from None
    service.log("trn-serve: stopped; " + ", ".join(f"{k} {v}" for k, v in
                                                   service.counters.items()))
