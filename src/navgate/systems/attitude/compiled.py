"""Seed 003's attitude solve, compiled: the program of :mod:`navgate.systems.attitude.program`
lowered to an op table and run sample after sample by a Numba kernel, bit-identical to
:class:`navgate.systems.attitude.mahony_fp32.MahonyCircuitFP32`.

The float32 ops (``mul add sub div sqrt neg``) are evaluated by :mod:`navgate.opflow.execute`'s
``apply_op`` (float64 on float32 values, rounded by its ``round_fp32``, the rule of
:mod:`navgate.numerics.fp32`); the circuit's own kinds are exact here: ``dbl`` (``x + x``,
rounded the same way), ``clampneg`` (a negative value -> +0), ``yawsel`` (``a < 0 ? b : a``)
and ``atan``, the fix16 arctangent of :mod:`navgate.systems.attitude.atan16` (Q2.13 inputs
rounded to nearest even and saturated, NaN -> 0 flagged; the same CORDIC on integers; the
Q2.13 result to float32, exact). The register file holds the program's values by name
(inputs, state, parameters, constants, every op result), the state is committed from its
``_n`` values after each solve. ``tests/systems/attitude/test_compiled.py`` checks the kernel
against ``MahonyCircuitFP32`` on random and bad inputs.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from navgate.numerics.fp32 import bits_to_f32, f32_to_bits, floats_to_bits, flush_subnormal
from navgate.opflow.execute import apply_op, round_fp32
from navgate.opflow.ir import KINDS
from navgate.systems.attitude import atan16
from navgate.systems.attitude.mahony import SEED003, MahonyParams
from navgate.systems.attitude.program import CONSTANTS, OUTPUTS, SENSORS, STATE, solve_program

__all__ = ["CompiledSolve"]

#: the float32 kinds evaluated by opflow's ``apply_op``, with opflow's opcodes
_SHARED = 6
_KINDS = KINDS[:_SHARED] + ("dbl", "clampneg", "yawsel", "atan")
_CODE = {k: i for i, k in enumerate(_KINDS)}
_ATAN_TABLE = atan16.ATAN_TABLE.astype(np.int64)


@njit(cache=True, inline="always")
def _to_fix(x):
    """float32 value -> Q2.13 (round half even, saturating); (value, flag)."""
    if x != x:
        return 0, True
    r = np.rint(x * 8192.0)
    if r > 32767.0:
        return 32767, True
    if r < -32768.0:
        return -32768, True
    return int(r), False


@njit(cache=True)
def _atan(c, s, table, half_pi):
    xc, fx = _to_fix(c)
    ys, fy = _to_fix(s)
    X = xc << 2
    Y = ys << 2
    z = 0
    if X < 0:
        if Y >= 0:
            z = half_pi
            X, Y = Y, -X
        else:
            z = -half_pi
            X, Y = -Y, X
    for i in range(table.shape[0]):
        dx = Y >> i
        dy = X >> i
        if Y >= 0:
            X, Y = X + dx, Y - dy
            z += table[i]
        else:
            X, Y = X - dx, Y + dy
            z -= table[i]
    ang = -((-z) >> 1) if z < 0 else z >> 1
    return ang / 8192.0, fx or fy


@njit(cache=True, error_model="numpy")
def _run(regs, ops, table, half_pi, in_idx, words, commit, out_idx, chk_idx, out, flags):
    """Solve every row of ``words`` (N, 9 float32 values in SENSORS order); ``out`` gets the
    values at ``out_idx`` after each solve, ``flags[k]`` = (invalid, saturated)."""
    for k in range(words.shape[0]):
        for i in range(in_idx.shape[0]):
            regs[in_idx[i]] = words[k, i]
        sat = False
        for n in range(ops.shape[0]):
            code = ops[n, 0]
            a = regs[ops[n, 2]]
            if code < _SHARED:
                r = apply_op(code, regs, ops[n, 2], ops[n, 3])
            elif code == 6:
                r = round_fp32(a + a)
            elif code == 7:
                r = 0.0 if a < 0.0 else a
            elif code == 8:
                r = regs[ops[n, 3]] if a < 0.0 else a
            else:
                r, s = _atan(a, regs[ops[n, 3]], table, half_pi)
                sat = sat or s
            regs[ops[n, 1]] = r
        bad = False
        for i in range(chk_idx.shape[0]):
            if regs[chk_idx[i]] != regs[chk_idx[i]]:
                bad = True
        for i in range(out_idx.shape[0]):
            out[k, i] = regs[out_idx[i]]
        flags[k, 0] = bad
        flags[k, 1] = sat
        for i in range(commit.shape[0]):
            regs[commit[i, 0]] = regs[commit[i, 1]]


class CompiledSolve:
    """The circuit from its reset state (q = 1, C = I, integral 0), as ``MahonyCircuitFP32``
    with ``batch=1``, solving a whole series in one call."""

    def __init__(self, params: MahonyParams = SEED003):
        self.p = params
        prog = solve_program()
        names = list(SENSORS) + list(STATE) + ["kp", "ki", "dt"] + list(CONSTANTS)
        names += [o.dst for o in prog.ops]
        self.index = {n: i for i, n in enumerate(names)}
        self.ops = np.array([[_CODE[o.kind], self.index[o.dst], self.index[o.srcs[0]],
                              self.index[o.srcs[1]] if len(o.srcs) > 1 else 0]
                             for o in prog.ops], dtype=np.int64)
        self.commit = np.array([[self.index[s], self.index[t]] for s, t in prog.commit.items()],
                               dtype=np.int64)
        self.regs = np.zeros(len(names))
        consts = dict(CONSTANTS)
        if params.gyro_scale != SEED003.gyro_scale:
            consts["D2R"] = int(f32_to_bits(params.gyro_scale))
        for k, v in consts.items():
            self.regs[self.index[k]] = _value(v)
        for k in ("kp", "ki", "dt"):
            self.regs[self.index[k]] = _value(f32_to_bits(getattr(params, k)))
        for s in STATE:
            self.regs[self.index[s]] = 1.0 if s in ("q0", "c11", "c22", "c33") else 0.0
        self.in_idx = np.array([self.index[s] for s in SENSORS], dtype=np.int64)
        self.out_names = tuple(f"q{i}_n" for i in range(4)) + OUTPUTS
        self.out_idx = np.array([self.index[n] for n in self.out_names], dtype=np.int64)
        chk = list(self.out_names) + [f"{c}_n" for c in STATE[4:13]]
        self.chk_idx = np.array([self.index[n] for n in chk], dtype=np.int64)

    def run(self, acc, mag, gyro):
        """Solve each row of the (N, 3) float32 bit-pattern arrays in turn. Returns (out, flags):
        ``out`` (N, 7) uint32 words q0..q3, pitch, roll, yaw (degrees); ``flags`` (N, 2) bool:
        any output NaN (as ``SolveBits.invalid``), a saturated arctangent input."""
        p = self.p
        acc = np.asarray(acc, np.uint32)
        mag = np.asarray(mag, np.uint32)
        if p.accel_sign < 0:
            acc = acc ^ np.uint32(0x80000000)
        mag = mag ^ np.array([0 if s > 0 else 0x80000000 for s in p.mag_sign], np.uint32)
        words = np.column_stack([acc, mag, np.asarray(gyro, np.uint32)])
        vals = _value(flush_subnormal(words))
        n = vals.shape[0]
        out = np.zeros((n, len(self.out_idx)))
        flags = np.zeros((n, 2), dtype=np.bool_)
        _run(self.regs, self.ops, _ATAN_TABLE, atan16.HALF_PI_Z, self.in_idx, vals,
             self.commit, self.out_idx, self.chk_idx, out, flags)
        return floats_to_bits(out).reshape(out.shape), flags


def _value(bits):
    return bits_to_f32(np.asarray(bits, np.uint32)).astype(np.float64)

