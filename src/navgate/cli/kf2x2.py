"""``navgate kf2x2``: seed 004's 2x2 adaptive fixed-point Kalman filter on the series-RLC demo.

Runs the discretised RLC circuit (capacitor voltage, inductor current; both measured with
noise whose standard deviation doubles half way through) through the bit-true model
(:mod:`navgate.systems.kf2x2.model`) and the float64 reference, and, with ``--engine amaranth``
or ``--engine verilator``, through the gateware (Amaranth simulator, or the emitted Verilog
in Verilator via cocotb), counting mismatches against the bit-true model word by word.
Writes ``summary.json``, ``frames.csv`` (truth, measurement, estimates, R estimate) and
``rlc.png`` (truth, measurement and estimate) into ``--out``.
"""

from __future__ import annotations

import csv
import time
from pathlib import Path

import click
import numpy as np

from navgate.cli.console import consoles
from navgate.cli.errors import CliError
from navgate.cli.outputs import atomic_output_dir, check_out_dir, default_out_dir, out_option
from navgate.cli.summary import write_summary

#: the word lengths the filter runs at: 9 (the 8-bit divider seed table needs N >= 9) to 32
#: (the model's reciprocal runs in Python integers beyond int64; tested at N = 30 and 32)
N_MIN, N_MAX = 9, 32
SIGMA_PROCESS = 0.1
SIGMA_MEAS = 1.0


def _plot(path: Path, sc, x_fix, x_flt, r_fix, step_frame) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.arange(sc.frames) * sc.dt * 1e3
    fig, axes = plt.subplots(3, 1, figsize=(10, 9), sharex=True)
    for i, (ax, label) in enumerate(zip(axes[:2], ("capacitor voltage [V]",
                                                   "inductor current [A]"), strict=True)):
        ax.plot(t, sc.z[:, i], ".", ms=1.5, color="0.7", label="measurement")
        ax.plot(t, sc.x[:, i], "k-", lw=1.0, label="truth")
        ax.plot(t, x_fix[:, i], "C0-", lw=0.8, label="fixed-point estimate")
        ax.plot(t, x_flt[:, i], "C1--", lw=0.6, label="float64 estimate")
        ax.set_ylabel(label)
        ax.legend(loc="upper right", fontsize=7)
    axes[2].plot(t, r_fix[:, 0], "C0-", lw=0.8, label="R00 estimate (fixed)")
    axes[2].plot(t, r_fix[:, 1], "C2-", lw=0.8, label="R11 estimate (fixed)")
    axes[2].plot(t, sc.sigma_v[:, 0] ** 2, "k--", lw=0.8, label="true variance")
    axes[2].set_ylabel("R [V^2, A^2]")
    axes[2].set_xlabel("time [ms]")
    axes[2].legend(loc="upper left", fontsize=7)
    if step_frame is not None:
        for ax in axes:
            ax.axvline(step_frame * sc.dt * 1e3, color="r", lw=0.5)
    fig.suptitle("seed 004 2x2 adaptive fixed-point Kalman filter, series RLC")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


@click.command()
@click.option("--frames", type=int, default=4000, show_default=True, help="Frames to run.")
@click.option("--n", "n", type=int, default=20, show_default=True,
              help=f"Word length N ({N_MIN}..{N_MAX}).")
@click.option("--frac", type=int, default=10, show_default=True,
              help="Fraction bits FRAC (1..N-2; the demo needs N-1-FRAC >= 5 integer bits).")
@click.option("--engine", type=click.Choice(["model", "amaranth", "verilator"]),
              default="model", show_default=True,
              help="model: bit-true model only; amaranth / verilator: also run the gateware "
                   "and compare it with the bit-true model on every frame.")
@click.option("--adapt-q/--no-adapt-q", default=False, show_default=True,
              help="Adapt Q from the corrections (R is always adapted).")
@click.option("--seed", type=int, default=0, show_default=True, help="Random seed.")
@out_option(default_out_dir("kf2x2"), "Output directory (written atomically).")
@click.option("--accept-overflow", is_flag=True,
              help="Exit 0 even when the word length overflows (results flagged).")
