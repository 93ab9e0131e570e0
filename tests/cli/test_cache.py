"""``navgate cache info`` / ``navgate cache clear``: counts, clearing, and one-line errors
(in a temporary ``NAVGATE_CACHE_DIR``)."""

from __future__ import annotations

import json

import pytest

from navgate import cache


@pytest.fixture
def root(tmp_path, monkeypatch):
    monkeypatch.setenv("NAVGATE_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("NAVGATE_VERILATOR_CACHE", raising=False)
    for n in range(2):
        cache.cached("verilog", f"d{n}", {}, lambda: {"verilog": "module d; endmodule\n"})
    cache.cached("synth", "s", {}, lambda: {"utilization": {"lut": 7}})
    return tmp_path / "cache"


def test_info_prints_root_and_counts(root, navgate_run):
    code, out, err = navgate_run(["cache", "info", "--json"])
    assert code == 0, err
    got = json.loads(out)
    assert got["root"] == str(root)
    assert {k: v["entries"] for k, v in got["kinds"].items()} == \
        {"verilog": 2, "verilator": 0, "synth": 1}
    assert got["kinds"]["synth"]["bytes"] == next((root / "synth").glob("s-*.json")).stat().st_size
    code, out, err = navgate_run(["cache", "info"])
    assert code == 0, err
    assert str(root) in out and "verilog" in out and "synth" in out


def test_clear_one_kind_then_all(root, navgate_run):
    code, _, err = navgate_run(["cache", "clear", "--kind", "synth"])
    assert code == 0 and "cleared synth: 1 entries" in err
    assert {k.kind: k.entries for k in cache.info()} == {"verilog": 2, "verilator": 0,
                                                         "synth": 0}
    code, _, err = navgate_run(["cache", "clear"])
    assert code == 0 and "cleared verilog: 2 entries" in err
    assert sum(k.entries for k in cache.info()) == 0


def test_bad_kind_is_one_line(root, navgate_run):
    code, _, err = navgate_run(["cache", "clear", "--kind", "netlists"])
    assert code == 2
    assert "--kind" in navgate_run.one_line(err)
    assert sum(k.entries for k in cache.info()) == 3  # nothing removed


def test_clear_outside_the_root_is_refused(root, navgate_run, tmp_path, monkeypatch):
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    (outside / "data.bin").write_bytes(b"keep")
    monkeypatch.setenv("NAVGATE_VERILATOR_CACHE", str(outside))
    code, _, err = navgate_run(["cache", "clear"])
    assert code == 2
    assert "outside the cache root" in navgate_run.one_line(err)
    assert (outside / "data.bin").read_bytes() == b"keep"
    assert sum(k.entries for k in cache.info()) == 4  # refused before anything was removed


def test_unknown_subcommand_is_one_line(root, navgate_run):
    code, _, err = navgate_run(["cache", "purge"])
    assert code == 2
    navgate_run.one_line(err)
