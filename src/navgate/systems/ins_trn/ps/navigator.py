"""Seed 000's navigator as a streaming system: the PS side over a PL engine.

Reference: seed 000 "System Architecture" / "Data Flow" (the PS runs the TRN correlation and
writes fixes; the PL runs calibration, mechanization, covariance propagation, the altitude
profile buffer and the Kalman update engine). The navigator consumes the sensor record stream
of :mod:`navgate.systems.ins_trn.ps.records` one record at a time (:meth:`Navigator.feed`) or a
whole stream (:meth:`Navigator.run`, which hands runs of consecutive IMU records to the engine
in one call with the same result; an engine with ``batch_records``, the float64 reference,
takes whole stretches of IMU and barometer records between the records the PS must see in one
compiled call, :meth:`PlEngine.run_records`, again with the same result) and talks to the PL
only through
:class:`navgate.systems.ins_trn.ps.pl_interface.PlEngine`:

- IMU record: ``engine.propagate`` (calibration, mechanization, covariance);
- barometer record: ``engine.update_altitude`` (an invalid sample is counted, not applied);
  the newest barometer altitude is kept for the profile;
- ranger record (TRN runs only): the profile consumer computes roll/pitch from the state
  registers and pushes the entry (``engine.profile_push``); on an accepted entry, when the
  fix schedule allows (one attempt per the TRN settings' ``fix_interval_s``,
  :class:`~navgate.systems.ins_trn.ps.trn_settings.TrnSettings`), the correlator runs on the
  profile snapshot with the search window from the horizontal covariance, and an accepted
  fix goes to ``engine.update_trn``; the applied correction shifts the stored profile. The
  correlator is in this process or, through a ``trn_link``
  (:mod:`navgate.systems.ins_trn.ps.trn_link`), on the Pi's TRN service; with
  ``trn_latency_s`` a fix is applied that long after its request (one request in flight),
  and dropped past ``trn_deadline_s``. In real-time mode (``realtime`` = speed factor,
  :mod:`navgate.systems.ins_trn.ps.realtime`) the stream is paced to the wall clock, the
  request goes to a worker thread, and its fix is applied through the same path at the first
  record after it arrives, its age added to the lag (not deterministic).
- logging: the state, the square roots of P's diagonal and P_NE are logged every
  ``imu_rate / log_rate`` IMU samples, after every record stamped at that time.
"""

from __future__ import annotations

import dataclasses
import math
import time as _time
from dataclasses import dataclass

import numpy as np

from navgate.nav import eskf
from navgate.nav.calibration import ImuCalibration
from navgate.nav.earth import LocalTangent
from navgate.sim import sensors
from navgate.systems.ins_trn.ps import pl_sensors
from navgate.systems.ins_trn.ps.pl_interface import EngineSetup, PlEngine, make_engine
from navgate.systems.ins_trn.ps.records import BARO, IMU, RANGER, RecordStream
from navgate.systems.ins_trn.ps.trn_settings import TrnSettings
from navgate.trn.profile import ACCEPTED


@dataclass
class NavRun:
    """Navigation output, logged at cfg.log_rate_hz."""

    name: str
    t: np.ndarray
    nav: np.ndarray  #: (M, 10)
    sigma: np.ndarray  #: (M, 15) square roots of P's diagonal
    p_ne: np.ndarray  #: (M,) P[0, 1]
    fixes: list  #: TercomResult rows (dicts) with "applied" and "nis"
    accepted: dict
    rejected: dict
    profile_counts: dict
    imu_samples_rejected: int
    wall_time_s: float
    engine: str = "reference"
    hardware: dict | None = None  #: the simulated PL's counts (PlEngine.hardware_stats)
    realtime: dict | None = None  #: real-time mode's figures (ps.realtime.Realtime.summary)


def make_correlator(trn: TrnSettings, dem, tangent):
    """The PS-side TRN correlator (the single call site of navgate.trn.correlators)."""
    from navgate.trn.correlators import make_correlator as _make

    return _make(trn.method, dem, tangent, trn.tercom, pmf=trn.pmf)


