"""Throughput of the bit-true numerics models (navgate.numerics), vectorised over NumPy.

Usage: python benchmarks/bench_numerics.py [--n 1000000] [--repeat 3] [--seed 0] [--accuracy]

Prints one table row per operation: elements per call, best wall time of ``--repeat``
calls, and operations per second. Inputs are random normal float32 patterns / random
in-range fixed-point integers drawn from ``--seed``. ``--accuracy`` adds two tables:
CORDIC vectoring angle error and Goldschmidt relative error, observed maximum over
random inputs versus the derived worst-case bound, per iteration count.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from rich.console import Console
from rich.table import Table

from navgate.numerics import (
    QFormat,
    angle_to_radians,
    cordic_error_bound,
    cordic_rotation,
    cordic_vectoring,
    fixed_add,
    fixed_mul_trunc,
    fp32_add,
    fp32_compare,
    fp32_div,
    fp32_from_int,
    fp32_mul,
    fp32_sqrt,
    fp32_sub,
    fp32_to_int,
    goldschmidt_divide,
    goldschmidt_error_bound,
    goldschmidt_normalised,
    goldschmidt_reciprocal,
)


def _normal_bits(rng, n):
    s = rng.integers(0, 2, n, dtype=np.uint32) << np.uint32(31)
    e = rng.integers(1, 255, n).astype(np.uint32) << np.uint32(23)
    return (s | e | rng.integers(0, 1 << 23, n, dtype=np.uint32)).astype(np.uint32)


def _best(fn, repeat):
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--accuracy", action="store_true", help="also print error-bound tables")
    args = ap.parse_args()
    n = args.n
    rng = np.random.default_rng(args.seed)
    a, b = _normal_bits(rng, n), _normal_bits(rng, n)
    i32 = rng.integers(-(2**31), 2**31, n)
    q = QFormat(20, 10)
    qa = rng.integers(q.min_int, q.max_int + 1, n)
    qb = rng.integers(q.min_int, q.max_int + 1, n)
    x16 = rng.integers(-(2**15), 2**15, n)
    y16 = rng.integers(-(2**15), 2**15, n)
    ang = rng.integers(-(2**15), 2**15, n)
    rows = [
        ("fp32_add", lambda: fp32_add(a, b)),
        ("fp32_sub", lambda: fp32_sub(a, b)),
        ("fp32_mul", lambda: fp32_mul(a, b)),
        ("fp32_div", lambda: fp32_div(a, b)),
        ("fp32_sqrt", lambda: fp32_sqrt(a)),
        ("fp32_compare", lambda: fp32_compare(a, b)),
        ("fp32_from_int (32)", lambda: fp32_from_int(i32, 32)),
        ("fp32_to_int (32)", lambda: fp32_to_int(a, 32)),
        ("fixed_add Q(20,10) sat", lambda: fixed_add(qa, qb, q)),
        ("fixed_mul_trunc Q(20,10)", lambda: fixed_mul_trunc(qa, qb, q)),
        ("cordic_vectoring w16 n16", lambda: cordic_vectoring(x16, y16, 16, 16)),
        ("cordic_rotation w16 n16", lambda: cordic_rotation(ang, 16, 16)),
        ("goldschmidt_reciprocal Q(20,10) k3", lambda: goldschmidt_reciprocal(qa, 20, 10)),
        ("goldschmidt_divide Q(20,10) k3", lambda: goldschmidt_divide(qa, qb, 20, 10)),
    ]
    table = Table(title=f"navgate.numerics throughput (n={n}, best of {args.repeat})")
    table.add_column("operation")
    table.add_column("elements", justify="right")
    table.add_column("time [ms]", justify="right")
    table.add_column("ops/s", justify="right")
    for name, fn in rows:
        t = _best(fn, args.repeat)
        table.add_row(name, f"{n}", f"{t * 1e3:.1f}", f"{n / t:,.0f}")
    console = Console()
    console.print(table)
    if args.accuracy:
        console.print(_accuracy_cordic(rng, n))
        console.print(_accuracy_goldschmidt(rng, n))


def _accuracy_cordic(rng, n):
    width, abits = 16, 16
    rmin = 2 ** (width - 2)
    th = rng.uniform(-np.pi, np.pi, n)
    r = rng.uniform(rmin, 2 ** (width - 1) - 1, n)
    x = np.clip(np.rint(r * np.cos(th)), -(2**15), 2**15 - 1).astype(np.int64)
    y = np.clip(np.rint(r * np.sin(th)), -(2**15), 2**15 - 1).astype(np.int64)
    keep = np.hypot(x, y) >= rmin
    x, y = x[keep], y[keep]
    ref = np.arctan2(y, x)
    t = Table(title=f"CORDIC vectoring, width {width}, angle_bits {abits}, |v| >= 2^14 "
                    f"({x.size} vectors): max |angle error| vs bound")
    for col in ("iterations", "guard", "observed [rad]", "bound [rad]", "bound/observed"):
        t.add_column(col, justify="right")
    for g in (0, 2):
        for it in (4, 6, 8, 10, 12, 14, 16, 18):
            _, a = cordic_vectoring(x, y, width, it, abits, guard_bits=g)
            d = angle_to_radians(a, abits) - ref
            err = float(np.abs((d + np.pi) % (2 * np.pi) - np.pi).max())
            b = cordic_error_bound(width, it, abits, g, rmin)
            t.add_row(str(it), str(g), f"{err:.3e}", f"{b:.3e}", f"{b / err:.2f}")
    return t


def _accuracy_goldschmidt(rng, n):
    F = 20
    D = rng.integers(2 ** (F - 1), 2**F, n)
    num = rng.integers(2 ** (F - 1), 2**F + 1, n)
    exact = num / D
    t = Table(title=f"Goldschmidt core, F = {F} fraction bits ({n} operands): "
                    "max relative error vs bound")
    for col in ("seed", "iterations", "observed", "bound", "bound/observed"):
        t.add_column(col, justify="right")
    for sb, seed in ((0, "table"), (2, "table"), (4, "table"), (0, "linear")):
        for k in range(5):
            N = goldschmidt_normalised(num, D, F, k, sb, seed)
            err = float(np.abs(N / 2.0**F / exact - 1).max())
            b = goldschmidt_error_bound(k, sb, F, seed)
            label = f"{seed} {sb} bits" if seed == "table" else "linear"
            t.add_row(label, str(k), f"{err:.3e}", f"{b:.3e}", f"{b / err:.2f}")
    return t


if __name__ == "__main__":
    main()
