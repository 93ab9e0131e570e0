"""The Raspberry Pi 5's TRN service of seed 000: terrain correlation on request over the link.

Seed 000 ("System Overview", "Data Flow") gives terrain correlation to a companion Pi 5 with a
DTED cache, talking to the Zynq's PS over SPI or USB. This service holds the terrain (one DEM
or a tile directory, :func:`navgate.trn.tiles.load_terrain`) and the correlators (PMF or
TERCOM, :mod:`navgate.trn`), and answers each profile request with a fix
(:mod:`navgate.systems.ins_trn.link.messages`).

Who owns what: the PS owns the navigation filter, its chi-square gate and the integrity
monitor, because they act on the filter's state (inflating P, counting gated fixes) and must
survive a Pi that reboots. The correlator's two state words (``used_until``, ``widen``) travel
in each request and come back with the fix. The service is therefore stateless between
requests apart from its counters and its terrain cache: a restarted service answers exactly as
the one before it, and a flight over the link equals the flight in one process.

Clients: one at a time (the seed draws one PS); a second client waits in the listen backlog
until the first disconnects. Every request logs one line on stderr; SIGTERM and SIGINT stop
the service cleanly after the request in hand; a status request returns the counters.
Heartbeats are answered at once and counted (``heartbeats``); the first of each client is
logged, and the count when the client goes.

A silent PS: a PS whose hello gives its heartbeat period (``heartbeat_s``; it sends
something at least that often) and then sends nothing for ``silent_periods`` of them (default
5; the bytes of a bad frame count as something; the silence counts from when the service
listens again after an answer) is dropped, counted (``silent_clients_dropped``) and logged,
so that the next client can connect (TCP) or say hello (a serial line, served on). A PS
without heartbeats (0, or an older PS that does not say) is never dropped for silence.
"""

from __future__ import annotations

import json
import math
import signal
import socket
import sys
import threading
import time
from dataclasses import fields

from navgate.systems.ins_trn.link import frames, messages
from navgate.systems.ins_trn.link.transport import LinkClosed, Transport, from_socket

#: how often a blocked read wakes up to look at the stop flag (s)
POLL_S = 0.2
#: PS sessions whose kept fragments and fixes the service remembers
SESSIONS_KEPT = 4
#: heartbeat periods of silence after which a PS is dropped
SILENT_PERIODS = 5


def _config(cls, values: dict):
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(values) - known)
    if unknown:
        raise messages.MessageError(f"unknown {cls.__name__} fields {unknown}")
    return cls(**values)


