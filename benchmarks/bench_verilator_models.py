"""The Verilator models the test suite compiles (issue 32): how many, of which design, and what
each costs to build, so that a new model in the cold suite is visible.

Every compiled model (:func:`navgate.gateware.verify._build_model`, the cocotb models;
:func:`navgate.gateware.native_stream.compile_native`, the native servers) is cached under
``verilator/`` of navgate's cache root (``$NAVGATE_CACHE_DIR``), keyed by its Verilog text. A
build writes ``navgate_build.json`` beside the model: its top, kind, key, the CPU seconds of
the build's child processes (Verilator, make, the C++ compiler; ``getrusage(RUSAGE_CHILDREN)``,
so load from other work on the machine does not inflate it), the wall seconds and the test
that asked for it (``PYTEST_CURRENT_TEST``).

Two modes:

``table`` (default)
    Read the records of a cache root (``--cache DIR``, default the current root) and print a
    table per design (top and kind): models, build CPU seconds, wall seconds, the tests that
    built them. Run it after ``NAVGATE_CACHE_DIR=/tmp/scratch pytest ...`` (an empty root) to
    see what a cold suite builds. Models built before the records existed have none and are
    counted as "unrecorded".
``map TESTS...``
    Run pytest in this process (``-n 0``) over ``TESTS`` with every model build intercepted:
    the test asks for its model (its Verilog is emitted as usual), the model's key is
    recorded, and the test is skipped instead of building and simulating. Prints which tests
    ask for which model and the number of distinct models, in seconds rather than the hour a
    cold build takes. ``--build`` builds each model asked for (into the cache root in force;
    use ``NAVGATE_CACHE_DIR=/tmp/scratch`` for a cold measurement) before skipping, so the
    build records are written one by one with nothing else running in this process. A test
    that asks for two models is skipped at its first, and a test that builds in a child
    process (``navgate`` run by ``subprocess``) is not seen: for those run the tests for real
    into a scratch root and use ``table``.

    python benchmarks/bench_verilator_models.py [--cache DIR]
    python benchmarks/bench_verilator_models.py map [--build] [--json OUT] tests/...
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections import defaultdict
from pathlib import Path


def _records(root: Path) -> tuple[list[dict], list[str]]:
    models = root / "verilator" if (root / "verilator").is_dir() else root
    found, unrecorded = [], []
    if not models.is_dir():
        return found, unrecorded
    for entry in sorted(models.iterdir()):
        if not entry.is_dir() or entry.name.startswith(".") or entry.name.count("-") < 1:
            continue
        rec = entry / "navgate_build.json"
        if not rec.exists():
            # a build under way (mkdtemp names have no 24-digit key) or an old model
            if (entry / "navgate_build.ok").exists() or any(entry.glob("V*")):
                unrecorded.append(entry.name)
            continue
        data = json.loads(rec.read_text())
        data["dir"] = entry.name
        found.append(data)
    return found, unrecorded


def _design(rec: dict) -> str:
    return rec["top"] if rec.get("kind") == "cocotb" else f"{rec.get('kind')}-{rec['top']}"


def table(root: Path) -> None:
    records, unrecorded = _records(root)
    groups: dict[str, list[dict]] = defaultdict(list)
    for rec in records:
        groups[_design(rec)].append(rec)
    print(f"Verilator models under {root}: {len(records)} recorded, "
          f"{len(unrecorded)} without a build record")
    print()
    print("| design | models | build CPU s | build wall s | Verilog kB | built for (first test) |")
    print("|---|---:|---:|---:|---:|---|")
    total_cpu = total_wall = 0.0
    for name, recs in sorted(groups.items(), key=lambda kv: -sum(r["cpu_s"] for r in kv[1])):
        cpu = sum(r["cpu_s"] for r in recs)
        wall = sum(r["wall_s"] for r in recs)
        total_cpu += cpu
        total_wall += wall
        kb = sum(r.get("verilog_bytes", 0) for r in recs) / 1e3
        tests = sorted({r.get("test") or "(not a test)" for r in recs})
        first = tests[0] + (f" (+{len(tests) - 1})" if len(tests) > 1 else "")
        print(f"| {name} | {len(recs)} | {cpu:.1f} | {wall:.1f} | {kb:.0f} | {first} |")
    print(f"| **all** | **{len(records)}** | **{total_cpu:.1f}** | **{total_wall:.1f}** | | |")
    for name in unrecorded:
        print(f"unrecorded: {name}")


class _MapPlugin:
    """Intercepts model builds during a pytest run (see the module docstring)."""

    def __init__(self, build: bool):
        self.build = build
        self.asked: list[dict] = []
        self._undo: list = []

    def _patch(self, module, name, replacement):
        self._undo.append((module, name, getattr(module, name)))
        setattr(module, name, replacement)

    def pytest_sessionstart(self, session):
        import pytest

        from navgate.gateware import native_axi, native_stream
        from navgate.gateware import verify as V
        from navgate.systems.attitude import native_sim

        original_model, original_native = V._build_model, native_stream.compile_native

        def ask(kind, top, key, text, build):
            test = os.environ.get("PYTEST_CURRENT_TEST", "").rsplit(" (", 1)[0]
            rec = {"test": test, "kind": kind, "top": top, "key": key,
                   "verilog_bytes": len(text.encode())}
            if self.build:
                path = Path(build())
                model = path if path.is_dir() else path.parent
                stored = model / V.BUILD_RECORD
                if stored.exists():
                    rec["build"] = json.loads(stored.read_text())
            self.asked.append(rec)
            pytest.skip(f"bench_verilator_models: asked for {top}-{key}")

        def model(verilog_text, top, extra_args=()):
            key = V.model_key(verilog_text, top, tuple(extra_args))
            return ask("cocotb", top, key, verilog_text,
                       lambda: original_model(verilog_text, top, extra_args))

        def native(verilog_text, main_src, top, kind="server"):
            key = native_stream.native_key(verilog_text, main_src, top)
            return ask(kind, top, key, verilog_text,
                       lambda: original_native(verilog_text, main_src, top, kind))

        self._patch(V, "_build_model", model)
        for module in (native_stream, native_axi, native_sim):
            self._patch(module, "compile_native", native)

    def pytest_sessionfinish(self, session):
        for module, name, value in reversed(self._undo):
            setattr(module, name, value)


def map_tests(tests: list[str], build: bool, out: str | None) -> None:
    import pytest

    plugin = _MapPlugin(build)
    pytest.main(["-q", "-n", "0", "-p", "no:cacheprovider", "-rN", *tests], plugins=[plugin])
    models: dict[str, list[dict]] = defaultdict(list)
    for rec in plugin.asked:
        models[f"{rec['kind']}:{rec['top']}-{rec['key']}"].append(rec)
    print()
    print(f"{len(plugin.asked)} requests for a model, {len(models)} distinct models")
    print()
    print("| model | Verilog kB | tests asking | build CPU s | first test |")
    print("|---|---:|---:|---:|---|")
    total = 0.0
    for name, recs in sorted(models.items(), key=lambda kv: kv[1][0]["test"]):
        cpu = recs[0].get("build", {}).get("cpu_s")
        total += cpu or 0.0
        print(f"| {name} | {recs[0]['verilog_bytes'] / 1e3:.0f} | {len(recs)} | "
              f"{'-' if cpu is None else f'{cpu:.1f}'} | {recs[0]['test']} |")
    if build:
        print(f"\nbuild CPU of the models built here: {total:.1f} s")
    if out:
        Path(out).write_text(json.dumps(plugin.asked, indent=1))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("mode", nargs="?", default="table", choices=["table", "map"])
    parser.add_argument("tests", nargs="*", help="test paths for map")
    parser.add_argument("--cache", type=Path, default=None,
                        help="cache root for table (default: $NAVGATE_CACHE_DIR or the user's)")
    parser.add_argument("--build", action="store_true", help="map: build each model asked for")
    parser.add_argument("--json", default=None, help="map: write the requests as JSON here")
    args = parser.parse_intermixed_args(argv)
    if args.mode == "map":
        if not args.tests:
            parser.error("map needs test paths")
        map_tests(args.tests, args.build, args.json)
        return 0
    from navgate.cache import cache_root

    table(args.cache or cache_root())
    return 0


if __name__ == "__main__":
    sys.exit(main())
