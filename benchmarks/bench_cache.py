"""The build caches (issue 32, navgate.cache): what a first and a second gateware run cost.

1. ``navgate fly --engine fp32 --duration D`` and ``navgate fly --engine rtl --duration D``
   twice, each in a fresh process, the rtl runs with an empty Verilog cache first (a new
   ``NAVGATE_CACHE_DIR``) and then warm. The Verilator models stay in the user's cache
   (``NAVGATE_VERILATOR_CACHE`` points there) unless ``--cold-verilator``: the Verilog text is
   the same, so the compiled model is found either way. Each rtl run is split into getting
   the Verilog (elaborating, or reading the cache), building or finding the Verilator model,
   the simulation itself (time inside the model's batches) and the rest (imports, scenario,
   the reference engine's run, report); a flight has two engines (INS only, INS + TRN), the
   stages are summed over both (the second finds the first one's Verilog and model).
2. ``navgate report`` over a set of blocks (``--report-blocks``; default: the yardsticks and
   two small cores, so the cold run fits in a few minutes; ``all`` for every block), cold and
   then warm, and which blocks the warm run took from the cache.

    python benchmarks/bench_cache.py [--duration 10] [--report-blocks all|A,B,...]
                                     [--cold-verilator] [--skip-fly] [--skip-report]

Prints tables. Wall times of whole processes (interpreter start included), one run each.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

DEFAULT_REPORT_BLOCKS = ("mul_24x17", "mul_20x20", "mul_24x24", "fixed_mul", "cordic_sincos")


def _child_fly(out_json: str, args: list[str]) -> None:
    """Run ``navgate fly ARGS`` in this process, recording the rtl engine's stages."""
    from navgate import cache
    from navgate.cli import main
    from navgate.systems.ins_trn.ps import rtl_engine

    links = []
    original = rtl_engine.NativeLink.__init__

    def record(self, *a, **k):
        original(self, *a, **k)
        links.append(self)

    rtl_engine.NativeLink.__init__ = record
    code = 0
    try:
        main(args)
    except SystemExit as exit_:
        code = exit_.code or 0
    split = {"exit": code, "verilog_cache": cache.STATS["verilog"]}
    # one engine per navigation (INS only, INS + TRN): the stages summed over them
    split.update(engines=len(links),
                 verilog_s=sum(link.server.verilog_seconds for link in links),
                 model_s=sum(link.server.model_seconds for link in links),
                 simulation_s=sum(link.batch_seconds for link in links))
    Path(out_json).write_text(json.dumps(split))


def _run(argv: list[str], env: dict[str, str]) -> tuple[float, dict]:
    with tempfile.TemporaryDirectory(prefix="bench-cache-") as scratch:
        out_json = os.path.join(scratch, "split.json")
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, __file__, "--child", out_json, "--", *argv],
                              env=env, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if proc.returncode != 0 or not os.path.exists(out_json):
            raise SystemExit(f"{' '.join(argv)} failed:\n{proc.stderr[-2000:]}")
        split = json.loads(Path(out_json).read_text())
        if split["exit"] != 0:
            raise SystemExit(f"{' '.join(argv)} exited {split['exit']}:\n{proc.stderr[-2000:]}")
    return wall, split


