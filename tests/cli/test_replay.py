"""`navgate fly --record` then `navgate replay`: the same figures, bad logs as one-line errors."""

import json
import subprocess
import sys

import pytest


def navgate(*args):
    return subprocess.run([sys.executable, "-m", "navgate.cli", *args], capture_output=True,
                          text=True, timeout=600)


@pytest.mark.parametrize("engine", ["reference", "fp32"])
def test_record_then_replay_reproduces_fly(tmp_path, engine):
    log = tmp_path / "flight.log"
    proc = navgate("fly", "--duration", "25", "--seed", "2", "--engine", engine, "--record",
                   str(log), "--out", str(tmp_path / "fly"), "--quiet")
    assert proc.returncode == 0, proc.stderr
    proc = navgate("replay", str(log), "--engine", engine, "--out", str(tmp_path / "rep"),
                   "--quiet")
    assert proc.returncode == 0, proc.stderr
    a = json.loads((tmp_path / "fly" / "summary.json").read_text())
    b = json.loads((tmp_path / "rep" / "summary.json").read_text())
    assert a["engine"] == b["engine"] == engine
    if engine == "fp32":
        assert a["fp32_vs_reference_max_position_difference_m"] < 0.1
    assert b["bad_records_total"] == 0 and b["scored"]
    for run in ("ins_only", "trn_aided"):
        for key in ("final_horizontal_error_m", "rms_horizontal_error_m",
                    "rms_horizontal_error_second_half_m", "nees_position_mean",
                    "baro_updates_accepted"):
            assert a[run][key] == b[run][key], (run, key)
    assert a["trn_aided"]["fixes_accepted"] == b["trn_aided"]["fixes_accepted"]


def test_replay_bad_logs_are_one_line_errors(tmp_path):
    for content, needle in (("junk\n", "not a navgate record log"),
                            ("navgate-records 1\nH {}\n", "no valid IMU record")):
        path = tmp_path / "bad.log"
        path.write_text(content)
        proc = navgate("replay", str(path), "--out", str(tmp_path / "o"))
        assert proc.returncode == 2
        lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
        assert len(lines) == 1 and lines[0].startswith("navgate replay: error:")
        assert needle in lines[0] and "Traceback" not in proc.stderr
    proc = navgate("replay", str(tmp_path / "missing.log"))
    assert proc.returncode == 2 and "cannot read" in proc.stderr


def test_replay_fpga_sim_refuses_an_ideal_sensor_log(tmp_path):
    """The whole-FPGA engine needs the IMU's int16 words: a log of the ideal sensors' float
    words is one line, exit 2, before any simulation."""
    log = tmp_path / "ideal.log"
    proc = navgate("fly", "--duration", "20", "--ideal-sensors", "--no-trn", "--record",
                   str(log), "--out", str(tmp_path / "fly"), "--quiet")
    assert proc.returncode == 0, proc.stderr
    proc = navgate("replay", str(log), "--engine", "fpga-sim", "--out", str(tmp_path / "rep"))
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "int16" in lines[0] and "Traceback" not in proc.stderr
    assert not (tmp_path / "rep").exists()
