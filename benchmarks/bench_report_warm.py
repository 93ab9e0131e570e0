"""``navgate report`` over every block on an unchanged tree (issue 32's target: at most 30 s),
and what an edit costs, without the hour-long cold run that would fill the synth cache first.

1. **Fill** (not timed as a target): ``navgate report`` in a fresh ``NAVGATE_CACHE_DIR`` with
   the synthesis step (:func:`navgate.hw.flow._run_tools`) replaced by a placeholder result.
   Every block is elaborated and its Verilog cached for real; the synth cache gets one entry
   per block under the key a real run computes (the key is the Verilog, the flow's sources,
   the options and the tool versions, never the result), so the next run finds them all.
2. **Warm** (the target): the real ``navgate report``, twice, in fresh processes: nothing is
   elaborated or synthesised; the time is imports, reading both caches, writing the outputs.
3. **Touched** (``--touch FILE``): a comment appended to one source file of the package (so
   the source fingerprint, and every Verilog key, changes), the report run again: every block
   is elaborated again, and the report's cache line says which were synthesised (blocks
   whose Verilog did not change come from the synth cache). The file is restored after.

The tables' figures of steps 1-3 are placeholders; only the times and the cache lines count.

    python benchmarks/bench_report_warm.py [--blocks all|A,B,...] [--touch src/navgate/...]

Prints a table of wall and CPU seconds (``resource.getrusage`` of the child), one run each.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CHILD = r"""
import sys
import navgate.hw.blocks as b
keep, stub = sys.argv[1], sys.argv[2] == "stub"
if keep != "all":
    names = keep.split(",")
    everything = b.all_blocks
    b.all_blocks = lambda: {n: v for n, v in everything().items() if n in names}
if stub:
    import navgate.hw.flow as flow

    def placeholder(text, name, target, *args, **kwargs):
        zero = {"lut": 0, "ff": 0, "dsp": 0, "carry4": 0, "bram36": 0}
        return {"utilization": {"block": name, "target": target, "part": "placeholder",
                                "flow": "placeholder", **zero, "percent": dict(zero),
                                "cells": {}}}

    flow._run_tools = placeholder
from navgate.cli import main
main(["report"])
"""


def _run(blocks: str, stub: bool, env: dict) -> tuple[float, float, str]:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", CHILD, blocks, "stub" if stub else "real"],
                          env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    if proc.returncode != 0:
        raise SystemExit(f"navgate report failed:\n{proc.stderr[-3000:]}")
    note = [line for line in proc.stdout.splitlines() if "cache" in line.lower()]
    return wall, cpu, " / ".join(note)[-300:]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--blocks", default="all")
    ap.add_argument("--touch", default=None, help="a source file to append a comment to")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-report-root-") as root:
        env = dict(os.environ, NAVGATE_CACHE_DIR=root)
        rows.append(("fill (synthesis stubbed, Verilog cold)", *_run(args.blocks, True, env)))
        for k in (1, 2):
            rows.append((f"warm, unchanged tree ({k})", *_run(args.blocks, False, env)))
        if args.touch:
            path = Path(args.touch)
            saved = path.read_bytes()
            try:
                path.write_bytes(saved + b"\n# bench_report_warm: touched\n")
                rows.append((f"after touching {path.name}", *_run(args.blocks, False, env)))
            finally:
                path.write_bytes(saved)
    print(f"\n`navgate report` over {args.blocks} blocks\n")
    print("| run | wall s | CPU s | report's cache line |")
    print("|---|---:|---:|---|")
    for label, wall, cpu, note in rows:
        print(f"| {label} | {wall:.1f} | {cpu:.1f} | {note} |")


if __name__ == "__main__":
    main()
