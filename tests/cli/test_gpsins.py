"""``navgate gpsins``: outputs, summary keys and values, bad options."""

import csv
import json

import pytest

from navgate.cli import main


def run_cli(args, capsys):
    code = 0
    try:
        main(["gpsins", *map(str, args)])
    except SystemExit as exit_:
        code = exit_.code
    out = capsys.readouterr()
    return code, out.out, out.err


def test_writes_report(tmp_path, capsys):
    out = tmp_path / "run"
    code, stdout, err = run_cli(["--duration", 260, "--outage-start", 220, "--seed", 1,
                                 "--out", out, "--quiet"], capsys)
    assert code == 0, err
    for name in ("summary.json", "trajectory.csv", "gps.csv", "errors.png"):
        assert (out / name).stat().st_size > 0
    s = json.loads((out / "summary.json").read_text())
    assert s["duration_s"] == 260 and s["seed"] == 1
    assert s["outage"] == {"start_s": 220.0, "length_s": 30.0}
    for key in ("rms_horizontal_error_m", "max_horizontal_error_during_outage_m",
                "nees_position_mean"):
        assert isinstance(s["gps_ins"][key], float)
    assert isinstance(s["gps_only"]["rms_horizontal_error_m"], float)
    for key in ("ratio_whole_flight", "ratio_outage_excluded", "bound_causal", "bound_rts"):
        assert isinstance(s[key], float) and 0 < s[key] < 1
    assert s["filter"]["kind"] == "full" and s["filter"]["n_states"] == 21
    assert "gps_ins_smoothed" not in s
    # the outage shows in the GPS log: 30 fixes flagged invalid out of 260
    with open(out / "gps.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 260 and sum(r["valid"] == "0" for r in rows) == 30
    with open(out / "trajectory.csv") as fh:
        header = fh.readline().strip().split(",")
    assert {"t_s", "err_north_m", "sigma_north_m", "gps_outage"} <= set(header)
    assert "wrote" not in stdout  # --quiet: table and progress hidden, stdout empty
    assert stdout == ""


def test_same_seed_same_numbers(tmp_path, capsys):
    sums = []
    for k in range(2):
        code, _, err = run_cli(["--duration", 250, "--outage-start", 200, "--out",
                                tmp_path / f"r{k}", "--quiet"], capsys)
        assert code == 0, err
        s = json.loads((tmp_path / f"r{k}" / "summary.json").read_text())
        s.pop("wall_time_s")
        sums.append(s)
    assert sums[0] == sums[1]


def test_tactical_imu_default_run_meets_the_one_third_target(tmp_path, capsys):
    """``navgate gpsins --imu tactical`` on the default 300 s flight (seed 0): GPS/INS RMS at
    most one third of GPS-only, outage inside 3-sigma; the summary carries the optimal-filter
    bound for the IMU (test_bound.py checks its value)."""
    code, _, err = run_cli(["--imu", "tactical", "--out", tmp_path / "t", "--quiet"], capsys)
    assert code == 0, err
    s = json.loads((tmp_path / "t" / "summary.json").read_text())
    assert s["imu"] == "tactical" and s["duration_s"] == 300
    gi = s["gps_ins"]
    assert gi["rms_ratio_to_gps_only"] <= 1 / 3
    assert gi["outage_within_3sigma_per_axis_fraction"] == 1.0
    assert 0 < s["optimal_filter_bound"]["rms_ratio_to_gps_only"] < 1 / 3


@pytest.mark.parametrize("smoother, extra", [("rts", []), ("fixed-lag", ["--lag", 5])])
def test_smoother_adds_a_smoothed_block(tmp_path, capsys, smoother, extra):
    out = tmp_path / "s"
    code, _, err = run_cli(["--duration", 250, "--outage-start", 200, "--smoother", smoother,
                            *extra, "--out", out, "--quiet"], capsys)
    assert code == 0, err
    s = json.loads((out / "summary.json").read_text())
    sm = s["gps_ins_smoothed"]
    assert sm["smoother"] == smoother
    assert isinstance(sm["rms_horizontal_error_m"], float)
    assert sm["rms_horizontal_error_m"] < s["gps_ins"]["rms_horizontal_error_m"]
    assert sm.get("lag_s") == (5.0 if smoother == "fixed-lag" else None)  # absent for rts
    with open(out / "trajectory.csv") as fh:
        assert "smoothed_horizontal_error_m" in fh.readline()


def test_seed_filter_stays_available(tmp_path, capsys):
    code, _, err = run_cli(["--duration", 250, "--outage-start", 200, "--filter", "seed",
                            "--out", tmp_path / "f", "--quiet"], capsys)
    assert code == 0, err
    s = json.loads((tmp_path / "f" / "summary.json").read_text())
    assert s["filter"]["kind"] == "seed" and s["filter"]["n_states"] == 9


@pytest.mark.parametrize("args, message", [
    (["--smoother", "rts", "--filter", "seed"], "needs --filter full"),
    (["--lag", 5], "--lag applies to --smoother fixed-lag"),
    (["--smoother", "fixed-lag", "--lag", 0.5], "--lag must be between"),
    (["--smoother", "fixed-lag", "--lag", 1.5], "--lag must be a whole number of GPS periods"),
    (["--smoother", "fixed-lag", "--lag", "nan"], "finite"),
    (["--smoother", "forward"], "--smoother"),
    (["--duration", 100], "at least 250 s"),
    (["--outage-start", 290], "must end before the flight"),
    (["--rate", 5], "--rate must be between"),
    (["--seed", -1], "non-negative"),
    (["--gyro-noise", 2], "--gyro-noise must be between"),
    (["--duration", "nan"], "finite"),
    (["--bogus"], "No such option"),
    (["--imu", "tactical", "--ideal-sensors"], "exclude each other"),
    (["--imu", "ideal", "--gyro-noise", "0.01"], "exclude each other"),
    (["--imu", "adxrs"], "--imu"),
])
def test_bad_options_one_line_exit_2(tmp_path, capsys, args, message):
    code, _, err = run_cli([*args, "--out", tmp_path / "o", "--quiet"], capsys)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("navgate gpsins: error:")
    assert message in lines[0]
