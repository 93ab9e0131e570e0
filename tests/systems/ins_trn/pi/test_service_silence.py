"""The Pi's TRN service drops a silent PS (issue 27): a client whose hello gives its heartbeat
period and then sends nothing for ``silent_periods`` of them is dropped and counted, and the
next client connects; a client without heartbeats is never dropped for silence. Over
loopback, with bounded waits."""

from __future__ import annotations

import os
import socket
import time

import pytest

from navgate.systems.ins_trn.link import frames, messages
from navgate.systems.ins_trn.link.transport import LinkClosed, from_socket
from navgate.systems.ins_trn.pi.service import TrnService
from navgate.trn.dem import Dem

PERIOD = 0.05  # the client's heartbeat period (s)
PERIODS = 4  # silence limit: 0.2 s


def _client(spec: str, heartbeat_s: float | None):
    host, port = spec.removeprefix("tcp://").rsplit(":", 1)
    link = from_socket(socket.create_connection((host, int(port)), timeout=5))
    body = {"client": "test", "version": frames.VERSION, "session": f"s{heartbeat_s}"}
    if heartbeat_s is not None:
        body["heartbeat_s"] = heartbeat_s
    link.send(messages.HELLO, 1, body)
    reply = link.recv(5.0)
    assert reply is not None and reply.kind == messages.CAPABILITIES
    return link


def _closed_within(link, seconds: float) -> float | None:
    """Seconds until the service closed the link (None if it did not within ``seconds``)."""
    start = time.monotonic()
    while time.monotonic() - start < seconds:
        try:
            frame = link.recv(0.05)
        except LinkClosed:
            return time.monotonic() - start
        assert frame is None
    return None


def test_a_silent_ps_is_dropped_and_counted_and_the_next_one_connects():
    service = TrnService(Dem.default(), log=lambda line: None, silent_periods=PERIODS)
    thread, spec = service.start_tcp()
    try:
        first = _client(spec, PERIOD)
        # alive: a heartbeat every period for 0.5 s (2.5 limits): never dropped
        for seq in range(2, 12):
            first.send(messages.HEARTBEAT, seq, {"time": 0.0})
            assert first.recv(2.0).kind == messages.HEARTBEAT
            time.sleep(PERIOD)
        # garbage every period for 0.5 s (bad frames, counted): something, so not silence
        bad = service.counters["bad_frames"]
        for _ in range(10):
            os.write(first.fd, b"\x13\x37 not a frame\x00")
            assert first.recv(PERIOD) is None
        assert service.counters["silent_clients_dropped"] == 0
        assert service.counters["bad_frames"] >= bad + 5
        # silent: dropped once the limit (0.2 s) has passed, within one poll of the service
        waited = _closed_within(first, 3.0)
        assert waited is not None and PERIOD * PERIODS - 0.05 <= waited <= 1.0, waited
        assert service.counters["silent_clients_dropped"] == 1
        first.close()
        # the next client connects, and one that sends no heartbeat period is never dropped
        second = _client(spec, None)
        assert _closed_within(second, 0.8) is None
        second.send(messages.STATUS_REQUEST, 2, {})
        status = second.recv(2.0)
        assert status.kind == messages.STATUS
        assert status.body["clients"] == 2 and status.body["silent_clients_dropped"] == 1
        second.close()
        # so is one whose period is 0 (heartbeats off)
        third = _client(spec, 0.0)
        assert _closed_within(third, 0.5) is None
        third.close()
    finally:
        service.stop.set()
        thread.join(10)
    assert not thread.is_alive()
    assert service.counters["silent_clients_dropped"] == 1


def test_silent_periods_zero_never_drops_and_negative_is_refused():
    service = TrnService(Dem.default(), log=lambda line: None, silent_periods=0)
    thread, spec = service.start_tcp()
    try:
        link = _client(spec, PERIOD)
        assert _closed_within(link, 0.5) is None
        link.close()
    finally:
        service.stop.set()
        thread.join(10)
    assert service.counters["silent_clients_dropped"] == 0
    with pytest.raises(ValueError, match="silent_periods"):
        TrnService(Dem.default(), silent_periods=-1)


def test_trn_serve_silent_periods_out_of_range_is_one_line(capsys):
    from navgate.cli import main

    with pytest.raises(SystemExit) as exit_:
        main(["trn-serve", "--silent-periods", "-1", "--listen", "tcp://127.0.0.1:0"])
    err = capsys.readouterr().err.strip().splitlines()
    assert exit_.value.code == 2 and len(err) == 1 and "--silent-periods" in err[0], err
