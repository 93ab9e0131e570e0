"""Seed 000's PL programs on opflow's register machine: the smallest seed-000 engine
(issue 29's one-lane machine reported beside the lane machines).

Reference: issue 29; :mod:`navgate.opflow.regmachine` (compiler, instruction-level model,
machine); the ``plain`` variant of :mod:`navgate.systems.ins_trn.pl.loop_programs` (each part
of the fp32 engine's programs in a step of its own: straight-line segments and loop nests),
as one sequence program (:func:`~navgate.systems.ins_trn.pl.loop_programs.to_sequence`),
bit for bit the fp32 engine's programs. docs/seed000-register-machine.md has the figures.

The register array ``R`` of the sequence form (state, configuration, inputs, passed values)
is the machine's register file; ``P``, ``cP``, ``F``, ``M``, ``E`` and the update vectors are
its data memory. :func:`register_engine` compiles once per process.
"""

from __future__ import annotations

from functools import lru_cache

from navgate.opflow.regmachine import RegisterProgram, compile_program
from navgate.systems.ins_trn.pl import loop_programs as L

__all__ = ["register_engine", "VARIANT"]

#: loop_programs' variant the machine runs: every nest in a step of its own (the fused
#: variant's long straight-line segments exist to fill a lane machine's idle slots)
VARIANT = "plain"


@lru_cache(maxsize=2)
def register_engine(variant: str = VARIANT) -> tuple[RegisterProgram, dict, dict]:
    """(compiled program, register index of array ``R``, loop programs) of seed 000."""
    lps = L.loop_programs(1, variant)
    prog, reg_index = L.to_sequence(lps)
    return compile_program(prog), reg_index, lps
