"""Seed 000's navigation loop over a simulated flight: INS + 15-state ESKF with barometric
altitude updates and (optionally) TRN position fixes.

The loop itself is the streaming navigator (:mod:`navgate.systems.ins_trn.ps.navigator`: the PS
side over a PL engine of :mod:`navgate.systems.ins_trn.ps.pl_interface`); this module turns the
scenario's sensor data into its record stream (:mod:`navgate.systems.ins_trn.ps.records`) and
runs it, with the float64 ``reference`` engine or the float32 ``fp32`` engine.
"""

from __future__ import annotations

from navgate.nav.earth import LocalTangent
from navgate.sim.flight import FlightConfig, InitialEstimate, SensorData
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
    """Closed-loop INS + ESKF over the sensor data, with baro and (optionally) TRN updates."""
    if stream is None:
        stream = flight_stream(data, dem, cfg, init, with_truth=False, trn=trn)
    return navigate(stream, cfg, engine=engine, dem=dem if use_trn else None, use_trn=use_trn,
                    name=name, progress=progress, trn=trn)


__all__ = ["NavRun", "flight_stream", "run_navigation"]
