"""Word-length sweep of seed 004's 2x2 Kalman filter: accuracy, resources, proxy Fmax.

For each N (FRAC chosen per N, see ``frac_for``) it runs the series-RLC demo (4000 frames,
noise step at frame 2000, adaptive R) on the bit-true model and the float64 reference and
synthesises the gateware (yosys synth_xilinx for the xc7z020: LUT, FF, DSP48E1, CARRY4);
``--timing`` adds the ECP5 nextpnr proxy Fmax (about 7 minutes per word length).
Prints a markdown table (docs/seed004-kf2x2.md carries its output).

    python benchmarks/bench_kf2x2.py [--n 16 20 24 28 32] [--timing] [--frames 4000]
                                     [--no-synth]

N runs up to 32: the Goldschmidt model switches to Python integers where its products
exceed int64 (``navgate.numerics.goldschmidt.goldschmidt_normalised``). ``--no-synth`` prints
the accuracy columns only (the synthesis of one word length takes minutes).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from navgate.hw.synth import synthesize, timing_ecp5
from navgate.hw.verilog import emit_verilog
from navgate.systems.kf2x2.model import (
    KfParams,
    init_state,
    quantize_frames,
    rlc_scenario,
    run_frames,
    run_frames_float,
)
from navgate.systems.kf2x2.top import Kf2x2

SIG_P, SIG_M = 0.1, 1.0


def frac_for(n: int) -> int:
    """Keep 9 integer bits + sign (values up to 512, as the default Q(20, 10)); every other
    bit goes to the fraction."""
    return n - 10


def accuracy(p: KfParams, frames: int, seed: int = 0) -> dict:
    sc = rlc_scenario(frames, seed=seed, sigma_process=SIG_P, sigma_meas=(SIG_M, SIG_M),
                      step_frame=frames // 2, step_factor=2.0)
    st = init_state(p, Q=(SIG_P**2, 0, SIG_P**2), R=(SIG_M**2, 0, SIG_M**2))
    bt = run_frames(p, st, quantize_frames(p, sc), adapt_q=False)
    init = {"x": [0, 0], "P": np.eye(2), "Q": np.eye(2) * SIG_P**2,
            "R": np.eye(2) * SIG_M**2, "dq": [0, 0]}
    fl = run_frames_float(p, init, sc, adapt_q=False)
    x = np.stack([bt["x0"], bt["x1"]], axis=1) / p.scale

    def rms(a):
        return float(np.sqrt(np.mean(np.asarray(a) ** 2)))

    return {"rms_fixed": rms(x - sc.x), "rms_float": rms(fl["x"] - sc.x),
            "rms_diff": rms(x - fl["x"]), "overflow": int(bt["overflow"].sum())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+",
                    default=[16, 18, 20, 22, 24, 26, 28, 30, 32])
    ap.add_argument("--no-synth", action="store_true", help="accuracy only, no synthesis")
    ap.add_argument("--frames", type=int, default=4000)
    ap.add_argument("--timing", action="store_true")
    args = ap.parse_args()
    rows = []
    for n in args.n:
        p = KfParams(n=n, frac=frac_for(n))
        t0 = time.perf_counter()
        acc = accuracy(p, args.frames)
        use, fmax = {k: None for k in ("lut", "ff", "dsp", "carry4")}, None
        if not args.no_synth:
            text = emit_verilog(Kf2x2(n=n, frac=p.frac), "kf2x2")
            with tempfile.TemporaryDirectory() as tmp:
                use = synthesize(text, "kf2x2", "xc7z020", Path(tmp) / "xc7")
                fmax = timing_ecp5(text, "kf2x2", Path(tmp) / "ecp5")["fmax_mhz"] \
                    if args.timing else None
        rows.append((n, p.frac, acc, use, fmax, time.perf_counter() - t0))
        print(f"# N={n} done in {rows[-1][-1]:.0f} s", flush=True)
    print("| N | FRAC | RMS err fixed | RMS err float64 | RMS fixed-float64 | overflow frames "
          "| LUT | FF | DSP48E1 | CARRY4 | Fmax ECP5 proxy (MHz) |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for n, frac, acc, use, fmax, _ in rows:
        print(f"| {n} | {frac} | {acc['rms_fixed']:.4f} | {acc['rms_float']:.4f} | "
              f"{acc['rms_diff']:.2e} | {acc['overflow']} | {_cell(use['lut'])} | "
              f"{_cell(use['ff'])} | {_cell(use['dsp'])} | {_cell(use['carry4'])} | "
              f"{'-' if fmax is None else f'{fmax:.1f}'} |")


def _cell(value) -> str:
    return "-" if value is None else str(value)


if __name__ == "__main__":
    main()
