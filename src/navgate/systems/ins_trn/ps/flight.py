"""The ``navgate fly`` run: plan, simulate, navigate INS-only and INS+TRN, and score both.

The scenario (route, truth, sensors, scoring) is :mod:`navgate.sim.flight`; the navigation
loop is the streaming navigator (:mod:`navgate.systems.ins_trn.ps.navigator`: the PS side over
a PL engine of :mod:`navgate.systems.ins_trn.ps.pl_interface`), fed by the record stream
(:mod:`navgate.systems.ins_trn.ps.records`) that :func:`flight_stream` makes of the simulated
sensor data; :func:`run_navigation` runs it once (INS + 15-state ESKF with barometric
altitude updates and, optionally, TRN position fixes). The report is
:mod:`navgate.systems.ins_trn.ps.report`.
"""

from __future__ import annotations

import dataclasses
import math
import time as _time
from dataclasses import dataclass

import numpy as np

from navgate.nav.earth import LocalTangent
from navgate.sim import sensors
from navgate.sim.flight import (
    FlightConfig,
    InitialEstimate,
    Route,
    RouteError,
    SensorData,
    initial_estimate,
    plan_route,
    score,
    simulate_sensors,
)
from navgate.systems.ins_trn.ps.navigator import NavRun, navigate
from navgate.systems.ins_trn.ps.records import RecordStream, make_header, stream_from_sensors
from navgate.systems.ins_trn.ps.trn_settings import TrnSettings
from navgate.trn.dem import Dem


def flight_stream(data: SensorData, dem: Dem, cfg: FlightConfig, init: InitialEstimate, *,
                  with_truth: bool = True, trn: TrnSettings | None = None) -> RecordStream:
    """The record stream (with its header, which records ``trn``) of a simulated flight."""
    tangent = LocalTangent(*dem.center, 0.0)
    header = make_header(cfg, data, init, data.imu.calibration, tangent, trn)
    header["dem"] = dem.name
    log_every = max(1, int(round(cfg.imu_rate_hz / cfg.log_rate_hz)))
    return stream_from_sensors(data, log_every if with_truth else None, header)


def run_navigation(data: SensorData, dem: Dem, cfg: FlightConfig, init: InitialEstimate, *,
                   use_trn: bool, name: str, progress=None, engine: str = "reference",
                   stream: RecordStream | None = None,
                   trn: TrnSettings | None = None) -> NavRun:
    """Closed-loop INS + ESKF over the sensor data, with baro and (optionally) TRN updates,
    with the float64 ``reference`` engine or another registered engine."""
    if stream is None:
        stream = flight_stream(data, dem, cfg, init, with_truth=False, trn=trn)
    return navigate(stream, cfg, engine=engine, dem=dem if use_trn else None, use_trn=use_trn,
                    name=name, progress=progress, trn=trn)


