"""The ranking weights of the banked engine's register layout
(``navgate.systems.ins_trn.pl.nav_engines.RANK_WEIGHTS``): every weighting in {1, 2, 3} of
the register reads of propagate, alt_apply and trn_apply, the cycles of the five programs
of ``ins_engines`` under each, best total first. The layout ranks the registers over the
banks by their (weighted) reads, round robin; the schedules follow the layout.

    python benchmarks/bench_bank_weights.py [--top 10] [--json out.json]

Prints a table and writes a JSON summary (default ``bench_bank_weights.json``).
"""

from __future__ import annotations

import argparse
import itertools
import json

from navgate.opflow.machine import BankedImage
from navgate.systems.ins_trn.pl import nav_engines as NE
from navgate.systems.ins_trn.pl.fp32_program import RESET_MODULE

WEIGHTED = ("propagate", "alt_apply", "trn_apply")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--top", type=int, default=10)
    ap.add_argument("--json", default="bench_bank_weights.json")
    args = ap.parse_args()
    allp = NE.engine_programs()
    progs = {k: allp[k] for k in NE.PROGRAM_SETS["ins_engines"]}
    rows = []
    for w in itertools.product((1, 2, 3), repeat=len(WEIGHTED)):
        weights = dict(zip(WEIGHTED, w, strict=True))
        img = BankedImage.build(progs, NE.ENGINE_UNITS, NE.fixed_names(progs),
                                rank_skip=(RESET_MODULE,), rank_weights=weights)
        cycles = {k: img.cycles(k) for k in progs}
        rows.append((sum(cycles.values()), weights, cycles))
    rows.sort(key=lambda r: r[0])
    keys = list(progs)
    print(f"{'weights (' + ', '.join(WEIGHTED) + ')':40s} " + " ".join(f"{k:>10s}" for k in keys)
          + f" {'total':>7s}")
    for total, weights, cycles in rows[:args.top]:
        mark = " <- RANK_WEIGHTS" if weights == NE.RANK_WEIGHTS else ""
        print(f"{str(tuple(weights.values())):40s} "
              + " ".join(f"{cycles[k]:10d}" for k in keys) + f" {total:7d}{mark}")
    with open(args.json, "w") as fh:
        json.dump([{"weights": w, "cycles": c, "total": t} for t, w, c in rows], fh, indent=1)
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
