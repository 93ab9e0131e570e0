"""The PS's end of the link to the Pi's TRN service (seed 000 "Data Flow": the PS sends the
altitude profile to the Pi and applies the fix that comes back).

:class:`TrnLink` opens the link (``tcp://HOST:PORT``, ``serial:PORT[@BAUD]``, or ``spawn``:
``navgate trn-serve`` started as a child process on a pseudo-terminal, so one command shows
the three computers), says hello, and carries requests with a timeout and retries.
:class:`RemoteCorrelator` has the interface of the in-process correlators
(``correlate``, ``reinitialise``), so the navigator, its filter and its integrity monitor are
the same whichever side correlates.

When the service does not answer (absent at start, link dropped, Pi rebooting, corrupted
frames), a request ends after its retries with "no fix: TRN service unavailable": the flight
goes on INS-only with the barometer, nothing waits forever, and every such case is counted.
A reply for another request (late, duplicated, reordered) is counted and never applied.

Heartbeats (``heartbeat_s`` > 0): a thread sends one when nothing has been sent for that long;
a reply missed within ``timeout_s`` marks the link down (counted) and reconnecting starts
at once, not at the next fix. A lock gives the link to one user at a time.
"""

from __future__ import annotations

import math
import os
import re
import socket
import subprocess
import sys
import threading
import time
from dataclasses import asdict

import numpy as np

from navgate.systems.ins_trn.link import frames, messages
from navgate.systems.ins_trn.link.faults import FaultInjector
from navgate.systems.ins_trn.link.transport import (
    LinkClosed,
    Transport,
    connect_tcp,
    open_serial,
    parse_tcp,
    pty_pair,
)

UNAVAILABLE = "no fix: TRN service unavailable"
INVALID = "no fix: invalid fix from TRN service"
#: the child's start-up (imports, terrain, compiled kernels) may take this long (s)
SPAWN_HELLO_TIMEOUT_S = 120.0
#: hello is sent again this often until the service answers (s)
HELLO_RESEND_S = 1.0


class LinkError(Exception):
    """The link cannot be opened as asked (bad spec, refused connection, no such device,
    another protocol version): one line for the user."""


def parse_spec(spec: str) -> tuple:
    """``tcp://HOST:PORT`` -> ("tcp", host, port); ``serial:PORT[@BAUD]`` -> ("serial", port,
    baud); ``spawn`` -> ("spawn",)."""
    if spec == "spawn":
        return ("spawn",)
    address = parse_tcp(spec)
    if address is not None and address[1] > 0:
        return ("tcp", *address)
    m = re.fullmatch(r"serial:([^@]+)(?:@(\d+))?", spec)
    if m:
        return ("serial", m.group(1), int(m.group(2) or 921600))
    raise LinkError(f"--trn-service must be tcp://HOST:PORT, serial:PORT[@BAUD] or spawn, "
                    f"got {spec!r}")


#: the longest wait (reply timeout, heartbeat period) a link accepts, in seconds
MAX_WAIT_S = 3600.0


