"""Seed 000's engine loop on opflow's compiled executor: its register file and the
propagate program run over N IMU samples with the covariance check.

The executors themselves (the bit-true interpreter, the Numba op-table kernel, the register
file built from :attr:`Program.registers`) are :mod:`navgate.opflow.execute`; this module adds
what belongs to seed 000's engine: :class:`Machine` with the indices of the 120 stored elements
of P (and of its copy cP), and :func:`run_samples`, the sample loop that feeds IMU words, runs
propagate and counts the samples where P is not positive definite or not finite. The names of
:mod:`navgate.opflow.execute` are re-exported for the engine's modules.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from navgate.opflow import execute as _x
from navgate.opflow.execute import (
    Compiled,
    commit,
    execute,
    run_bittrue,
    to_f32,
)

__all__ = ["Machine", "run_samples", "Compiled", "commit", "execute", "run_bittrue", "to_f32"]

@njit(cache=True)
def _cholesky_ok(regs, p_idx, work):
    """P (from its 120 stored elements) positive definite: Cholesky in float64."""
    n = 15
    m = 0
    for i in range(n):
        for j in range(i, n):
            v = regs[p_idx[m]]
            work[i, j] = v
            work[j, i] = v
            m += 1
    for j in range(n):
        s = work[j, j]
        for k in range(j):
            s -= work[j, k] * work[j, k]
        if not s > 0.0:
            return False
        d = math.sqrt(s)
        work[j, j] = d
        for i in range(j + 1, n):
            t = work[i, j]
            for k in range(j):
                t -= work[i, k] * work[j, k]
            work[i, j] = t / d
    return True


# not cached: Numba's cache checks only this file, so a cached copy would keep an old
# opflow.execute kernel after that file changed (compiling takes about 0.4 s per process)
@njit(error_model="numpy")
def run_samples(regs, ops, table, in_idx, gyro_words, accel_words, check_pd, p_idx, stats):
    """The propagate program over N samples of IMU words. ``stats``: [samples with P not
    positive definite, samples with a non-finite state or P word] (counted when check_pd)."""
    work = np.empty((15, 15))
    for k in range(gyro_words.shape[0]):
        for i in range(3):
            regs[in_idx[i]] = gyro_words[k, i]
            regs[in_idx[3 + i]] = accel_words[k, i]
        execute(regs, ops)
        commit(regs, table)
        if check_pd:
            if not _cholesky_ok(regs, p_idx, work):
                stats[0] += 1
            for m in range(p_idx.shape[0]):
                if not math.isfinite(regs[p_idx[m]]):
                    stats[1] += 1
                    break


class Machine(_x.Machine):
    """The engine's register file (:class:`navgate.opflow.execute.Machine` over its programs,
    whose named registers are the state list) with the register indices of P and cP."""

    def __init__(self, programs: dict):
        super().__init__(programs)
        self.p_idx = np.array([self.index[f"P{i}_{j}"] for i in range(15) for j in range(i, 15)],
                              dtype=np.int64)
        self.cp_idx = np.array([self.index[f"cP{i}_{j}"] for i in range(15)
                                for j in range(i, 15)], dtype=np.int64)
