"""``navgate ahrs --engine reference|fp32|rtl``: the seed 003 circuit's engines write
identical CSVs, track the truth of a synthetic swing, and refuse what the circuit cannot do;
the circuit's invalid (NaN) rows are flagged, summarised and end the run with exit 2; time
gaps are counted by every engine; every run writes its JSON summary."""

import json
import math
import re

import numpy as np
import pytest

from navgate.cli import main
from navgate.nav.rotations import euler_to_dcm_array

G0 = 9.80665


def run_cli(args, capsys):
    code = 0
    try:
        main(["ahrs", *map(str, args)])
    except SystemExit as exit_:
        code = exit_.code
    out = capsys.readouterr()
    return code, out.out, out.err


def write_plain(path, t, gyro, acc, mag=None):
    cols = [t, gyro, acc] + ([mag] if mag is not None else [])
    header = "t,gx,gy,gz,ax,ay,az" + (",mx,my,mz" if mag is not None else "")
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=header, comments="",
               fmt="%.10g")


def still(duration=4.0, hz=100.0, rpy_deg=(20.0, -10.0, 30.0)):
    """A sensor held still at roll/pitch/yaw ``rpy_deg`` (FRD readings, rad/s, m/s^2):
    f = C_n^b (0, 0, -g), field (0.45, 0, 0.9) in NED."""
    t = np.arange(int(duration * hz) + 1) / hz
    r, p, y = np.radians(rpy_deg)
    cnb = euler_to_dcm_array(r, p, y).T
    n = len(t)
    f = np.tile(cnb @ np.array([0.0, 0.0, -G0]), (n, 1))
    m = np.tile(cnb @ np.array([0.45, 0.0, 0.9]), (n, 1))
    return t, np.zeros((n, 3)), f, m, np.tile(rpy_deg, (n, 1))


@pytest.fixture(scope="module")
def swing(tmp_path_factory):
    path = tmp_path_factory.mktemp("ahrs") / "still.csv"
    t, gyro, acc, mag, truth = still()
    write_plain(path, t, gyro, acc, mag)
    return path, truth


def test_fp32_and_rtl_write_identical_csvs(swing, tmp_path, capsys):
    path, truth = swing
    texts = {}
    for engine in ("fp32", "rtl"):
        out = tmp_path / f"{engine}.csv"
        code, _, err = run_cli([path, "--engine", engine, "--out", out, "--kp", 5,
                                "--quiet"], capsys)
        assert code == 0, err
        texts[engine] = out.read_text()
    assert texts["fp32"] == texts["rtl"]
    rows = np.loadtxt(tmp_path / "rtl.csv", delimiter=",", skiprows=1)
    assert rows.shape == (len(truth), 9)  # t, q, roll/pitch/yaw, invalid
    assert not rows[:, 8].any()
    # the float64 filter from identity with the same gains sees the same samples: its row
    # k + 1 (k + 1 updates) is the circuit's row k (k + 1 updates, the first sample
    # included). They differ by float32 rounding and the fix16 angle output: the Q2.13
    # arctangent is within 3 LSB = 0.021 deg (tests/systems/attitude/test_mahony_fp32.py)
    ref = tmp_path / "ref.csv"
    code, _, err = run_cli([path, "--out", ref, "--kp", 5, "--init", "identity", "--quiet"],
                           capsys)
    assert code == 0, err
    r64 = np.loadtxt(ref, delimiter=",", skiprows=1)
    d = rows[:-1, 5:8] - r64[1:, 5:8]
    d[:, 2] = (d[:, 2] + 180) % 360 - 180
    assert np.abs(d).max() < 0.03
    assert np.abs(rows[:-1, 1:5] - r64[1:, 1:5]).max() < 1e-4
    assert np.abs(rows[0, 5:8] - truth[0]).max() > 5  # it did start from identity
    assert np.abs(np.linalg.norm(rows[:, 1:5], axis=1) - 1).max() < 1e-6


