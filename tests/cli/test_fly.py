"""`navgate fly` as a user runs it: outputs, summary keys, and one-line errors (exit 2)."""

import json
import subprocess
import sys

import numpy as np
import pytest
import rasterio
from rasterio.transform import from_origin


def navgate(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "navgate.cli", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=600)


def assert_one_line_error(proc, needle):
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("navgate fly: error:") and needle in lines[0], lines[0]
    assert "Traceback" not in proc.stderr + proc.stdout


def test_short_flight_writes_every_output(tmp_path):
    out = tmp_path / "run"
    proc = navgate("fly", "--duration", "90", "--seed", "3", "--out", str(out), "--quiet")
    assert proc.returncode == 0, proc.stderr
    for name in ("summary.json", "trajectory.csv", "trn_fixes.csv", "track.png", "errors.png"):
        assert (out / name).stat().st_size > 0, name
    s = json.loads((out / "summary.json").read_text())
    for key in ("duration_s", "imu_rate_hz", "wall_time_s"):
        assert key in s
    for key in ("final_horizontal_error_m", "rms_horizontal_error_m"):
        assert np.isfinite(s["ins_only"][key])
    for key in ("final_horizontal_error_m", "rms_horizontal_error_m",
                "rms_horizontal_error_second_half_m", "fixes_accepted", "fixes_rejected",
                "nees_position_mean"):
        assert key in s["trn_aided"]
    assert s["duration_s"] == 90.0 and s["seed"] == 3
    header = (out / "trajectory.csv").read_text().splitlines()[0].split(",")
    assert {"truth_north_m", "ins_only_north_m", "trn_aided_north_m",
            "trn_aided_sigma_north_m"} <= set(header)


def test_no_trn_and_ideal_sensors(tmp_path):
    proc = navgate("fly", "--duration", "30", "--no-trn", "--ideal-sensors", "--out",
                   str(tmp_path), "--quiet")
    assert proc.returncode == 0, proc.stderr
    s = json.loads((tmp_path / "summary.json").read_text())
    assert "trn_aided" not in s and s["ideal_sensors"] is True
    assert s["ins_only"]["final_horizontal_error_m"] < 0.01


@pytest.mark.parametrize("args, needle", [
    (["--duration", "-5"], "--duration"),
    (["--duration", "abc"], "--duration"),
    (["--imu-rate", "10"], "--imu-rate"),
    (["--seed", "-1"], "--seed"),
    (["--ranger", "sonar"], "--ranger"),
    (["--trn", "magic"], "--trn"),
    (["--bogus"], "--bogus"),
])
def test_bad_option_values(tmp_path, args, needle):
    assert_one_line_error(navgate("fly", *args, "--out", str(tmp_path)), needle)


def test_bad_dem_files(tmp_path):
    assert_one_line_error(navgate("fly", "--dem", str(tmp_path / "nope.tif")), "not found")
    junk = tmp_path / "junk.dt1"
    junk.write_bytes(b"\x00garbage" * 10)
    assert_one_line_error(navgate("fly", "--dem", str(junk)), "not a readable DEM")
    small = tmp_path / "small.tif"
    transform = from_origin(-84.0, 36.5, 1 / 1200, 1 / 1200)
    with rasterio.open(small, "w", driver="GTiff", width=40, height=40, count=1, dtype="float32",
                       crs="EPSG:4326", transform=transform) as d:
        d.write(np.random.default_rng(0).uniform(200, 600, (40, 40)).astype("float32"), 1)
    assert_one_line_error(navgate("fly", "--dem", str(small)), "DEM too small")


def test_unwritable_output_directory(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert_one_line_error(navgate("fly", "--duration", "10", "--out", str(blocker / "sub")),
                          "output directory")


def test_hardware_line_reports_the_simulated_pl():
    """The fly/replay line for a simulated PL's counts (summary "hardware")."""
    from navgate.cli.console import hardware_line

    line = hardware_line({"simulated_cycles": 322_200_000, "cycles_per_imu_sample": 1342.4,
                          "update_interrupts": 15040, "profile_dmas": 108,
                          "profile_entries_pushed": 1045, "baro_samples_through_pins": 15000,
                          "ranger_frames_through_pins": 6000, "bus_batches": 1,
                          "bus_commands": 2})
    assert line.startswith("322.2 M cycles simulated (1,342 per IMU sample)")
    assert "108 profile DMAs" in line and "6,000 ranger frames" in line
    assert hardware_line({"engine_cycles": 2_500_000, "engine_cycles_per_imu_sample": 669.0}) \
        == "2.5 M engine cycles (669 per IMU sample)"


@pytest.mark.parametrize("engine, key", [
    ("fp32", "fp32_vs_reference_max_position_difference_m"),
    ("rtl", "rtl_vs_reference_max_position_difference_m"),
    ("fpga-sim", "fpga_sim_vs_reference_max_position_difference_m"),
])
def test_engine_comparison_is_named_after_the_engine(engine, key, capsys):
    """rtl and fpga-sim flights store and print their own comparison with the reference,
    not "fp32 vs reference" (issue 31)."""
    import dataclasses

    from rich.console import Console

    from navgate.cli import fly as cmd
    from navgate.systems.ins_trn.ps import flight
    from navgate.trn.dem import Dem

    dem = Dem.default()
    cfg = flight.FlightConfig(duration_s=2.0, trn=False)
    result = flight.fly(dem, cfg)
    ref = {name: dataclasses.replace(run, nav=run.nav.copy()) for name, run in
           result.runs.items()}
    ref["ins_only"].nav[-1, 0] += 1e-6  # the reference ends 6.4 m north
    result = dataclasses.replace(result, engine=engine, reference_runs=ref)
    s = result.summary()
    assert [k for k in s if k.endswith("_vs_reference_max_position_difference_m")] == [key]
    assert s[key] == pytest.approx(6.37, abs=0.05)
    cmd._print_table(Console(file=sys.stderr, width=120), s)
    err = capsys.readouterr().err
    assert f"{engine} vs reference: max position difference {s[key]:.2f} m" in err
    assert engine == "fp32" or "fp32" not in err
