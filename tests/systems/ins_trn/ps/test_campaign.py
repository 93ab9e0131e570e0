"""Monte Carlo campaign: seed parsing, the per-configuration statistics, and a short campaign
on a Dask LocalCluster in which a failing configuration is reported, never dropped."""

import math

import numpy as np
import pytest
from scipy.stats import chi2

from navgate.systems.ins_trn.ps import campaign as camp


def test_parse_seeds():
    assert camp.parse_seeds("0-4") == [0, 1, 2, 3, 4]
    assert camp.parse_seeds("7, 2,3-4,3") == [2, 3, 4, 7]
    for bad in ("", "a", "5-2", "-3", "1,,2", "0-x"):
        with pytest.raises(ValueError):
            camp.parse_seeds(bad)


def _row(seed, rms2, final, ins_final, ttff, nees, outside, samples=100, status="ok"):
    return {"dem": "default", "trn": "pmf", "ranger": "long-range", "seed": seed,
            "status": status, "error": "" if status == "ok" else "boom",
            "rms_second_half_m": rms2, "rms_m": rms2, "final_error_m": final,
            "ins_only_final_error_m": ins_final, "ins_only_rms_second_half_m": 2 * rms2,
            "trn_worse_than_ins_only": final > ins_final, "time_to_first_fix_s": ttff,
            "nees_mean": nees, "outside_3sigma_samples": outside, "samples": samples,
            "divergence_events": 0, "errors": np.arange(1.0, 101.0) * seed,
            "nees": np.ones(10)}


def test_aggregate_statistics():
    conf = camp.Configuration("default", "pmf")
    rows = [_row(1, 10.0, 5.0, 300.0, 20.0, 1.5, 1),
            _row(2, 20.0, 400.0, 300.0, math.nan, 2.5, 3),
            {**_row(3, 0, 0, 0, 0, 0, 0, status="failed")}]
    s = camp.aggregate(conf, rows)
    assert s["runs"] == 3 and s["failed"] == 1 and s["failed_seeds"] == [3]
    assert s["rms_second_half_m_mean"] == 15.0 and s["rms_second_half_m_max"] == 20.0
    assert s["final_error_m_mean"] == 202.5 and s["ins_only_final_error_m_mean"] == 300.0
    assert s["runs_trn_worse_than_ins_only"] == 1
    assert s["time_to_first_fix_s_mean"] == 20.0 and s["runs_without_fix"] == 1
    assert s["nees_mean"] == 2.0
    assert s["nees_band_95"] == pytest.approx([chi2.ppf(0.025, 4) / 2, chi2.ppf(0.975, 4) / 2])
    assert s["outside_3sigma_fraction"] == pytest.approx(4 / 200)
    pooled = np.concatenate([np.arange(1.0, 101.0), 2 * np.arange(1.0, 101.0)])
    assert s["cep50_m"] == pytest.approx(np.quantile(pooled, 0.5))
    assert s["cep95_m"] == pytest.approx(np.quantile(pooled, 0.95))
    empty = camp.aggregate(conf, [rows[2]])
    assert empty["runs"] == 1 and empty["failed"] == 1 and empty["nees_mean"] is None


def test_short_campaign_on_a_local_cluster_reports_failures(tmp_path):
    spec = camp.Campaign.build([0, 1], ["default"], ["pmf", "no-such-method"], duration_s=30.0)
    seen = []
    result = camp.run_campaign(spec, workers=1, progress=seen.append)
    assert len(seen) == len(result.rows) == 4
    good = [r for r in result.rows if r["trn"] == "pmf"]
    bad = [r for r in result.rows if r["trn"] != "pmf"]
    assert [r["seed"] for r in good] == [0, 1] and all(r["status"] == "ok" for r in good)
    assert all(r["status"] == "failed" and "unknown TRN method" in r["error"] for r in bad)
    for r in good:
        assert r["ins_only_final_error_m"] > 0 and np.isfinite(r["rms_second_half_m"])
        assert r["samples"] == 301 and r["fixes_attempted"] >= 2
    s = result.summary()
    assert s["runs"] == 4 and s["failed"] == 2
    assert {(f["trn"], f["seed"]) for f in s["failed_runs"]} == {("no-such-method", 0),
                                                                 ("no-such-method", 1)}
    conf = {c["trn"]: c for c in s["configurations"]}
    assert conf["pmf"]["runs"] == 2 and conf["pmf"]["failed"] == 0
    assert conf["no-such-method"]["failed"] == 2
    assert s["workers"] == 1 and s["wall_time_s"] > 0 and s["scaling_ratio"] > 0
    files = camp.write_report(result, tmp_path)
    lines = files["results_csv"].read_text().splitlines()
    assert len(lines) == 5 and lines[0].startswith("dem,trn,ranger,seed,status,error")
    assert all(p.stat().st_size > 0 for p in files.values())
