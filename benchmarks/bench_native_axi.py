"""Simulation rate of the native AXI4-Lite co-simulation (navgate.gateware.native_axi) on the
small test top of tests/gateware/test_native_axi.py (register bank of an 8-register map, an
80-bit input stream, ``irq``): transactions per second one per round trip and batched, stream
pushes, idle cycles, and the cost of random channel delays (the first run builds the model).

    python benchmarks/bench_native_axi.py [--n 20000] [--json bench_native_axi.json]

Prints a table and writes a JSON summary (default ``bench_native_axi.json`` in the current
directory).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from navgate.hw.regmap import load_rdl

TEST = Path(__file__).resolve().parents[1] / "tests" / "gateware" / "test_native_axi.py"


def load_test_top():
    spec = importlib.util.spec_from_file_location("_native_axi_test", TEST)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "axisim_test.rdl"
        path.write_text(mod.RDL)
        regmap = load_rdl(path)
    return mod, mod.AccumulatorTop(regmap)


def measure(sim, label, transactions, fn):
    c0 = sim.cycles
    t0 = time.perf_counter()
    fn()
    secs = time.perf_counter() - t0
    cycles = sim.cycles - c0
    row = {"case": label, "transactions": transactions, "seconds": secs,
           "transactions_per_s": transactions / secs, "cycles": cycles,
           "cycles_per_transaction": cycles / transactions, "cycles_per_s": cycles / secs}
    print(f"{label:44s} {transactions:8d} {secs:8.3f} {row['transactions_per_s']:12,.0f} "
          f"{row['cycles_per_transaction']:8.2f} {row['cycles_per_s']:12,.0f}")
    return row


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=20_000, help="transactions per batched case")
    ap.add_argument("--json", default="bench_native_axi.json")
    args = ap.parse_args()
    n, n1 = args.n, max(1, args.n // 2)
    mod, top = load_test_top()
    rows = []
    sim = mod.new_sim(top)
    print(f"model build/cache lookup: {sim.build_seconds:.1f} s")
    print(f"{'case':44s} {'n':>8s} {'s':>8s} {'per s':>12s} {'cyc/tr':>8s} {'cycles/s':>12s}")
    rng = np.random.default_rng(0)
    rows.append(measure(sim, "write, one per round trip", n1,
                        lambda: [sim.write(0x0, i) for i in range(n1)]))
    rows.append(measure(sim, "read, one per round trip", n1,
                        lambda: [sim.read(0x8) for _ in range(n1)]))

    def deferred_writes():
        for start in range(0, n, 1000):
            with sim.deferred():
                for i in range(start, min(n, start + 1000)):
                    sim.write(0x0, i)

    rows.append(measure(sim, "write, deferred (1000 per batch)", n, deferred_writes))
    rows.append(measure(sim, "read, raw batch of 1000", n,
                        lambda: [sim.batch(["R 8"] * 1000) for _ in range(n // 1000)]))
    pay = mod.random_payloads(rng, n)
    rows.append(measure(sim, "stream push (80-bit), one batch", n,
                        lambda: sim.push("feed", pay)))
    idle = 1000 * n
    rows.append(measure(sim, f"idle cycles (one C {idle})", idle, lambda: sim.run(idle)))
    sim.close()
    sim = mod.new_sim(top, delay_probability=0.5, max_delay=4, seed=1)
    rows.append(measure(sim, "write, deferred, random delays p=0.5 max 4", n,
                        deferred_writes))
    sim.close()
    with open(args.json, "w") as fh:
        json.dump({"design": "tests/gateware/test_native_axi.py AccumulatorTop",
                   "rows": rows}, fh, indent=1)


if __name__ == "__main__":
    main()
