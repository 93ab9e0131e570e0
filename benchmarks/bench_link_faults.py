"""A 10-minute flight over a faulty PS <-> Pi link against the clean link (issue 27's fault
target): 1e-3 bit flips per byte on every frame the PS sends, one 20 s link drop and one
service restart. Prints the second-half RMS of both runs, their ratio, and every fault and
recovery counted; writes ``navgate-out/bench/bench_link_faults.json``.

The service runs in a thread on 127.0.0.1 (the Pi); the drop is a window of simulated flight
time during which every byte the PS sends is lost; the restart is the service stopping after
``RESTART_AFTER`` requests and a new one starting on the same port, as a rebooted Pi would.

    python benchmarks/bench_link_faults.py [DURATION_S] [FLIP_RATE]   (about a minute)
"""

from __future__ import annotations

import json
import socket
import sys
import threading
import time
from pathlib import Path

import numpy as np

from navgate.sim.flight import FlightConfig, score
from navgate.systems.ins_trn.link.faults import FaultInjector
from navgate.systems.ins_trn.pi.service import TrnService
from navgate.systems.ins_trn.ps import flight
from navgate.systems.ins_trn.ps.trn_link import TrnLink
from navgate.trn.dem import Dem

DROP = (200.0, 220.0)  #: flight seconds during which the link carries nothing
RESTART_AFTER = 15  #: the service stops after this many requests and comes back


class Pi:
    def __init__(self, dem, port, max_requests=None):
        self.service = TrnService(dem, log=lambda line: None)
        self.thread, _ = self.service.start_tcp(port=port, max_requests=max_requests)


class DroppingLink(TrnLink):
    """Loses every byte it sends while the request's flight time is inside DROP."""

    def request(self, body):
        self.faults.drop = DROP[0] <= body["t_request"] < DROP[1]
        return super().request(body)


def main():
    duration = float(sys.argv[1]) if len(sys.argv) > 1 else 600.0
    flip = float(sys.argv[2]) if len(sys.argv) > 2 else 1e-3
    dem = Dem.default()
    cfg = FlightConfig(duration_s=duration)
    route, data, stream = flight.record_stream(dem, cfg)
    log_every = max(1, int(round(cfg.imu_rate_hz / cfg.log_rate_hz)))
    clean = flight.fly_stream(stream, dem, cfg)["trn_aided"]
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    first = Pi(dem, port, max_requests=RESTART_AFTER)
    later = []

    def reboot():
        first.thread.join()
        time.sleep(0.5)
        later.append(Pi(dem, port))

    threading.Thread(target=reboot, daemon=True).start()
    faults = FaultInjector(seed=1, flip_rate=flip)
    start = time.perf_counter()
    with DroppingLink(f"tcp://127.0.0.1:{port}", timeout_s=0.2, retries=3,
                      faults=faults) as link:
        faulty = flight.fly_stream(stream, dem, cfg, trn_link=link)["trn_aided"]
        stats = link.stats()
    wall = time.perf_counter() - start
    service_bad = first.service.counters["bad_frames"] + sum(
        p.service.counters["bad_frames"] for p in later)
    for p in later:
        p.service.stop.set()
    s_clean = score(clean, data.truth, log_every).summary(clean.t)
    s_faulty = score(faulty, data.truth, log_every).summary(faulty.t)
    key = "rms_horizontal_error_second_half_m"
    applied = [f["time_s"] for f in faulty.fixes if f["applied"]]
    rows = {
        "flight (s)": duration, "flip rate per byte": flip,
        "clean RMS 2nd half (m)": s_clean[key], "faulty RMS 2nd half (m)": s_faulty[key],
        "ratio": s_faulty[key] / s_clean[key],
        "fixes applied clean / faulty": f"{sum(f['applied'] for f in clean.fixes)} / "
                                        f"{len(applied)}",
        "fix applied twice": len(applied) - len(set(applied)),
        "requests": stats["requests"], "replies": stats["replies"],
        "timeouts": stats["timeouts"], "retries": stats["retries"],
        "reconnects": stats["reconnects"], "unavailable": stats["unavailable"],
        "frames corrupted (injected)": faults.counts.get("corrupted_frames", 0),
        "frames dropped (injected)": faults.counts.get("dropped", 0),
        "bad frames counted by the service": service_bad,
        "service restarts": len(later), "final position finite": bool(
            np.all(np.isfinite(faulty.nav[-1]))),
        "wall (s)": wall,
    }
    for k, v in rows.items():
        print(f"{k:<36}{v if isinstance(v, str) else f'{v:.4g}':>14}")
    out = Path("navgate-out/bench")
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench_link_faults.json").write_text(json.dumps(rows, indent=2, default=str))


if __name__ == "__main__":
    main()
