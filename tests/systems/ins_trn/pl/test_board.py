"""The Zybo Z7-20 pin assignment (navgate.systems.ins_trn.pl.board)."""

from __future__ import annotations

import re

import pytest

from navgate.systems.ins_trn.pl.board import PULL_UPS, ZYBO_Z7_20_PINS, zybo_z7_20_xdc

# PL package pins of the Zybo Z7-20's oscillator, BTN0, LD0-3 and Pmods JC, JD, JE (the
# board's master constraints, revision B)
BOARD_PINS = {"K17", "K18", "M14", "M15", "G14", "D18",
              "V15", "W15", "T11", "T10", "W14", "Y14", "T12", "U12",
              "T14", "T15", "P14", "R14", "U14", "U15", "V17", "V18",
              "V12", "W16", "J15", "H15", "V13", "U17", "T17", "Y17"}


def test_every_port_on_its_own_board_pin():
    pins = [pin for pin, _ in ZYBO_Z7_20_PINS.values()]
    assert len(set(pins)) == len(pins)
    assert set(pins) <= BOARD_PINS


def test_xdc_constrains_each_port_once_with_clock_and_pullups():
    xdc = zybo_z7_20_xdc()
    for port, (pin, _) in ZYBO_Z7_20_PINS.items():
        lines = [line for line in xdc.splitlines() if f"{{ {port} }}" in line
                 and "PACKAGE_PIN" in line]
        assert len(lines) == 1 and f"PACKAGE_PIN {pin} " in lines[0]
        assert ("PULLUP true" in lines[0]) == (port in PULL_UPS)
    assert re.search(r"create_clock .* -period 8\.00 .*clk_in", xdc)
    assert "create_clock" not in zybo_z7_20_xdc(["imu_miso"])
    with pytest.raises(KeyError, match="no Zybo Z7-20 pin for gps_rx"):
        zybo_z7_20_xdc(["gps_rx"])
