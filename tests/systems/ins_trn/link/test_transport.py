"""Transports over 127.0.0.1 and a pty: frames arrive whole, reads time out, closes are seen."""

from __future__ import annotations

import socket
import threading

import pytest

from navgate.systems.ins_trn.link import transport
from navgate.systems.ins_trn.link.faults import FaultInjector


def _tcp_pair(**kw):
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    server.settimeout(2.0)
    client = transport.connect_tcp("127.0.0.1", server.getsockname()[1], **kw)
    conn, _ = server.accept()
    server.close()
    return client, transport.from_socket(conn)


@pytest.mark.parametrize("make", [_tcp_pair, transport.pty_pair], ids=["tcp", "pty"])
def test_exchange_and_timeout(make):
    a, b = make()
    try:
        big = {"profile": [float(i) for i in range(5000)]}
        # a pty buffers a few kB only: the sender writes while the receiver reads
        sender = threading.Thread(target=a.send, args=(1, 10, big), daemon=True)
        sender.start()
        frame = b.recv(2.0)
        sender.join(2.0)
        assert (frame.kind, frame.seq, frame.body) == (1, 10, big)
        b.send(2, 10, "fix")
        assert a.recv(2.0).body == "fix"
        assert b.recv(0.05) is None  # nothing sent: the read times out
        assert a.sent_bytes == b.received_bytes > 5000 * 9
    finally:
        a.close()
        b.close()


def test_tcp_close_and_faults():
    a, b = _tcp_pair(faults=FaultInjector(seed=0, drop=True))
    try:
        a.send(1, 1, "lost")
        assert b.recv(0.05) is None and a.faults.counts == {"dropped": 1}
        a.close()
        with pytest.raises(transport.LinkClosed):
            b.recv(2.0)
    finally:
        a.close()
        b.close()
