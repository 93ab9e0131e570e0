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


# ---------------------------------------------------------------------------------------------
# damaged logs (issue 31): resynchronisation, the used fraction, malformed headers, outputs


@pytest.fixture(scope="module")
def short_log(tmp_path_factory):
    """A 5 s INS-only flight's record log (with truth) and fly's summary of it."""
    d = tmp_path_factory.mktemp("short")
    proc = navgate("fly", "--duration", "5", "--no-trn", "--record", str(d / "f.log"), "--out",
                   str(d / "fly"))
    assert proc.returncode == 0, proc.stderr
    assert "wrote the sensor record log" in proc.stderr  # fly says it wrote the record
    return d / "f.log", json.loads((d / "fly" / "summary.json").read_text())


def _lines(log):
    return log.read_text().splitlines()


def test_replay_writes_fly_report_and_used_fraction(short_log, tmp_path, navgate_run):
    log, fly_summary = short_log
    code, out, err = navgate_run(["replay", log, "--out", tmp_path / "r"])
    assert code == 0, err
    names = sorted(p.name for p in (tmp_path / "r").iterdir())
    assert names == ["errors.png", "summary.json", "track.png", "trajectory.csv",
                     "trn_fixes.csv"]
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert s["used_fraction"] == 1.0 and s["records_read"] == len(_lines(log)) - 2
    assert s["scored"]
    for key in ("final_horizontal_error_m", "rms_horizontal_error_second_half_m",
                "nees_position_mean"):
        assert s["ins_only"][key] == fly_summary["ins_only"][key], key
    assert "used 100.00 % of the log's" in out
    rows = (tmp_path / "r" / "trajectory.csv").read_text().splitlines()
    assert rows[0].startswith("t_s,truth_lat_deg") and len(rows) == 1 + 5 * 10 + 1


def test_replay_resynchronises_after_a_wrong_time_stamp(short_log, tmp_path, navgate_run):
    """One stamp far ahead used to make every later record "time goes backwards" (99.6 % of
    the log dropped, still scored); now it costs that record alone."""
    log, fly_summary = short_log
    lines = _lines(log)
    k = next(i for i, ln in enumerate(lines) if ln.startswith("I,")) + 10
    parts = lines[k].split(",")
    lines[k] = ",".join([parts[0], "1e9", *parts[2:]])
    bad = tmp_path / "stamp.log"
    bad.write_text("\n".join(lines) + "\n")
    code, _, err = navgate_run(["replay", bad, "--out", tmp_path / "r", "--quiet"])
    assert code == 0, err
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert s["bad_records"] == {"time out of order": 1}
    assert s["imu_records"] == 1999 and s["records"] == s["records_read"] - 1
    assert s["used_fraction"] == pytest.approx(1 - 1 / s["records_read"], abs=1e-15)
    # the whole 5 s navigated (50 of 51 solutions at 10 Hz: one IMU sample short): metres, not the
    # kilometres of a log cut after its 10th sample
    rows = (tmp_path / "r" / "trajectory.csv").read_text().splitlines()
    assert len(rows) >= 1 + 50
    assert abs(s["ins_only"]["final_horizontal_error_m"]
               - fly_summary["ins_only"]["final_horizontal_error_m"]) < 5.0


def test_replay_refuses_a_log_it_can_use_too_little_of(short_log, tmp_path, navgate_run):
    log, _ = short_log
    lines = _lines(log)
    imu = [i for i, ln in enumerate(lines) if ln.startswith("I,")]
    for i in imu[::3]:  # a third of the IMU words overflow int16
        lines[i] = lines[i].rsplit(",", 1)[0] + ",40000"
    bad = tmp_path / "overflow.log"
    bad.write_text("\n".join(lines) + "\n")
    code, _, err = navgate_run(["replay", bad, "--out", tmp_path / "r"])
    line = navgate_run.one_line(err)
    assert code == 2 and "below --min-used 0.95" in line and "IMU word outside int16" in line
    assert not (tmp_path / "r").exists()
    code, _, err = navgate_run(["replay", bad, "--out", tmp_path / "r", "--min-used", "0.5",
                                "--quiet"])
    assert code == 0, err
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    assert s["bad_records"] == {"IMU word outside int16": len(imu[::3])}
    assert s["used_fraction"] == pytest.approx(1 - len(imu[::3]) / s["records_read"])
    for value in ("1.5", "-0.1", "nan"):
        code, _, err = navgate_run(["replay", bad, "--min-used", value])
        assert code == 2 and "--min-used" in navgate_run.one_line(err)


def _with_header(log, tmp_path, edit):
    lines = _lines(log)
    header = json.loads(lines[1][2:])
    text = edit(header)
    lines[1] = "H " + (text if isinstance(text, str) else json.dumps(header))
    path = tmp_path / "h.log"
    path.write_text("\n".join(lines) + "\n")
    return path