@dataclass
class FlightResult:
    config: FlightConfig
    dem: Dem
    route: Route
    data: SensorData
    runs: dict  #: name -> NavRun
    scores: dict  #: name -> Score
    log_every: int
    wall_time_s: float
    engine: str = "reference"
    reference_runs: dict | None = None  #: name -> NavRun of the reference engine (fp32 runs)
    stream: object = None  #: the sensor record stream (records.RecordStream)
    trn: TrnSettings = dataclasses.field(default_factory=TrnSettings)  #: the navigator's TRN

    def summary(self) -> dict:
        cfg = self.config
        truth = self.data.truth
        out = {
            "duration_s": float(truth.t[-1] - truth.t[0]),
            "imu_rate_hz": cfg.imu_rate_hz,
            "wall_time_s": self.wall_time_s,
            "seed": cfg.seed,
            "engine": self.engine,
            "ideal_sensors": cfg.ideal_sensors,
            "dem": {"name": self.dem.name, "rows": self.dem.shape[0], "cols": self.dem.shape[1],
                    "post_spacing_m": list(self.dem.post_spacing_m()),
                    "void_fraction": self.dem.void_fraction(),
                    **({"tile_store": self.dem.stats()} if hasattr(self.dem, "stats") else {})},
            "route": {"start_lat_deg": math.degrees(self.route.lat0),
                      "start_lon_deg": math.degrees(self.route.lon0),
                      "cruise_altitude_m": self.route.h0,
                      "distance_km": float(np.sum(np.linalg.norm(truth.v_ned, axis=1))
                                           / cfg.imu_rate_hz / 1000.0)},
            "sensors": {"imu": "ideal" if cfg.ideal_sensors else sensors.ADIS16500.name,
                        "imu_saturated_words": self.data.imu.saturated,
                        "baro": "ideal" if cfg.ideal_sensors else sensors.BMP390.name,
                        "ranger": cfg.ranger,
                        "ranger_valid_fraction": float(np.mean(self.data.ranger.valid))},
        }
        for name, run in self.runs.items():
            s = self.scores[name].summary(run.t)
            s["baro_updates_accepted"] = run.accepted.get("baro", 0)
            s["baro_updates_rejected"] = run.rejected.get("baro", 0)
            s["baro_samples_invalid"] = run.rejected.get("baro invalid sample", 0)
            s["imu_samples_rejected"] = run.imu_samples_rejected
            s["wall_time_s"] = run.wall_time_s
            if run.hardware:
                s["hardware"] = run.hardware
            if name == "trn_aided":
                applied = [f for f in run.fixes if f["applied"]]
                reasons = {}
                for f in run.fixes:
                    if not f["applied"]:
                        reasons[f["reason"]] = reasons.get(f["reason"], 0) + 1
                events = {}
                for f in run.fixes:
                    if f.get("integrity"):
                        events[f["integrity"]] = events.get(f["integrity"], 0) + 1
                s["trn_method"] = self.trn.method
                s["integrity_events"] = events
                s["fixes_attempted"] = len(run.fixes)
                s["fixes_accepted"] = len(applied)
                s["fixes_rejected"] = len(run.fixes) - len(applied)
                s["fix_rejection_reasons"] = reasons
                s["profile_sample_counts"] = run.profile_counts
                nis = [f["nis"] for f in applied]
                s["nis_trn_mean"] = float(np.mean(nis)) if nis else None
                if run.realtime is not None:
                    s["realtime"] = run.realtime
            out[name] = s
        if self.reference_runs:
            diffs, ref_wall = [], 0.0
            for name, run in self.runs.items():
                ref = self.reference_runs[name]
                diffs.append(max_position_difference(self.dem, run, ref))
                ref_wall += ref.wall_time_s
                out[name]["reference_wall_time_s"] = ref.wall_time_s
            # named after the engine that flew (fp32, rtl, fpga_sim), never "fp32" for all
            engine = out.get("engine", "fp32").replace("-", "_")
            out[f"{engine}_vs_reference_max_position_difference_m"] = float(max(diffs))
            eng_wall = sum(r.wall_time_s for r in self.runs.values())
            out["engine_wall_time_s"] = eng_wall
            out["reference_engine_wall_time_s"] = ref_wall
            out["engine_wall_time_ratio"] = eng_wall / ref_wall if ref_wall > 0 else None
        return out


def max_position_difference(dem: Dem, a: NavRun, b: NavRun) -> float:
    """Largest 3-D distance (m) between two runs' logged positions."""
    from navgate.nav.earth import LocalTangent

    tan = LocalTangent(*dem.center, 0.0)
    an, ae = tan.to_ned(a.nav[:, 0], a.nav[:, 1])
    bn, be = tan.to_ned(b.nav[:, 0], b.nav[:, 1])
    d = np.sqrt((an - bn) ** 2 + (ae - be) ** 2 + (a.nav[:, 2] - b.nav[:, 2]) ** 2)
    return float(np.max(d))