@pytest.mark.parametrize("extra,message", [
    (["--no-mag"], "always uses the magnetometer"),
    (["--filter", "complementary"], "use --filter mahony"),
])
def test_circuit_engines_refuse(swing, capsys, extra, message):
    path, _ = swing
    code, _, err = run_cli([path, "--engine", "fp32", *extra], capsys)
    assert code == 2
    assert message in err and len(err.strip().splitlines()) == 1


def test_engine_needs_magnetometer(tmp_path, capsys):
    t, gyro, acc, _mag, _ = still(duration=0.5)
    path = tmp_path / "imu.csv"
    write_plain(path, t, gyro, acc)
    code, _, err = run_cli([path, "--engine", "rtl"], capsys)
    assert code == 2 and "magnetometer" in err


def test_unknown_engine(swing, capsys):
    path, _ = swing
    code, _, err = run_cli([path, "--engine", "gpu"], capsys)
    assert code == 2 and "engine" in err


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    """A run without --out writes navgate-out/ahrs/summary.json: keep it out of the tree."""
    monkeypatch.chdir(tmp_path)


def _still_log(path, zero=None, rows=slice(20, 30), gap_after=None, gap_s=0.52):
    """The still sensor of :func:`still` (0.5 s at 100 Hz), with the accelerometer (``zero=
    "acc"``) or magnetometer (``"mag"``) columns 0 over ``rows``, and a time gap of ``gap_s``
    after sample ``gap_after``."""
    t, gyro, acc, mag, _ = still(duration=0.5)
    if zero == "acc":
        acc[rows] = 0.0
    elif zero == "mag":
        mag[rows] = 0.0
    if gap_after is not None:
        t[gap_after + 1:] += gap_s - (t[1] - t[0])
    write_plain(path, t, gyro, acc, mag)
    return path


@pytest.mark.parametrize("engine, zero, first, reason", [
    ("fp32", "acc", 20, "zero-norm acceleration"),
    ("fp32", "mag", 20, "zero-norm magnetic field"),
    ("rtl", "acc", 20, "zero-norm acceleration"),
])
def test_circuit_invalid_output_is_flagged_and_exits_2(tmp_path, capsys, engine, zero, first,
                                                       reason):
    """Free fall (accelerometer 0 for 10 rows) or a dead magnetometer makes the circuit's
    state NaN for good (its genuine float32 behaviour): the CSV flags those rows (column
    invalid = 1, nan in every attitude column, never the arctangent-of-NaN 99.88 deg as an
    angle), the table and summary.json give the count, the first invalid sample and why, no
    final attitude is printed as valid, and the run ends with one line and exit 2. It used
    to exit 0 with bare NaN rows and "final roll / pitch / yaw 99.88 / 99.88 / 99.88"."""
    log = _still_log(tmp_path / "imu.csv", zero=zero)
    out = tmp_path / "att.csv"
    code, stdout, err = run_cli([log, "--engine", engine, "--out", out], capsys)
    assert code == 2, err
    lines = [ln for ln in err.splitlines() if "error" in ln]
    assert len(lines) == 1 and "Traceback" not in err, err
    assert f"invalid at sample {first}" in lines[0] and reason in lines[0], lines[0]
    # the CSV: written (the rows before are the engineer's evidence), every later row flagged
    header = out.read_text().splitlines()[0]
    assert header == "t,qw,qx,qy,qz,roll_deg,pitch_deg,yaw_deg,invalid"
    rows = np.genfromtxt(out, delimiter=",", skip_header=1)
    flag = rows[:, 8]
    assert set(np.unique(flag)) <= {0.0, 1.0}
    assert not flag[:first].any() and flag[first:].all()
    assert np.isfinite(rows[:first, 1:8]).all()
    assert np.isnan(rows[first:, 1:8]).all()
    assert not np.isclose(rows[:, 5:8], 99.87595).any()
    # the summary beside it
    summary = json.loads((tmp_path / "att.summary.json").read_text())
    n = len(rows)
    assert summary["engine"] == engine and summary["samples"] == n
    assert summary["invalid_samples"] == n - first
    assert summary["first_invalid_sample"] == first
    assert summary["first_invalid_t_s"] == pytest.approx(rows[first, 0], abs=1e-6)
    assert reason in summary["first_invalid_reason"]
    assert summary["final_valid"] is False and "final_roll_deg" not in summary
    assert summary["last_valid_sample"] == first - 1
    assert summary["last_valid_roll_deg"] == pytest.approx(rows[first - 1, 5], abs=1e-5)
    # the table: no invalid final attitude printed as one
    assert "99.88" not in stdout
    assert "INVALID" in stdout and "first invalid sample" in stdout, stdout


