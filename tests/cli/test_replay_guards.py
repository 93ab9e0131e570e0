"""``navgate replay`` of a log whose header holds an initial state the engines
refuse (NaN or indefinite P0, latitude 100 deg, a height of -7,000 km, a zero quaternion):
one line naming the field, exit 2, no output directory (it ended in ``internal error``,
exit 3, before)."""

from __future__ import annotations

import json
import math

import numpy as np
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


def header():
    """A record log's header built by hand (records.make_header's fields; no flight is
    simulated): a level, still start at the DEM's centre."""
    from dataclasses import asdict

    from navgate.nav import eskf
    from navgate.sim.flight import FlightConfig
    from navgate.trn.dem import Dem

    lat, lon = Dem.default().center
    p0 = eskf.initial_covariance(pos_sigma=30.0, vel_sigma=0.5, att_sigma=0.01,
                                 accel_bias_sigma=0.01, gyro_bias_sigma=1e-4)
    eye = np.eye(3).tolist()
    return {"config": asdict(FlightConfig()), "ideal": True, "imu_rate_hz": 400.0, "t0": 0.0,
            "n_imu": 1,
            "calibration": {"gyro_bias": [0.0] * 3, "gyro_matrix": eye, "accel_bias": [0.0] * 3,
                            "accel_matrix": eye, "gyro_lsb": 1e-4, "accel_lsb": 1e-3},
            "initial": {"nav": [lat, lon, 500.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
                        "p0": p0.tolist(), "bias_a": [0.0] * 3, "bias_g": [0.0] * 3},
            "reference": {"lat_rad": lat, "lon_rad": lon, "h_m": 500.0}}


def test_the_hand_made_header_passes_the_checks():
    from navgate.sim.flight import FlightConfig
    from navgate.systems.ins_trn.ps.navigator import engine_setup
    from navgate.systems.ins_trn.ps.pl_interface import check_setup

    check_setup(engine_setup(header(), FlightConfig()))


def damaged(tmp_path, edit):
    h = header()
    edit(h["initial"])
    path = tmp_path / "damaged.log"
    path.write_text("navgate-records 1\nH " + json.dumps(h) + "\n"
                    "I,0.0025,0.0,0.0,0.0,0.0,0.0,-9806.65\n")
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


@pytest.mark.parametrize("edit, word", [(_p0_nan, "initial.p0 holds non-finite"),
                                        (_p0_indefinite, "initial.p0 is not positive"),
                                        (_lat_100, "initial.nav latitude"),
                                        (_height, "initial.nav height"),
                                        (_quat, "initial.nav quaternion")],
                         ids=["p0 nan", "p0 indefinite", "latitude 100", "height", "quaternion"])
def test_damaged_initial_state_is_one_line_exit_2(tmp_path, capsys, edit, word):
    path = damaged(tmp_path, edit)
    code, _, err = run_cli([path, "--out", tmp_path / "rep", "--quiet"], capsys)
    lines = err.strip().splitlines()
    assert code == 2, err
    assert len(lines) == 1 and lines[0].startswith("navgate replay: error:"), err
    assert word in lines[0], lines[0]  # the header check names the field
    assert not (tmp_path / "rep").exists()
