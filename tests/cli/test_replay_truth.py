"""``navgate replay`` scoring against truth only at the truth's own times (a log missing a
truth record, truncated mid-record, or with a gap in its truth), header configurations that
ended in ``internal error``, and a log recorded over another DEM (audit of the replay)."""

import csv
import json
import subprocess
import sys

import pytest


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    """A 5 s INS+TRN flight's record log and fly's trajectory (t_s -> row)."""
    d = tmp_path_factory.mktemp("flight")
    proc = subprocess.run([sys.executable, "-m", "navgate.cli", "fly", "--duration", "5",
                           "--record", str(d / "f.log"), "--out", str(d / "fly"), "--quiet"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    with open(d / "fly" / "trajectory.csv") as fh:
        rows = {row["t_s"]: row for row in csv.DictReader(fh)}
    return d / "f.log", rows


def _write(tmp_path, lines, name="edited.log"):
    path = tmp_path / name
    path.write_text("\n".join(lines) + "\n")
    return path


def _replay(navgate_run, log, out):
    code, stdout, err = navgate_run(["replay", log, "--out", out])
    assert code == 0, err
    with open(out / "trajectory.csv") as fh:
        rows = list(csv.DictReader(fh))
    return json.loads((out / "summary.json").read_text()), rows, stdout, err


def _no_duplicate_times(rows):
    times = [r["t_s"] for r in rows]
    assert len(times) == len(set(times)), times


def test_a_missing_last_truth_record_is_not_borrowed(flight, tmp_path, navgate_run):
    """Without T at 5.0 the 5.0 s solution was scored against the 4.9 s truth (8.8 m, not
    6.5 m, "used 100 %") and trajectory.csv had two rows stamped 4.9."""
    log, fly_rows = flight
    lines = [ln for ln in log.read_text().splitlines() if not ln.startswith("T,5.0,")]
    s, rows, stdout, err = _replay(navgate_run, _write(tmp_path, lines), tmp_path / "r")
    _no_duplicate_times(rows)
    assert s["scored"] and s["truth"]["scored_solutions"] == 50
    assert s["truth"]["solutions"] == 51 and s["truth"]["unscored_intervals_s"] == [[5.0, 5.0]]
    for run in ("ins_only", "trn_aided"):  # the final scored figure is fly's at 4.9 s
        assert s[run]["final_horizontal_error_m"] == pytest.approx(
            float(fly_rows["4.9"][f"{run}_horizontal_error_m"]), rel=1e-8)
    assert rows[-1]["t_s"] == "5" and rows[-1]["truth_lat_deg"] == "nan"
    assert "truth scored 50 of 51 solutions" in stdout and "warning: truth scored" in err


def test_a_log_truncated_mid_record_scores_no_duplicate(flight, tmp_path, navgate_run):
    log, _ = flight
    text = log.read_text()
    cut = text.index("\nT,2.6,") + 20  # inside the 2.6 s truth record
    path = tmp_path / "cut.log"
    path.write_text(text[:cut])
    s, rows, _, _ = _replay(navgate_run, path, tmp_path / "r")
    _no_duplicate_times(rows)
    assert s["bad_records"] == {"truncated record": 1}
    assert s["truth"]["scored_solutions"] == s["truth"]["solutions"] - 1


def test_a_gap_in_the_truth_scores_the_rest(flight, tmp_path, navgate_run):
    """Truth missing over 2-3 s used to drop all scoring ("- (no truth)", scored false)."""
    log, fly_rows = flight
    lines = [ln for ln in log.read_text().splitlines()
             if not (ln.startswith("T,") and 2.0 <= float(ln.split(",")[1]) <= 3.0)]
    s, rows, stdout, _ = _replay(navgate_run, _write(tmp_path, lines), tmp_path / "r")
    assert s["scored"] and s["truth"]["records"] == 40
    assert s["truth"]["scored_solutions"] == 40
    assert s["truth"]["unscored_intervals_s"] == [[2.0, 3.0]]
    assert s["ins_only"]["final_horizontal_error_m"] == pytest.approx(
        float(fly_rows["5"]["ins_only_horizontal_error_m"]), rel=1e-8)
    assert sorted(p.name for p in (tmp_path / "r").iterdir()) == [
        "errors.png", "summary.json", "track.png", "trajectory.csv", "trn_fixes.csv"]
    assert "no truth)" not in stdout and "no truth at 2-3 s" in stdout


def _with_header(log, tmp_path, edit):
    lines = log.read_text().splitlines()
    header = json.loads(lines[1][2:])
    edit(header)
    lines[1] = "H " + json.dumps(header)
    return _write(tmp_path, lines, "h.log")


@pytest.mark.parametrize("section, key, needle", [
    ("config", "init_gyro_bias_sigma", "config.init_gyro_bias_sigma"),
    ("config", "init_accel_bias_sigma", "config.init_accel_bias_sigma"),
    ("config", "imu_rate_hz", "config.imu_rate_hz"),
    ("calibration", "gyro_lsb", "navigation failed"),
    ("calibration", "accel_lsb", "navigation failed"),
])
def test_absurd_header_numbers_are_one_line_exit_2(flight, tmp_path, navgate_run, section, key,
                                                   needle):
    """1e300 in these fields was an OverflowError or ValueError: "internal error", exit 3."""
    log, _ = flight
    path = _with_header(log, tmp_path, lambda h: h[section].update({key: 1e300}))
    code, _, err = navgate_run(["replay", path, "--out", tmp_path / "r", "--quiet"])
    line = navgate_run.one_line(err)
    assert code == 2 and needle in line, line
    assert not (tmp_path / "r").exists()


def test_a_log_over_another_dem_needs_dem(flight, tmp_path, navgate_run):
    """A log recorded over another DEM replayed silently over the embedded one."""
    log, _ = flight
    path = _with_header(log, tmp_path, lambda h: h.update(dem="swiss.tif"))
    code, _, err = navgate_run(["replay", path, "--out", tmp_path / "r"])
    line = navgate_run.one_line(err)
    assert code == 2 and "'swiss.tif'" in line and "--dem" in line
    assert not (tmp_path / "r").exists()


def test_replay_summary_has_fly_fix_rejection_reasons(flight, tmp_path, navgate_run):
    log, _ = flight
    s, _, _, _ = _replay(navgate_run, log, tmp_path / "r")
    reasons = s["trn_aided"]["fix_rejection_reasons"]
    assert sum(reasons.values()) == s["trn_aided"]["fixes_rejected"]
    assert s["truth"]["coverage"] == 1.0


def test_the_final_state_is_stamped_at_its_own_time(flight, tmp_path, navgate_run):
    """A log ending one IMU sample short of a log boundary: the last row holds the state at
    4.9975 s; it was stamped 4.9 s and scored against the 4.9 s truth."""
    log, _ = flight
    lines = log.read_text().splitlines()
    last = max(i for i, ln in enumerate(lines) if ln.startswith("I,"))
    s, rows, _, _ = _replay(navgate_run, _write(tmp_path, lines[:last]), tmp_path / "r")
    _no_duplicate_times(rows)
    assert float(rows[-1]["t_s"]) == pytest.approx(4.9975, abs=1e-12)
    assert s["truth"]["unscored_intervals_s"] == [[pytest.approx(4.9975), pytest.approx(4.9975)]]
