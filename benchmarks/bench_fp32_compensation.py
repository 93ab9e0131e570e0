"""Seed 000's float32 engine against the float64 reference engine on one long INS + TRN
flight: position and covariance differences, for the effect of how the Kalman update treats
P's Kahan compensation words (docs/seed000-engines.md, "Compensation words of P").

    python benchmarks/bench_fp32_compensation.py [--seconds 3600] [--seed 0]
    python benchmarks/bench_fp32_compensation.py --engine reference --save ref.npz
    python benchmarks/bench_fp32_compensation.py --engine fp32 --against ref.npz

Runs the reference engine and the fp32 engine on the same records (or one of them, saving
its log with ``--save``, or comparing with a saved run with ``--against``: a one-hour flight
takes some 15 minutes per engine, and the reference run is the same for every version of
the fp32 programs). Prints, at the end of each quarter of the flight, the horizontal
position difference fp32 - reference (largest so far, and at that time), the largest
relative difference of the 15 standard deviations so far (square roots of P's diagonal as
the engine reports it: P - cP for fp32) and its state index; then over the whole flight the
RMS position difference and the median and 99th percentile of the largest relative sigma
difference per log line (the maximum is set by moments when one run has applied a fix that
the other applies a log line later), the fixes applied and the second-half RMS error of each
run.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from navgate.nav.earth import A
from navgate.systems.ins_trn.ps import flight
from navgate.systems.ins_trn.ps.flight import flight_stream
from navgate.systems.ins_trn.ps.navigator import Navigator, engine_setup
from navgate.systems.ins_trn.ps.pl_interface import make_engine
from navgate.trn.dem import Dem


def run_engine(name, data, dem, cfg, init) -> dict:
    stream = flight_stream(data, dem, cfg, init)
    eng = make_engine(name, engine_setup(stream.header, cfg))
    t0 = time.perf_counter()
    run = Navigator(eng, cfg, t0=stream.header["t0"], dem=dem, use_trn=True).run(stream)
    print(f"{name}: {time.perf_counter() - t0:.1f} s")
    err = flight.score(run, data.truth, 40).horizontal_error
    return {"t": run.t, "nav": run.nav, "sigma": run.sigma, "err": err,
            "applied": sum(f["applied"] for f in run.fixes)}


def compare(ref: dict, f32: dict) -> None:
    m = min(len(ref["t"]), len(f32["t"]))
    # lat/lon differences to metres (the Earth's equatorial radius: a 0.3 % scale at most)
    dpos = A * np.hypot(f32["nav"][:m, 0] - ref["nav"][:m, 0],
                        (f32["nav"][:m, 1] - ref["nav"][:m, 1]) * np.cos(ref["nav"][:m, 0]))
    rel = np.abs(f32["sigma"][:m] - ref["sigma"][:m]) / np.maximum(ref["sigma"][:m], 1e-30)
    print(f"{'to t (s)':>9} {'max |dpos| (m)':>15} {'|dpos| end (m)':>15} "
          f"{'max rel dsigma':>15} {'state':>6}")
    for q in (1, 2, 3, 4):
        k = m * q // 4
        worst = int(np.argmax(rel[:k].max(axis=0)))
        print(f"{ref['t'][k - 1] - ref['t'][0]:9.0f} {dpos[:k].max():15.3f} "
              f"{dpos[k - 1]:15.3f} {rel[:k].max():15.3e} {worst:6d}")
    worst = rel.max(axis=1)
    print(f"over the flight: RMS |dpos| {np.sqrt(np.mean(dpos**2)):.3f} m; largest relative "
          f"sigma difference per log line: median {np.median(worst):.3e}, 99th percentile "
          f"{np.percentile(worst, 99):.3e}; at the end {worst[-1]:.3e}")
    for name, r in (("reference", ref), ("fp32", f32)):
        e = r["err"]
        print(f"{name}: fixes applied {int(r['applied'])}, 2nd-half RMS error "
              f"{np.sqrt(np.mean(e[len(e) // 2:] ** 2)):.2f} m")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=3600.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--engine", choices=("both", "reference", "fp32"), default="both")
    ap.add_argument("--save", help="write the run (one engine) to this .npz")
    ap.add_argument("--against", help="a saved reference run to compare the fp32 run with")
    args = ap.parse_args()
    dem = Dem.default()
    cfg = flight.FlightConfig(duration_s=args.seconds, seed=args.seed)
    route = flight.plan_route(dem, cfg)
    data = flight.simulate_sensors(route, dem, cfg)
    init = flight.initial_estimate(data, cfg)
    names = ("reference", "fp32") if args.engine == "both" else (args.engine,)
    runs = {n: run_engine(n, data, dem, cfg, init) for n in names}
    if args.save:
        np.savez(args.save, **runs[names[-1]])
    if args.against:
        runs["reference"] = dict(np.load(args.against))
    if "reference" in runs and "fp32" in runs:
        compare(runs["reference"], runs["fp32"])


if __name__ == "__main__":
    main()
