"""``navgate build`` / ``navgate report`` command line: outputs and error handling."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest


def navgate(*args: str, cwd=None, env=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "navgate.cli", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=300, env=env)


def assert_one_line_error(proc: subprocess.CompletedProcess, fragment: str) -> None:
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert fragment in lines[0]
    assert "Traceback" not in proc.stderr


def test_list_names_every_block():
    proc = navgate("build", "--list")
    assert proc.returncode == 0, proc.stderr
    names = [line.split()[0] for line in proc.stdout.splitlines()]
    for name in ("cordic_atan2", "cordic_sincos", "goldschmidt_div", "fixed_mul", "fp32_add"):
        assert name in names
    assert all(len(line.split(None, 1)) == 2 for line in proc.stdout.splitlines())


def test_unknown_block(tmp_path):
    assert_one_line_error(navgate("build", "no_such_block", "--out", str(tmp_path)),
                          "unknown block 'no_such_block'")


def test_missing_block(tmp_path):
    assert_one_line_error(navgate("build", "--out", str(tmp_path)), "missing BLOCK")


def test_unknown_target(tmp_path):
    assert_one_line_error(navgate("build", "fixed_mul", "--target", "xc7z999", "--out",
                                  str(tmp_path)), "unknown target 'xc7z999'")


def test_unwritable_out(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    assert_one_line_error(navgate("build", "fixed_mul", "--out", str(blocker / "sub")),
                          "cannot create output directory")


def test_report_unwritable_out(tmp_path):
    assert_one_line_error(navgate("report", "--out", str(tmp_path / "missing" / "r.md")),
                          "cannot write")
    assert_one_line_error(navgate("report", "--target", "nope"), "unknown target")


def test_bad_option_is_one_line(tmp_path):
    assert_one_line_error(navgate("build", "fixed_mul", "--bogus"), "--bogus")


def test_bad_ecp5_seeds(tmp_path):
    assert_one_line_error(navgate("build", "fixed_mul", "--timing", "--ecp5-seeds", "1,x",
                                  "--out", str(tmp_path)), "--ecp5-seeds")


def test_bad_nexus_seeds(tmp_path):
    assert_one_line_error(navgate("build", "fixed_mul", "--timing", "--nexus-seeds", "2,y",
                                  "--out", str(tmp_path)), "--nexus-seeds")


def test_list_names_the_yardsticks():
    proc = navgate("build", "--list")
    names = [line.split()[0] for line in proc.stdout.splitlines()]
    assert {"mul_24x17", "mul_20x20", "mul_24x24", "kf2x2", "fp32_mul"} <= set(names)


@pytest.fixture(scope="module")
def built_fixed_mul(tmp_path_factory):
    out = tmp_path_factory.mktemp("build")
    proc = navgate("build", "fixed_mul", "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    return out, proc


def test_build_writes_three_files(built_fixed_mul):
    out, proc = built_fixed_mul
    assert (out / "fixed_mul.v").read_text().count("\nmodule fixed_mul(") == 1
    desc = json.loads((out / "fixed_mul.json").read_text())
    assert desc["latency_cycles"] == 3 and desc["throughput"] == "1"
    assert desc["parameters"] == {"width": 20, "frac": 10}
    assert {p["name"] for p in desc["ports"]} >= {"clk", "rst", "i__payload", "o__payload"}
    use = json.loads((out / "fixed_mul.utilization.json").read_text())
    assert {"lut", "ff", "dsp", "carry4", "bram36", "cells", "target"} <= set(use)
    # exact counts of the default Q(20, 10) multiplier (Yosys 0.70): a 20x20 product takes
    # two DSP48E1 (25x18 each) and a 4-CARRY4 adder joining them
    assert (use["lut"], use["ff"], use["dsp"], use["carry4"], use["bram36"]) == (37, 81, 2, 4, 0)
    assert "timing" not in use
    assert "fixed_mul: LUT 37, FF 81, DSP 2" in proc.stdout
    # tool work files are removed unless --keep-work
    assert not (out / "work").exists() and not (out / "fixed_mul.timing.json").exists()


def test_build_is_deterministic(built_fixed_mul, tmp_path):
    out, _ = built_fixed_mul
    # a fresh build cache: elaborated and synthesised again, not read back (navgate.cache)
    env = dict(os.environ, NAVGATE_CACHE_DIR=str(tmp_path / "cache"))
    proc = navgate("build", "fixed_mul", "--out", str(tmp_path / "again"), env=env)
    assert proc.returncode == 0, proc.stderr
    for kind in ("verilog", "synth"):  # built into the fresh cache, so not a hit
        assert len(list((tmp_path / "cache" / kind).glob("fixed_mul-*.json"))) == 1
    for name in ("fixed_mul.v", "fixed_mul.json", "fixed_mul.utilization.json"):
        assert (tmp_path / "again" / name).read_bytes() == (out / name).read_bytes()


def test_board_target_builds_a_block_without_a_board_variant(tmp_path):
    """``--target zybo-z7-20`` is the xc7z020 part: a block that has no board variant builds
    as it is (same cells); ins_trn_top's variant is tested in tests/systems/ins_trn."""
    proc = navgate("build", "fixed_mul", "--target", "zybo-z7-20", "--out", str(tmp_path))
    assert proc.returncode == 0, proc.stderr
    desc = json.loads((tmp_path / "fixed_mul.json").read_text())
    use = json.loads((tmp_path / "fixed_mul.utilization.json").read_text())
    assert desc["target"] == "zybo-z7-20" and use["part"] == "xc7z020clg400-1"
    assert (use["lut"], use["ff"], use["dsp"], use["carry4"]) == (37, 81, 2, 4)
    assert not list(tmp_path.glob("*.xdc"))
