"""``navgate ahrs``: formats, unit conversion, filters on a synthetic log, bad input, and the
real x-io log (skipped when ../shared/data/fusion_sensor_data.csv is absent)."""

import math
import os
import re
from pathlib import Path

import numpy as np
import pytest

from navgate.cli import main
from navgate.nav.rotations import euler_to_dcm_array

G0 = 9.80665
REPO = Path(__file__).resolve().parents[2]
FUSION_CSV = Path(os.environ.get("NAVGATE_FUSION_CSV",
                                 REPO.parent / "shared" / "data" / "fusion_sensor_data.csv"))


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    """A run without --out writes navgate-out/ahrs/summary.json: keep it out of the tree."""
    monkeypatch.chdir(tmp_path)


def run_cli(args, capsys):
    code = 0
    try:
        main(["ahrs", *map(str, args)])
    except SystemExit as exit_:
        code = exit_.code
    out = capsys.readouterr()
    return code, out.out, out.err


def synthetic(duration=20.0, hz=100.0):
    """Truth and consistent FRD readings for a sensor swinging in roll, pitch and yaw.

    Body rates from the Euler-angle kinematics (exact for the sampled angles' derivatives),
    specific force f = C_n^b (0, 0, -g) (no linear acceleration), field (0.45, 0, 0.9)."""
    t = np.arange(int(duration * hz) + 1) / hz
    w1, w2, w3 = 0.7, 0.5, 0.3
    roll = 0.5 * np.sin(w1 * t)
    pitch = 0.3 * np.sin(w2 * t)
    yaw = 1.2 * np.sin(w3 * t)
    droll, dpitch, dyaw = 0.5 * w1 * np.cos(w1 * t), 0.3 * w2 * np.cos(w2 * t), 1.2 * w3 * np.cos(
        w3 * t)
    # body rates for ZYX angles: p = droll - sin(pitch) dyaw, etc.
    p = droll - np.sin(pitch) * dyaw
    q = np.cos(roll) * dpitch + np.sin(roll) * np.cos(pitch) * dyaw
    r = -np.sin(roll) * dpitch + np.cos(roll) * np.cos(pitch) * dyaw
    cbn = euler_to_dcm_array(roll, pitch, yaw)
    cnb = np.swapaxes(cbn, -1, -2)
    f = cnb @ np.array([0.0, 0.0, -G0])
    m = cnb @ np.array([0.45, 0.0, 0.9])
    return t, np.column_stack([p, q, r]), f, m, np.degrees(np.column_stack([roll, pitch, yaw]))


def write_plain(path, t, gyro, acc, mag=None):
    cols = [t, gyro, acc] + ([mag] if mag is not None else [])
    header = "t,gx,gy,gz,ax,ay,az" + (",mx,my,mz" if mag is not None else "")
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=header, comments="",
               fmt="%.10g")


def write_xio(path, t, gyro, acc, mag):
    """x-io headers and units with z-up (FLU) axes: (x, -y, -z) of the FRD data."""
    s = np.array([1.0, -1.0, -1.0])
    header = ("Time (s),Gyroscope X (deg/s),Gyroscope Y (deg/s),Gyroscope Z (deg/s),"
              "Accelerometer X (g),Accelerometer Y (g),Accelerometer Z (g),"
              "Magnetometer X (uT),Magnetometer Y (uT),Magnetometer Z (uT)")
    data = np.column_stack([t, np.degrees(gyro) * s, acc / G0 * s, mag * 50.0 * s])
    np.savetxt(path, data, delimiter=",", header=header, comments="", fmt="%.10g")


def read_out(path):
    with open(path) as fh:
        assert fh.readline().strip() == "t,qw,qx,qy,qz,roll_deg,pitch_deg,yaw_deg"
    return np.loadtxt(path, delimiter=",", skiprows=1)


def angle_err(a, b):
    d = a - b
    d[:, 2] = (d[:, 2] + 180) % 360 - 180
    return np.abs(d)


