"""Transports for the link: a byte stream (TCP socket, pseudo-terminal or serial port) carrying
frames (link.frames), with a timeout on every read and an optional fault injector on the
sending side.

Serial ports use pyserial, imported only when a serial port is opened.
"""

from __future__ import annotations

import os
import re
import select
import socket
import time

from navgate.systems.ins_trn.link import frames
from navgate.systems.ins_trn.link.faults import FaultInjector


class LinkClosed(Exception):
    """The peer closed the stream."""


class Transport:
    """Frames over a readable/writable file descriptor."""

    def __init__(self, fd: int, *, closer=None, faults: FaultInjector | None = None):
        self.fd = fd
        self._closer = closer
        self.faults = faults
        self.decoder = frames.Decoder()
        self.sent_bytes = 0
        self.received_bytes = 0
        self._pending: list[frames.Frame] = []

    def send(self, kind: int, seq: int, body: object) -> None:
        wire = frames.encode(kind, seq, body)
        for chunk in self.faults(wire) if self.faults else [wire]:
            view = memoryview(chunk)
            while view:
                n = os.write(self.fd, view)
                view = view[n:]
                self.sent_bytes += n

    def recv(self, timeout: float) -> frames.Frame | None:
        """The next good frame, or None when none arrived within ``timeout`` seconds."""
        deadline = time.monotonic() + timeout
        while not self._pending:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            ready, _, _ = select.select([self.fd], [], [], left)
            if not ready:
                return None
            try:
                data = os.read(self.fd, 65536)
            except OSError as exc:  # a pty whose other side closed reads EIO
                raise LinkClosed(str(exc)) from exc
            if not data:
                raise LinkClosed("peer closed the stream")
            self.received_bytes += len(data)
            self._pending += self.decoder.feed(data)
        return self._pending.pop(0)

    def close(self) -> None:
        if self._closer is not None:
            self._closer()
            self._closer = None


def parse_tcp(spec: str) -> tuple[str, int] | None:
    """``tcp://HOST:PORT`` -> (host, port) with 0 <= port <= 65535; None for anything else."""
    m = re.fullmatch(r"tcp://([^:/]+):(\d{1,5})", spec)
    if m is None or int(m.group(2)) > 65535:
        return None
    return m.group(1), int(m.group(2))


def from_socket(sock: socket.socket, **kw) -> Transport:
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return Transport(sock.fileno(), closer=sock.close, **kw)


def connect_tcp(host: str, port: int, timeout: float = 2.0, **kw) -> Transport:
    return from_socket(socket.create_connection((host, port), timeout=timeout), **kw)


def open_serial(port: str, baud: int, **kw) -> Transport:
    import serial  # lazily: only serial links need pyserial

    ser = serial.Serial(port, baud, timeout=0)
    return Transport(ser.fileno(), closer=ser.close, **kw)


def pty_pair(**kw) -> tuple[Transport, Transport]:
    """Two ends of a raw pseudo-terminal (for `spawn` and tests)."""
    import tty

    controller, terminal = os.openpty()
    tty.setraw(terminal)
    return (Transport(controller, closer=lambda: os.close(controller), **kw),
            Transport(terminal, closer=lambda: os.close(terminal)))
