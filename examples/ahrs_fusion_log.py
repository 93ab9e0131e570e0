"""Attitude from a real IMU log: seed 003's Mahony filter and the complementary filter over the
x-io 100 Hz IMU + magnetometer log in ../shared/data/fusion_sensor_data.csv.

Usage: python examples/ahrs_fusion_log.py [LOG.csv] [--plot OUT.png]

The same as ``navgate ahrs LOG.csv --filter mahony --out ...`` but through the library:
read the log (x-io headers, units converted from the header), run both filters in NED/FRD
(x-io sensors read +1 g on z when flat, so the log's axes are mapped to FRD), and print the
attitude every 10 s with the quiet-period agreement between the filters.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from navgate.sim.imu_log import LogError, read_imu_csv
from navgate.systems.attitude.estimate import estimate_attitude

DEFAULT = Path(__file__).resolve().parents[2] / "shared" / "data" / "fusion_sensor_data.csv"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("log", nargs="?", type=Path, default=DEFAULT)
    ap.add_argument("--plot", type=Path, default=None, help="write a PNG of the angles")
    args = ap.parse_args(argv)
    try:
        log = read_imu_csv(args.log)
    except LogError as error:
        print(f"error: {error}")
        return 2
    print(f"{args.log.name}: {len(log)} samples, {log.t[-1] - log.t[0]:.1f} s, "
          f"{log.style} headers, {log.skipped_rows} rows skipped")
    m = estimate_attitude(log, "mahony")
    c = estimate_attitude(log, "complementary")
    print(f"axes {m.axes}; magnetometer {'used' if m.used_mag else 'absent'}")
    print("   t (s) | Mahony roll pitch yaw (deg) | complementary roll pitch yaw (deg)")
    for k in np.searchsorted(log.t, np.arange(0.0, log.t[-1], 10.0)):
        print(f"{log.t[k]:8.1f} | {m.roll_deg[k]:7.2f} {m.pitch_deg[k]:6.2f} "
              f"{m.yaw_deg[k]:7.2f} | {c.roll_deg[k]:7.2f} {c.pitch_deg[k]:6.2f} "
              f"{c.yaw_deg[k]:7.2f}")
    quiet = np.linalg.norm(log.gyro, axis=1) < np.radians(2.0)
    d = np.abs(np.column_stack([m.roll_deg - c.roll_deg, m.pitch_deg - c.pitch_deg]))[quiet]
    print(f"quiet samples (|gyro| < 2 deg/s): {quiet.sum()}; roll/pitch difference between "
          f"the filters: median {np.median(d):.2f} deg, 95th percentile "
          f"{np.percentile(d, 95):.2f} deg")
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(3, 1, sharex=True, figsize=(10, 7))
        for a, name in zip(ax, ("roll_deg", "pitch_deg", "yaw_deg"), strict=True):
            a.plot(m.t, getattr(m, name), label="Mahony (seed 003)")
            a.plot(c.t, getattr(c, name), label="complementary", alpha=0.7)
            a.set_ylabel(name.replace("_deg", " (deg)"))
        ax[0].legend()
        ax[-1].set_xlabel("time (s)")
        fig.tight_layout()
        fig.savefig(args.plot, dpi=100)
        print(f"wrote {args.plot}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
