"""Seed 000's PS <-> Pi link (docs/seed000-link.md): round-trip latency of a profile request
-> fix over TCP on 127.0.0.1, over a pseudo-terminal, and over a pseudo-terminal opened by
pyserial at 921,600 baud (with the time the same bytes take on a real 921,600-baud UART added),
and the bytes each request costs.

The service (:class:`navgate.systems.ins_trn.pi.service.TrnService`) runs in a thread on the
same machine, so the figures are the protocol's and the correlator's own cost, not a real
wire's: docs/seed000-link.md turns the bytes into time on a Pi 5's USB or SPI link. The
profiles are those of the default flight's first ``REQUESTS`` PMF fix attempts (the real
request sizes). Prints a table; writes ``navgate-out/bench/bench_link.json``.

    python benchmarks/bench_link.py [REQUESTS]      (about 20 s)
"""

from __future__ import annotations

import json
import sys
import threading
import time
from pathlib import Path

import numpy as np

from navgate.sim.flight import FlightConfig
from navgate.systems.ins_trn.link import messages
from navgate.systems.ins_trn.link.transport import pty_pair
from navgate.systems.ins_trn.pi.service import TrnService
from navgate.systems.ins_trn.ps import flight
from navgate.systems.ins_trn.ps.trn_link import TrnLink
from navgate.trn.dem import Dem


def requests_of_a_flight(n: int) -> list[dict]:
    """Profile requests of a real flight (captured through a TCP service)."""
    dem = Dem.default()
    cfg = FlightConfig(duration_s=120.0 + 5.0 * n)
    _, _, stream = flight.record_stream(dem, cfg)
    service = TrnService(dem, log=lambda line: None)
    captured = []
    original = service.correlate

    def capture(body):
        captured.append(body)
        return original(body)

    service.correlate = capture
    thread, spec = service.start_tcp()
    with TrnLink(spec) as link:
        flight.fly_stream(stream, dem, cfg, trn_link=link)
    service.stop.set()
    thread.join(10)
    return captured[:n]


BAUD = 921600


def measure(link_factory, bodies, service, keep=False) -> dict:
    link = link_factory()
    times, sent, received = [], [], []
    for body in bodies:
        s0, r0 = link.sent_bytes, link.received_bytes
        t0 = time.perf_counter()
        for piece in messages.fragments(body["id"], body):  # as the PS sends it
            link.send(messages.PROFILE_FRAGMENT, piece["index"], piece)
        while True:
            frame = link.recv(30)
            if frame is not None and frame.kind == messages.FIX:
                break
        times.append(time.perf_counter() - t0)
        sent.append(link.sent_bytes - s0)
        received.append(link.received_bytes - r0)
    link.close()
    t = np.array(times) * 1e3
    out = {"median_ms": float(np.median(t)), "p99_ms": float(np.percentile(t, 99)),
           "max_ms": float(t.max()), "request_bytes": float(np.mean(sent)),
           "fix_bytes": float(np.mean(received)), "requests": len(times)}
    if keep:  # each round trip's time and bytes (both ways)
        out["times_ms"] = t.tolist()
        out["bytes"] = (np.array(sent) + np.array(received)).tolist()
    return out


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 40
    bodies = requests_of_a_flight(n)
    dem = Dem.default()
    rows = {}
    # in-process correlation of the same requests: the floor the link adds to
    service = TrnService(dem, log=lambda line: None)
    for body in bodies:  # warm the correlator kernels
        service.correlate(body)
    t = []
    for body in bodies:
        t0 = time.perf_counter()
        service.correlate(body)
        t.append(time.perf_counter() - t0)
    rows["in-process correlation"] = {"median_ms": float(np.median(t) * 1e3),
                                      "p99_ms": float(np.percentile(t, 99) * 1e3)}

    # TCP on loopback
    import socket

    from navgate.systems.ins_trn.link.transport import from_socket

    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]
    svc = TrnService(dem, log=lambda line: None)

    def serve_one():
        sock, _ = server.accept()
        svc.serve(from_socket(sock))

    th = threading.Thread(target=serve_one, daemon=True)
    th.start()
    rows["TCP 127.0.0.1"] = measure(
        lambda: from_socket(socket.create_connection(("127.0.0.1", port))), bodies, svc)
    th.join(5)
    server.close()

    # pseudo-terminal (raw; no baud limit applies to a pty)
    ps_end, pi_end = pty_pair()
    svc2 = TrnService(dem, log=lambda line: None)
    th = threading.Thread(target=svc2.serve, args=(pi_end,), daemon=True)
    th.start()
    rows["pseudo-terminal"] = measure(lambda: ps_end, bodies, svc2)
    svc2.stop.set()
    th.join(5)

    # the service's end opened by pyserial at 921,600 baud (as trn-serve --serial does); a
    # pseudo-terminal carries bytes at memory speed whatever the baud, so the row after it
    # adds the time the same bytes take on a real 921,600-baud UART (10 bits a byte, 8N1)
    try:
        import serial  # noqa: F401
    except ImportError:
        print('(no pyserial: the serial rows need pip install "navgate[serial]")')
    else:
        import os
        import tty

        from navgate.systems.ins_trn.link.transport import Transport, open_serial

        controller, terminal = os.openpty()
        tty.setraw(terminal)
        pi_serial = open_serial(os.ttyname(terminal), BAUD)
        svc3 = TrnService(dem, log=lambda line: None)
        th = threading.Thread(target=svc3.serve, args=(pi_serial,), daemon=True)
        th.start()
        row = measure(lambda: Transport(controller), bodies, svc3, keep=True)
        svc3.stop.set()
        th.join(5)
        pi_serial.close()
        os.close(terminal)
        os.close(controller)
        rows[f"pyserial pty {BAUD} Bd"] = {k: v for k, v in row.items() if k != "times_ms"}
        wire = (np.array(row["bytes"]) * 10 / BAUD * 1e3)
        t = np.array(row["times_ms"]) + wire
        rows[f"+ {BAUD} Bd UART wire"] = {
            "median_ms": float(np.median(t)), "p99_ms": float(np.percentile(t, 99)),
            "request_bytes": row["request_bytes"], "fix_bytes": row["fix_bytes"]}
        for r in rows.values():
            r.pop("bytes", None)

    print(f"{'path':<26}{'median ms':>11}{'p99 ms':>9}{'req B':>8}{'fix B':>8}")
    for name, r in rows.items():
        nan = float("nan")
        print(f"{name:<26}{r['median_ms']:>11.2f}{r['p99_ms']:>9.2f}"
              f"{r.get('request_bytes', nan):>8.0f}{r.get('fix_bytes', nan):>8.0f}")
    req = rows["TCP 127.0.0.1"]["request_bytes"] + rows["TCP 127.0.0.1"]["fix_bytes"]
    print(f"\nbytes per round trip {req:.0f}: on a wire that is "
          f"{req * 10 / 921600 * 1e3:.1f} ms at 921,600 baud (8N1), "
          f"{req * 8 / 10e6 * 1e3:.2f} ms on 10 MHz SPI, "
          f"{req * 8 / 480e6 * 1e3:.3f} ms of USB 2.0 high-speed payload")
    out = Path("navgate-out/bench")
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench_link.json").write_text(json.dumps(rows, indent=2))


if __name__ == "__main__":
    main()
