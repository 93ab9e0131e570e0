"""Seed 000's PL programs as one :class:`~navgate.opflow.sequence.SequenceProgram`: the
segments and loop nests of :mod:`navgate.systems.ins_trn.pl.loop_programs` (variant
``fused``) on opflow's sequence machine, entries ``propagate``, ``alt_gate``, ``alt_apply``,
``trn_gate``, ``trn_apply``, bit for bit the fp32 engine's programs
(:func:`navgate.systems.ins_trn.pl.fp32_program.programs`).

Reference: issue 29 (loop-controlled engines); :mod:`navgate.opflow.segments` (straight-line
programs as one-iteration nests); :mod:`navgate.opflow.sequence` (program, executor,
schedules, machine). docs/seed000-loop-engine.md has the layout, the cycles and the
resources.

Memory layout (every register of the fp32 engine is a word of an array):

* ``S``: the scalar state and configuration registers, :data:`S_REGS` (the fp32 engine's
  ``STATE_REGS`` without P and its compensation words), in that order;
* ``P``, ``cP``: the 120 stored elements of P and their Kahan compensation words in
  ``P_REGS`` / ``CP_REGS`` order (loop_programs' arrays, 128 words, word 127 of ``P`` a ROM
  1.0);
* ``IN``: the per-call inputs, :data:`IN_REGS` (IMU words, altitude measurement, TRN
  measurement, R, lag, gate). ``cvt`` is done at the boundary: the host writes the float32
  of each IMU word (exact for int16), which is what ``cvt`` of the word gives;
* ``X``: values one segment passes to a later one of the same entry (loop_programs'
  registers passed on) and the outputs the host reads (``nis``, ``accept``, ``positive``);
  one word per name over every entry (an entry writes a word before it reads it);
* loop_programs' own arrays (``F``, ``M``, ``E``; ``C``, ``K``, ``W``, ``DX``, ``C0`` ..
  ``W1``; one-word ``s_*``) with its ROM words (1.0, -0.0) as the arrays' initial values.

The ``dx`` outputs of the apply entries are the words of ``DX``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from navgate.opflow.execute import to_f32
from navgate.opflow.loops import LoopError, LoopNest
from navgate.opflow.segments import named_reads, segment_nest
from navgate.opflow.sequence import (
    SequenceProgram,
    SequenceSchedule,
    run_sequence,
    schedule_sequence,
)
from navgate.systems.ins_trn.pl import fp32_program as fp
from navgate.systems.ins_trn.pl import loop_programs as L

__all__ = ["ENTRIES", "S_REGS", "IN_REGS", "LoopEngine", "loop_engine", "engine_schedule",
           "DEFAULT_LANES"]

ENTRIES = ("propagate", "alt_gate", "alt_apply", "trn_gate", "trn_apply")
S_REGS = tuple(n for n in fp.STATE_REGS if n not in L.STATE_WORDS)
IN_REGS = tuple(dict.fromkeys(n for k in ENTRIES for n in fp.programs()[k].inputs))
#: the default lane count (float32 multiplier + adder pairs): chosen against issue 29's cycle
#: targets and its 6 DSP48E1 (docs/seed000-loop-engine.md)
DEFAULT_LANES = 3
#: the compensation words of P are dealt over this many arrays (word k in array k mod
#: CP_BANKS): only segments touch them, and the 120 stores of a segment's Kahan step or
#: reset would otherwise queue on one write port
CP_BANKS = 4


@dataclass
class LoopEngine:
    """The sequence program and where every register, input and output lives."""

    program: SequenceProgram
    places: dict  #: register / input / passed value -> (array, word)
    outputs: dict  #: entry -> {output: (array, word)}
    init: dict  #: array -> float64 words (the ROM words; zeros elsewhere)
    exchange: dict  #: passed value or output -> its word of ``X``

    def memories(self, state: dict, inputs: dict | None = None) -> dict:
        """Arrays holding ``state`` (every register of ``fp32_program.STATE_REGS``) and
        ``inputs`` (IMU words as numbers: written as their float32, the boundary's cvt)."""
        missing = [n for n in fp.STATE_REGS if n not in state]
        if missing:
            raise LoopError(f"state lacks {len(missing)} register(s), first {missing[0]!r}")
        mem = {a: v.copy() for a, v in self.init.items()}
        for n in fp.STATE_REGS:
            a, w = self.places[n]
            mem[a][w] = to_f32(state[n])
        for n, v in (inputs or {}).items():
            if n not in self.places or self.places[n][0] != "IN":
                raise LoopError(f"unknown input {n!r}; known: {', '.join(IN_REGS)}")
            a, w = self.places[n]
            mem[a][w] = to_f32(v)
        return mem

    def state(self, mem: dict) -> dict:
        """The registers of ``fp32_program.STATE_REGS`` held by the arrays ``mem``."""
        return {n: _word(mem, *self.places[n]) for n in fp.STATE_REGS}

    def read_outputs(self, entry: str, mem: dict) -> dict:
        return {k: _word(mem, a, w) for k, (a, w) in self.outputs[entry].items()}

    def restricted(self, entries) -> SequenceProgram:
        """The sequence program with only ``entries`` (their segments, the arrays those
        touch, sizes unchanged): a smaller machine for one entry."""
        segs = {s: self.program.segments[s] for e in entries for s in self.program.entries[e]}
        used = {a for n in segs.values() for a in n.arrays}
        return SequenceProgram(f"{self.program.name}_{'_'.join(entries)}",
                               {a: w for a, w in self.program.arrays.items() if a in used},
                               segs, {e: self.program.entries[e] for e in entries})

    def run(self, entry: str, state: dict, inputs: dict | None = None,
            compiled: dict | None = None) -> tuple[dict, dict]:
        """Run ``entry`` with :func:`~navgate.opflow.sequence.run_sequence`: (new state,
        outputs), as the fp32 engine's program of that name."""
        mem = run_sequence(self.program, self.memories(state, inputs), entry, compiled)
        return self.state(mem), self.read_outputs(entry, mem)


def _word(mem, a, w):
    v = np.asarray(mem[a])
    if v.dtype == np.uint32:
        return float(v.view(np.float32)[w])
    return float(v[w])


@lru_cache(maxsize=8)
def loop_engine(lanes: int = DEFAULT_LANES, cp_banks: int = CP_BANKS) -> LoopEngine:
    """The seed-000 sequence program whose chained sums carry ``lanes`` terms per iteration
    (loop_programs' ``fused`` variant), the compensation words in ``cp_banks`` arrays."""
    lps = L.loop_programs(lanes, "fused")
    fps = fp.programs()
    arrays: dict = {}
    for lp in lps.values():
        for a, w in lp.arrays.items():
            if arrays.setdefault(a, w) != w:
                raise LoopError(f"array {a} has {w} and {arrays[a]} words")
    if any("cP" in s.arrays for lp in lps.values() for s in lp.steps
           if isinstance(s, LoopNest)):
        raise LoopError("a nest reads cP: it cannot be banked")
    places = {n: ("S", k) for k, n in enumerate(S_REGS)}
    places |= {n: ("P", k) for k, n in enumerate(fp.P_REGS)}
    if type(cp_banks) is not int or cp_banks < 1:
        raise LoopError(f"cp_banks must be a positive integer, got {cp_banks!r}")
    del arrays["cP"]
    for b in range(cp_banks):
        arrays[f"cP{b}"] = -(-len(fp.CP_REGS) // cp_banks)
    places |= {n: (f"cP{k % cp_banks}", k // cp_banks) for k, n in enumerate(fp.CP_REGS)}
    places |= {n: ("IN", k) for k, n in enumerate(IN_REGS)}
    xw: dict = {}  # X words by name

    def xword(n):
        return ("X", xw.setdefault(n, len(xw)))

    segments: dict = {}
    entries: dict = {}
    outputs: dict = {}
    pending = []
    for key in ENTRIES:
        lp = lps[key]
        steps = []
        want = set(fps[key].outputs) - set(lp.outputs)
        later = [set(s.prog.inputs) if not isinstance(s, LoopNest) else set()
                 for s in lp.steps]
        passed: set = set()
        for k, step in enumerate(lp.steps):
            if isinstance(step, LoopNest):
                nest = step
            else:
                p = step.prog
                pl = {}
                for n in named_reads(p):
                    if n in step.reads:
                        pl[n] = step.reads[n]
                    elif n in places:
                        pl[n] = places[n]
                    elif n in passed:
                        pl[n] = xword(n)
                    else:
                        raise LoopError(f"{key}/{p.name}: {n!r} has no place")
                for r in p.commit:
                    pl.setdefault(r, places[r])
                readers = set().union(*later[k + 1:]) if k + 1 < len(later) else set()
                writes = dict(step.writes)
                for o in p.outputs:
                    if o not in writes and (o in readers or o in want):
                        writes[o] = xword(o)
                        passed.add(o)
                pending.append((p, pl, writes))
                nest = None
            steps.append(step.name)
            if nest is not None:
                if segments.get(nest.name, nest) is not nest:
                    raise LoopError(f"two segments named {nest.name}")
                segments[nest.name] = nest
        entries[key] = tuple(steps)
        outputs[key] = {o: lp.outputs[o] if o in lp.outputs else xword(o)
                        for o in fps[key].outputs}
    arrays |= {"S": len(S_REGS), "IN": len(IN_REGS), "X": len(xw)}
    for p, pl, writes in pending:
        if p.name in segments:
            raise LoopError(f"two segments named {p.name}")
        segments[p.name] = segment_nest(p, pl, arrays, writes)
    init = {a: np.zeros(w) for a, w in arrays.items()}
    for lp in lps.values():
        for a, words in lp.rom.items():
            for i, v in words.items():
                init[a][i] = v
    prog = SequenceProgram("seed000", arrays, segments, entries)
    return LoopEngine(prog, places, outputs, init, xw)


@lru_cache(maxsize=8)
def engine_schedule(lanes: int = DEFAULT_LANES, cp_banks: int = CP_BANKS,
                    registered: bool = True, read_ports: int | None = None) -> SequenceSchedule:
    """The sequence machine's schedule of :func:`loop_engine` on ``lanes`` lanes
    (``read_ports`` per array, default max(2, lanes): a chained sum loads ``lanes`` words of
    each of its arrays per iteration; ``registered``: operands and memory words
    registered)."""
    return schedule_sequence(loop_engine(lanes, cp_banks).program, lanes,
                             read_ports=read_ports or max(2, lanes), registered=registered)
