"""The tile store under a capped cache: a flight over a 4x4 split of the embedded DEM.

The tile set is made here: the embedded Jacksboro DEM (344 x 403 posts, 3 arc-second) cut by
``navgate.trn.tiles.split_dem`` into 4 x 4 GeoTIFF tiles sharing their edge posts, in a
temporary directory. The flight is ``navgate fly``'s default scenario (seed 0, PMF), over the
store with its cache capped at a quarter of the tile set's in-memory size; the route circles
the whole DEM so it crosses many tiles. Prints tile loads, evictions, hits, peak cached bytes,
the TRN fixes and final error (equal to the whole-DEM flight's, which is also flown and
compared), and the process's peak resident memory.

    python benchmarks/bench_tiles.py [--seconds 3600] [--grid 4x4] [--cap-fraction 0.25]
"""

from __future__ import annotations

import argparse
import resource
import tempfile
import time
from pathlib import Path

from navgate.systems.ins_trn.ps import flight
from navgate.trn.dem import Dem
from navgate.trn.tiles import load_terrain, split_dem


def fly(dem, seconds):
    cfg = flight.FlightConfig(duration_s=seconds, seed=0)
    route = flight.plan_route(dem, cfg)
    t0 = time.perf_counter()
    result = flight.fly(dem, cfg, route=route)
    return result.summary(), time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=3600.0)
    ap.add_argument("--grid", default="4x4")
    ap.add_argument("--cap-fraction", type=float, default=0.25)
    args = ap.parse_args()
    rows, cols = (int(x) for x in args.grid.lower().split("x"))
    dem = Dem.default()
    with tempfile.TemporaryDirectory() as tmp:
        split_dem(dem, rows, cols, Path(tmp))
        probe = load_terrain(tmp)
        set_bytes = sum(t.nbytes for t in probe.tiles)
        cap_mb = args.cap_fraction * set_bytes / 2**20
        store = load_terrain(tmp, cache_mb=cap_mb)
        tiled, wall_tiled = fly(store, args.seconds)
        stats = store.stats()
    whole, wall_whole = fly(dem, args.seconds)
    tiled["dem"].pop("tile_store", None)

    def figures(node):  # the summary less wall-clock times and the DEM's name
        if isinstance(node, dict):
            return {k: figures(v) for k, v in node.items() if k not in ("wall_time_s", "name")}
        return node

    tiled, whole = figures(tiled), figures(whole)
    rss_mib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    rows_out = [
        ("flight (s)", f"{args.seconds:g}"),
        ("tiles", f"{rows} x {cols} = {stats['tiles']}"),
        ("tile set in memory (MiB)", f"{set_bytes / 2**20:.3f}"),
        ("cache cap (MiB)", f"{cap_mb:.3f} ({args.cap_fraction:g} of the set)"),
        ("tile loads", f"{stats['tile_loads']}"),
        ("tile evictions", f"{stats['tile_evictions']}"),
        ("tile hits", f"{stats['tile_hits']}"),
        ("peak cached (MiB)", f"{stats['peak_cached_bytes'] / 2**20:.3f}"),
        ("gap queries", f"{stats['gap_queries']}"),
        ("wall, tiles / whole DEM (s)", f"{wall_tiled:.1f} / {wall_whole:.1f}"),
        ("summary equal to whole-DEM flight", str(tiled == whole)),
        ("peak RSS of the process (MiB)", f"{rss_mib:.0f}"),
    ]
    width = max(len(a) for a, _ in rows_out)
    for a, b in rows_out:
        print(f"{a:<{width}}  {b}")


if __name__ == "__main__":
    main()
