"""Seed 001 TinyKalman, parallel and serial chips: settled roll/pitch error against
the atan2 truth over held attitudes in all four roll quadrants and both pitch signs.

Each attitude is held for 700 samples (11 time constants of the ``>>> 6`` filter) with the
gyro at rest; the accelerometer words are the MPU-6500's at 16384 LSB/g, rounded. Truth:
roll = atan2(ay, az), pitch = atan2(-ax, sqrt(ay^2 + az^2)) on the same rounded words. The
parallel column runs :class:`TinyKalmanDatapath` with the parallel angle block, the serial
column the serial chip's data path (:class:`TinyKalmanSerialDatapath`: the bit-serial CORDIC
and the bit-serial filter of :mod:`navgate.systems.tinykalman.serial`), both in Verilator;
the two must be equal (same arithmetic) and equal to the integer model.

Run from the checkout root: ``python benchmarks/bench_tinykalman_settled.py`` (1.9 min CPU,
16 min wall on the shared machine at load ~10, both Verilator builds uncached).
"""

from __future__ import annotations

import math

import numpy as np

from navgate.gateware import verify as V
from navgate.systems.tinykalman.datapath import TinyKalmanDatapath
from navgate.systems.tinykalman.model import BAM_PER_DEG
from navgate.systems.tinykalman.rtl_sim import datapath_model
from navgate.systems.tinykalman.serial import TinyKalmanSerialDatapath

HOLD = 700
ATTITUDES = [(r, p) for r in (45.0, 135.0, -135.0, -45.0) for p in (30.0, -30.0)]


def words(roll_deg: float, pitch_deg: float) -> tuple[int, int, int]:
    r, p = math.radians(roll_deg), math.radians(pitch_deg)
    g = 16384
    return (round(-math.sin(p) * g), round(math.cos(p) * math.sin(r) * g),
            round(math.cos(p) * math.cos(r) * g))


def wrap_deg(d):
    return (np.asarray(d) + 180.0) % 360.0 - 180.0


def main() -> None:
    ins = {k: [] for k in ("ax", "ay", "az", "gx", "gy", "ok")}
    for r, p in ATTITUDES:
        ax, ay, az = words(r, p)
        for k, v in (("ax", ax), ("ay", ay), ("az", az), ("gx", 0), ("gy", 0), ("ok", 1)):
            ins[k] += [v] * HOLD
    ins = {k: np.asarray(v, np.int64) for k, v in ins.items()}
    runs = {}
    def serial_model(seen):
        exp = datapath_model(seen)
        return {k: exp[k] for k in ("roll", "pitch", "sat", "ok")}

    for name, comp, model in (("parallel", TinyKalmanDatapath(), datapath_model),
                              ("serial", TinyKalmanSerialDatapath(), serial_model)):
        res = V.verify(comp, model, ins, backend="verilator", keep_outputs=True)
        res.assert_ok()  # bit-exact to the model
        runs[name] = res.outputs
    assert all(np.array_equal(runs["parallel"][k], runs["serial"][k]) for k in ("roll", "pitch"))
    print(f"{'roll deg':>8s} {'pitch deg':>9s} {'truth roll':>10s} {'truth pitch':>11s} "
          f"{'par roll err':>12s} {'par pitch err':>13s} {'ser roll err':>12s} "
          f"{'ser pitch err':>13s}")
    for i, (r, p) in enumerate(ATTITUDES):
        ax, ay, az = words(r, p)
        tr = math.degrees(math.atan2(ay, az))
        tp = math.degrees(math.atan2(-ax, math.hypot(ay, az)))
        k = (i + 1) * HOLD - 1
        errs = []
        for name in ("parallel", "serial"):
            er = wrap_deg(int(runs[name]["roll"][k]) / BAM_PER_DEG - tr)
            ep = wrap_deg(int(runs[name]["pitch"][k]) / BAM_PER_DEG - tp)
            errs += [er, ep]
        print(f"{r:8.1f} {p:9.1f} {tr:10.3f} {tp:11.3f} " + " ".join(
            f"{e:12.4f}" if j % 2 == 0 else f"{e:13.4f}" for j, e in enumerate(errs)))
    print(f"\n{HOLD} samples per attitude; errors in degrees after the last sample; parallel "
          "and serial outputs identical sample for sample")


if __name__ == "__main__":
    main()
