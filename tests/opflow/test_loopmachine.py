"""The loop machine in Amaranth's simulator: bit-exact against the loop executor
(:func:`navgate.opflow.loops.run_nest`) on random and special-value memories, two runs in a
row (the sequencer restarts), exact cycle counts, and the host port."""

from __future__ import annotations

import numpy as np
import pytest

from navgate.gateware.fp32 import Fp32Add
from navgate.numerics.fp32 import floats_to_bits
from navgate.opflow import loop_kernels as K
from navgate.opflow.loopmachine import simulate
from navgate.opflow.loops import LoopUnits, modulo_schedule, run_nest


def cases(rows, cols):
    return {  # name: (nest, units, exact cycles of the schedule)
        "rank1_15": (K.sym_rank1_update(15), LoopUnits(), 119 + 16),
        "rank1_5_scaled": (K.sym_rank1_update(5, 0.5), LoopUnits(), 14 * 2 + 21),
        "rank1_5_one_port": (K.sym_rank1_update(5), LoopUnits(read_ports=1), 14 * 2 + 17),
        "spmv": (K.sparse_matvec(rows, cols, 6, 6), LoopUnits(), 7 * Fp32Add.LATENCY + 16),
        "matvec_3x4": (K.dense_matvec(3, 4), LoopUnits(), 11 * Fp32Add.LATENCY + 16),
        "matvec_bias_3x3": (K.dense_matvec(3, 3, bias=True), LoopUnits(),
                            8 * Fp32Add.LATENCY + 16),
        "matvec_il_3x4": (K.dense_matvec_interleaved(3, 4), LoopUnits(), 11 * 3 + 16),
        "matvec_il_9x3": (K.dense_matvec_interleaved(9, 3), LoopUnits(), 26 * 1 + 16),
    }


@pytest.mark.parametrize("case", ["rank1_15", "rank1_5_scaled", "rank1_5_one_port", "spmv",
                                  "matvec_3x4", "matvec_bias_3x3", "matvec_il_3x4",
                                  "matvec_il_9x3"])
def test_machine_bit_exact_and_exact_cycles(case, loop_data):
    nest, units, cycles = cases(loop_data.rows, loop_data.cols)[case]
    s = modulo_schedule(nest, units)
    assert s.cycles == cycles
    rng = np.random.default_rng(sum(map(ord, case)))
    special = case in ("rank1_5_scaled", "spmv")
    mems = loop_data.memories(nest, rng, special=special)
    want1 = run_nest(nest, mems)
    want2 = run_nest(nest, want1)
    runs = simulate(s, mems, runs=2)
    for (got, n), want in zip(runs, (want1, want2), strict=True):
        assert n == cycles + 1  # start cycle to done
        for name in nest.arrays:
            assert np.array_equal(got[name], floats_to_bits(want[name])), (case, name)


def test_machine_edge_cases_rank1():
    """Overflow to infinity, inf - inf = NaN, signed zeros, underflow to zero, NaN in k."""
    nest = K.sym_rank1_update(4)
    k = np.array([3e19, -3e19, 1e-20, np.nan])
    p = np.array([0.0, -0.0, np.inf, -np.inf, -np.inf, -1.0, 0.0, -0.0, 5.0, 7.0])
    mems = {"P": p, "k": k}
    want = run_nest(nest, mems)
    got, n = simulate(modulo_schedule(nest), mems)[0]
    assert n == 9 + 16 + 1
    assert np.array_equal(got["P"], floats_to_bits(want["P"]))
    w = want["P"]
    assert w[0] == np.inf and w[1] == -np.inf and w[2] == np.inf  # 9e38 overflows
    assert np.isnan(w[4])  # -inf + inf
    assert w[7] == 0.0 and not np.signbit(w[7])  # -0 + (1e-40 flushed to +0)
    assert np.isnan(w[9]) and np.isnan(w[3])  # NaN spreads
