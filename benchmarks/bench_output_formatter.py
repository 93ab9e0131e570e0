"""Accuracy of seed 000's nav_output_formatter bit-true model against its float64 reference,
beside the derived bounds (issue 12; docs/seed000-output-formatter.md).

Random unit quaternions (uniform on the 3-sphere, then rounded to float32), quaternions near
gimbal lock (pitch within 1e-9 .. 1e-1 rad of +-90 deg) and yaw near +-180 deg; for each set
the largest error of roll, pitch and yaw (radians, modulo 2 pi), the largest ratio to the
per-sample bound (``euler_error_bound``, where it is below 0.1 rad: near gimbal lock yaw and
roll alone are ill-conditioned and the bound grows as 1/M), and the largest angle between
the rotation the three angles describe and the quaternion's rotation (against
``rotation_error_bound``).
Prints a table and writes ``summary.json`` into ``--out``.

Usage: ``python benchmarks/bench_output_formatter.py [--n 100000] [--seed 1] [--out DIR]``
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from navgate.nav.rotations import euler_to_dcm_array
from navgate.numerics.fp32 import bits_to_f32, f32_to_bits
from navgate.systems.ins_trn.pl import output_formatter as F


def euler_quat(roll, pitch, yaw):
    a, b, c = yaw / 2, pitch / 2, roll / 2
    ca, sa, cb, sb, cc, sc = (np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c),
                              np.sin(c))
    return np.stack([ca * cb * cc + sa * sb * sc, ca * cb * sc - sa * sb * cc,
                     ca * sb * cc + sa * cb * sc, sa * cb * cc - ca * sb * sc], axis=-1)


def evaluate(q):
    n = len(q)
    words = {name: np.zeros(n, dtype=np.uint32) for name in F.IN_FIELDS}
    for i in range(4):
        words[f"q{i}"] = f32_to_bits(q[:, i].astype(np.float32))
    qv = np.stack([bits_to_f32(words[f"q{i}"]).astype(np.float64) for i in range(4)], 1)
    bt = F.formatter_bittrue(words)
    ref = F.reference_format({k: bits_to_f32(v).astype(np.float64) for k, v in words.items()})
    got = {a: bits_to_f32(bt[a]).astype(np.float64) for a in ("roll", "pitch", "yaw")}
    mp = np.hypot(qv[:, 0] - qv[:, 2], qv[:, 3] + qv[:, 1])
    mm = np.hypot(qv[:, 0] + qv[:, 2], qv[:, 3] - qv[:, 1])
    bounds = np.array([F.euler_error_bound(a, b, c) for a, b, c in zip(mp, mm, ref["norm"],
                                                                         strict=True)])
    row = {}
    for a, col in (("roll", 0), ("pitch", 1), ("yaw", 0)):
        d = got[a] - ref[a]
        err = np.abs((d + np.pi) % (2 * np.pi) - np.pi)
        row[f"{a}_max_err"] = float(err.max())
        row[f"{a}_median_err"] = float(np.median(err))
        useful = bounds[:, col] < 0.1  # the per-angle bound grows as 1/M near gimbal lock
        row[f"{a}_max_ratio"] = float((err / bounds[:, col])[useful].max())
    c1 = euler_to_dcm_array(got["roll"], got["pitch"], got["yaw"])
    r = F.reference_euler(qv)
    c2 = euler_to_dcm_array(r[0], r[1], r[2])
    tr = np.einsum("nij,nij->n", c1, c2)
    rot = np.arccos(np.clip((tr - 1) / 2, -1, 1))
    row["rotation_max_err"] = float(rot.max())
    row["flags_nonzero"] = int(np.count_nonzero(bt["flags"]))
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100_000)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", type=Path, default=Path("build/bench_output_formatter"))
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    q = rng.normal(size=(args.n, 4))
    sets = {"random unit": q / np.linalg.norm(q, axis=1)[:, None]}
    k = max(1, args.n // 5)
    pitch = np.where(rng.random(k) < 0.5, 1, -1) * (np.pi / 2 - 10.0 ** rng.uniform(-9, -1, k))
    sets["near gimbal lock"] = euler_quat(rng.uniform(-np.pi, np.pi, k), pitch,
                                          rng.uniform(-np.pi, np.pi, k))
    yaw = np.pi - 10.0 ** rng.uniform(-8, -2, k) * np.where(rng.random(k) < 0.5, 1, -1)
    sets["yaw near 180 deg"] = euler_quat(rng.uniform(-1, 1, k), rng.uniform(-1, 1, k), yaw)
    rows = {name: evaluate(qs) for name, qs in sets.items()}
    b_ry, b_p = F.euler_error_bound(1.0, 1.0)
    summary = {"n": args.n, "seed": args.seed, "rows": rows,
               "bound_roll_yaw_at_m_1": b_ry, "bound_pitch_at_m_1": b_p,
               "rotation_bound": F.rotation_error_bound()}
    print(f"bounds at M+ = M- = 1: roll/yaw {b_ry:.3e} rad, pitch {b_p:.3e} rad; rotation "
          f"(everywhere) {summary['rotation_bound']:.3e} rad")
    print(f"{'set':18s} {'n':>7s} {'roll max':>10s} {'pitch max':>10s} {'yaw max':>10s} "
          f"{'yaw med':>10s} {'max/bound':>9s} {'rot max':>10s}")
    for name, r in rows.items():
        ratio = max(r["roll_max_ratio"], r["pitch_max_ratio"], r["yaw_max_ratio"])
        print(f"{name:18s} {len(sets[name]):7d} {r['roll_max_err']:10.3e} "
              f"{r['pitch_max_err']:10.3e} {r['yaw_max_err']:10.3e} "
              f"{r['yaw_median_err']:10.3e} {ratio:9.3f} {r['rotation_max_err']:10.3e}")
    args.out.mkdir(parents=True, exist_ok=True)
    finite = all(math.isfinite(v) for r in rows.values() for v in r.values())
    if not finite:
        raise SystemExit("non-finite result")
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2))


if __name__ == "__main__":
    main()
