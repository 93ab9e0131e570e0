"""Straight-line op programs as one-iteration loop nests over named arrays, so that a whole
program of segments and nests runs on the sequence machine
(:mod:`navgate.opflow.sequence`).

Reference: the op-program IR (:mod:`navgate.opflow.ir`: SSA ops, named registers read at
program start, commits applied at its end, outputs) and the loop-nest IR
(:mod:`navgate.opflow.loops`: a nest with ``trips == ()`` is one iteration, list-scheduled
without wrap-around).

:func:`segment_nest` turns a :class:`~navgate.opflow.ir.Program` into a
:class:`~navgate.opflow.loops.LoopNest` with ``trips == ()``:

* every named value the program reads (a state register, an input, a value an earlier step
  passed on) lives in a word of an array: ``places`` maps its name to ``(array, word)``;
  the nest loads it once, at a constant address (``Addr(offset=word)``), in the order of its
  first use;
* every commit ``register <- temp`` is a store to the register's word, every kept output a
  store to its word in ``writes``; a commit or an output that is itself a named value is a
  load and a store (a copy). The nest's stores are issued after every load of their array
  (:func:`~navgate.opflow.loops.modulo_schedule`), which is the program's rule "every read
  sees the value at program start";
* float32 constants ``c:<hex>`` stay constants (the machine's constant sources);
* ops whose results reach no store are left out;
* ``cvt`` (an input number to float32) is done at the boundary, not on the datapath: the
  word of its source must already hold the float32 of the number, which the writer of that
  word (the host) converts. Every word of an array is a float32 pattern and every value in
  the executors is a float32 number with subnormals flushed, so ``cvt`` of such a word is the
  word itself: it becomes an alias of its source. A loop memory cannot hold the int16 or
  int32 pattern of an IMU word for a ``cvt`` unit to read, because a memory read flushes
  subnormal patterns (small positive integers read as float32 are subnormal).

:func:`program_arrays` lays out the words of a program's named values in arrays by a rule
(name -> array), in first-seen order.
"""

from __future__ import annotations

from collections.abc import Callable

from navgate.opflow.ir import Program
from navgate.opflow.loops import Addr, LoopError, LoopNest, LOp, Store, check_nest

__all__ = ["segment_nest", "program_arrays", "named_reads"]

#: op kinds that map one to one onto the loop IR
_KINDS = ("add", "sub", "mul", "div", "sqrt", "neg", "lt", "le")


def named_reads(prog: Program, outputs=None) -> list:
    """The named values (not temporaries, not constants) ``prog`` reads, in first-use order:
    operands of its ops, then commits and ``outputs`` (default: all) that are named values."""
    temps = {op.dst for op in prog.ops}
    outs = prog.outputs if outputs is None else {k: prog.outputs[k] for k in outputs}
    seen: dict = {}
    for op in prog.ops:
        for s in op.srcs:
            if s not in temps and not s.startswith("c:"):
                seen[s] = None
    for v in list(prog.commit.values()) + list(outs.values()):
        if v not in temps and not v.startswith("c:"):
            seen[v] = None
    return list(seen)


def program_arrays(names, array_of: Callable[[str], str], arrays: dict | None = None) -> dict:
    """Give each name a word: ``array_of(name)`` names its array, words in first-seen order
    after the words ``arrays`` (array -> {name: word}) already holds. Returns array -> {name:
    word} (a new dict; ``arrays`` untouched)."""
    out = {a: dict(w) for a, w in (arrays or {}).items()}
    for n in names:
        a = array_of(n)
        words = out.setdefault(a, {})
        if n not in words:
            words[n] = len(words)
    return out


def segment_nest(prog: Program, places: dict, arrays: dict, writes: dict | None = None,
                 name: str | None = None) -> LoopNest:
    """``prog`` as a one-iteration nest (module docstring). ``places``: named value -> (array,
    word) for every named value it reads or commits; ``writes``: output -> (array, word) for
    the outputs to keep (others are dropped); ``arrays``: array -> words (the nest keeps those
    it touches). Raises :class:`~navgate.opflow.loops.LoopError` for a name with no place, an
    op kind the loop IR lacks, or a store of a constant."""
    writes = dict(writes or {})
    name = name or prog.name
    by_dst = {op.dst: op for op in prog.ops}
    alias: dict = {}  # cvt results -> their sources

    def resolve(v):
        while v in alias:
            v = alias[v]
        return v

    for op in prog.ops:
        if op.kind == "cvt":
            alias[op.dst] = op.srcs[0]
        elif op.kind not in _KINDS:
            raise LoopError(f"{name}: op kind {op.kind!r} has no loop form")
    for k in writes:
        if k not in prog.outputs:
            raise LoopError(f"{name}: no output {k!r} to write")
    sinks = [(places.get(r), resolve(t), f"commit {r}") for r, t in prog.commit.items()]
    sinks += [(writes[k], resolve(prog.outputs[k]), f"output {k}") for k in writes]
    live: set = set()
    for where, v, what in sinks:
        if where is None:
            raise LoopError(f"{name}: {what} has no place")
        if v.startswith("c:"):
            raise LoopError(f"{name}: {what} stores the constant {v}; give it an op")
        live.add(v)
    kept = []
    for op in reversed(prog.ops):
        if op.dst in live and op.kind != "cvt":
            kept.append(op)
            live.update(resolve(s) for s in op.srcs)
    kept.reverse()
    temps = {op.dst for op in kept}
    loads: dict = {}  # named value -> load temp
    for op in kept:
        for s in op.srcs:
            s = resolve(s)
            if s not in temps and not s.startswith("c:"):
                loads.setdefault(s, f"ld:{s}")
    for _, v, _ in sinks:
        if v not in temps and v not in by_dst:
            loads.setdefault(v, f"ld:{v}")
    body = []
    for n, dst in loads.items():
        if n not in places:
            raise LoopError(f"{name}: named value {n!r} has no place")
        a, w = places[n]
        body.append(LOp(dst, "load", (a,), Addr(None, (), int(w))))

    def opnd(s):
        s = resolve(s)
        return loads.get(s, s)

    body += [LOp(op.dst, op.kind, tuple(opnd(s) for s in op.srcs)) for op in kept]
    stores = [Store(a, Addr(None, (), int(w)), opnd(v)) for (a, w), v, _ in sinks]
    used = {op.srcs[0] for op in body if op.kind == "load"} | {s.array for s in stores}
    for a in used:
        if a not in arrays:
            raise LoopError(f"{name}: array {a!r} not among the arrays")
    nest = LoopNest(name, (), {a: arrays[a] for a in arrays if a in used}, {}, body, [],
                    stores)
    check_nest(nest)
    return nest
