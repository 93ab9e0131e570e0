"""Seed 000: the INS + TRN system of the Zynq-7020 design (docs/architecture.md, docs/trn.md).

``navigation`` (the navigation loop: INS + 15-state ESKF, barometric altitude updates, the
altitude profile buffer, TERCOM fixes), ``flight`` (the ``navgate fly`` run: INS-only and
INS+TRN over the scenario of :mod:`navgate.sim.flight`, scored against the truth) and
``report`` (its CSV files and plots).
"""
