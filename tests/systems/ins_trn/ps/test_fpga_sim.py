"""The whole FPGA in the loop: ``ins_trn_top`` in Verilator (IMU words through an ADIS16500
emulator onto its SPI pins, the barometer and the ranger through theirs, the profile through
the PL's FIFO and DMA, the PS through AXI4-Lite registers) equals the fp32 engine bit
for bit over a 60 s flight of the default mission with altitude and TRN updates; then the
top's output registers against their bit-true models, every register of the SystemRDL source
through the driver, and SLVERR for unmapped offsets."""

from __future__ import annotations

import numpy as np
import pytest

from navgate.hw.regmap import Registers
from navgate.numerics.fp32 import float_to_bits, fp32_add, fp32_sqrt
from navgate.systems.ins_trn.pl.fp32_program import N_STATES, p_reg
from navgate.systems.ins_trn.pl.output_formatter import (
    OUT_WORDS,
    REGISTER_OF,
    SIGMA_GROUPS,
    STATE_WORDS,
    formatter_bittrue,
)
from navgate.systems.ins_trn.pl.registers import ID_VALUE, register_map
from navgate.systems.ins_trn.pl.sequencer import job_cycles
from navgate.systems.ins_trn.pl.top import LIDAR_TIMEOUT_BITS
from navgate.systems.ins_trn.ps.fpga_sim import FpgaSimError


def _output_registers(eng, regs: Registers, n_samples: int, last_words):
    """The formatted outputs, sigmas, diagonal, biases and counters of the top."""
    g = {n: float_to_bits(eng.m.get(n)) for n in STATE_WORDS}
    g["ref_alt"] = float_to_bits(eng.setup.reference.h0)
    want = formatter_bittrue({k: np.array([v], np.uint32) for k, v in g.items()})
    for w in OUT_WORDS:
        assert regs.read(REGISTER_OF[w]) == int(want[w][0]), w
    assert regs.read("NAV_FLAGS") == int(want["flags"][0])
    diag = [float_to_bits(eng.m.get(p_reg(i, i))) for i in range(N_STATES)]
    for k in range(N_STATES):
        assert regs.read(f"COV_DIAG_{k}") == diag[k]
    for reg, group in zip(("COV_POS", "COV_VEL", "COV_ATT"), SIGMA_GROUPS, strict=True):
        acc = np.uint32(diag[group[0]])
        for k in group[1:]:
            acc = fp32_add(acc, np.uint32(diag[k]))
        assert regs.read(reg) == int(fp32_sqrt(acc)), reg
    for i, axis in enumerate("XYZ"):
        assert regs.read(f"BIAS_A{axis}") == float_to_bits(eng.m.get(f"ba{i}"))
        assert regs.read(f"BIAS_G{axis}") == float_to_bits(eng.m.get(f"bg{i}"))
    assert regs.read("SAMPLE_COUNT") == n_samples
    # the barometer and the ranger through their pins: every sample counted, the last read
    assert regs.read("BARO_SAMPLES") == eng.baro_samples
    assert regs.read("LIDAR_FRAMES") == eng.lidar_frames
    assert regs.read("ERROR_COUNT") == 0
    assert regs.read_fields("ENG_STATUS") == {"busy": 0, "propagations": n_samples}
    assert regs.read_fields("STATUS") == {"running": 1, "error": 0}
    raw = ("RAW_GYRO_X", "RAW_GYRO_Y", "RAW_GYRO_Z", "RAW_ACCEL_X", "RAW_ACCEL_Y", "RAW_ACCEL_Z")
    for reg, w in zip(raw, last_words, strict=True):
        assert regs.read(reg) == int(w) & 0xFFFFFFFF


def _error_interrupt(regs: Registers, sim):
    """A missing ranger, once enabled, times out: the error interrupt fires, IRQ_STATUS.error
    is read to clear, STATUS.error stays set until CTRL.reset."""
    regs.read("IRQ_STATUS")
    regs.write("IRQ_ENABLE", update=0, error=1)
    # 16 clocks a bit: the receiver's silence timeout (free-running) expires within
    # LIDAR_TIMEOUT_BITS bit times of enabling it, or at once if it already expired
    regs.write("LIDAR_CFG", baud_div=16, enable=0)
    regs.write("LIDAR_CFG", baud_div=16, enable=1)
    waited = sim.wait("irq", limit=LIDAR_TIMEOUT_BITS * 16 + 100)
    assert waited <= LIDAR_TIMEOUT_BITS * 16 + 16, waited
    assert regs.read_fields("IRQ_STATUS")["error"] == 1
    assert regs.read_fields("IRQ_STATUS")["error"] == 0  # read to clear
    assert regs.read_fields("STATUS")["error"] == 1
    regs.write("LIDAR_CFG", baud_div=868, enable=0)
    regs.write("CTRL", enable=1, reset=1)
    regs.write("CTRL", enable=1, reset=0)
    assert regs.read_fields("STATUS") == {"running": 1, "error": 0}


