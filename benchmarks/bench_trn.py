"""Speed of the terrain correlators on the embedded DEM: one TERCOM match of a 64-sample
profile and one point-mass filter fix of a 20-sample segment, for several prior sigmas
(the grid grows with the prior up to 161 x 161 points).

    python benchmarks/bench_trn.py [--repeat 5]

Prints a table; best-of-repeat wall time on one core after Numba's cache is warm.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from navgate.nav.earth import LocalTangent
from navgate.trn.dem import Dem
from navgate.trn.pmf import PointMassCorrelator
from navgate.trn.profile import ProfileSnapshot
from navgate.trn.tercom import TercomCorrelator


def profile(dem, tangent, n, rng):
    s = np.arange(n) * 30.0
    pn, pe = -2000.0 + s * math.cos(0.6), 1000.0 + s * math.sin(0.6)
    h = dem.height(*tangent.to_geodetic(pn, pe)) + rng.standard_normal(n) * 2.0
    return ProfileSnapshot(h, pn - 12.0, pe + 7.0, np.arange(n) * 0.5)


def best(fn, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    dem = Dem.default()
    tan = LocalTangent(*dem.center, 0.0)
    rng = np.random.default_rng(0)
    long_prof, short_prof = profile(dem, tan, 64, rng), profile(dem, tan, 20, rng)
    print("| correlator | samples | prior sigma (m) | grid points | time per fix (ms) |")
    print("|---|---|---|---|---|")
    for sigma in (10.0, 50.0, 200.0, 600.0):
        ter = TercomCorrelator(dem, tan)
        ter.correlate(long_prof, sigma)
        t = best(lambda ter=ter, sigma=sigma: ter.correlate(long_prof, sigma), args.repeat)
        res = ter.correlate(long_prof, sigma)
        cells = (2 * math.ceil(res.half_width_m / ter.step) + 1) ** 2
        print(f"| tercom | 64 | {sigma:g} | {cells} | {1e3 * t:.1f} |")
    for sigma in (10.0, 50.0, 200.0, 600.0):
        pmf = PointMassCorrelator(dem, tan)

        def fix(pmf=pmf, sigma=sigma):
            pmf.used_until = -math.inf
            return pmf.correlate(short_prof, sigma)

        fix()
        t = best(fix, args.repeat)
        res = fix()
        step = max(min(pmf.step, sigma / 2), 2 * res.half_width_m / (pmf.config.max_cells - 1))
        cells = (2 * math.ceil(res.half_width_m / step) + 1) ** 2
        print(f"| pmf ({res.reason}) | 20 | {sigma:g} | {cells} (+ refinement) | "
              f"{1e3 * t:.1f} |")


if __name__ == "__main__":
    main()
