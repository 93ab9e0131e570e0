"""``navgate ahrs --engine reference|fp32|rtl``: the seed 003 circuit's engines write
identical CSVs, track the truth of a synthetic swing, and refuse what the circuit cannot do."""

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
    assert rows.shape == (len(truth), 8)
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
