"""opflow: navgate's op-program toolchain for scheduled float32 datapaths, shared by every
machine that runs a straight-line op program or a loop nest on a few shared arithmetic
units.

- :mod:`navgate.opflow.ir`: ops, programs (with their own named registers) and a builder;
- :mod:`navgate.opflow.execute`: the bit-true interpreter (:mod:`navgate.numerics.fp32` on bit
  patterns, a client's own kinds through the functions it passes) and the compiled Numba
  executor over a register file built from the programs;
- :mod:`navgate.opflow.schedule`: the op form (SSA ops, commit map, outputs), unit kinds and
  latencies, and the banked list scheduler with its port and bank rules;
- :mod:`navgate.opflow.machine`: the banked datapath and its microcode control, emitted from a
  schedule, and the command-stream wrapper;
- :mod:`navgate.opflow.phased`: the phased list scheduler (one unit per kind, a client's own
  unit kinds included, flip-flop sources and sinks, result bypass, a control FSM's phases,
  small register banks); :mod:`navgate.opflow.phased_machine`: the datapath and control ROM
  emitted from its schedules;
- :mod:`navgate.opflow.loops`: loop nests (ROM address generators, accumulators), their
  bit-true executor (Numba) and the modulo scheduler of their bodies;
- :mod:`navgate.opflow.loopmachine`: the sequencer and delay-line datapath that runs a
  modulo-scheduled nest; :mod:`navgate.opflow.loop_kernels`: generic kernels built on it.

The package knows no client system: programs, unit choices and tops stay with their clients in
``navgate.systems``.
"""
