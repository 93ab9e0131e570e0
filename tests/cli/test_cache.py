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


def test_report_says_per_block_whether_it_came_from_the_cache(root, navgate_run,
                                                             monkeypatch):
    """Two blocks (synthesis stubbed): the first report synthesises both, the second takes
    both from the cache without synthesising, a changed block is synthesised again alone."""
    import navgate.hw.blocks as blocks
    import navgate.hw.flow as flow

    everything = blocks.all_blocks
    monkeypatch.setattr(blocks, "all_blocks", lambda: {
        n: b for n, b in everything().items() if n in ("fixed_mul", "mul_24x17")})
    calls = []

    def synthesize(text, name, *a):
        calls.append(name)
        return {"lut": len(text), "ff": 1, "dsp": 0, "carry4": 0, "bram36": 0}

    monkeypatch.setattr(flow, "synthesize", synthesize)
    code, first, err = navgate_run(["report"])
    assert code == 0, err
    assert sorted(calls) == ["fixed_mul", "mul_24x17"]
    assert "Synthesised in this run: 2 of 2 blocks: fixed_mul, mul_24x17." in first
    assert err.count(", synthesised)") == 2
    code, second, err = navgate_run(["report"])
    assert code == 0, err
    assert len(calls) == 2  # nothing synthesised again
    assert "from the cache (`navgate cache info`): 2 of 2 blocks: fixed_mul, mul_24x17." \
        in second
    assert err.count("from the cache)") == 2
    table = [line for line in first.splitlines() if line.startswith("|")]
    assert table == [line for line in second.splitlines() if line.startswith("|")]
    # fixed_mul's Verilog changes (its Verilog entry replaced, as a source edit would): only
    # fixed_mul is synthesised again
    (entry,) = (root / "verilog").glob("fixed_mul-*.json")
    data = json.loads(entry.read_text())
    key, name = data["key"], data["name"]
    payload = dict(data["payload"], verilog=data["payload"]["verilog"] + "// edited\n")
    entry.unlink()
    cache.store("verilog", name, key, payload)
    code, third, err = navgate_run(["report"])
    assert code == 0, err
    assert calls[2:] == ["fixed_mul"]
    assert "Synthesised in this run: 1 of 2 blocks: fixed_mul." in third


def test_info_refuses_a_cache_root_that_is_a_file(tmp_path, monkeypatch, navgate_run):
    monkeypatch.setenv("NAVGATE_CACHE_DIR", str(tmp_path / "afile"))
    monkeypatch.delenv("NAVGATE_VERILATOR_CACHE", raising=False)
    (tmp_path / "afile").write_text("x")
    for args in (["cache", "info"], ["cache", "info", "--json"]):
        code, _, err = navgate_run(args)
        assert code == 2 and "afile is not a directory" in navgate_run.one_line(err)
