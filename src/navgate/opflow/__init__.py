"""opflow: navgate's op-program toolchain for scheduled float32 datapaths, shared by every
machine that runs a straight-line op program on a few shared arithmetic units.

- :mod:`navgate.opflow.ir`: ops, programs (with their own named registers) and a builder;
- :mod:`navgate.opflow.execute`: the bit-true interpreter (:mod:`navgate.numerics.fp32` on bit
  patterns) and the compiled Numba executor over a register file built from the programs;
- :mod:`navgate.opflow.schedule`: the op form (SSA ops, commit map, outputs), unit kinds and
  latencies, and the banked list scheduler with its port and bank rules (a schedule is a list
  of issue cycles; loop nests would enter as a schedule of bodies, which this scheduler does
  not yet produce);
- :mod:`navgate.opflow.machine`: the banked datapath and its microcode control, emitted from a
  schedule, and the command-stream wrapper.

The package knows no client system: programs, unit choices and tops stay with their clients in
``navgate.systems``.
"""