def _p0(value):
    def edit(h):
        h["initial"]["p0"] = value(h["initial"]["p0"])
    return edit


def _nav(index, value):
    def edit(h):
        h["initial"]["nav"][index] = value
    return edit


HEADERS = {
    "NaN P0": (_p0(lambda p: [[float("nan")] * 15] * 15), "initial.p0 holds non-finite"),
    "indefinite P0": (_p0(lambda p: [[-x for x in row] for row in p]), "not positive definite"),
    "asymmetric P0": (_p0(lambda p: [[1.0 if j > i else 0.0 for j in range(15)]
                                     for i in range(15)]), "not symmetric"),
    "P0 shape": (_p0(lambda p: [row[:14] for row in p]), "initial.p0 has shape (15, 14)"),
    "NaN state": (_nav(3, float("nan")), "initial.nav holds non-finite"),
    "latitude 100 deg": (_nav(0, 1.745329), "latitude"),
    "state shape": (lambda h: h["initial"].update(nav=[0.1] * 9), "initial.nav has shape"),
    "gyro matrix shape": (lambda h: h["calibration"].update(gyro_matrix=[1.0, 0.0]),
                          "calibration.gyro_matrix has shape"),
    "negative lsb": (lambda h: h["calibration"].update(accel_lsb=-1.0), "accel_lsb"),
    "reference latitude": (lambda h: h["reference"].update(lat_rad=2.0), "reference.lat_rad"),
    "missing initial": (lambda h: h.pop("initial"), "lacks 'initial'"),
    "zero imu rate": (lambda h: h["config"].update(imu_rate_hz=0.0), "flight configuration"),
    "TRN fix interval 0": (lambda h: h["trn"].update(fix_interval_s=0.0), "fix_interval_s"),
    "unknown TRN setting": (lambda h: h["trn"].update(magic=1), "unknown TRN setting(s): magic"),
    "old layout, unknown method": (lambda h: (h.pop("trn"), h["config"].update(
        trn_method="magic")), "unknown TRN method 'magic'"),
    "nested 100,000 deep": (lambda h: "[" * 100_000 + "]" * 100_000, "nested too deeply"),
    "not an object": (lambda h: "[1, 2]", "not a JSON object"),
}


@pytest.mark.parametrize("case", sorted(HEADERS))
def test_malformed_headers_are_one_line(case, short_log, tmp_path, navgate_run):
    log, _ = short_log
    edit, needle = HEADERS[case]
    path = _with_header(log, tmp_path, edit)
    code, _, err = navgate_run(["replay", path, "--out", tmp_path / "r"])
    line = navgate_run.one_line(err)
    assert code == 2 and needle in line, line
    assert not (tmp_path / "r").exists()


def test_interrupted_replay_keeps_the_previous_results(short_log, tmp_path, navgate_run,
                                                       monkeypatch):
    """An interrupt while the report is written: exit 130, the previous summary intact."""
    import navgate.systems.ins_trn.ps.report as report

    log, _ = short_log
    out = tmp_path / "r"
    out.mkdir()
    (out / "summary.json").write_text("previous\n")

    def interrupt(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(report, "plot_errors", interrupt)
    code, _, err = navgate_run(["replay", log, "--out", out, "--quiet"])
    assert code == 130 and "interrupted" in navgate_run.one_line(err)
    assert sorted(p.name for p in out.iterdir()) == ["summary.json"]
    assert (out / "summary.json").read_text() == "previous\n"
    assert not [p for p in tmp_path.iterdir() if "navgate-tmp" in p.name]


def _old_layout(h):
    """The header as logs written before the scenario/navigator split have it: the TRN
    settings inside the flight configuration, under their old names."""
    trn = h.pop("trn")
    h["config"].update(trn_method=trn["method"], fix_interval_s=trn["fix_interval_s"],
                       lag_compensation=trn["lag_compensation"], pmf=trn["pmf"],
                       tercom=trn["tercom"])


def test_replay_reads_a_log_of_the_old_header_layout(short_log, tmp_path, navgate_run):
    """A log whose config still holds the TRN keys replays as the new layout does."""
    log, fly_summary = short_log
    assert "trn" in json.loads(_lines(log)[1][2:])  # fly writes the new layout
    path = _with_header(log, tmp_path, _old_layout)
    code, _, err = navgate_run(["replay", path, "--out", tmp_path / "r"])
    assert code == 0, err
    s = json.loads((tmp_path / "r" / "summary.json").read_text())
    for key in ("final_horizontal_error_m", "rms_horizontal_error_second_half_m",
                "nees_position_mean"):
        assert s["ins_only"][key] == fly_summary["ins_only"][key], key