@pytest.mark.parametrize("method", ["mahony", "complementary"])
def test_tracks_a_synthetic_swing(tmp_path, capsys, method):
    """Noise-free readings at 100 Hz: the filters follow the truth after the start. Both
    integrate the gyro by one step per sample; the Mahony's first-order step loses
    ~(|w| h)^2 / 8 rad per step relative to the exact rotation (|w| <= 0.6 rad/s, h = 0.01 s:
    4.5e-6 rad) and the sensor-interval mismatch of sampled rates (rates change by <= 0.3
    rad/s^2 * h per step: 3e-5 rad per step), both corrected with rate Kp g >= 0.23/s (the
    weakest mag axis, see tests/attitude/test_mahony.py): steady error <= 3.5e-5 / (0.23 h)
    = 0.015 rad = 0.9 deg; the complementary filter's gain alpha = 0.02 per step pulls
    harder (2/s). Asserted: 1 deg after 10 s."""
    t, gyro, acc, mag, truth = synthetic()
    src = tmp_path / "log.csv"
    out = tmp_path / "att.csv"
    write_plain(src, t, gyro, acc, mag)
    code, stdout, err = run_cli([src, "--filter", method, "--out", out, "--quiet"], capsys)
    assert code == 0, err
    res = read_out(out)
    assert res.shape == (len(t), 8)
    np.testing.assert_allclose(np.linalg.norm(res[:, 1:5], axis=1), 1.0, atol=1e-12)
    e = angle_err(res[:, 5:8], truth)
    assert e[t >= 10].max() < 1.0
    assert e[0].max() < 1e-6  # initialised from the first accelerometer/magnetometer sample


def test_xio_units_and_axes_give_the_same_attitude(tmp_path, capsys):
    """The same motion written in x-io style (deg/s, g, uT x 50, z-up axes) gives the same
    output as the plain SI FRD file: unit conversion is exact up to the 10 significant
    digits written (relative 5e-10), and the magnetometer scale does not matter."""
    t, gyro, acc, mag, _ = synthetic(duration=5.0)
    write_plain(tmp_path / "plain.csv", t, gyro, acc, mag)
    write_xio(tmp_path / "xio.csv", t, gyro, acc, mag)
    for name in ("plain", "xio"):
        code, _, err = run_cli([tmp_path / f"{name}.csv", "--out", tmp_path / f"{name}.out",
                                "--quiet"], capsys)
        assert code == 0, err
    a, b = read_out(tmp_path / "plain.out"), read_out(tmp_path / "xio.out")
    assert np.max(angle_err(a[:, 5:8], b[:, 5:8])) < 1e-5


def test_mahony_without_magnetometer(tmp_path, capsys):
    t, gyro, acc, _, truth = synthetic(duration=12.0)
    write_plain(tmp_path / "imu.csv", t, gyro, acc)
    code, stdout, err = run_cli([tmp_path / "imu.csv", "--out", tmp_path / "o.csv"], capsys)
    assert code == 0, err
    res = read_out(tmp_path / "o.csv")
    e = angle_err(res[:, 5:8], truth)
    assert e[t >= 10, :2].max() < 1.0  # roll and pitch still observed
    assert "not used" in stdout  # the summary (stdout) says the magnetometer was not used


@pytest.mark.parametrize("content, message", [
    ("t,gx,gy,gz,ax,ay\n0,0,0,0,0,0\n", "missing column(s) az"),
    ("t,gx,gy,gz,ax,ay,az,mx,my\n0,0,0,0,0,0,1,0,0\n", "magnetometer columns incomplete"),
    ("", "empty file"),
    ("t,gx,gy,gz,ax,ay,az\n", "no data rows"),
    ("t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,-9.8\n0.02,0,0,0,0,0,-9.8\n0.01,0,0,0,0,0,-9.8\n",
     "time does not increase at line 4"),
    ("Time (s),Gyroscope X (rpm),Gyroscope Y (rpm),Gyroscope Z (rpm)\n0,0,0,0\n",
     "unknown gyroscope unit 'rpm'"),
])
def test_bad_input_one_line_exit_2(tmp_path, capsys, content, message):
    src = tmp_path / "bad.csv"
    src.write_text(content)
    code, _, err = run_cli([src], capsys)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("navgate ahrs: error:")
    assert message in lines[0]
    assert "Traceback" not in err


def test_missing_file_and_bad_option(tmp_path, capsys):
    code, _, err = run_cli([tmp_path / "nope.csv"], capsys)
    assert code == 2 and "no such file" in err
    t, gyro, acc, mag, _ = synthetic(duration=1.0)
    write_plain(tmp_path / "ok.csv", t, gyro, acc, mag)
    code, _, err = run_cli([tmp_path / "ok.csv", "--kp", "-1"], capsys)
    assert code == 2 and "non-negative" in err
    code, _, err = run_cli([tmp_path / "ok.csv", "--filter", "complementary", "--gain", "2"],
                           capsys)
    assert code == 2 and "between 0 and 1" in err