def engine_setup(header: dict, cfg) -> EngineSetup:
    """The engine's configuration from a stream header (see records.make_header)."""
    ideal = bool(header["ideal"])
    filter_cfg = eskf.FilterConfig.from_imu_spec(
        sensors.IDEAL_IMU if ideal else sensors.ADIS16500, rate_hz=cfg.imu_rate_hz,
        residual_accel_bias=cfg.init_accel_bias_sigma,
        residual_gyro_bias=cfg.init_gyro_bias_sigma)
    c = header["calibration"]
    cal = ImuCalibration(np.array(c["gyro_bias"]), np.array(c["gyro_matrix"]),
                         np.array(c["accel_bias"]), np.array(c["accel_matrix"]),
                         c["gyro_lsb"], c["accel_lsb"])
    ini = header["initial"]
    ref = header["reference"]
    return EngineSetup(cal, filter_cfg, cfg.imu_rate_hz, np.array(ini["nav"], float),
                       np.array(ini["p0"], float), np.array(ini["bias_a"], float),
                       np.array(ini["bias_g"], float),
                       LocalTangent(ref["lat_rad"], ref["lon_rad"], ref["h_m"]),
                       cfg.profile_spacing_m, float(header["t0"]))


class Navigator:
    """The PS side of seed 000 over one PL engine: ``cfg`` is the scenario (rates, ranger,
    profile spacing), ``trn`` the navigator's TRN settings (default :class:`TrnSettings`)."""

    def __init__(self, engine: PlEngine, cfg, *, t0: float, dem=None, use_trn: bool = True,
                 name: str = "nav", progress=None, trn_link=None,
                 trn_latency_s: float = 0.0, trn_deadline_s: float = 30.0,
                 realtime: float | None = None, trn: TrnSettings | None = None):
        self.engine = engine
        self.cfg = cfg
        if trn is None:
            trn = TrnSettings()
        if not isinstance(trn, TrnSettings):
            raise ValueError(f"trn must be TrnSettings, got {type(trn).__name__}")
        self.trn = trn
        self.use_trn = bool(use_trn) and dem is not None
        self.name = name
        self.progress = progress
        self.t0 = float(t0)
        self.dt = 1.0 / cfg.imu_rate_hz
        self.log_every = max(1, int(round(cfg.imu_rate_hz / cfg.log_rate_hz)))
        self.baro_sigma = max(sensors.Barometer(sensors.BMP390).altitude_noise_m, 0.05)
        self.ranger_unit = pl_sensors.ranger_unit(cfg.ranger)
        self.tangent = engine.setup.reference
        self.correlator = self.monitor = None
        if self.use_trn:  # the Pi's service over the link, or the correlator in this process
            from navgate.trn.correlators import make_monitor

            self.correlator = (trn_link.correlator(trn, self.tangent) if trn_link is not None
                               else make_correlator(trn, dem, self.tangent))
            self.monitor = make_monitor(self.correlator)
        for arg, value in (("trn_latency_s", trn_latency_s), ("trn_deadline_s", trn_deadline_s)):
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{arg} must be a finite number of seconds >= 0, got {value!r}")
        #: a fix is applied this long after its request (the link and the Pi's time), and
        #: dropped when that is later than ``trn_deadline_s`` after the request
        self.trn_latency_s = float(trn_latency_s)
        self.trn_deadline_s = float(trn_deadline_s)
        self._pending = None  #: (apply time, request time, result, sigma_max)
        #: real-time mode (``realtime`` = speed factor): paced to the wall clock, requests
        #: on a worker thread (ps.realtime); the request in flight: (future, time, sigma_max)
        self.realtime = None
        self._inflight = None
        if realtime is not None:
            from navgate.systems.ins_trn.ps.realtime import Realtime

            if self.trn_latency_s:
                raise ValueError("trn_latency_s is for simulated time; real-time mode "
                                 "measures the real latency")
            self.realtime = Realtime(realtime, self.t0, 1.0 / cfg.baro_rate_hz,
                                     trn.fix_interval_s)
        self.fixes: list = []
        self.last_fix_t = -math.inf
        self.h_baro = math.nan
        self.baro_invalid = 0
        self.samples = 0
        self._nav, self._sigma, self._p_ne = [], [], []
        self._start = _time.perf_counter()

    # -- logging ------------------------------------------------------------------------------
    def _log(self):
        e = self.engine
        self._nav.append(e.read_nav())
        self._sigma.append(np.sqrt(np.maximum(e.read_cov_diag(), 0.0)))
        self._p_ne.append(float(e.read_p_horizontal()[0, 1]))

    def _before_imu(self):
        if self.samples % self.log_every == 0 and len(self._nav) == self.samples // self.log_every:
            self._log()

    # -- records --------------------------------------------------------------------------------
    def feed_imu(self, gyro_words, accel_words):
        """IMU records (N, 3) + (N, 3), in order; split at the log boundaries."""
        gyro_words = np.atleast_2d(gyro_words)
        accel_words = np.atleast_2d(accel_words)
        i, n = 0, gyro_words.shape[0]
        while i < n:
            self._before_imu()
            step = self.log_every - self.samples % self.log_every
            j = min(n, i + step)
            self.engine.propagate(gyro_words[i:j], accel_words[i:j])
            self.samples += j - i
            if self.progress is not None:
                self.progress(j - i)
            i = j

    def feed_baro(self, t, altitude, valid=True, words=None):
        """A barometer record; with a PL engine it is read through the PL (pl_sensors), from
        the ADC ``words`` (up, ut, ok) when :meth:`run` has encoded them already."""
        h = float(altitude) if valid else math.nan
        if self.engine.pl_sensors and math.isfinite(h):
            if words is None:
                up, ut, ok = (w[0] for w in pl_sensors.baro_words(h))
            else:
                up, ut, ok = words
            h = (pl_sensors.altitude_from_pressure(self.engine.read_baro(int(up), int(ut)))
                 if ok else math.nan)
        self.h_baro = h
        if math.isfinite(h):
            self.engine.update_altitude(h, self.baro_sigma)
        else:
            self.baro_invalid += 1

    def feed_ranger(self, t, slant_range, valid):
        if not self.use_trn:
            return
        e = self.engine
        if e.pl_sensors:  # the frame through the PL's receiver
            dist, strength = e.read_ranger(*pl_sensors.ranger_words(
                float(slant_range), bool(valid), self.ranger_unit))
            slant_range, valid = pl_sensors.range_from_words(dist, strength, self.ranger_unit)
        nav = e.read_nav()
        roll, pitch, _ = _euler(nav[6:10])
        pn, pe = e.read_position_ned()
        status = e.profile_push(time=t, h_baro=float(self.h_baro), slant_range=float(slant_range),
                                range_valid=bool(valid), roll=roll, pitch=pitch,
                                pos_n=float(pn), pos_e=float(pe))
        if (status == ACCEPTED and t - self.last_fix_t >= self.trn.fix_interval_s
                and self._pending is None and self._inflight is None):  # one at a time
            self.last_fix_t = t
            self._fix(t)

    def _fix(self, t):
        e = self.engine
        p2 = e.read_p_horizontal()
        sigma_max = math.sqrt(max(np.linalg.eigvalsh(p2).max(), 0.0))
        if self.realtime is not None:  # the worker asks the Pi; the loop goes on
            future = self.realtime.submit(self.correlator.correlate, e.profile_read(),
                                          sigma_max, prior_cov=p2)
            self._inflight = (future, t, sigma_max)
            return
        result = self.correlator.correlate(e.profile_read(), sigma_max, prior_cov=p2)
        if self.trn_latency_s > 0:
            self._pending = (t + self.trn_latency_s, t, result, sigma_max)
        else:
            self._apply(result, t, t, sigma_max)

    def _due(self, t):
        """Apply the fix in flight once its time has come (simulated link latency) or, in
        real time, once it has arrived (never waiting for it)."""
        if self._inflight is not None and self.realtime.done(self._inflight[0]):
            future, t_request, sigma_max = self._inflight
            self._inflight = None
            try:
                result = future.result()
            except Exception:  # noqa: BLE001 - counted; the flight goes on INS-only
                self.realtime.counts["worker_errors"] += 1
                return
            self.realtime.arrived(t - t_request, bool(result.accepted)
                                  and t - t_request > self.trn_deadline_s)
            self._apply(result, t_request, t, sigma_max)
        if self._pending is not None and t >= self._pending[0]:
            _, t_request, result, sigma_max = self._pending
            self._pending = None
            self._apply(result, t_request, t, sigma_max)

    def _apply(self, result, t_request, t, sigma_max):
        e = self.engine
        row = result.as_row()
        row["applied"] = False
        row["nis"] = math.nan
        row["applied_at_s"] = t
        upd = y = None
        if result.accepted and t - t_request > self.trn_deadline_s:
            result = dataclasses.replace(result, accepted=False,
                                         reason="no fix: arrived after its deadline")
            row.update(accepted=False, reason=result.reason)
        if result.accepted:
            # y = p_ins - p_fix = -shift, measured lag_s ago (plus the link's latency)
            y = np.array([result.ins_n - result.fix_n, result.ins_e - result.fix_e])
            lag = result.lag_s + (t - t_request) if self.trn.lag_compensation else 0.0
            upd = e.update_trn(y, result.cov, lag)
            row["nis"] = upd.nis
            row["applied"] = upd.accepted
            if upd.accepted:
                c = upd.correction
                e.profile_shift(-c[0], -c[1], -c[3], -c[4], now=t)
            else:
                row["reason"] = upd.reason or "rejected by chi-square gate"
        review = self.monitor.review(result, upd, y, sigma_max)
        row["integrity"] = review.event
        if review.inflate is not None:  # divergence: reopen the filter's position
            e.inflate_p_horizontal(review.inflate)
        self.fixes.append(row)

    def feed(self, kind, t, payload):
        """One record: kind (records.IMU/BARO/RANGER/TRUTH), time, payload tuple."""
        if kind != IMU:
            self._due(t)
        if kind == IMU:
            self.feed_imu(np.asarray(payload[0]).reshape(1, 3),
                          np.asarray(payload[1]).reshape(1, 3))
        elif kind == BARO:
            self.feed_baro(t, *payload)
        elif kind == RANGER:
            self.feed_ranger(t, *payload)

    def run(self, stream: RecordStream) -> NavRun:
        """Consume a whole stream (runs of IMU records go to the engine in one call; with an
        engine that takes them, whole stretches of IMU and barometer records)."""
        if self.engine.batch_records and not self.engine.pl_sensors and self.realtime is None:
            return self._run_batched(stream)
        kind = stream.kind
        other = np.flatnonzero(kind != IMU)
        baro = None
        if self.engine.pl_sensors:  # the BMP390's words for every record, encoded at once
            baro = pl_sensors.baro_words(np.where(stream.baro_status == 0,
                                                  stream.baro_altitude, np.nan))
            self.engine.prepare_baro(baro[0][baro[2]], baro[1][baro[2]])
        pos = 0
        if self.realtime is not None:
            self.realtime.start()
        for m in list(other) + [len(stream)]:
            if self.realtime is not None:  # this block's records are due on the wall clock
                self.realtime.pace(float(stream.t[min(m, len(stream) - 1)]))
            if m > pos:
                a, b = stream.index[pos], stream.index[m - 1] + 1
                self.feed_imu(stream.gyro_words[a:b], stream.accel_words[a:b])
            if m == len(stream):
                break
            k, t, i = kind[m], float(stream.t[m]), stream.index[m]
            self._due(t)
            if k == BARO:
                self.feed_baro(t, stream.baro_altitude[i], stream.baro_status[i] == 0,
                               None if baro is None else (baro[0][i], baro[1][i], baro[2][i]))
            elif k == RANGER:
                self.feed_ranger(t, stream.ranger_range[i], stream.ranger_status[i] == 0)
            pos = m + 1
        return self.finish()

    def _run_batched(self, stream: RecordStream) -> NavRun:
        """:meth:`run` with the engine's :meth:`PlEngine.run_records`: the stretches between
        the records the PS must see (ranger records on TRN runs; while a fix is in flight,
        the first record at or after its time) go to the engine in one call each, the rest
        through the per-record methods, so the result equals :meth:`feed` record by record."""
        kind, times = stream.kind, stream.t
        n_total = self.samples + int(np.count_nonzero(kind == IMU))
        rows = n_total // self.log_every + 2
        log = (np.empty((rows, 10)), np.empty((rows, 15)), np.empty(rows))
        logged = len(self._nav)
        for j in range(logged):  # rows logged before this call
            log[0][j], log[1][j], log[2][j] = self._nav[j], self._sigma[j], self._p_ne[j]
        other = np.flatnonzero(kind != IMU)
        stops = np.flatnonzero(kind == RANGER) if self.use_trn else np.empty(0, np.int64)
        stops = list(stops) + [len(stream)]
        pos = 0

        def stretch(a, b):
            nonlocal logged
            if b <= a:
                return
            n, logged, h, invalid = self.engine.run_records(
                stream, a, b, baro_sigma=self.baro_sigma, log_every=self.log_every,
                logged=logged, log=log)
            self.samples += n
            self.baro_invalid += invalid
            if h is not None:
                self.h_baro = h
            if self.progress is not None and n:
                self.progress(n)

        for m in stops:
            while self._pending is not None and pos < m:
                # the first non-IMU record at or after the fix's time applies it
                j0 = np.searchsorted(other, pos)
                cand = other[j0:np.searchsorted(other, m)]
                due = cand[times[cand] >= self._pending[0]]
                if not due.size:
                    break
                j = int(due[0])
                stretch(pos, j)
                self._due(float(times[j]))
                if kind[j] == BARO:
                    i = stream.index[j]
                    self._sync_log(log, logged)
                    self.feed_baro(float(times[j]), stream.baro_altitude[i],
                                   stream.baro_status[i] == 0)
                pos = j + 1
            stretch(pos, m)
            if m == len(stream):
                break
            t = float(times[m])
            self._due(t)
            i = stream.index[m]
            self.feed_ranger(t, stream.ranger_range[i], stream.ranger_status[i] == 0)
            pos = m + 1
        self._sync_log(log, logged)
        return self.finish()

    def _sync_log(self, log, logged):
        """The rows the engine logged into ``log``, as :meth:`_log` would have kept them."""
        for j in range(len(self._nav), logged):
            self._nav.append(log[0][j].copy())
            self._sigma.append(log[1][j].copy())
            self._p_ne.append(float(log[2][j]))

    def finish(self) -> NavRun:
        e = self.engine
        if self.realtime is not None:
            self.realtime.close()  # waits for the request in hand, if any
            if self._inflight is not None:
                future, t_request, sigma_max = self._inflight
                self._inflight = None
                self.realtime.counts["in_flight_at_end"] += 1
                if future.exception() is None:
                    self._apply(dataclasses.replace(
                        future.result(), accepted=False,
                        reason="no fix: the flight ended before it arrived"),
                        t_request, t_request, sigma_max)
        if self._pending is not None:  # the flight ended before the fix arrived
            _, t_request, result, sigma_max = self._pending
            self._pending = None
            self._apply(dataclasses.replace(result, accepted=False,
                                            reason="no fix: the flight ended before it arrived"),
                        t_request, t_request, sigma_max)
        n_log = self.samples // self.log_every + 1
        if len(self._nav) < n_log:
            self._log()
        elif self.samples % self.log_every:
            # the last row holds the final state (the float64 loop's convention)
            self._nav.pop(), self._sigma.pop(), self._p_ne.pop()
            self._log()
        t_log = self.t0 + np.arange(n_log) * self.log_every * self.dt
        if self.samples % self.log_every:  # the last row is the final state: stamped so
            t_log[-1] = self.t0 + self.samples * self.dt
        rejected = dict(e.rejected)
        if self.baro_invalid:
            rejected["baro invalid sample"] = self.baro_invalid
        return NavRun(self.name, t_log, np.array(self._nav), np.array(self._sigma),
                      np.array(self._p_ne), self.fixes, dict(e.accepted), rejected,
                      dict(e.profile.counts), e.imu_samples_rejected,
                      _time.perf_counter() - self._start, e.name, e.hardware_stats(),
                      None if self.realtime is None else self.realtime.summary())


