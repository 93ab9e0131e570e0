"""``navgate kf2x2``: outputs, summary keys and values, gateware engine, bad options."""

import json

import pytest

from navgate.cli import main


def run_cli(args, capsys):
    code = 0
    try:
        main(["kf2x2", *map(str, args)])
    except SystemExit as exit_:
        code = exit_.code
    out = capsys.readouterr()
    return code, out.out, out.err


def test_model_run_writes_summary_plot_and_csv(tmp_path, capsys):
    out = tmp_path / "run"
    code, _, err = run_cli(["--frames", 1200, "--seed", 2, "--out", out, "--quiet"], capsys)
    assert code == 0, err
    for name in ("summary.json", "frames.csv", "rlc.png"):
        assert (out / name).stat().st_size > 0
    s = json.loads((out / "summary.json").read_text())
    assert s["frames"] == 1200 and s["cycles_per_frame"] == 34
    assert s["n"] == 20 and s["frac"] == 10 and s["engine"] == "model"
    assert "mismatches_vs_bit_true" not in s  # not applicable: absent, never null
    for i in (0, 1):
        # the estimate beats the raw measurement, fixed point close to float64
        assert s["rms_error_fixed"][i] < 0.5 * s["rms_error_measurement"][i]
        assert s["rms_error_fixed"][i] < 1.5 * s["rms_error_float64"][i]
        # the noise std doubles at the step: the R estimate grows about 4x
        assert 2.5 < s["r_estimate_after_step"][i] / s["r_estimate_before_step"][i] < 6
    assert len((out / "frames.csv").read_text().splitlines()) == 1201


def test_verilator_engine_counts_zero_mismatches(tmp_path, capsys):
    out = tmp_path / "v"
    code, _, err = run_cli(["--frames", 300, "--engine", "verilator", "--out", out, "--quiet"],
                           capsys)
    assert code == 0, err
    s = json.loads((out / "summary.json").read_text())
    assert s["engine"] == "verilator" and s["mismatches_vs_bit_true"] == 0


@pytest.mark.parametrize("args, message", [
    (["--frames", 5], "--frames"),
    (["--n", 40], "word length"),
    (["--n", 33], "--n: the word length must be in [9, 32], got 33"),
    (["--n", 8], "--n: the word length must be in [9, 32], got 8"),
    (["--n", 20, "--frac", 16], "holds values only up to"),
    (["--seed", -1], "--seed"),
])
def test_bad_options_fail_cleanly(tmp_path, capsys, args, message):
    code, _, err = run_cli([*args, "--out", tmp_path / "x", "--quiet"], capsys)
    assert code == 2
    assert message in err
    assert "Traceback" not in err


@pytest.mark.parametrize("n", [30, 31, 32])
def test_word_lengths_up_to_32_run_as_the_help_says(n, tmp_path, capsys):
    """The model runs N up to 32 (tests/systems/kf2x2/test_model.py); --help says so."""
    code, _, err = run_cli(["--n", n, "--frames", 40, "--out", tmp_path / "w", "--quiet"],
                           capsys)
    assert code == 0, err
    assert json.loads((tmp_path / "w" / "summary.json").read_text())["n"] == n
    code, out, _ = run_cli(["--help"], capsys)
    assert code == 0 and "Word length N (9..32)" in out


def test_an_overflowing_run_commits_nothing(tmp_path, capsys):
    out = tmp_path / "run"
    code, _, err = run_cli(["--frames", 200, "--out", out, "--quiet"], capsys)
    assert code == 0, err
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    assert sorted(before) == ["frames.csv", "rlc.png", "summary.json"]
    code, _, err = run_cli(["--n", 9, "--frac", 3, "--frames", 200, "--out", out, "--quiet"],
                           capsys)
    assert code == 2 and "overflows in" in err and "nothing written" in err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    code, _, err = run_cli(["--n", 9, "--frac", 3, "--frames", 200, "--out", tmp_path / "new",
                            "--quiet"], capsys)
    assert code == 2 and not (tmp_path / "new").exists()
