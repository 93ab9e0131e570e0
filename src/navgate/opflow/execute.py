"""The bit-true executors of opflow's float32 op programs: the interpreter and the compiled
machine.

Two executors of the same :class:`navgate.opflow.ir.Program`:

* :func:`run_bittrue`: every op through :mod:`navgate.numerics.fp32` on uint32 bit patterns
  (the specification; vectorised over independent lanes; slow);
* :class:`Machine`: programs lowered to integer op tables over one register file (the named
  registers of the programs, :attr:`Program.registers`, then inputs, constants and shared
  temporaries) and run by the Numba kernel :func:`execute`. Registers hold float64 values that
  are exactly float32 numbers; each op is evaluated in float64 on them and rounded with
  :func:`round_fp32`, the rule of :mod:`navgate.numerics.fp32` (round the float64 result to
  24 significant bits, ties to even, with unbounded exponent; below 2^-126 -> signed zero;
  overflow -> infinity; NaN canonical on export). The float64 step is exact for mul (48-bit
  products) and for add/sub of float32 operands whose result is tiny, and a double rounding
  that is innocuous for add, sub, div and sqrt (53 >= 2 * 24 + 2; see the numerics.fp32
  docstring): the two executors agree bit for bit, which tests/opflow/test_execute.py checks
  op by op on random programs, special values included.

Clients drive their own loops around :func:`execute` and :func:`commit` in their own Numba
kernels (a client's kernel may call these, they are compiled functions).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from navgate.numerics import fp32 as F
from navgate.opflow.ir import OPCODE, Program, const_value

__all__ = ["round_fp32", "apply_op", "execute", "commit", "Compiled", "Machine", "to_f32",
           "run_bittrue"]

_MIN_NORMAL = 2.0**-126
_ZERO_BELOW = 2.0**-126 - 2.0**-151  #: magnitudes that round (24 bits) to below 2^-126


@njit(cache=True, inline="always")
def round_fp32(r):
    if r != r:
        return r
    a = abs(r)
    if a < _MIN_NORMAL:
        if a < _ZERO_BELOW:
            return math.copysign(0.0, r)
        return math.copysign(_MIN_NORMAL, r)
    return np.float64(np.float32(r))


@njit(cache=True, inline="always", error_model="numpy")
def apply_op(k, regs, ia, ib):
    """One float32 op of opcode ``k`` (:data:`navgate.opflow.ir.OPCODE`) on the registers at
    ``ia`` and ``ib`` (``ib`` is not read by a one-operand kind), rounded by
    :func:`round_fp32`. A client's kernel with kinds of its own calls it for these kinds."""
    a = regs[ia]
    if k == 2:
        r = a * regs[ib]
    elif k == 0:
        r = a + regs[ib]
    elif k == 1:
        r = a - regs[ib]
    elif k == 3:
        r = a / regs[ib]
    elif k == 4:
        r = math.sqrt(a) if a >= 0.0 or a != a else (a if a == 0.0 else math.nan)
    elif k == 5:
        r = -a
    elif k == 6:
        r = a
    elif k == 7:
        r = 1.0 if a <= regs[ib] else 0.0
    else:
        r = 1.0 if a < regs[ib] else 0.0
    return round_fp32(r)


@njit(cache=True, error_model="numpy")
def execute(regs, ops):
    """Run an op table (rows: opcode, dst, src a, src b) on the register file."""
    for n in range(ops.shape[0]):
        regs[ops[n, 1]] = apply_op(ops[n, 0], regs, ops[n, 2], ops[n, 3])


@njit(cache=True)
def commit(regs, table):
    for n in range(table.shape[0]):
        regs[table[n, 0]] = regs[table[n, 1]]


class Compiled:
    """One program lowered onto a machine's register file."""

    def __init__(self, prog: Program, index: dict):
        self.prog = prog
        self.ops = np.array([[OPCODE[op.kind], index[op.dst], index[op.srcs[0]],
                              index[op.srcs[1]] if len(op.srcs) > 1 else 0]
                             for op in prog.ops], dtype=np.int64).reshape(-1, 4)
        self.table = np.array([[index[s], index[t]] for s, t in prog.commit.items()],
                              dtype=np.int64).reshape(-1, 2)
        self.inputs = np.array([index[n] for n in prog.inputs], dtype=np.int64)
        self.outputs = {k: index[v] for k, v in prog.outputs.items()}


