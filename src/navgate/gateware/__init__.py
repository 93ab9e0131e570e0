"""Amaranth 0.5 arithmetic cores shared by the seed systems, and the verification harness.

* :mod:`navgate.gateware.fp32` - float32 cores (add/sub, mul, div, sqrt,
  compare, int/fixed conversions), bit-true to :mod:`navgate.numerics.fp32`;
* :mod:`navgate.gateware.verify` - the verification harness (Amaranth
  simulator and Verilator/cocotb back ends, lint) every block is checked with;
  :mod:`navgate.gateware.verify_fp32` holds the float32 test vectors.

Submodules are imported on demand; importing this package pulls in nothing.
"""
