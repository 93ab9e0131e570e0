"""Seed 000: the INS + TRN system of the Zynq-7020 design (docs/architecture.md, docs/trn.md).

Arranged by the computer each part runs on, as seed 000's "System Overview" draws them:
``pl`` (the FPGA fabric: engines, sensor subsystem, register bank, profile DMA, top) and ``ps``
(the Zynq's ARM: navigator, engine backends, records, the ``navgate fly`` run, campaigns).
"""
