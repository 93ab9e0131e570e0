"""Seed 000's programmable logic: what runs in the Zynq-7020's fabric (docs/architecture.md).

The engines (mechanization, covariance propagation, Kalman update) as float32 op programs and
their scheduled datapath, the sensor subsystem (``sensors/``), the SystemRDL register bank, the
altitude profile manager with its DMA, the output formatter, the sequencer, clocking and
interrupts, and ``ins_trn_top`` with its Zybo Z7-20 board files. Nothing here imports the PS
side (:mod:`navgate.systems.ins_trn.ps`): the fabric does not know its driver.
"""
