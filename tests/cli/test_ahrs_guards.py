"""``navgate ahrs`` with absurd logs and gains: every engine (reference, fp32, rtl)
ends with the same one line and exit 2 (the checks of estimate.check_run run before any
filtering or Verilator build), and writes no output."""

from __future__ import annotations

import numpy as np
import pytest

from navgate.cli import main

G0 = 9.80665


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


def write(path, t, acc):
    n = len(t)
    cols = [t, np.zeros((n, 3)), np.tile(acc, (n, 1)), np.tile([0.45, 0.0, 0.9], (n, 1))]
    np.savetxt(path, np.column_stack(cols), delimiter=",", comments="", fmt="%.10g",
               header="t,gx,gy,gz,ax,ay,az,mx,my,mz")
    return path


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("ahrs_guards")
    t = np.arange(401) / 100.0
    return {"level": write(d / "level.csv", t, [0.0, 0.0, -G0]),
            "picosecond": write(d / "ps.csv", np.arange(401) * 1e-12, [0.0, 0.0, -G0]),
            "zero acc": write(d / "zero.csv", t, [0.0, 0.0, 0.0])}


CASES = {
    "picosecond step": ("picosecond", [], "dt:"),
    "zero accelerometer": ("zero acc", [], "specific force is zero"),
    "ki 1e5": ("level", ["--ki", "1e5"], "ki:"),
    "kp 1e6": ("level", ["--kp", "1e6"], "kp"),
}


@pytest.mark.parametrize("engine", ["reference", "fp32", "rtl"])
@pytest.mark.parametrize("case", list(CASES), ids=list(CASES))
def test_one_line_exit_2_for_every_engine(logs, tmp_path, capsys, engine, case):
    key, extra, word = CASES[case]
    out = tmp_path / "att.csv"
    code, stdout, err = run_cli([logs[key], "--engine", engine, "--out", out, *extra], capsys)
    lines = err.strip().splitlines()
    assert code == 2, (stdout, err)
    assert len(lines) == 1 and lines[0].startswith("navgate ahrs: error:"), err
    assert word in lines[0], lines[0]
    assert "Traceback" not in err and not out.exists()


def test_sound_gains_still_run(logs, tmp_path, capsys):
    """ki just inside the bound at 100 Hz (ki < 2 (1 - kp T) / T^2 = 19800 at kp 1) runs."""
    out = tmp_path / "att.csv"
    code, _, err = run_cli([logs["level"], "--ki", "19000", "--out", out, "--quiet"], capsys)
    assert code == 0, err
    rows = np.loadtxt(out, delimiter=",", skiprows=1)
    assert np.abs(rows[:, 5:7]).max() < 1e-6  # a level, still, noise-free log stays level
