"""navgate.cache: content-keyed entries, hits and misses, corrupt entries, info and clear,
the Verilog cache on a small block (navgate.gateware.verify.emit_verilog) and the build
flow's Verilog + synth caches (navgate.hw.flow.build_block). Every test works in a temporary
``NAVGATE_CACHE_DIR``, never in the user's cache."""

from __future__ import annotations

import json
import sys
import threading
import time

import pytest

from navgate import cache


@pytest.fixture
def root(tmp_path, monkeypatch):
    monkeypatch.setenv("NAVGATE_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.delenv("NAVGATE_VERILATOR_CACHE", raising=False)
    for counts in cache.STATS.values():
        for k in counts:
            counts[k] = 0
    return tmp_path / "cache"


def test_root_and_kind_dirs(root, monkeypatch, tmp_path):
    assert cache.cache_root() == root
    assert cache.kind_dir("synth") == root / "synth"
    assert cache.kind_dir("verilator") == root / "verilator"
    monkeypatch.setenv("NAVGATE_VERILATOR_CACHE", str(tmp_path / "models"))
    assert cache.kind_dir("verilator") == tmp_path / "models"
    with pytest.raises(cache.CacheError, match="unknown cache kind"):
        cache.kind_dir("netlists")


def test_default_root_follows_the_platform(monkeypatch, tmp_path):
    import platformdirs

    monkeypatch.delenv("NAVGATE_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.cache_root() == platformdirs.user_cache_path("navgate", appauthor=False)
    if sys.platform == "linux":
        assert cache.cache_root() == tmp_path / "xdg" / "navgate"


def test_miss_then_hit_and_a_changed_parameter_misses(root):
    calls = []

    def build(n):
        def run():
            calls.append(n)
            return {"value": n * n, "order": {"z": 1, "a": 2}}
        return run

    first, hit = cache.cached("synth", "blk", {"n": 3}, build(3))
    assert (first["value"], hit, calls) == (9, False, [3])
    again, hit = cache.cached("synth", "blk", {"n": 3}, build(3))
    assert (again, hit, calls) == (first, True, [3])  # not built again
    # key order kept: a payload read back is the payload written
    assert list(again["order"]) == ["z", "a"]
    other, hit = cache.cached("synth", "blk", {"n": 4}, build(4))
    assert (other["value"], hit, calls) == (16, False, [3, 4])
    assert cache.STATS["synth"] == {"hit": 1, "miss": 2, "corrupt": 0}


def test_key_parts_must_be_plain_data(root):
    with pytest.raises(TypeError, match="not plain data"):
        cache.make_key({"units": object()})
    # the same parts in another order are the same key; another value is another key
    assert cache.make_key({"a": 1, "b": [1, 2]}) == cache.make_key({"b": [1, 2], "a": 1})
    assert cache.make_key({"a": 1}) != cache.make_key({"a": 1.5})


@pytest.mark.parametrize("damage", ["truncate", "garbage", "payload", "key"])
def test_a_corrupt_entry_is_detected_and_rebuilt(root, damage):
    payload, _ = cache.cached("verilog", "d", {"p": 1}, lambda: {"verilog": "module d; endmodule"})
    (path,) = (root / "verilog").glob("d-*.json")
    text = path.read_text()
    if damage == "truncate":  # an interrupted writer without the atomic rename
        path.write_text(text[: len(text) // 2])
    elif damage == "garbage":
        path.write_bytes(b"\x00\xff" * 10)
    elif damage == "payload":  # valid JSON whose payload no longer matches its checksum
        entry = json.loads(text)
        entry["payload"]["verilog"] = "module d; wire x; endmodule"
        path.write_text(json.dumps(entry))
    else:  # an entry of another key under this name
        entry = json.loads(text)
        entry["key"] = "0" * 24
        path.write_text(json.dumps(entry))
    rebuilt = []
    again, hit = cache.cached("verilog", "d", {"p": 1},
                              lambda: rebuilt.append(1) or {"verilog": "module d; endmodule"})
    assert (again, hit, rebuilt) == (payload, False, [1])
    assert cache.STATS["verilog"]["corrupt"] == 1
    assert json.loads(path.read_text())["payload"] == payload  # the entry is whole again


def test_concurrent_writers_build_once_and_leave_a_whole_entry(root):
    builds = []
    results = []

    def build():
        builds.append(1)
        time.sleep(0.2)
        return {"verilog": "x" * 100_000}

    def worker():
        results.append(cache.cached("verilog", "c", {}, build))

    threads = [threading.Thread(target=worker) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(builds) == 1
    assert sorted(hit for _, hit in results) == [False, True, True, True]
    assert {len(payload["verilog"]) for payload, _ in results} == {100_000}
    assert not list((root / "verilog").glob("*.tmp"))  # no temporary file left


def test_source_fingerprint_changes_with_any_source_file(tmp_path):
    package = tmp_path / "pkg"
    (package / "sub").mkdir(parents=True)
    (package / "a.py").write_text("X = 1\n")
    (package / "sub" / "map.rdl").write_text("addrmap m {};\n")
    (package / "notes.txt").write_text("not a source\n")
    before = cache.package_fingerprint(package)
    (package / "notes.txt").write_text("changed\n")
    assert cache.package_fingerprint(package) == before  # not a source file
    (package / "sub" / "map.rdl").write_text("addrmap m { };\n")
    after = cache.package_fingerprint(package)
    assert after != before
    (package / "b.v").write_text("module b; endmodule\n")
    assert cache.package_fingerprint(package) != after
    assert len(cache.source_fingerprint()) == 64


def test_info_counts_and_clear_empties(root):
    for n in range(3):
        cache.cached("verilog", f"v{n}", {}, lambda: {"verilog": "module v; endmodule"})
    cache.cached("synth", "s", {}, lambda: {"utilization": {"lut": 1}})
    model = root / "verilator" / "dut-0123"
    model.mkdir(parents=True)
    (model / "Vdut").write_bytes(b"\0" * 1000)
    (root / "verilator" / "dut-0123.lock").write_text("")  # not an entry
    found = {k.kind: k for k in cache.info()}
    assert (found["verilog"].entries, found["synth"].entries, found["verilator"].entries) == \
        (3, 1, 1)
    assert found["verilator"].bytes == 1000
    assert found["verilog"].bytes == sum(p.stat().st_size
                                         for p in (root / "verilog").glob("v*.json"))
    removed = cache.clear("verilog")
    assert [(k.kind, k.entries) for k in removed] == [("verilog", 3)]
    found = {k.kind: k for k in cache.info()}
    assert (found["verilog"].entries, found["synth"].entries, found["verilator"].entries) == \
        (0, 1, 1)
    cache.clear()
    assert sum(k.entries for k in cache.info()) == 0
    assert not any((root / "verilator").iterdir())


def test_clear_refuses_a_directory_outside_the_root(root, tmp_path, monkeypatch):
    outside = tmp_path / "precious"
    outside.mkdir()
    (outside / "keep.txt").write_text("mine")
    monkeypatch.setenv("NAVGATE_VERILATOR_CACHE", str(outside))
    with pytest.raises(cache.CacheError, match="outside the cache root"):
        cache.clear()
    assert (outside / "keep.txt").read_text() == "mine"
    monkeypatch.delenv("NAVGATE_VERILATOR_CACHE")
    (root).mkdir(parents=True, exist_ok=True)
    (root / "synth").symlink_to(outside)  # a link out of the root is refused as well
    with pytest.raises(cache.CacheError, match="outside the cache root"):
        cache.clear("synth")
    assert (outside / "keep.txt").read_text() == "mine"


# --------------------------------------------------------------------------- Verilog cache


class _Counting:
    """A FixedMul whose elaborations are counted."""

    def __new__(cls, width, frac, counter):
        from navgate.gateware.fixed import FixedMul

        class Counted(FixedMul):
            def elaborate(self, platform):
                counter.append((width, frac))
                return super().elaborate(platform)

        return Counted(width, frac)


def test_emit_verilog_cached_by_design_and_parameters(root):
    from navgate.gateware import verify as V

    counter: list = []

    def emit(width, frac):
        return V.emit_verilog(_Counting(width, frac, counter), "fm", design="FixedMul",
                              params={"width": width, "frac": frac})

    first = emit(8, 4)
    assert counter == [(8, 4)]
    assert emit(8, 4) == first and counter == [(8, 4)]  # a hit: not elaborated
    other = emit(10, 4)  # a parameter changed: a miss, elaborated, other Verilog
    assert counter == [(8, 4), (10, 4)] and other != first
    assert "[9:0]" in other and "[9:0]" not in first
    # the text equals a plain emission
    from navgate.gateware.fixed import FixedMul

    assert first == V.emit_verilog(FixedMul(8, 4), "fm")
    assert cache.STATS["verilog"] == {"hit": 1, "miss": 2, "corrupt": 0}


def test_verilator_models_live_under_the_root(root):
    from navgate.gateware import verify as V

    assert V.verilator_cache_dir() == root / "verilator"


def _fake_synthesize(calls):
    """Stands in for Yosys (the cache logic is what is tested here; the real figures of
    fixed_mul are checked in tests/hw/test_cli_build.py): counts from the Verilog text."""
    def synthesize(text, top, target, workdir):
        calls.append(top)
        return {"block": top, "target": target, "lut": text.count("\n"), "ff": len(text),
                "dsp": 0, "carry4": 0, "bram36": 0, "percent": {"lut": 0.5},
                "cells": {"LUT2": 3}}
    return synthesize


@pytest.fixture(scope="module")
def flow_cache(tmp_path_factory):
    """fixed_mul built twice through the flow into one temporary cache."""
    import os

    from navgate.hw import flow

    base = tmp_path_factory.mktemp("flowcache")
    saved = os.environ.get("NAVGATE_CACHE_DIR")
    os.environ["NAVGATE_CACHE_DIR"] = str(base / "cache")
    real = flow.synthesize
    calls: list = []
    flow.synthesize = _fake_synthesize(calls)
    try:
        (base / "one").mkdir()
        (base / "two").mkdir()
        first = flow.build_block("fixed_mul", base / "one")
        assert calls == ["fixed_mul"]
        second = flow.build_block("fixed_mul", base / "two")
        assert calls == ["fixed_mul"]  # not synthesised again
        (base / "three").mkdir()
        third = flow.build_block("fixed_mul", base / "three", use_cache=False)
        assert calls == ["fixed_mul", "fixed_mul"]
    finally:
        flow.synthesize = real
        if saved is None:
            os.environ.pop("NAVGATE_CACHE_DIR", None)
        else:
            os.environ["NAVGATE_CACHE_DIR"] = saved
    return base, first, second, third


def test_build_block_second_run_comes_from_the_cache(flow_cache):
    base, first, second, third = flow_cache
    assert first["cache"] == {"verilog": False, "synth": False}
    assert second["cache"] == {"verilog": True, "synth": True}
    assert third["cache"] == {"verilog": False, "synth": False}
    text = (base / "one" / "fixed_mul.v").read_text()
    assert second["utilization"]["lut"] == text.count("\n")
    for name in ("fixed_mul.v", "fixed_mul.json", "fixed_mul.utilization.json"):
        assert (base / "two" / name).read_bytes() == (base / "one" / name).read_bytes()
        assert (base / "three" / name).read_bytes() == (base / "one" / name).read_bytes()


def test_synth_key_follows_the_verilog_and_options(flow_cache):
    from navgate.hw.flow import synth_key

    base = flow_cache[0]
    text = (base / "one" / "fixed_mul.v").read_text()
    args = ("fixed_mul", "xc7z020", False, ("xc7",), (1,), (1,), None, None)
    key = cache.make_key(synth_key(text, *args))
    assert cache.make_key(synth_key(text, *args)) == key
    assert cache.make_key(synth_key(text.replace("fixed_mul", "fixed_mul "), *args)) != key
    timed = ("fixed_mul", "xc7z020", True, ("xc7",), (1,), (1,), None, None)
    assert cache.make_key(synth_key(text, *timed)) != key


def test_an_unwritable_cache_warns_and_still_gives_the_result(tmp_path, monkeypatch):
    blocker = tmp_path / "not-a-directory"
    blocker.write_text("a file where the cache root should be")
    monkeypatch.setenv("NAVGATE_CACHE_DIR", str(blocker))
    with pytest.warns(RuntimeWarning, match="cannot write"):
        payload, hit = cache.cached("synth", "b", {}, lambda: {"utilization": {"lut": 3}})
    assert (payload, hit) == ({"utilization": {"lut": 3}}, False)
    assert blocker.read_text().startswith("a file")
    assert [k.entries for k in cache.info()] == [0, 0, 0]
