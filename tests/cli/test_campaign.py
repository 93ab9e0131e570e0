"""`navgate campaign` as a user runs it: one-line errors for bad input (no cluster started),
and (slow) a short campaign writing every output with the summary keys the issue names."""

import json
import subprocess
import sys

import pytest


def navgate(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "navgate.cli", *args], capture_output=True,
                          text=True, cwd=cwd, timeout=900)


@pytest.mark.parametrize("args, needle", [
    (["--seeds", "5-2"], "--seeds"),
    (["--seeds", "a"], "--seeds"),
    (["--trn", "magic"], "--trn"),
    (["--ranger", "sonar"], "--ranger"),
    (["--workers", "0"], "--workers"),
    (["--duration", "-1"], "--duration"),
    (["--dem", "/nonexistent/dem.tif"], "not found"),
    (["--duration", "0.001"], "--duration 0.001 s is too short"),
    (["--scheduler", "bogus"], "--scheduler 'bogus' is not a scheduler address"),
    (["--scheduler", "tcp://host:port"], "--scheduler"),
    (["--scheduler", "tcp://host:99999"], "--scheduler"),
    (["--scheduler", "foo://host:8786"], "unknown protocol"),
    (["--scheduler", " "], "--scheduler must not be empty"),
])
def test_bad_options_one_line_error(tmp_path, capsys, args, needle):
    from navgate.cli import main

    with pytest.raises(SystemExit) as exit_:
        main(["campaign", *args, "--out", str(tmp_path)])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("navgate campaign: error:"), err
    assert needle in lines[0] and "Traceback" not in err


@pytest.mark.slow
def test_short_campaign_writes_every_output(tmp_path):
    proc = navgate("campaign", "--seeds", "0-1", "--duration", "40", "--workers", "2",
                   "--trn", "pmf", "--trn", "tercom", "--out", str(tmp_path))
    assert proc.returncode == 0, proc.stderr
    for name in ("summary.json", "results.csv", "error_cdf.png", "nees_hist.png"):
        assert (tmp_path / name).stat().st_size > 0, name
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["runs"] == 4 and s["failed"] == 0 and s["workers"] == 2
    assert [c["trn"] for c in s["configurations"]] == ["pmf", "tercom"]
    for c in s["configurations"]:
        assert c["dem"] == "default" and c["runs"] == 2
        for key in ("rms_second_half_m_mean", "rms_second_half_m_max", "final_error_m_mean",
                    "ins_only_final_error_m_mean", "runs_trn_worse_than_ins_only",
                    "time_to_first_fix_s_mean", "nees_mean", "outside_3sigma_fraction",
                    "cep50_m", "cep95_m"):
            assert c[key] is not None, key
    assert "Monte Carlo" in proc.stdout and "pmf" in proc.stdout


def test_table_fits_120_columns_when_redirected(capsys):
    """Redirected (not a terminal), the table is 120 columns wide, not 200."""
    import io

    from rich.console import Console

    from navgate.cli import campaign as cmd

    conf = {"label": "default / pmf / long-range", "runs": 10, "failed": 0,
            "rms_second_half_m_mean": 12.3, "rms_second_half_m_max": 45.6, "cep50_m": 8.1,
            "cep95_m": 30.2, "final_error_m_mean": 11.0, "ins_only_final_error_m_mean": 812.4,
            "runs_trn_worse_than_ins_only": 0, "time_to_first_fix_s_mean": 31.5,
            "nees_mean": 1.93, "nees_band_95": [1.51, 2.55], "outside_3sigma_fraction": 0.004}
    summary = {"runs": 10, "duration_s": 600.0, "wall_time_s": 321.0, "workers": 2,
               "configurations": [conf], "failed_runs": [], "run_wall_s_mean": 64.0,
               "scaling_ratio": 1.0}
    redirected = Console(file=io.StringIO())
    assert not redirected.is_terminal
    cmd._print_table(cmd._table_console(redirected), summary)
    out = capsys.readouterr().out
    widths = [len(line) for line in out.splitlines()]
    assert max(widths) <= cmd.TABLE_WIDTH_REDIRECTED, max(widths)
    assert "default" in out and "1.93" in out and "Monte Carlo: 10 runs" in out


def test_dask_shutdown_warnings_are_silenced_then_restored():
    import logging

    from navgate.systems.ins_trn.ps import campaign as camp

    nanny = logging.getLogger("distributed.nanny")
    before = nanny.level
    seen = []

    class Catch(logging.Handler):
        def emit(self, record):
            seen.append(record.getMessage())

    handler = Catch(logging.WARNING)
    logging.getLogger().addHandler(handler)
    try:
        with camp._quiet_dask_shutdown():
            nanny.warning("Worker process still alive after 3.9999 seconds, killing")
            nanny.error("a real failure")
        nanny.warning("after the shutdown")
    finally:
        logging.getLogger().removeHandler(handler)
    assert seen == ["a real failure", "after the shutdown"]
    assert nanny.level == before


def test_results_csv_leaves_a_missing_time_to_first_fix_empty(tmp_path):
    """A run without a fix has no time to first fix: an empty field, never a literal nan."""
    import csv
    import math
    import types

    from navgate.systems.ins_trn.ps.campaign import RESULT_FIELDS, write_results_csv

    rows = [{k: 1.5 for k in RESULT_FIELDS}, {k: 2.5 for k in RESULT_FIELDS}]
    rows[1]["time_to_first_fix_s"] = math.nan
    path = write_results_csv(types.SimpleNamespace(rows=rows), tmp_path / "results.csv")
    read = list(csv.DictReader(path.open()))
    assert read[0]["time_to_first_fix_s"] == "1.5" and read[1]["time_to_first_fix_s"] == ""
    assert "nan" not in path.read_text().lower()