def navigate(stream: RecordStream, cfg, *, engine: str = "reference", dem=None,
             use_trn: bool = True, name: str = "nav", progress=None, trn_link=None,
             trn_latency_s: float = 0.0, realtime: float | None = None,
             trn: TrnSettings | None = None, engine_options: dict | None = None) -> NavRun:
    """Build the engine from the stream header and run the navigator over the stream
    (``trn_link``: a :class:`~navgate.systems.ins_trn.ps.trn_link.TrnLink` to correlate on
    the Pi's service instead of in this process; ``trn``: the TRN settings, default
    :class:`TrnSettings`; ``engine_options``: keyword arguments of the engine)."""
    eng = make_engine(engine, engine_setup(stream.header, cfg), **(engine_options or {}))
    nav = Navigator(eng, cfg, t0=stream.header["t0"], dem=dem, use_trn=use_trn, name=name,
                    progress=progress, trn_link=trn_link, trn_latency_s=trn_latency_s,
                    realtime=realtime, trn=trn)
    return nav.run(stream)


def _euler(q):
    """(roll, pitch, yaw) of C_b^n(q): the elements of ``rotations.quat_to_dcm_array`` in
    the same arithmetic, on Python floats (one quaternion per ranger record; the array
    version costs ~25 us of NumPy overhead each)."""
    q0, q1, q2, q3 = (float(x) for x in q)
    c00 = q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3
    c10 = 2.0 * (q1 * q2 + q0 * q3)
    c20 = 2.0 * (q1 * q3 - q0 * q2)
    c21 = 2.0 * (q2 * q3 + q0 * q1)
    c22 = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3
    return (math.atan2(c21, c22), -math.asin(max(-1.0, min(1.0, c20))), math.atan2(c10, c00))
