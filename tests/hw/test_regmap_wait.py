"""Registers.wait_until and read_later on a plain bus (navgate.hw.regmap): over MemoryBus
(a RegisterFileModel whose fabric inputs change as it is read) the register is read in a
bounded loop until it holds the value (exactly as many reads as it takes), RegisterTimeout
after ``limit`` reads; fields give the mask and value; a bus with ``poll`` is handed the
wait instead; bad arguments are refused before the bus is touched."""

from __future__ import annotations

import pytest

from navgate.hw.bus import MemoryBus
from navgate.hw.regmap import Reading, RegisterFileModel, Registers, RegisterTimeout
from navgate.systems.ins_trn.pl.registers import register_map


class SteppingBus(MemoryBus):
    """MemoryBus whose ENG_STATUS reads busy (and ``props`` propagations) for the first
    ``busy_reads`` reads of it, then idle with ``props + 1`` propagations."""

    def __init__(self, model, busy_reads: int, props: int = 4):
        super().__init__(model)
        self.offset = model.regmap["ENG_STATUS"].offset
        self.busy_reads, self.props, self.reads = busy_reads, props, 0

    def read(self, offset):
        if offset == self.offset:
            done = self.reads >= self.busy_reads
            self.model.hw_inputs["ENG_STATUS"] = ((self.props + done) << 8) | (not done)
            self.reads += 1
        return super().read(offset)


@pytest.fixture(scope="module")
def regmap():
    return register_map()


@pytest.mark.parametrize("busy_reads", [0, 1, 7])
def test_wait_until_reads_until_the_fields_hold(regmap, busy_reads):
    bus = SteppingBus(RegisterFileModel(regmap), busy_reads)
    regs = Registers(regmap, bus)
    got = regs.wait_until("ENG_STATUS", busy=0, propagations=5, limit=8)
    assert isinstance(got, Reading) and got.value == 5 << 8
    assert bus.reads == busy_reads + 1


def test_wait_until_mask_and_value_and_timeout(regmap):
    bus = SteppingBus(RegisterFileModel(regmap), busy_reads=10)
    regs = Registers(regmap, bus)
    with pytest.raises(RegisterTimeout, match=r"ENG_STATUS & 0xffffff01 != 0x500 after 10 "
                                              r"reads \(last 0x401\)"):
        regs.wait_until("ENG_STATUS", 0xFFFFFF01, 0x500, limit=10)
    assert bus.reads == 10
    assert regs.wait_until("ENG_STATUS", 0x1, 0, limit=1).value == 0x500
    assert bus.reads == 11


def test_field_mask(regmap):
    regs = Registers(regmap, MemoryBus(RegisterFileModel(regmap)))
    assert regs.field_mask("ENG_STATUS", busy=0, propagations=3) == (0xFFFFFF01, 0x300)
    assert regs.field_mask("IMU_CFG", spi_div=2, dr_sync=1) == (0x2FF, 0x202)


def test_wait_until_hands_the_wait_to_a_polling_bus(regmap):
    class PollingBus(MemoryBus):
        calls = []

        def poll(self, offset, mask, value, limit):
            self.calls.append((offset, mask, value, limit))
            return value | 0x80

        def read(self, offset):
            raise AssertionError("a polling bus is not read in a loop")

    regs = Registers(regmap, PollingBus(RegisterFileModel(regmap)))
    got = regs.wait_until("BARO_SAMPLES", count=17, limit=123)
    assert got.value == 17 | 0x80
    assert PollingBus.calls == [(regmap["BARO_SAMPLES"].offset, 0xFFFFFFFF, 17, 123)]


@pytest.mark.parametrize("args, kwargs, error, match", [
    ((0xF, 0x10), {}, ValueError, "outside mask"),
    ((1, 0), {"limit": 0}, ValueError, "wait limit 0"),
    ((1,), {}, TypeError, "needs mask and value"),
    ((1, 0), {"busy": 0}, TypeError, "not both"),
    ((), {"idle": 0}, KeyError, "no field 'idle'"),
    ((), {"busy": 2}, ValueError, "does not fit 1 bits"),
])
def test_wait_until_refuses(regmap, args, kwargs, error, match):
    bus = SteppingBus(RegisterFileModel(regmap), busy_reads=0)
    with pytest.raises(error, match=match):
        Registers(regmap, bus).wait_until("ENG_STATUS", *args, **kwargs)
    assert bus.reads == 0


def test_read_later_and_deferred_on_a_plain_bus(regmap):
    model = RegisterFileModel(regmap)
    regs = Registers(regmap, MemoryBus(model))
    model.hw_set("IRQ_STATUS", 0b10)
    with regs.deferred():  # nothing to defer on a plain bus: every access happens at once
        regs.write("IMU_CFG", spi_div=3, enable=1)
        first = regs.read_later("IRQ_STATUS")
        assert first.ready and first.value == 0b10
        assert regs.read_later("IRQ_STATUS").value == 0  # read to clear, at once
    assert regs.decode("IMU_CFG", regs.read("IMU_CFG")) == {"spi_div": 3, "enable": 1,
                                                              "dr_sync": 0}
    with pytest.raises(RuntimeError, match="has not been sent"):
        _ = Reading().value
