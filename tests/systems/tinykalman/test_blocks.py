"""Seed 001 blocks in the registry: they build, document LATENCY/THROUGHPUT, and the top has
the TinyTapeout ports."""

from fractions import Fraction

import pytest
from amaranth.hdl import Fragment

from navgate.hw.blocks import get_block
from navgate.hw.verilog import emit_verilog, verilog_ports
from navgate.systems.tinykalman.datapath import TinyKalmanCordic, TinyKalmanDatapath

NAMES = ["tinykalman_top", "mpu6500_spi", "kalman_steady", "uart_tx"]


@pytest.mark.parametrize("name", NAMES)
def test_blocks_build_and_document_timing(name):
    _check(get_block(name).factory())


@pytest.mark.parametrize("cls", [TinyKalmanCordic, TinyKalmanDatapath])
def test_unregistered_stream_blocks_document_timing(cls):
    _check(cls())


def _check(c):
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
