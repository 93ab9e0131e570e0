"""``navgate replay``: run seed 000's navigator on a sensor record log (``navgate fly --record``).

The log format is documented in :mod:`navgate.systems.ins_trn.ps.records`. Bad records
(truncated, unparsable, non-finite, out-of-order time, int16 overflow) are counted by reason,
skipped and reported in summary.json; only a log without a valid IMU record is an error. When
the log holds truth records, both runs are scored exactly as ``navgate fly`` scores them.
"""

from __future__ import annotations

import time

import click

from navgate.cli.common import (
    CliError,
    engine_choice,
    hardware_line,
    load_engine_class,
    prepare_out_dir,
    simulation_errors,
    write_summary,
)


@click.command()
@click.argument("log_path", type=click.Path(dir_okay=False))
@click.option("--engine", type=engine_choice(), default="reference", show_default=True,
              help="PL engine: float64 reference, float32 bit-true model, the ins_engines "
                   "gateware in Verilator, or the whole FPGA (ins_trn_top) in Verilator.")
@click.option("--dem", "dem_path", type=click.Path(dir_okay=True), default=None,
              help="DEM for TRN (default: the embedded Jacksboro fault DEM).")
@click.option("--no-trn", is_flag=True, help="Run INS-only (with baro) and skip TRN.")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default="navgate-replay",
              show_default=True, help="Output directory.")
@click.option("--quiet", is_flag=True, help="No table on stdout.")
def replay(log_path, engine, dem_path, no_trn, out_dir, quiet):
    """Navigate a recorded sensor stream; score it when the log carries truth."""
    from dataclasses import fields, replace

    from navgate.sim.flight import FlightConfig, score
    from navgate.systems.ins_trn.ps.flight import fly_stream
    from navgate.systems.ins_trn.ps.records import LogError, read_log
    from navgate.trn.dem import DemError
    from navgate.trn.pmf import PmfConfig
    from navgate.trn.tercom import TercomConfig
    from navgate.trn.tiles import load_terrain

    try:
        stream = read_log(log_path)
    except LogError as error:
        raise CliError(str(error)) from None
    header = stream.header
    try:
        conf = dict(header["config"])
        conf["tercom"] = TercomConfig(**conf.get("tercom", {}))
        conf["pmf"] = PmfConfig(**conf.get("pmf", {}))
        known = {f.name for f in fields(FlightConfig)}
        cfg = FlightConfig(**{k: v for k, v in conf.items() if k in known})
        for key in ("ideal", "t0", "calibration", "initial", "reference"):
            header[key]
    except (KeyError, TypeError, ValueError) as error:
        raise CliError(f"{log_path}: header lacks a usable flight configuration ({error})"
                       ) from None
    try:  # the engines' own checks of the initial state (p0, nav0, rate, ...), up front
        from navgate.systems.ins_trn.ps.engine import check_setup
        from navgate.systems.ins_trn.ps.navigator import engine_setup

        check_setup(engine_setup(header, cfg))
    except (KeyError, TypeError, IndexError, ValueError) as error:
        raise CliError(f"{log_path}: the header's initial state is not usable ({error})"
                       ) from None
    if header.get("ideal") and load_engine_class(engine, "navgate replay").needs_imu_words:
        raise CliError(f"{log_path}: --engine {engine} needs the IMU's int16 output words; "
                       "this log has the ideal sensors' float words")
    if no_trn:
        cfg = replace(cfg, trn=False)
    try:
        dem = load_terrain(dem_path)
    except DemError as error:
        raise CliError(str(error)) from None
    out = prepare_out_dir(out_dir)
    start = time.perf_counter()
    try:
        runs = fly_stream(stream, dem, cfg, engine=engine)
    except simulation_errors() as error:
        raise CliError(f"--engine {engine}: the co-simulation failed: {error}") from None
    except DemError as error:
        raise CliError(str(error)) from None
    summary = {
        "log": str(log_path), "engine": engine, "dem": dem.name,
        "log_dem": header.get("dem"), "records": len(stream), "imu_records": stream.n_imu,
        "bad_records": dict(stream.bad_records),
        "bad_records_total": int(sum(stream.bad_records.values())),
        "scored": stream.truth.shape[0] > 0,
    }
    log_every = 1
    truth = None
    if stream.truth.shape[0]:
        truth = _Truth(stream.truth)
    for name, run in runs.items():
        s = {"wall_time_s": run.wall_time_s,
             "baro_updates_accepted": run.accepted.get("baro", 0),
             "baro_updates_rejected": run.rejected.get("baro", 0),
             "baro_samples_invalid": run.rejected.get("baro invalid sample", 0),
             "imu_samples_rejected": run.imu_samples_rejected,
             "final_lat_deg": float(run.nav[-1, 0] * 180.0 / 3.141592653589793),
             "final_lon_deg": float(run.nav[-1, 1] * 180.0 / 3.141592653589793),
             "final_h_m": float(run.nav[-1, 2])}
        if truth is not None and len(truth) >= run.t.size:
            s.update(score(run, truth, log_every).summary(run.t))
        if name == "trn_aided":
            applied = [f for f in run.fixes if f["applied"]]
            s["fixes_attempted"] = len(run.fixes)
            s["fixes_accepted"] = len(applied)
            s["fixes_rejected"] = len(run.fixes) - len(applied)
        if run.hardware:
            s["hardware"] = run.hardware
        summary[name] = s
    summary["wall_time_s"] = time.perf_counter() - start
    path = write_summary(out, summary)
    if not quiet:
        click.echo(f"replayed {stream.n_imu} IMU records ({summary['bad_records_total']} bad "
                   f"records skipped) with the {engine} engine")
        for name in runs:
            r = summary[name]
            if "final_horizontal_error_m" in r:
                click.echo(f"  {name}: final error {r['final_horizontal_error_m']:.1f} m, "
                           f"RMS 2nd half {r['rms_horizontal_error_second_half_m']:.1f} m, "
                           f"NEES {r['nees_position_mean']:.2f}")
            else:
                click.echo(f"  {name}: final position {r['final_lat_deg']:.6f}, "
                           f"{r['final_lon_deg']:.6f}, {r['final_h_m']:.1f} m")
            if "hardware" in r:
                click.echo(f"  {name}: {hardware_line(r['hardware'])}")
    click.echo(f"wrote {path}")


class _Truth:
    """Truth at the log rows (lat, lon, h), shaped for navgate.sim.flight.score."""

    def __init__(self, rows):
        self.lat, self.lon, self.h = rows[:, 0], rows[:, 1], rows[:, 2]

    def __len__(self):
        return self.lat.size