def _profile_dma(regs: Registers, eng):
    """The timestamp correlator latches the INS position words and the IMU sample count when a
    ranger frame arrives; the PS pushes 70 terrain heights (the FIFO keeps the newest 64) and
    takes the newest 40 by DMA into the co-simulation's DDR: the words read back are the
    entries, oldest first, in the seed's 128-bit format; the DMA's end raises the update
    interrupt."""
    from navgate.systems.ins_trn.pl.profile_manager import pack_entry
    from navgate.systems.ins_trn.ps.fpga_sim import DMA_WINDOW, LIDAR_TEMP_WORD

    sim = eng.sim
    frames = regs.read("LIDAR_FRAMES")
    regs.bus.push("lidar_feed", {"dist": 1234, "strength": 2000, "temp": LIDAR_TEMP_WORD})
    regs.wait_until("LIDAR_FRAMES", count=frames + 1, limit=20_000)
    pn, pe = (float_to_bits(eng.m.get(n)) for n in ("pN", "pE"))
    assert regs.read("PROF_SAMPLE_N") == pn and regs.read("PROF_SAMPLE_E") == pe
    assert regs.read("PROF_SAMPLE_T") == eng.samples
    rng = np.random.default_rng(11)
    entries = []
    with sim.deferred():
        for _ in range(70):
            h = float_to_bits(np.float32(rng.uniform(-5e2, 5e3)))
            entries.append(pack_entry(h, pn, pe, eng.samples, 1))
            regs.write("PROF_ENTRY_H", h)
            regs.write("PROF_PUSH", push=1)
    assert regs.read_fields("PROF_STATUS") == {"busy": 0, "count": 64}
    regs.read("IRQ_STATUS")
    regs.write("IRQ_ENABLE", update=1, error=0)
    regs.write("PROF_ADDR", 0x40)
    regs.write("PROF_COUNT", 40)
    regs.write("PROF_CTRL", start=1)
    sim.wait("irq", limit=10_000)
    assert regs.read_fields("IRQ_STATUS")["update"] == 1
    assert regs.read_fields("PROF_STATUS") == {"busy": 0, "count": 64}
    words = [regs.bus.read(DMA_WINDOW + 0x40 + 4 * k) for k in range(40 * 4)]
    got = [sum(words[4 * j + i] << (32 * i) for i in range(4)) for j in range(40)]
    assert got == entries[-40:]
    # the PS's checks: a latch that is not the model's, a DMA of no or too many entries
    fifo = eng.profile.fifo
    with pytest.raises(FpgaSimError, match="timestamp correlator latched"):
        fifo.push((0, pn ^ 1, pe, eng.samples | 1 << 24))
    for count in (0, 65):
        with pytest.raises(FpgaSimError, match="profile DMA of"):
            fifo.read(count)


def _push_too_soon(regs: Registers, sim):
    """The FIFO writes an entry into block RAM one word a cycle, so it takes one push every
    four cycles: PROF_PUSH written twice with nothing between (the driver at full speed puts
    the two strobes three cycles apart) stores one entry and raises the error interrupt;
    with PROF_ENTRY_H between, both are stored (the DMA of the newest three shows which)."""
    from navgate.systems.ins_trn.ps.fpga_sim import DMA_WINDOW

    heights = [float_to_bits(np.float32(h)) for h in (101.5, 202.5, 303.5)]
    regs.read("IRQ_STATUS")
    with sim.deferred():
        regs.write("PROF_ENTRY_H", heights[0])
        regs.write("PROF_PUSH", push=1)
        regs.write("PROF_ENTRY_H", heights[1])
        regs.write("PROF_PUSH", push=1)
        regs.write("PROF_ENTRY_H", heights[2])
        regs.write("PROF_PUSH", push=1)
        regs.write("PROF_PUSH", push=1)  # too soon: not stored
    assert regs.read_fields("IRQ_STATUS") == {"update": 0, "error": 1}
    assert regs.read_fields("STATUS")["error"] == 1
    regs.write("IRQ_ENABLE", update=1, error=0)
    regs.write("PROF_ADDR", 0x40)
    regs.write("PROF_COUNT", 3)
    regs.write("PROF_CTRL", start=1)
    sim.wait("irq", limit=10_000)
    assert regs.read_fields("IRQ_STATUS") == {"update": 1, "error": 0}
    assert [regs.bus.read(DMA_WINDOW + 0x40 + 16 * k) for k in range(3)] == heights
    regs.write("CTRL", enable=1, reset=1)
    regs.write("CTRL", enable=1, reset=0)
    assert regs.read_fields("STATUS") == {"running": 1, "error": 0}