def test_circuit_invalid_without_out_still_summarised(tmp_path, capsys):
    log = _still_log(tmp_path / "imu.csv", zero="acc")
    code, _, err = run_cli([log, "--engine", "fp32", "--quiet"], capsys)
    assert code == 2 and "invalid at sample 20" in err
    summary = json.loads((tmp_path / "navgate-out/ahrs/summary.json").read_text())
    assert summary["invalid_samples"] == 31 and summary["first_invalid_sample"] == 20


@pytest.mark.parametrize("engine", ["reference", "fp32"])
def test_time_gaps_counted_by_every_engine(tmp_path, capsys, engine):
    """A 0.52 s gap in a 100 Hz log: the reference restarts its filter there, the fixed-rate
    circuit runs through it, and both count it (table and summary). fp32 used to say
    nothing. The gap rule is the reference's: a step over GAP_PERIODS (5) nominal periods."""
    log = _still_log(tmp_path / "imu.csv", gap_after=25)
    out = tmp_path / "att.csv"
    code, stdout, err = run_cli([log, "--engine", engine, "--out", out], capsys)
    assert code == 0, err
    assert re.search(r"time gaps[^│]*│\s*1\s*│", stdout), stdout
    summary = json.loads((tmp_path / "att.summary.json").read_text())
    assert summary["time_gaps"] == 1
    code, _, err = run_cli([_still_log(tmp_path / "plain.csv"), "--engine", engine, "--out",
                            tmp_path / "plain_att.csv", "--quiet"], capsys)
    assert code == 0, err
    assert json.loads((tmp_path / "plain_att.summary.json").read_text())["time_gaps"] == 0


@pytest.mark.parametrize("engine", ["reference", "fp32"])
@pytest.mark.parametrize("with_out", [True, False])
def test_every_engine_writes_its_summary(tmp_path, capsys, engine, with_out):
    """summary.json beside the report: OUT_STEM.summary.json beside --out, else
    navgate-out/ahrs/summary.json; its counts and final attitude are the table's and the
    CSV's. ahrs used to write none."""
    log = _still_log(tmp_path / "imu.csv")
    out = tmp_path / "att.csv"
    args = [log, "--engine", engine] + (["--out", out] if with_out else [])
    code, stdout, err = run_cli(args, capsys)
    assert code == 0, err
    path = tmp_path / ("att.summary.json" if with_out else "navgate-out/ahrs/summary.json")
    summary = json.loads(path.read_text())
    assert str(path.name) in " ".join(err.split())
    for key in ("log", "engine", "samples", "skipped_rows", "implausible_rows", "time_gaps",
                "invalid_samples", "final_roll_deg", "final_pitch_deg", "final_yaw_deg",
                "wall_seconds"):
        assert key in summary, key
    assert summary["engine"] == engine and summary["log"] == str(log)
    assert summary["samples"] == 51 and summary["invalid_samples"] == 0
    assert summary["final_valid"] is True
    assert None not in summary.values()  # keys that do not apply are absent, never null
    assert all(math.isfinite(v) for v in summary.values() if isinstance(v, float))
    final = "{:.2f} / {:.2f} / {:.2f} deg".format(
        *(summary[f"final_{a}_deg"] for a in ("roll", "pitch", "yaw")))
    assert final in stdout
    if with_out:
        assert summary["out"] == str(out)
        last = np.loadtxt(out, delimiter=",", skiprows=1)[-1]
        assert summary["final_roll_deg"] == pytest.approx(last[5], abs=1e-5)
    else:
        assert "out" not in summary and not out.exists()