def bench_fly(duration: float, cold_verilator: bool) -> None:
    from navgate.gateware.verify import verilator_cache_dir

    models = str(verilator_cache_dir())
    with tempfile.TemporaryDirectory(prefix="bench-cache-root-") as root, \
            tempfile.TemporaryDirectory(prefix="bench-cache-out-") as out:
        env = dict(os.environ, NAVGATE_CACHE_DIR=root)
        if not cold_verilator:
            env["NAVGATE_VERILATOR_CACHE"] = models
        else:
            env.pop("NAVGATE_VERILATOR_CACHE", None)
        fly = ["fly", "--duration", str(duration), "--quiet", "--out"]
        # warm-up (Numba's cache, the OS file cache), not timed
        _run([*fly, os.path.join(out, "warm"), "--engine", "fp32"], env)
        fp32_wall, _ = _run([*fly, os.path.join(out, "fp32"), "--engine", "fp32"], env)
        rows = []
        for label in ("rtl, first run (empty Verilog cache)", "rtl, second run"):
            wall, split = _run([*fly, os.path.join(out, "rtl"), "--engine", "rtl"], env)
            rest = wall - split["verilog_s"] - split["model_s"] - split["simulation_s"]
            rows.append((label, wall, split, rest))
    print(f"\n`navgate fly --duration {duration:g}` (one process each; Verilator models "
          f"{'built from scratch' if cold_verilator else 'from the user cache'})\n")
    print("| run | wall (s) | Verilog (s) | Verilator model (s) | simulation (s) | rest (s) | "
          "Verilog cache |")
    print("|---|---:|---:|---:|---:|---:|---|")
    print(f"| fp32 | {fp32_wall:.1f} | - | - | - | - | - |")
    for label, wall, split, rest in rows:
        hits = split["verilog_cache"]
        state = (f"{hits['miss']} miss, {hits['hit']} hit" if hits["miss"]
                 else f"{hits['hit']} hit")
        print(f"| {label} | {wall:.1f} | {split['verilog_s']:.2f} | {split['model_s']:.2f} | "
              f"{split['simulation_s']:.2f} | {rest:.1f} | {state} |")
    second = rows[1]
    target = 2 * fp32_wall + second[2]["simulation_s"]
    print(f"\ntarget for the second rtl run: 2 x fp32 wall + simulation = {target:.1f} s; "
          f"measured {second[1]:.1f} s ({'met' if second[1] <= target else 'missed'})")


def bench_report(blocks: str) -> None:
    with tempfile.TemporaryDirectory(prefix="bench-cache-root-") as root:
        env = dict(os.environ, NAVGATE_CACHE_DIR=root)
        code = ("import sys, navgate.hw.blocks as b\n"
                "keep = sys.argv[1]\n"
                "if keep != 'all':\n"
                "    names = keep.split(',')\n"
                "    everything = b.all_blocks\n"
                "    b.all_blocks = lambda: {n: v for n, v in everything().items() if n in names}\n"
                "from navgate.cli import main\n"
                "main(['report'])\n")
        rows = []
        for label in ("cold (empty cache)", "second run, unchanged tree"):
            t0 = time.perf_counter()
            proc = subprocess.run([sys.executable, "-c", code, blocks], env=env,
                                  capture_output=True, text=True)
            wall = time.perf_counter() - t0
            if proc.returncode != 0:
                raise SystemExit(f"navgate report failed:\n{proc.stderr[-2000:]}")
            note = [line for line in proc.stdout.splitlines()
                    if line.startswith("Synthesis results from the cache")]
            rows.append((label, wall, note[0] if note else "?"))
    count = "every block" if blocks == "all" else f"{len(blocks.split(','))} blocks ({blocks})"
    print(f"\n`navgate report` over {count}\n")
    print("| run | wall (s) | from the cache |")
    print("|---|---:|---|")
    for label, wall, note in rows:
        print(f"| {label} | {wall:.1f} | {note.split(': ', 1)[1].split(':')[0].rstrip('.')} |")


def main() -> None:
    if len(sys.argv) > 2 and sys.argv[1] == "--child":
        _child_fly(sys.argv[2], sys.argv[4:])
        return
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=10.0)
    ap.add_argument("--report-blocks", default=",".join(DEFAULT_REPORT_BLOCKS))
    ap.add_argument("--cold-verilator", action="store_true",
                    help="also build the Verilator model from scratch (minutes)")
    ap.add_argument("--skip-fly", action="store_true")
    ap.add_argument("--skip-report", action="store_true")
    args = ap.parse_args()
    if not args.skip_fly:
        bench_fly(args.duration, args.cold_verilator)
    if not args.skip_report:
        bench_report(args.report_blocks)


if __name__ == "__main__":
    main()