def record_stream(dem: Dem, cfg: FlightConfig, route: Route | None = None,
                  trn: TrnSettings | None = None):
    """Plan (unless ``route`` is given) and simulate a flight, and package its sensor records
    for the navigator (the header records ``trn``): (route, sensor data, record stream)."""
    if route is None:
        route = plan_route(dem, cfg)
    data = simulate_sensors(route, dem, cfg)
    return route, data, flight_stream(data, dem, cfg, initial_estimate(data, cfg), trn=trn)


def fly(dem: Dem, cfg: FlightConfig, progress=None, stage=None, route: Route | None = None,
        engine: str = "reference", trn_link=None, trn_latency_s: float = 0.0,
        realtime: float | None = None, trn: TrnSettings | None = None,
        engine_options: dict | None = None) -> FlightResult:
    """Plan, simulate and navigate a flight; ``progress(n)`` reports IMU samples done.

    ``engine``: the PL engine (``reference`` or ``fp32``); with a non-reference engine the
    reference engine flies the same records too, for the comparison in the summary.
    ``engine_options``: keyword arguments of the engine's constructor (the ``board`` engine's
    opened board).
    ``trn``: the navigator's TRN settings (default :class:`TrnSettings`: PMF, its own fix
    interval, lag compensation on).
    """
    start = _time.perf_counter()
    if trn is None:
        trn = TrnSettings()
    if route is None:
        if stage:
            stage("planning route")
        route = plan_route(dem, cfg)
    if stage:
        stage("simulating sensors")
    data = simulate_sensors(route, dem, cfg)
    init = initial_estimate(data, cfg)
    stream = flight_stream(data, dem, cfg, init, trn=trn)
    runs = fly_stream(stream, dem, cfg, engine=engine, progress=progress, stage=stage,
                      trn_link=trn_link, trn_latency_s=trn_latency_s, realtime=realtime,
                      trn=trn, engine_options=engine_options)
    reference_runs = None
    if engine != "reference":
        reference_runs = fly_stream(stream, dem, cfg, engine="reference", stage=stage, trn=trn)
    log_every = max(1, int(round(cfg.imu_rate_hz / cfg.log_rate_hz)))
    scores = {name: score(run, data.truth, log_every) for name, run in runs.items()}
    return FlightResult(cfg, dem, route, data, runs, scores, log_every,
                        _time.perf_counter() - start, engine, reference_runs, stream, trn)


def fly_stream(stream, dem: Dem, cfg: FlightConfig, *, engine="reference", progress=None,
               stage=None, trn_link=None, trn_latency_s: float = 0.0,
               realtime: float | None = None, trn: TrnSettings | None = None,
               engine_options: dict | None = None) -> dict:
    """The INS-only and (cfg.trn) INS+TRN runs over one record stream, the latter with the
    TRN settings ``trn`` (default :class:`TrnSettings`); ``realtime`` (a speed factor) paces
    the INS+TRN run to the wall clock (the INS-only run, which does not talk to the Pi, runs
    as fast as it can)."""
    runs = {}
    if stage:
        stage(f"navigating: INS only ({engine})")
    runs["ins_only"] = navigate(stream, cfg, engine=engine, dem=None, use_trn=False,
                                name="ins_only", progress=progress,
                                engine_options=engine_options)
    if cfg.trn:
        if stage:
            stage(f"navigating: INS + TRN ({engine})")
        runs["trn_aided"] = navigate(stream, cfg, engine=engine, dem=dem, use_trn=True,
                                     name="trn_aided", progress=progress, trn_link=trn_link,
                                     trn_latency_s=trn_latency_s, realtime=realtime, trn=trn,
                                     engine_options=engine_options)
    return runs


__all__ = ["FlightConfig", "FlightResult", "NavRun", "RouteError", "TrnSettings", "fly",
           "flight_stream", "fly_stream", "record_stream", "max_position_difference",
           "plan_route", "run_navigation"]
