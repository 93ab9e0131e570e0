"""The register driver's guards (navgate.hw.regmap.Registers): NaN, inf and values
beyond float32's range are refused for float registers, 1e300, 1.5, NaN and strings for
integer registers and fields, each with a ValueError naming the register (never an
OverflowError or TypeError), and nothing reaches the bus."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navgate.hw.regmap import Registers, bits_f32
from navgate.systems.ins_trn.pl.registers import register_map


class RecordingBus:
    def __init__(self):
        self.writes = []

    def write(self, offset, value):
        self.writes.append((offset, value))

    def read(self, offset):
        return 0


@pytest.fixture(scope="module")
def regmap():
    return register_map()


def raises_naming(name, fn, *args, **kwargs):
    with pytest.raises(ValueError) as info:
        fn(*args, **kwargs)
    assert str(info.value).startswith(name), str(info.value)
    return str(info.value)


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, 1e300, -3.5e38, "12"])
def test_float_register_refuses(regmap, value):
    bus = RecordingBus()
    raises_naming("TRN_POS_N", Registers(regmap, bus).write_f32, "TRN_POS_N", value)
    assert bus.writes == []


def test_float_register_largest_float32_still_written(regmap):
    bus = RecordingBus()
    top = float(np.finfo(np.float32).max)
    Registers(regmap, bus).write_f32("TRN_POS_N", top)
    assert bits_f32(bus.writes[0][1]) == top


@pytest.mark.parametrize("value", [1e300, 1.5, math.nan, "3", None, -1, 2**32])
def test_integer_register_refuses(regmap, value):
    bus = RecordingBus()
    regs = Registers(regmap, bus)
    if value is None:  # no value and no fields: the reset value is written, not an error
        regs.write("IMU_CFG")
        assert len(bus.writes) == 1
        return
    raises_naming("IMU_CFG", regs.write, "IMU_CFG", value)
    assert bus.writes == []


@pytest.mark.parametrize("value", [1e300, 1.5, math.nan, "9", 256])
def test_integer_field_refuses(regmap, value):
    bus = RecordingBus()
    raises_naming("IMU_CFG.spi_div", Registers(regmap, bus).write, "IMU_CFG", spi_div=value)
    assert bus.writes == []


def test_integral_float_and_numpy_integer_are_accepted(regmap):
    bus = RecordingBus()
    regs = Registers(regmap, bus)
    regs.write("IMU_CFG", spi_div=4.0, enable=np.int64(1))
    regs.write("IMU_CFG", 7.0)
    off = regmap["IMU_CFG"].offset
    f = {x.name: x for x in regmap["IMU_CFG"].fields}
    assert (bus.writes[0][1] >> f["spi_div"].lsb) & 0xFF == 4
    assert (bus.writes[0][1] >> f["enable"].lsb) & 1 == 1
    assert bus.writes[1] == (off, 7)