def test_nan_and_garbage_rows_are_skipped_and_counted(tmp_path, capsys):
    t, gyro, acc, mag, truth = synthetic(duration=3.0)
    src = tmp_path / "holes.csv"
    write_plain(src, t, gyro, acc, mag)
    lines = src.read_text().splitlines()
    lines[10] = lines[10].replace(lines[10].split(",")[4], "nan", 1)
    lines[20] = "0.2,abc,0,0,0,0,-9.8,1,0,0"
    lines[30] = ""
    src.write_text("\n".join(lines) + "\n")
    code, stdout, err = run_cli([src, "--out", tmp_path / "o.csv"], capsys)
    assert code == 0, err
    res = read_out(tmp_path / "o.csv")
    assert len(res) == len(t) - 3
    assert re.search(r"skipped rows\D*3\D", stdout)
    assert np.isfinite(res).all()


@pytest.mark.skipif(not FUSION_CSV.exists(), reason="shared x-io log not present")
def test_real_xio_log(tmp_path, capsys):
    """The shared 100 Hz x-io log: both filters run, and in the first 5 s (the sensor lies
    still: |gyro| <= 1 deg/s) their roll and pitch equal the accelerometer tilt of that
    window to within 0.5 deg (the accelerometer noise is ~1e-3 g, i.e. 0.06 deg, and both
    filters start from it)."""
    from navgate.sim.imu_log import read_imu_csv

    log = read_imu_csv(FUSION_CSV)
    assert log.style == "x-io" and len(log) > 10000 and log.mag is not None
    still = log.t < 5.0
    f = log.acc[still].mean(axis=0) * np.array([1, -1, -1])  # FLU -> FRD
    roll_acc = math.degrees(math.atan2(-f[1], -f[2]))
    pitch_acc = math.degrees(math.asin(f[0] / np.linalg.norm(f)))
    for method in ("mahony", "complementary"):
        out = tmp_path / f"{method}.csv"
        code, _, err = run_cli([FUSION_CSV, "--filter", method, "--out", out, "--quiet"],
                               capsys)
        assert code == 0, err
        res = read_out(out)
        assert len(res) == len(log)
        assert np.all(np.abs(res[still, 5] - roll_acc) < 0.5)
        assert np.all(np.abs(res[still, 6] - pitch_acc) < 0.5)


def _level_log(path, n=300, hz=100.0, t_scale=1.0, roll_deg=0.0, acc_scale=1.0):
    t = np.arange(n) / hz * t_scale
    r = math.radians(roll_deg)
    acc = np.tile([0.0, -G0 * math.sin(r), -G0 * math.cos(r)], (n, 1)) * acc_scale
    np.savetxt(path, np.column_stack([t, np.zeros((n, 3)), acc, np.tile([20.0, 0.0, 40.0],
                                                                         (n, 1))]),
               delimiter=",", header="t,gx,gy,gz,ax,ay,az,mx,my,mz", comments="", fmt="%.10g")
    return path


def _one_line(err):
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in err and "internal error" not in err, err
    return lines[0]


@pytest.mark.parametrize("engine", ["reference", "fp32", "rtl"])
def test_absurd_period_and_gains_refused_by_every_engine(engine, tmp_path, capsys):
    """The circuit engines keep the reference's bounds (issue 31): a picosecond time step, an
    unstable --ki, --kp 1e6 and a zero accelerometer are one line, exit 2, before any run."""
    pico = _level_log(tmp_path / "pico.csv", t_scale=1e-10)
    level = _level_log(tmp_path / "level.csv")
    zero = _level_log(tmp_path / "zero.csv", acc_scale=0.0)
    for args, needle in (([pico], "1e-12 s"),
                         # with a magnetometer the bound is ki T^2 < 2 (1 - kp T)
                         ([level, "--ki", "1e5"], "ki < 1.98e+04"),
                         ([level, "--kp", "1e6"], "kp * dt = 1e+04"),
                         ([zero], "zero specific force")):
        code, _, err = run_cli([*args, "--engine", engine], capsys)
        assert code == 2 and needle in _one_line(err), (args, err)


def test_ki_bound_is_the_discrete_stability_limit(tmp_path, capsys):
    """Just inside the bound (ki dt^2 < 4 - 2 kp dt) the filter still levels a 10 deg tilt
    from an identity start; just outside it is refused."""
    tilt = _level_log(tmp_path / "tilt.csv", n=3000, roll_deg=10.0)
    code, out, err = run_cli([tilt, "--init", "identity", "--no-mag", "--ki", "39000"], capsys)
    assert code == 0, err
    roll = float(re.search(r"final roll / pitch / yaw\s*│\s*([-\d.]+)", out).group(1))
    assert roll == pytest.approx(10.0, abs=0.05)
    code, _, err = run_cli([tilt, "--init", "identity", "--ki", "39801"], capsys)
    assert code == 2 and "unstable" in _one_line(err)
