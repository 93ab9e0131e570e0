"""Seed 001 blocks in the registry: they build, document LATENCY/THROUGHPUT, and the top has
the TinyTapeout ports."""

from fractions import Fraction

import pytest
from amaranth.hdl import Fragment

from navgate.hw.blocks import get_block
from navgate.hw.verilog import emit_verilog, verilog_ports

NAMES = ["tinykalman_top", "mpu6500_spi", "tinykalman_cordic", "kalman_steady",
         "tinykalman_datapath", "uart_tx"]


@pytest.mark.parametrize("name", NAMES)
def test_blocks_build_and_document_timing(name):
    c = get_block(name).factory()
    Fragment.get(c, None)
    assert int(c.LATENCY) >= 1
    assert 0 < Fraction(c.THROUGHPUT) <= 1


def test_top_has_the_tinytapeout_ports():
    ports = verilog_ports(emit_verilog(get_block("tinykalman_top").factory(), "tt_um_x"),
                          "tt_um_x")
    assert sorted(ports) == sorted([
        ("ui_in", "input", 8), ("uo_out", "output", 8), ("uio_in", "input", 8),
        ("uio_out", "output", 8), ("uio_oe", "output", 8), ("ena", "input", 1),
        ("clk", "input", 1), ("rst_n", "input", 1)])