class TrnService:
    """Answers link messages; :meth:`serve` runs it over one transport."""

    def __init__(self, terrain, *, log=None, latency_s: float = 0.0,
                 silent_periods: int = SILENT_PERIODS):
        self.terrain = terrain
        if silent_periods < 0:
            raise ValueError(f"silent_periods must be >= 0, got {silent_periods}")
        self.silent_periods = int(silent_periods)
        #: the client's silence limit (s), from its hello's heartbeat period (None: no limit)
        self._silence_s: float | None = None
        #: fault injection: a slow Pi answers each profile request this much later (s)
        self.latency_s = float(latency_s)
        self.log = log if log is not None else (lambda line: print(line, file=sys.stderr,
                                                                   flush=True))
        self.stop = threading.Event()
        self.started = time.time()
        self.counters = {"clients": 0, "requests": 0, "fixes_accepted": 0,
                         "fixes_rejected": 0, "errors": 0, "bad_frames": 0,
                         "heartbeats": 0, "status_requests": 0, "silent_clients_dropped": 0}
        self._correlators: dict = {}
        self._reassembly = messages.Reassembly()
        self._sessions: dict[str, messages.Reassembly] = {}
        self._client_heartbeats = 0

    # -- requests ---------------------------------------------------------------------------
    def _correlator(self, method: str, config: dict, tangent):
        from navgate.nav.earth import LocalTangent
        from navgate.trn.correlators import METHODS, make_correlator
        from navgate.trn.pmf import PmfConfig
        from navgate.trn.tercom import TercomConfig

        if method not in METHODS:
            raise messages.MessageError(f"unknown TRN method {method!r}")
        key = (method, json.dumps(config, sort_keys=True), tuple(tangent))
        if key not in self._correlators:
            cls = PmfConfig if method == "pmf" else TercomConfig
            conf = _config(cls, config)
            self._correlators[key] = make_correlator(
                method, self.terrain, LocalTangent(*tangent),
                tercom=conf if method == "tercom" else None,
                pmf=conf if method == "pmf" else None)
        return self._correlators[key]

    def correlate(self, body) -> dict:
        """A profile request's body -> the fix's body (MessageError if malformed)."""
        from navgate.trn.profile import ProfileSnapshot

        start = time.perf_counter()
        req = messages.read_profile_request(body)
        corr = self._correlator(req["method"], req["config"], req["tangent"])
        if hasattr(corr, "used_until"):
            corr.used_until = req["used_until"]
            corr.widen = req["widen"]
        snapshot = ProfileSnapshot(h_terrain=req["h_terrain"], pos_n=req["pos_n"],
                                   pos_e=req["pos_e"], time=req["time"])
        result = corr.correlate(snapshot, req["sigma_max"], prior_cov=req["prior_cov"])
        return messages.fix_body(req["id"], result, getattr(corr, "used_until", -math.inf),
                                 getattr(corr, "widen", 1.0), time.perf_counter() - start)

    def status(self) -> dict:
        out = dict(self.counters)
        out["uptime_s"] = time.time() - self.started
        out["terrain"] = getattr(self.terrain, "name", "dem")
        if hasattr(self.terrain, "stats"):
            out["tile_store"] = self.terrain.stats()
        return out

    def capabilities(self) -> dict:
        from navgate.trn.correlators import METHODS

        return {"methods": list(METHODS), "terrain": getattr(self.terrain, "name", "dem"),
                "posts": list(self.terrain.shape), "version": frames.VERSION,
                "clients": "one at a time"}

    def handle(self, frame: frames.Frame) -> tuple[int, dict] | None:
        """The answer to one frame (kind, body), or None for none."""
        kind = frame.kind
        if kind == messages.HELLO:
            # a PS session (its request ids start at 1) keeps its own fragments and fixes: a
            # PS that reconnects names its session again and finds them; another session (a
            # new PS, or one restarted on a serial line that keeps one serve()) starts afresh
            body = frame.body if isinstance(frame.body, dict) else {}
            session = body.get("session")
            if isinstance(session, str) and session:
                self._reassembly = self._sessions.pop(session, None) or messages.Reassembly()
                self._sessions[session] = self._reassembly
                while len(self._sessions) > SESSIONS_KEPT:
                    self._sessions.pop(next(iter(self._sessions)))
            else:
                self._reassembly = messages.Reassembly()
            period = body.get("heartbeat_s")
            self._silence_s = None
            if (isinstance(period, (int, float)) and not isinstance(period, bool)
                    and math.isfinite(period) and period > 0 and self.silent_periods):
                self._silence_s = self.silent_periods * float(period)
            self.log(f"trn-serve: hello from {body.get('client', '?')}")
            return messages.CAPABILITIES, self.capabilities()
        if kind == messages.HEARTBEAT:
            self.counters["heartbeats"] += 1
            self._client_heartbeats += 1
            if self._client_heartbeats == 1:  # one line, not one a second for hours
                self.log("trn-serve: heartbeats from the client (answered; counted in status)")
            return messages.HEARTBEAT, {"time": time.time()}
        if kind == messages.STATUS_REQUEST:
            self.counters["status_requests"] += 1
            return messages.STATUS, self.status()
        if kind == messages.PROFILE_FRAGMENT:
            try:
                state, value = self._reassembly.add(frame.body)
            except messages.MessageError as error:
                self.counters["errors"] += 1
                return messages.ERROR, {"id": None, "error": str(error)}
            if state == "partial":
                return None
            if state == "answered":
                self.counters["fixes_resent"] = self.counters.get("fixes_resent", 0) + 1
                return value
            answer = self.handle(frames.Frame(messages.PROFILE_REQUEST, frame.seq, value))
            rid = value.get("id") if isinstance(value, dict) else None
            if rid is not None:
                self._reassembly.remember(int(rid), answer)
            return answer
        if kind == messages.PROFILE_REQUEST:
            self.counters["requests"] += 1
            if self.latency_s > 0:
                time.sleep(self.latency_s)
            try:
                body = self.correlate(frame.body)
            except (messages.MessageError, ValueError) as error:
                self.counters["errors"] += 1
                rid = frame.body.get("id") if isinstance(frame.body, dict) else None
                self.log(f"trn-serve: request {rid}: refused: {error}")
                return messages.ERROR, {"id": rid, "error": str(error)}
            r = body["result"]
            self.counters["fixes_accepted" if r["accepted"] else "fixes_rejected"] += 1
            self.log(f"trn-serve: request {body['id']} t={r['time']:.2f} s "
                     f"{'fix' if r['accepted'] else 'no fix: ' + str(r['reason'])} "
                     f"({1e3 * body['service_time_s']:.1f} ms)")
            return messages.FIX, body
        self.counters["errors"] += 1
        return messages.ERROR, {"id": None, "error": f"unknown message type {kind}"}

    # -- the loop ---------------------------------------------------------------------------
    def serve(self, link: Transport, max_requests: int | None = None) -> bool:
        """Answer frames on ``link`` until the peer closes it, the stop flag is set,
        ``max_requests`` profile requests have been answered, or the client falls silent
        (module docstring); True in the last case (the link may serve the next client)."""
        self.counters["clients"] += 1
        self._client_heartbeats = 0
        self._silence_s = None  # until the client's hello gives its heartbeat period
        heard = time.monotonic()
        got_bytes = getattr(link, "received_bytes", 0)
        self._reassembly = messages.Reassembly()  # until the client's hello names its session
        bad_base = self.counters["bad_frames"] - sum(link.decoder.bad.values())
        try:
            while not self.stop.is_set():
                try:
                    frame = link.recv(POLL_S)
                except frames.VersionMismatch as error:
                    self.counters["errors"] += 1
                    self.log(f"trn-serve: peer speaks another protocol version ({error})")
                    link.send(messages.ERROR, 0, {"id": None, "error":
                                                  f"protocol version {frames.VERSION} only"})
                    return False
                finally:  # counted as they happen, so a status request sees them
                    self.counters["bad_frames"] = bad_base + sum(link.decoder.bad.values())
                now = time.monotonic()
                got = getattr(link, "received_bytes", 0)
                if got != got_bytes:  # any byte, even of a frame that was bad, is not silence
                    heard, got_bytes = now, got
                if frame is None:
                    if self._silence_s is not None and now - heard > self._silence_s:
                        self.counters["silent_clients_dropped"] += 1
                        self.log(f"trn-serve: client silent for {now - heard:.1f} s "
                                 f"({self.silent_periods} heartbeat periods): dropped")
                        return True
                    continue
                heard = now
                answer = self.handle(frame)
                if answer is not None:
                    link.send(answer[0], frame.seq, answer[1])
                heard = time.monotonic()  # silence counts from when the service listens again
                if max_requests is not None and self.counters["requests"] >= max_requests:
                    return False
        except (LinkClosed, BrokenPipeError, ConnectionResetError):
            self.log(f"trn-serve: client closed the link "
                     f"({self._client_heartbeats} heartbeats answered)")
        finally:
            self.counters["bad_frames"] = bad_base + sum(link.decoder.bad.values())
        return False

    def serve_tcp(self, host: str, port: int, *, ready=None, max_requests=None) -> None:
        """Listen on host:port; one client at a time until stopped."""
        server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            server.bind((host, port))
            server.listen(4)
            server.settimeout(POLL_S)
            if ready is not None:
                ready(server.getsockname())
            self.log(f"trn-serve: listening on tcp://{host}:{server.getsockname()[1]}")
            while not self.stop.is_set():
                try:
                    sock, peer = server.accept()
                except TimeoutError:
                    continue
                sock.settimeout(None)
                self.log(f"trn-serve: client {peer[0]}:{peer[1]}")
                link = from_socket(sock)
                try:
                    self.serve(link, max_requests)
                finally:
                    link.close()
                if max_requests is not None and self.counters["requests"] >= max_requests:
                    return
        finally:
            server.close()

    def start_tcp(self, host: str = "127.0.0.1", port: int = 0, *,
                  max_requests: int | None = None, timeout_s: float = 10.0):
        """:meth:`serve_tcp` in a daemon thread, for a PS and a Pi in one process (tests,
        benchmarks); returns the thread and the ``tcp://HOST:PORT`` it listens on."""
        ready = threading.Event()
        address = []
        thread = threading.Thread(
            target=self.serve_tcp, args=(host, port), daemon=True,
            kwargs={"ready": lambda a: (address.append(a), ready.set()),
                    "max_requests": max_requests})
        thread.start()
        if not ready.wait(timeout_s):
            raise OSError(f"the TRN service did not start listening on {host}:{port}")
        return thread, f"tcp://{address[0][0]}:{address[0][1]}"

    def stop_on_signals(self) -> None:
        """SIGTERM / SIGINT set the stop flag (the loop ends after the request in hand)."""
        def handler(signum, _frame):
            self.log(f"trn-serve: {signal.Signals(signum).name}: stopping")
            self.stop.set()

        signal.signal(signal.SIGTERM, handler)
        signal.signal(signal.SIGINT, handler)
