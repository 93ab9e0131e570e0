"""Bounded reading of the command line's input files (README, "Conventions of every command").

Every reader stops at a size or a time limit with one line (:class:`CliError`, exit 2), never
a hang or an exhausted memory: ``/dev/zero``, a FIFO without a writer, an endless pipe.

- :func:`regular_input` is for inputs that a library reads by path (record logs, IMU CSV
  logs): a device, FIFO or socket is refused before it is opened (opening a FIFO for reading
  blocks until a writer appears), and so is a file larger than the command's limit.
- :func:`dem_input` is for DEM paths (read by seeking, GDAL): a regular file or a directory
  of tiles; anything else is refused before GDAL opens it.
- :func:`fifo_guard` is for inputs that may stream from a pipe (``navgate ahrs``): a FIFO
  must get a writer within a time limit (opening it blocks until one appears).
- :func:`read_bounded` reads a whole input into memory: a regular file up to ``max_bytes``;
  anything else (a FIFO, a pipe, a character device) is opened non-blocking and read until
  end of file, ``max_bytes`` or ``max_seconds``, whichever comes first; reaching a limit
  before the end is an error.
"""

from __future__ import annotations

import os
import select
import stat
import threading
import time
from pathlib import Path

from navgate.cli.errors import CliError


def _mib(n: int) -> str:
    return f"{n / 2**20:g} MiB"


def _stat(path: str | Path) -> os.stat_result:
    try:
        return os.stat(path)
    except OSError as error:
        raise CliError(f"cannot read {path}: {error.strerror or error}") from None


def regular_input(path: str | Path, max_bytes: int | None = None) -> Path:
    """``path`` as a Path when it is a regular file no larger than ``max_bytes``."""
    st = _stat(path)
    if stat.S_ISDIR(st.st_mode):
        raise CliError(f"cannot read {path}: it is a directory")
    if not stat.S_ISREG(st.st_mode):
        raise CliError(f"cannot read {path}: not a regular file (a device, FIFO or socket "
                       "is an endless or blocking input)")
    if max_bytes is not None and st.st_size > max_bytes:
        raise CliError(f"{path}: {st.st_size / 2**20:.1f} MiB is more than the "
                       f"{_mib(max_bytes)} this command reads")
    return Path(path)


def read_bounded(path: str | Path, max_bytes: int, max_seconds: float = 10.0) -> bytes:
    """The contents of ``path``; a :class:`CliError` when a limit comes before its end."""
    st = _stat(path)
    if stat.S_ISDIR(st.st_mode):
        raise CliError(f"cannot read {path}: it is a directory")
    if stat.S_ISREG(st.st_mode) and st.st_size > max_bytes:
        raise CliError(f"{path}: {st.st_size / 2**20:.1f} MiB is more than the "
                       f"{_mib(max_bytes)} this command reads")
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as error:
        raise CliError(f"cannot read {path}: {error.strerror or error}") from None
    chunks: list[bytes] = []
    size = 0
    deadline = time.monotonic() + max_seconds
    try:
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise CliError(f"{path}: no end of input after {max_seconds:g} s (a FIFO or "
                               "device without an end?); stopped")
            ready, _, _ = select.select([fd], [], [], min(left, 0.5))
            if not ready:
                continue
            try:
                chunk = os.read(fd, min(1 << 20, max_bytes + 1 - size))
            except BlockingIOError:
                continue
            except OSError as error:
                raise CliError(f"cannot read {path}: {error.strerror or error}") from None
            if not chunk:
                if stat.S_ISFIFO(st.st_mode) and size == 0:
                    # a FIFO opened non-blocking reads end-of-file until a writer opens it:
                    # wait for one (up to the deadline) rather than take an empty input
                    time.sleep(0.05)
                    continue
                break
            chunks.append(chunk)
            size += len(chunk)
            if size > max_bytes:
                raise CliError(f"{path}: more than the {_mib(max_bytes)} this command reads "
                               "(an endless input?); stopped")
    finally:
        os.close(fd)
    return b"".join(chunks)



def dem_input(path: str | Path | None) -> str | Path | None:
    """``path`` unchanged when it is absent (the library names the missing file), a regular
    file or a directory; a device, FIFO or socket is one line before GDAL opens it."""
    if path is None or str(path) == "default" or not os.path.exists(path):
        return path
    st = _stat(path)
    if not (stat.S_ISREG(st.st_mode) or stat.S_ISDIR(st.st_mode)):
        raise CliError(f"cannot read {path}: not a regular file or a directory (a DEM is read "
                       "by seeking; a device, FIFO or socket cannot be)")
    return path


#: how long a FIFO input may wait for its writer (fifo_guard)
FIFO_WAIT_S = 10.0


def fifo_guard(path: str | Path, max_seconds: float | None = None):
    """When ``path`` is a FIFO, wait at most ``max_seconds`` (:data:`FIFO_WAIT_S`) for a
    writer to open it (a plain open would block for ever) and return the open binary file to
    read it through (reopening it could block again once the writer has finished); None for
    any other path."""
    max_seconds = FIFO_WAIT_S if max_seconds is None else max_seconds
    try:
        if not stat.S_ISFIFO(os.stat(path).st_mode):
            return None
    except OSError:
        return None  # the reader names a missing or unreadable file itself
    opened: list[int] = []
    lock = threading.Lock()
    gave_up = threading.Event()

    def wait():  # a blocking open returns once a writer has opened the FIFO
        try:
            fd = os.open(path, os.O_RDONLY)
        except OSError:
            return
        with lock:
            if gave_up.is_set():  # too late: let the writer see no reader of ours
                os.close(fd)
            else:
                opened.append(fd)

    waiter = threading.Thread(target=wait, daemon=True)
    waiter.start()
    waiter.join(max_seconds)
    with lock:
        if not opened:
            gave_up.set()
            raise CliError(f"{path}: a FIFO that no writer opened within {max_seconds:g} s; "
                           "stopped")
    return os.fdopen(opened[0], "rb")
