"""Seed 000's processing system: what runs on the Zynq's ARM cores (docs/architecture.md).

The navigator (fix schedule, barometer, TRN requests, profile consumer) over the PL engine
interface and its backends (``reference`` float64, ``fp32`` bit-true, ``rtl`` and ``fpga-sim``
in Verilator), the sensor record stream and its log format, the ``navgate fly`` run with its
report, and Monte Carlo campaigns.
"""
