"""The op-program IR of opflow: float32 ops in SSA form, programs (ops, inputs, the commit map
register <- temporary read at program start, outputs, and the program's own named persistent
registers), and a builder that emits ops and names float32 constants ``c:<hex>`` (subnormals
flushed to signed zero, as the float32 cores do). Kinds: ``add sub mul div sqrt neg cvt le
lt``; ``neg`` is a sign flip on an operand path (unit ``wire``). A client may add kinds of
its own units (:meth:`Builder.op`; it evaluates them itself, e.g. through ``run_bittrue``'s
``kinds``, and maps them to units in its scheduler's unit table). Loop nests have their own
IR in :mod:`navgate.opflow.loops` (bodies of these float32 kinds over array memories).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from navgate.numerics.fp32 import bits_to_float

__all__ = ["KINDS", "OPCODE", "UNIT", "const_name", "const_value", "Op", "Program", "Builder"]

KINDS = ("add", "sub", "mul", "div", "sqrt", "neg", "cvt", "le", "lt")
OPCODE = {k: i for i, k in enumerate(KINDS)}
#: the arithmetic unit each kind runs on (neg is a sign flip on an operand path)
UNIT = {"add": "add", "sub": "add", "mul": "mul", "div": "div", "sqrt": "sqrt", "neg": "wire",
        "cvt": "cvt", "le": "cmp", "lt": "cmp"}


def const_name(value: float) -> str:
    bits = int(np.float32(value).view(np.uint32))  # NaN keeps its payload: no canonical NaN
    if (bits & 0x7F800000) == 0:
        bits &= 0x80000000
    return f"c:{bits:08x}"


def const_value(name: str) -> float:
    return bits_to_float(int(name[2:], 16))


@dataclass(frozen=True)
class Op:
    """``dst = kind(*srcs)`` in ``module`` (one operation of one float32 core)."""

    dst: str
    kind: str
    srcs: tuple
    module: str


@dataclass
class Program:
    name: str
    ops: list = field(default_factory=list)
    inputs: tuple = ()
    commit: dict = field(default_factory=dict)  #: state register -> temp
    outputs: dict = field(default_factory=dict)  #: output name -> temp
    #: the persistent named registers the program runs against (state, configuration)
    registers: tuple = ()

    def counts(self) -> dict:
        """Operations by kind (``neg`` is a sign flip and costs no unit; a client's own
        kinds follow the float32 ones)."""
        out = {k: 0 for k in KINDS}
        for op in self.ops:
            out[op.kind] = out.get(op.kind, 0) + 1
        return out

    def counts_by_module(self) -> dict:
        out: dict = {}
        for op in self.ops:
            m = out.setdefault(op.module, {k: 0 for k in KINDS})
            m[op.kind] = m.get(op.kind, 0) + 1
        return out

    def names(self) -> list:
        """Every register name the program reads or writes (named, input, const, temp)."""
        seen = dict.fromkeys(self.registers)
        for name in self.inputs:
            seen[name] = None
        for op in self.ops:
            for s in op.srcs:
                seen[s] = None
            seen[op.dst] = None
        return list(seen)


class Builder:
    """Emits SSA ops; each helper returns the name of its result (``t<n>``, or ``name``
    where given: a value the client reads by name, such as a new state or an output)."""

    def __init__(self, name: str, inputs=(), registers=()):
        self.prog = Program(name, inputs=tuple(inputs), registers=tuple(registers))
        self.module = name
        self._n = 0

    def _emit(self, kind, *srcs, name=None):
        srcs = tuple(self.c(s) if isinstance(s, (int, float)) else s for s in srcs)
        self._n += 1
        dst = f"t{self._n}" if name is None else name
        self.prog.ops.append(Op(dst, kind, srcs, self.module))
        return dst

    def op(self, kind: str, *srcs, name: str | None = None) -> str:
        """Any kind, a client's own included; ``name``: the result's name."""
        return self._emit(kind, *srcs, name=name)

    @staticmethod
    def c(value: float) -> str:
        return const_name(value)

    def add(self, a, b):
        return self._emit("add", a, b)

    def sub(self, a, b):
        return self._emit("sub", a, b)

    def mul(self, a, b):
        return self._emit("mul", a, b)

    def div(self, a, b):
        return self._emit("div", a, b)

    def sqrt(self, a):
        return self._emit("sqrt", a)

    def neg(self, a):
        return self._emit("neg", a)

    def cvt(self, a):
        return self._emit("cvt", a)

    def le(self, a, b):
        return self._emit("le", a, b)

    def lt(self, a, b):
        return self._emit("lt", a, b)

    def sum(self, terms):
        """Left-to-right sum of ``(sign, value)`` pairs (sign +1/-1; the first may be -1)."""
        acc = None
        for sgn, v in terms:
            if acc is None:
                acc = v if sgn > 0 else self.neg(v)
            else:
                acc = self.add(acc, v) if sgn > 0 else self.sub(acc, v)
        return acc