class TrnLink:
    """A connection to a TRN service, with counters for the flight's summary."""

    def __init__(self, spec: str, *, terrain_path=None, cache_mb: float | None = None,
                 timeout_s: float = 5.0, retries: int = 2, faults: FaultInjector | None = None,
                 fragment_bytes: int = messages.FRAGMENT_BYTES, heartbeat_s: float = 0.0):
        # at most an hour: a socket timeout of 1e10 s overflowed the platform's time_t
        if not (math.isfinite(timeout_s) and 0 < timeout_s <= MAX_WAIT_S):
            raise ValueError(f"timeout_s must lie in (0, {MAX_WAIT_S:g}] s, got {timeout_s!r}")
        if not (math.isfinite(heartbeat_s) and 0 <= heartbeat_s <= MAX_WAIT_S):
            raise ValueError(f"heartbeat_s must lie in [0, {MAX_WAIT_S:g}] s, got "
                             f"{heartbeat_s!r}")
        self.spec = spec
        self.kind = parse_spec(spec)
        self.terrain_path = terrain_path
        self.cache_mb = cache_mb
        self.timeout_s = timeout_s
        self.retries = int(retries)
        self.faults = faults
        self.fragment_bytes = int(fragment_bytes)  #: 0: one frame per request
        self.child: subprocess.Popen | None = None
        self.link: Transport | None = None
        self.seq = 0
        self.next_id = 1
        self.capabilities: dict = {}
        #: names this PS session in each hello (request ids start at 1 in each session): the
        #: service keeps a session's fragments and fixes across reconnects, not across sessions
        self.session = f"{socket.gethostname()}-{os.getpid()}-{time.time_ns()}"
        self.counters = {"absent_at_start": 0, "requests": 0, "replies": 0, "timeouts": 0,
                         "retries": 0,
                         "unavailable": 0, "stale_replies": 0, "service_errors": 0,
                         "reconnects": 0, "invalid_fixes": 0, "bad_frames": 0, "bytes_sent": 0,
                         "bytes_received": 0, "heartbeats_sent": 0, "heartbeat_replies": 0,
                         "heartbeats_missed": 0, "link_down": 0}
        #: one user of the link at a time: the flight's requests (the caller's thread or the
        #: realtime worker) and the heartbeat thread
        self._lock = threading.RLock()
        self._closing = threading.Event()
        self._last_sent = time.monotonic()
        self.heartbeat_s = float(heartbeat_s)
        self._heartbeat_thread = None
        #: a spawned service whose hello never completed (every frame corrupted): starting
        #: it again would not help, so it stays unavailable for the rest of the flight
        self._spawn_gave_up = False
        self._open(first=True)
        if self.heartbeat_s > 0:
            self._heartbeat_thread = threading.Thread(target=self._heartbeats, daemon=True,
                                                      name="trn-link-heartbeat")
            self._heartbeat_thread.start()

    # -- opening ----------------------------------------------------------------------------
    def _open(self, first: bool = False) -> None:
        kind = self.kind[0]
        try:
            if kind == "tcp":
                self.link = connect_tcp(self.kind[1], self.kind[2], timeout=self.timeout_s,
                                        faults=self.faults)
            elif kind == "serial":
                self.link = open_serial(self.kind[1], self.kind[2], faults=self.faults)
            else:
                self._spawn()
        except socket.gaierror as error:
            raise LinkError(f"cannot resolve {self.spec}: {error.strerror or error}") from None
        except ImportError:
            raise LinkError(f'--trn-service {self.spec} needs pyserial: pip install '
                            f'"navgate[serial]"') from None
        except (ConnectionRefusedError, TimeoutError):
            # absent (not started yet, rebooting): fly on INS-only, try again at the next fix
            if first:
                self.counters["absent_at_start"] = 1
            self.link = None
            return
        except OSError as error:
            raise LinkError(f"cannot open {self.spec}: {error.strerror or error}") from None
        self._hello(SPAWN_HELLO_TIMEOUT_S if kind == "spawn" else self.timeout_s, first)

    def _spawn(self) -> None:
        ps_end, pi_end = pty_pair(faults=self.faults)
        cmd = [sys.executable, "-m", "navgate.cli", "trn-serve", "--fd", str(pi_end.fd)]
        if self.terrain_path is not None:
            cmd += ["--tiles", str(self.terrain_path)]
        if self.cache_mb is not None:
            cmd += ["--cache-mb", repr(self.cache_mb)]
        self.child = subprocess.Popen(cmd, pass_fds=[pi_end.fd], stdin=subprocess.DEVNULL,
                                      stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL)
        pi_end.close()
        self.link = ps_end

    def _hello(self, timeout: float, first: bool) -> None:
        deadline = time.monotonic() + timeout
        resend = 0.0
        while time.monotonic() < deadline:
            if time.monotonic() >= resend:
                # again each second: a serial port opened after the hello was sent (the Pi
                # still booting) flushes what was waiting in its input
                self._send(messages.HELLO, {"client": "navgate ps", "version": frames.VERSION,
                                            "session": self.session,
                                            "heartbeat_s": self.heartbeat_s})
                resend = time.monotonic() + HELLO_RESEND_S
            try:
                frame = self.link.recv(min(0.5, max(deadline - time.monotonic(), 0.01)))
            except frames.VersionMismatch as error:
                raise LinkError(f"the TRN service at {self.spec} speaks another protocol "
                                f"version ({error})") from None
            except LinkClosed:
                break
            if frame is not None and frame.kind == messages.CAPABILITIES:
                self.capabilities = frame.body if isinstance(frame.body, dict) else {}
                return
            if frame is not None and frame.kind == messages.ERROR:
                raise LinkError(f"the TRN service refused the link: {frame.body}")
            if self.child is not None and self.child.poll() is not None:
                break
        if first:
            # there, but no hello completed (silent, or every frame corrupted): as an absent
            # service, the flight goes on INS-only, counted, and the link is tried again (a
            # spawned one is not: it is our own child, and it had its start-up time)
            self.counters["absent_at_start"] = 1
        self._spawn_gave_up = self.kind[0] == "spawn"
        self._drop()

    def _drop(self) -> None:
        if self.link is not None:
            self._account()
            self.link.close()
            self.link = None

    def _account(self) -> None:
        link = self.link
        self.counters["bad_frames"] += sum(link.decoder.bad.values())
        self.counters["bytes_sent"] += link.sent_bytes
        self.counters["bytes_received"] += link.received_bytes
        link.decoder.bad.clear()
        link.sent_bytes = link.received_bytes = 0

    def _send(self, kind: int, body) -> int:
        self.seq = (self.seq + 1) & 0xFFFF
        self._last_sent = time.monotonic()
        self.link.send(kind, self.seq, body)
        return self.seq

    # -- heartbeats -------------------------------------------------------------------------
    def _heartbeats(self) -> None:
        """The heartbeat thread: after ``heartbeat_s`` with nothing sent, a heartbeat; a
        missed reply marks the link down and reconnecting starts at once, so the link is up
        again (if the service is) before the next fix is due."""
        while not self._closing.wait(self.heartbeat_s / 4):
            if time.monotonic() - self._last_sent < self.heartbeat_s:
                continue
            if not self._lock.acquire(blocking=False):  # a request is in hand
                continue
            try:
                if self._closing.is_set():
                    return
                if self.link is None:
                    self._reconnect()
                elif not self._heartbeat():
                    self.counters["heartbeats_missed"] += 1
                    self.counters["link_down"] += 1
                    self._drop()
                    self._reconnect()
            except Exception:  # noqa: BLE001 - the thread must not die; the flight goes on
                self._drop()
            finally:
                self._lock.release()

    def _heartbeat(self) -> bool:
        """One heartbeat; True when the service answered within ``timeout_s``."""
        self.counters["heartbeats_sent"] += 1
        try:
            self._send(messages.HEARTBEAT, {"time": time.time()})
            deadline = time.monotonic() + self.timeout_s
            while (left := deadline - time.monotonic()) > 0:
                frame = self.link.recv(left)
                if frame is None:
                    continue
                if frame.kind == messages.HEARTBEAT:
                    self.counters["heartbeat_replies"] += 1
                    return True
                if frame.kind in (messages.FIX, messages.ERROR):
                    self.counters["stale_replies"] += 1
        except (LinkClosed, frames.VersionMismatch, OSError):
            pass
        return False

    def _spawn_stays(self) -> bool:
        """A spawned service is not started again: its child still runs, or it never
        completed a hello (:attr:`_spawn_gave_up`)."""
        return self.kind[0] == "spawn" and (self._spawn_gave_up or (
            self.child is not None and self.child.poll() is None))

    def _reconnect(self) -> None:
        """Open the link again (a spawned service: start a new one once the old has gone)."""
        self._last_sent = time.monotonic()  # one attempt per heartbeat period
        if self._spawn_stays():
            return
        self.counters["reconnects"] += 1
        try:
            self._open()
        except LinkError:
            self.link = None

    # -- requests ---------------------------------------------------------------------------
    def request(self, body: dict) -> dict | None:
        """Send a profile request; the fix body, or None when the service gave none."""
        with self._lock:
            return self._request(body)

    def _request(self, body: dict) -> dict | None:
        rid = body["id"]
        self.counters["requests"] += 1
        for attempt in range(self.retries + 1):
            if attempt:
                self.counters["retries"] += 1
            if self.link is None:
                if self._spawn_stays():
                    break
                self.counters["reconnects"] += 1
                self._open()
                if self.link is None:
                    continue
            try:
                if self.fragment_bytes:
                    for piece in messages.fragments(rid, body, self.fragment_bytes):
                        self._send(messages.PROFILE_FRAGMENT, piece)
                else:
                    self._send(messages.PROFILE_REQUEST, body)
                reply = self._await(rid)
            except (LinkClosed, BrokenPipeError, ConnectionResetError, OSError):
                self._drop()
                continue
            if reply is not None:
                return reply
        self.counters["unavailable"] += 1
        return None

    def _await(self, rid: int) -> dict | None:
        deadline = time.monotonic() + self.timeout_s
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                self.counters["timeouts"] += 1
                return None
            frame = self.link.recv(left)
            if frame is None:
                continue
            body = frame.body if isinstance(frame.body, dict) else {}
            if frame.kind == messages.FIX and body.get("id") == rid:
                self.counters["replies"] += 1
                return body
            if frame.kind == messages.ERROR and body.get("id") == rid:
                self.counters["service_errors"] += 1
                return None
            if frame.kind in (messages.FIX, messages.ERROR):
                self.counters["stale_replies"] += 1

    def status(self) -> dict | None:
        """The service's counters (a status request), or None without an answer."""
        with self._lock:
            if self.link is None:
                return None
            try:
                self._send(messages.STATUS_REQUEST, {})
                deadline = time.monotonic() + self.timeout_s
                while time.monotonic() < deadline:
                    frame = self.link.recv(deadline - time.monotonic())
                    if frame is not None and frame.kind == messages.STATUS:
                        return frame.body
            except (LinkClosed, OSError):
                self._drop()
            return None

    def correlator(self, trn, tangent) -> RemoteCorrelator:
        """The Pi's correlator for ``trn`` (the navigator's TrnSettings) at ``tangent``."""
        return RemoteCorrelator(self, trn.method, asdict(trn.correlator_config),
                                (tangent.lat0, tangent.lon0, tangent.h0))

    def new_id(self) -> int:
        rid = self.next_id
        self.next_id += 1
        return rid

    def stats(self) -> dict:
        with self._lock:
            if self.link is not None:
                self._account()
            out = dict(self.counters)
        out["heartbeat_s"] = self.heartbeat_s
        out["service"] = self.spec
        if self.faults is not None:
            out["injected_faults"] = dict(self.faults.counts)
        return out

    def close(self) -> None:
        self._closing.set()
        if self._heartbeat_thread is not None:
            self._heartbeat_thread.join()
            self._heartbeat_thread = None
        if self.link is not None:
            self._drop()
        if self.child is not None:
            if self.child.poll() is None:
                self.child.terminate()
                try:
                    self.child.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    self.child.kill()
                    self.child.wait()
            self.child = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class RemoteCorrelator:
    """A correlator whose work is done by the TRN service (the in-process interface)."""

    def __init__(self, link: TrnLink, method: str, config: dict, tangent):
        from navgate.trn.pmf import PmfResult
        from navgate.trn.tercom import TercomResult

        self.link = link
        self.method = method
        self.config = config
        self.tangent = tangent
        self.result_type = PmfResult if method == "pmf" else TercomResult
        self.used_until = -math.inf
        self.widen = 1.0

    def reinitialise(self, widen: float = 3.0):
        self.widen = max(self.widen, widen)

    def correlate(self, snapshot, sigma_max_m: float, prior_cov=None):
        now = float(snapshot.time[-1]) if len(snapshot) else math.nan
        body = messages.profile_request(
            self.link.new_id(), method=self.method, config=self.config, tangent=self.tangent,
            time=snapshot.time, pos_n=snapshot.pos_n, pos_e=snapshot.pos_e,
            h_terrain=snapshot.h_terrain, sigma_max=sigma_max_m, prior_cov=prior_cov,
            used_until=self.used_until, widen=self.widen, t_request=now)
        reply = self.link.request(body)
        if reply is None:
            return self.result_type(False, UNAVAILABLE, now)
        try:
            rid, result, used_until, widen = messages.read_fix(reply, self.result_type)
        except messages.MessageError:
            self.link.counters["service_errors"] += 1
            return self.result_type(False, UNAVAILABLE, now)
        if rid != body["id"] or not _same_time(result.time, now):
            # another request's fix (or, with the same id, another session's): never applied
            self.link.counters["stale_replies"] += 1
            return self.result_type(False, UNAVAILABLE, now)
        self.used_until, self.widen = used_until, widen
        if result.accepted and not _usable(result):
            self.link.counters["invalid_fixes"] += 1
            return self.result_type(False, INVALID, now)
        return result


def _same_time(a, b) -> bool:
    """The fix is stamped with its profile's last time tag (both NaN for an empty profile)."""
    try:
        a, b = float(a), float(b)
    except (TypeError, ValueError):
        return False
    return a == b or (math.isnan(a) and math.isnan(b))


def _usable(result) -> bool:
    """An accepted fix the filter can take: finite positions and lag, and a covariance that
    is finite, symmetric and positive definite (the chi-square gate judges the rest)."""
    values = (result.fix_n, result.fix_e, result.ins_n, result.ins_e, result.lag_s)
    if not all(isinstance(v, int | float) and math.isfinite(v) for v in values):
        return False
    cov = np.asarray(result.cov, float)
    if cov.shape != (2, 2) or not np.all(np.isfinite(cov)) or cov[0, 1] != cov[1, 0]:
        return False
    return bool(cov[0, 0] > 0 and np.linalg.det(cov) > 0)


__all__ = ["LinkError", "RemoteCorrelator", "TrnLink", "UNAVAILABLE", "parse_spec"]