def _every_register(regs: Registers):
    """Every register of the map read (OKAY) and every software-writable one written and read
    back through the driver; write-1 strobes read 0; unmapped offsets answer SLVERR."""
    regmap = register_map()
    rng = np.random.default_rng(5)
    assert regs.read("ID") == ID_VALUE
    regs.write("CTRL", 0)  # stop the pipeline first: writes below must not start anything
    skip_write = {"CTRL", "ENG_CMD", "TRN_CTRL", "ALT_CTRL", "CAL_APPLY", "PROF_CTRL"}
    for reg in regmap.registers:
        value = regs.read(reg.name)
        if reg.pulse_mask:
            assert value & reg.pulse_mask == 0, reg.name
        if reg.sw_write_mask and reg.name not in skip_write:
            v = int(rng.integers(0, 2**32)) & reg.sw_write_mask
            regs.write(reg.name, v)
            assert regs.read(reg.name) & reg.sw_write_mask == v, reg.name
    # strobes: a profile DMA of 0 entries completes at once, CAL_APPLY is accepted
    fill = regs.read_fields("PROF_STATUS")["count"]
    regs.write("PROF_COUNT", 0)
    regs.write("PROF_CTRL", start=1)
    regs.write("CAL_APPLY", apply=1)
    assert regs.read_fields("PROF_STATUS") == {"busy": 0, "count": fill}
    mapped = {r.offset for r in regmap.registers}
    unmapped = [o for o in range(0, 1 << regmap.address_width, 4) if o not in mapped]
    for off in unmapped[:: max(1, len(unmapped) // 64)]:
        with pytest.raises(OSError, match="SLVERR"):
            regs.bus.read(off)
        with pytest.raises(OSError, match="SLVERR"):
            regs.bus.write(off, 0)


def test_fpga_sim_equals_fp32_60s_flight(against_fp32):
    """Issue 12's target: 60 s of the default mission with the whole FPGA in the loop."""
    stream, _, run, engs = against_fp32.fly("fpga-sim", 60.0)
    eng = engs["fpga-sim"]
    # every valid barometer record and every ranger record went through the pins
    assert eng.baro_samples == int(np.sum(stream.baro_status == 0)) > 1000
    assert eng.lidar_frames == stream.ranger_range.size > 500
    assert sum(run.accepted.values()) > 10 and eng.interrupts > 10
    # the correlator's profile came from the PL's FIFO by DMA, once per correlation, and the
    # FIFO holds every accepted terrain sample (the newest 64)
    hw = run.hardware
    assert hw["profile_dmas"] == len(run.fixes) > 5
    assert hw["profile_entries_pushed"] == run.profile_counts["accepted"] > 64
    # the cycles the run reported: at least the sequencer's IMU job per sample
    imu_job = job_cycles(eng.image, "imu")
    assert eng.samples * imu_job <= hw["simulated_cycles"] <= eng.cycles
    assert hw["update_interrupts"] == eng.interrupts
    n = round(60.0 * 400)
    assert eng.samples == n
    regs = eng.regs  # the engine's own driver (Registers over NativeAxiBus)
    assert regs.regmap.registers == register_map().registers
    last = list(stream.gyro_words[-1]) + list(stream.accel_words[-1])
    _output_registers(eng, regs, n, last)
    assert regs.read_fields("PROF_STATUS") == {"busy": 0, "count": 64}
    against_fp32.directed_updates(engs, "fpga-sim")
    _profile_dma(regs, eng)
    # a wait that runs out inside an engine job is the engine's error, the model still usable
    frames = regs.read("LIDAR_FRAMES")
    with pytest.raises(FpgaSimError, match="poll of 0x74 timed out after 50 cycles"):
        with eng._job() as job:
            job.wait_until("LIDAR_FRAMES", count=frames + 1, limit=50)
    assert regs.read("LIDAR_FRAMES") == frames
    _error_interrupt(regs, eng.sim)
    _push_too_soon(regs, eng.sim)
    _every_register(regs)
    eng.close()


@pytest.mark.slow
def test_fpga_sim_equals_fp32_whole_default_flight(against_fp32):
    """The whole 10-minute default flight through the whole FPGA, bit for bit."""
    _, _, run, engs = against_fp32.fly("fpga-sim", 600.0, seed=0)
    assert sum(run.accepted.values()) > 100
    engs["fpga-sim"].close()
