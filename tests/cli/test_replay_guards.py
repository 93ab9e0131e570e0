"""Issue 31, ``navgate replay`` of a log whose header holds an initial state the engines
refuse (NaN or indefinite P0, latitude 100 deg, a height of -7,000 km, a zero quaternion):
one line naming the field, exit 2, no output directory (it ended in ``internal error``,
exit 3, before)."""

from __future__ import annotations

import json
import math

import pytest

from navgate.cli import main


def run_cli(args, capsys):
    code = 0
    try:
        main(["replay", *map(str, args)])
    except SystemExit as exit_:
        code = exit_.code
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.fixture(scope="module")
def log_lines(tmp_path_factory):
    from navgate.sim.flight import FlightConfig
    from navgate.systems.ins_trn.ps.flight import record_stream
    from navgate.systems.ins_trn.ps.records import write_log
    from navgate.trn.dem import Dem

    path = tmp_path_factory.mktemp("replay_guards") / "flight.log"
    _, _, stream = record_stream(Dem.default(), FlightConfig(duration_s=5.0, seed=1))
    write_log(stream, path)
    return path.read_text().splitlines(keepends=True)


def damaged(lines, tmp_path, edit):
    i = next(k for k, ln in enumerate(lines) if ln.startswith("H "))
    header = json.loads(lines[i][2:])
    edit(header["initial"])
    path = tmp_path / "damaged.log"
    path.write_text("".join(lines[:i] + ["H " + json.dumps(header) + "\n"] + lines[i + 1:]))
    return path


def _p0_nan(ini):
    ini["p0"][3][3] = math.nan


def _p0_indefinite(ini):
    ini["p0"][0][0] = -ini["p0"][0][0]


def _lat_100(ini):
    ini["nav"][0] = math.radians(100.0)


def _height(ini):
    ini["nav"][2] = -7e6


def _quat(ini):
    ini["nav"][6:10] = [0.0, 0.0, 0.0, 0.0]


@pytest.mark.parametrize("edit, word", [(_p0_nan, "p0"), (_p0_indefinite, "p0"),
                                        (_lat_100, "nav0[0]"), (_height, "nav0[2]"),
                                        (_quat, "nav0[6:10]")],
                         ids=["p0 nan", "p0 indefinite", "latitude 100", "height", "quaternion"])
def test_damaged_initial_state_is_one_line_exit_2(log_lines, tmp_path, capsys, edit, word):
    path = damaged(log_lines, tmp_path, edit)
    code, _, err = run_cli([path, "--out", tmp_path / "rep", "--quiet"], capsys)
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("navgate replay: error:"), err
    assert f"({word}" in lines[0], lines[0]
    assert not (tmp_path / "rep").exists()