class Machine:
    """A register file shared by several programs: their named registers (the union of every
    program's :attr:`Program.registers`, in order), their inputs, the float32 constants they
    read, and temporaries (t1..tN of every program share the slots above those)."""

    def __init__(self, programs: dict):
        names: list = []
        for p in programs.values():
            names += [n for n in p.registers if n not in names]
        self.registers = tuple(names)
        for p in programs.values():
            names += [n for n in p.inputs if n not in names]
        consts = sorted({s for p in programs.values() for op in p.ops for s in op.srcs
                         if s.startswith("c:")})
        names += consts
        self.index = {n: i for i, n in enumerate(names)}
        base = len(names)
        size = base + max((len(p.ops) for p in programs.values()), default=0)
        self.compiled = {}
        for key, p in programs.items():
            idx = {n: self.index[n] for n in names}
            for m, op in enumerate(p.ops):
                idx[op.dst] = base + m
            self.compiled[key] = Compiled(p, idx)
        self.regs = np.zeros(size)
        for c in consts:
            self.regs[self.index[c]] = const_value(c)

    def set(self, name, value):
        """Write a float32 register from a float64 value (rounded to nearest, flushed)."""
        self.regs[self.index[name]] = to_f32(value)

    def get(self, name) -> float:
        return float(self.regs[self.index[name]])

    def run(self, key, **inputs) -> dict:
        c = self.compiled[key]
        for name, v in inputs.items():
            self.regs[self.index[name]] = to_f32(v)
        execute(self.regs, c.ops)
        out = {k: float(self.regs[i]) for k, i in c.outputs.items()}
        commit(self.regs, c.table)
        return out

    def bits(self) -> dict:
        """Every named register as a uint32 bit pattern (NaN canonical)."""
        return {n: F.float_to_bits(self.regs[self.index[n]]) for n in self.registers}


def to_f32(value) -> float:
    """float64 -> the float32 value a PS register write stores (RNE, subnormals flushed)."""
    v = float(np.float32(value))
    if v != 0.0 and abs(v) < _MIN_NORMAL:
        return math.copysign(0.0, v)
    return v




# ------------------------------------------------------------------ bit-true interpreter


def _cvt_bits(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, np.float64)
    if np.all(np.isfinite(x)) and np.all(x == np.round(x)) and np.all(np.abs(x) < 2**31):
        return np.asarray(F.fp32_from_int(x.astype(np.int64), 32), np.uint32)
    return np.asarray(F._round_f64(x), np.uint32)


def run_bittrue(prog: Program, state: dict, inputs: dict, lanes: int = 1,
                kinds: dict | None = None):
    """Run ``prog`` with :mod:`navgate.numerics.fp32` on bit patterns.

    ``state``: register name -> uint32 bit patterns (scalar or (lanes,)); ``inputs``: name ->
    values: float64 numbers for registers read by ``cvt`` (IMU words), otherwise uint32 bit
    patterns; ``kinds``: a client's own op kinds -> their bit-true function (uint32 arrays
    in, uint32 array out). Returns (new state dict, outputs dict, every temporary dict)."""
    kinds = kinds or {}
    regs: dict = {}
    for k, v in state.items():
        regs[k] = np.broadcast_to(np.asarray(v, np.uint32), (lanes,)).copy()
    raw = {}
    for k, v in inputs.items():
        arr = np.asarray(v)
        if arr.dtype.kind == "f":
            raw[k] = np.broadcast_to(arr.astype(np.float64), (lanes,)).copy()
        else:
            regs[k] = np.broadcast_to(arr.astype(np.uint32), (lanes,)).copy()

    def get(name):
        if name.startswith("c:"):
            return np.full(lanes, int(name[2:], 16), np.uint32)
        return regs[name]

    for op in prog.ops:
        k = op.kind
        if k in kinds:
            r = kinds[k](*(get(s) for s in op.srcs))
        elif k == "cvt":
            src = op.srcs[0]
            r = _cvt_bits(raw[src]) if src in raw else F.flush_subnormal(get(src))
        elif k in ("add", "sub", "mul", "div"):
            fn = {"add": F.fp32_add, "sub": F.fp32_sub, "mul": F.fp32_mul, "div": F.fp32_div}[k]
            r = fn(get(op.srcs[0]), get(op.srcs[1]))
        elif k == "sqrt":
            r = F.fp32_sqrt(get(op.srcs[0]))
        elif k == "neg":
            r = F.fp32_neg(get(op.srcs[0]))
        elif k in ("le", "lt"):
            cmp = F.fp32_compare(get(op.srcs[0]), get(op.srcs[1]))
            flag = cmp["lt"] | cmp["eq"] if k == "le" else cmp["lt"]
            r = np.where(flag, np.uint32(0x3F800000), np.uint32(0)).astype(np.uint32)
        else:
            raise ValueError(f"{prog.name}: op {op.dst} has unknown kind {k!r}")
        regs[op.dst] = np.asarray(r, np.uint32).reshape(lanes)
    outputs = {k: regs[v] for k, v in prog.outputs.items()}
    new_state = {k: regs[k] for k in state}
    for s, t in prog.commit.items():
        new_state[s] = regs[t]
    return new_state, outputs, regs