@click.option("--quiet", is_flag=True, help="No table.")
def kf2x2(frames, n, frac, engine, adapt_q, seed, out, accept_overflow, quiet):
    """Seed 004: 2x2 adaptive fixed-point Kalman filter (34 cycles a frame) on an RLC circuit."""
    from rich.table import Table

    from navgate.systems.kf2x2.model import (
        KfParams,
        init_state,
        quantize_frames,
        rlc_scenario,
        run_frames,
        run_frames_float,
    )

    table_console, console = consoles(quiet)
    if engine != "model":
        from navgate.cli.extras import SIMULATION, require_gateware

        require_gateware(f"navgate kf2x2 --engine {engine}",
                         SIMULATION if engine == "verilator" else ("amaranth",))
    if not 10 <= frames <= 100_000:
        raise CliError(f"--frames must be between 10 and 100000, got {frames}")
    if seed < 0:
        raise CliError(f"--seed must be non-negative, got {seed}")
    check_out_dir(out)  # before the run: the outputs are written only after it
    if not N_MIN <= n <= N_MAX:
        raise CliError(f"--n: the word length must be in [{N_MIN}, {N_MAX}], got {n}")
    try:
        params = KfParams(n=n, frac=frac)
    except ValueError as error:
        raise CliError(f"bad word length Q({n}, {frac}): {error}") from None
    if params.max_int / params.scale < 16:
        raise CliError(f"Q({n}, {frac}) holds values only up to "
                       f"{params.max_int / params.scale:g}; the RLC demo needs at least 16 "
                       "(use fewer fraction bits)")
    step = frames // 2
    sc = rlc_scenario(frames, seed=seed, sigma_process=SIGMA_PROCESS,
                      sigma_meas=(SIGMA_MEAS, SIGMA_MEAS), step_frame=step, step_factor=2.0)
    st = init_state(params, Q=(SIGMA_PROCESS**2, 0, SIGMA_PROCESS**2),
                    R=(SIGMA_MEAS**2, 0, SIGMA_MEAS**2))
    qframes = quantize_frames(params, sc)
    t0 = time.perf_counter()
    bt = run_frames(params, st, qframes, adapt_q=adapt_q)
    t_model = time.perf_counter() - t0
    init = {"x": [0.0, 0.0], "P": np.eye(2), "Q": np.eye(2) * SIGMA_PROCESS**2,
            "R": np.eye(2) * SIGMA_MEAS**2, "dq": [0.0, 0.0]}
    fl = run_frames_float(params, init, sc, adapt_q=adapt_q)
    x_fix = np.stack([bt["x0"], bt["x1"]], axis=1) / params.scale
    r_fix = np.stack([bt["R00"], bt["R11"]], axis=1) / params.scale

    def rms(a):
        return np.sqrt(np.mean(np.asarray(a) ** 2, axis=0))

    mismatches = None
    gate_seconds = None
    if engine != "model":
        from navgate.systems.kf2x2.rtl_sim import verify_frames

        console.print(f"running {frames} frames on the gateware ({engine}) ...")
        res = verify_frames(params, st, qframes, adapt_q=adapt_q, backend=engine,
                            keep_outputs=True)
        mismatches = res.n_mismatches
        gate_seconds = res.seconds
        cycles = sorted(set(int(c) for c in res.outputs["cycles"]))
        if cycles != [34]:
            raise CliError(f"gateware frames took {cycles} cycles, expected 34")
        if mismatches:
            console.print(res.report())
    summary = {
        "frames": frames,
        "cycles_per_frame": 34,
        "n": n,
        "frac": frac,
        "engine": engine,
        "seed": seed,
        "adapt_q": adapt_q,
        "adapt_r": True,
        "measurement_noise_std": [SIGMA_MEAS, 2 * SIGMA_MEAS],
        "noise_step_frame": step,
        "rms_error_measurement": rms(sc.z - sc.x).tolist(),
        "rms_error_fixed": rms(x_fix - sc.x).tolist(),
        "rms_error_float64": rms(fl["x"] - sc.x).tolist(),
        "rms_fixed_minus_float64": rms(x_fix - fl["x"]).tolist(),
        "r_estimate_before_step": r_fix[step // 2: step].mean(axis=0).tolist(),
        "r_estimate_after_step": r_fix[step + step // 2:].mean(axis=0).tolist(),
        "overflow_frames": int(bt["overflow"].sum()),
        # measurements/source beyond Q(n, frac), saturated on conversion (as an ADC clips)
        "input_saturated_words": qframes.saturated,
        "input_saturated_frames": len(qframes.saturated_frames),
        "div_zero_frames": int(bt["div_zero"].sum()),
        "mismatches_vs_bit_true": mismatches,
        "model_seconds": round(t_model, 3),
        "gateware_seconds": None if gate_seconds is None else round(gate_seconds, 3),
    }
    overflow = summary["overflow_frames"]
    summary["overflow_accepted"] = bool(overflow and accept_overflow)
    table = Table(title=f"kf2x2 Q({n}, {frac}), {frames} frames, engine {engine}")
    table.add_column("quantity")
    table.add_column("v_C")
    table.add_column("i_L")
    for label, key in (("RMS error, measurement", "rms_error_measurement"),
                       ("RMS error, fixed point", "rms_error_fixed"),
                       ("RMS error, float64", "rms_error_float64"),
                       ("RMS fixed - float64", "rms_fixed_minus_float64"),
                       ("R estimate before step", "r_estimate_before_step"),
                       ("R estimate after step", "r_estimate_after_step")):
        table.add_row(label, *(f"{v:.4f}" for v in summary[key]))
    table.add_row("overflow frames", f"{overflow} of {frames}"
                  + (" (OVERFLOW: results invalid)" if overflow else ""), "")
    if qframes.saturated:
        table.add_row("saturated input frames", f"{len(qframes.saturated_frames)} of {frames}", "")
    table_console.print(table)
    if mismatches is not None:
        table_console.print(f"gateware ({engine}): {mismatches} mismatching frames of {frames}, "
                      "34 cycles each")
    # a failed run commits nothing (earlier results in --out stay as they were)
    if overflow and not accept_overflow:
        raise CliError(f"Q({n}, {frac}) overflows in {overflow} of {frames} frames (RMS error "
                       f"{max(summary['rms_error_fixed']):.3g}); use a longer word or fewer "
                       "fraction bits, or --accept-overflow; nothing written")
    if mismatches:
        raise CliError(f"{mismatches} frames differ from the bit-true model; nothing written")
    with atomic_output_dir(out) as stage:
        write_summary(stage, summary)
        with open(stage / "frames.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["frame", "v_true", "i_true", "v_meas", "i_meas", "v_fixed", "i_fixed",
                        "v_float", "i_float", "R00_fixed", "R11_fixed"])
            for k in range(frames):
                w.writerow([k, *(f"{v:.6f}" for v in (*sc.x[k], *sc.z[k], *x_fix[k],
                                                       *fl["x"][k], *r_fix[k]))])
        _plot(stage / "rlc.png", sc, x_fix, fl["x"], r_fix, step)
    console.print(f"wrote summary.json, frames.csv, rlc.png in {out}", highlight=False)
