"""BMP390 facts: NVM layout, compensation (float64, float32 bit-true program and its error
bound over the whole range), raw encoder, and the SPI slave model."""

import numpy as np
import pytest

from navgate.devices import bmp390 as B
from navgate.devices.spi import drive_transfer
from navgate.numerics.fp32 import bits_to_f32

HALF = 60e-9  # 8.3 MHz


def test_nvm_round_trip_and_coefficients():
    block = B.nvm_bytes()
    assert len(block) == 21 and B.parse_nvm(block) == B.DEFAULT_NVM
    c = B.coefficients(B.DEFAULT_NVM)
    assert c["T1"] == B.DEFAULT_NVM["T1"] * 256.0
    assert c["P1"] == (B.DEFAULT_NVM["P1"] - 2**14) / 2**20
    assert c["P11"] == B.DEFAULT_NVM["P11"] / 2.0**65
    with pytest.raises(ValueError):
        B.parse_nvm(block[:20])


def test_encoder_inverts_the_formulas_to_one_count():
    p = np.linspace(*B.PRESSURE_RANGE_PA, 7)
    t = np.linspace(*B.TEMPERATURE_RANGE_C, 7)
    up, ut = B.encode(p, t)
    pc, tc = B.compensate(up, ut)
    # one ADC count is |dP/dup| ~ 0.015 Pa and dT/dut ~ 1.8e-5 degC: rounding is half of it
    assert np.max(np.abs(pc - p)) < 0.02
    assert np.max(np.abs(tc - t)) < 2e-5


def test_fp32_program_within_its_rigorous_bound_over_the_whole_range():
    pp, tt = np.meshgrid(np.linspace(*B.PRESSURE_RANGE_PA, 41),
                         np.linspace(*B.TEMPERATURE_RANGE_C, 26))
    up, ut = B.encode(pp.ravel(), tt.ravel())
    p64, t64 = B.compensate(up, ut)
    p32, t32 = B.compensate_fp32(up, ut)
    pv, tv, bp, bt = B.compensate_fp32_bound(up, ut)
    assert np.allclose(pv, p64, rtol=1e-12) and np.allclose(tv, t64, rtol=1e-12)
    err_p = np.abs(bits_to_f32(p32).astype(float) - p64)
    err_t = np.abs(bits_to_f32(t32).astype(float) - t64)
    assert np.all(err_p <= bp) and np.all(err_t <= bt)
    # the bound itself over the whole range: ~0.1 Pa (1 cm) and ~2e-5 degC
    assert bp.max() < 0.15 and bt.max() < 3e-5


def _read(model, addr, n, t0):
    return drive_transfer(model, [0x80 | addr] + [0] * (n + 1), 8, t0=t0, half=HALF,
                          cs_setup=HALF, cs_hold=HALF)


def test_model_registers_nvm_and_sample_stream():
    st = B.BaroStream.from_physical([90000.0, 95000.0], [20.0, 21.0])
    m = B.Bmp390Model(st)
    rx, t = _read(m, 0x00, 10, 0.0)
    assert rx[2] == B.CHIP_ID and rx[2 + 3] == B.STATUS_CMD_RDY  # sleep mode: no drdy
    _, t = drive_transfer(m, [B.REG["PWR_CTRL"], B.PWR_CTRL_NORMAL], 8, t0=t + 1e-6, half=HALF,
                          cs_setup=HALF, cs_hold=HALF)
    rx, t = _read(m, 0x00, 0x46, t + 1e-6)
    assert bytes(rx[2 + 0x31:2 + 0x46]) == B.nvm_bytes()
    assert m.served == []  # the start-up read does not consume a sample
    for k in range(2):
        rx, t = _read(m, 0x00, 10, t + 1e-6)
        assert rx[2 + 3] & 0x60 == 0x60
        assert bytes(rx[2 + 4:2 + 10]) == B.data_bytes(st.uncomp_press[k], st.uncomp_temp[k])
    assert m.served == [0, 1] and m.violations == []


@pytest.mark.parametrize("code, kw", [
    ("f_sclk", dict(half=45e-9)),  # 11.1 MHz
    ("t_cs_setup", dict(cs_setup=15e-9)),
    ("t_cs_hold", dict(cs_hold=30e-9)),
    ("t_mosi_setup", dict(mosi_lead=10e-9)),
    ("t_low", dict(low=15e-9, half=100e-9)),
    ("t_high", dict(low=100e-9, half=15e-9)),
    ("cpol", dict(cpol=0)),
])
def test_model_rejects_timing_violations(code, kw):
    m = B.Bmp390Model(B.BaroStream.from_physical([90000.0], [20.0]))
    args = dict(t0=0.0, half=HALF, cs_setup=HALF, cs_hold=HALF)
    args.update(kw)
    drive_transfer(m, [0x80, 0, 0], 8, **args)
    assert code in {v.code for v in m.violations}, m.violations


def test_model_rejects_mosi_hold_violation():
    m = B.Bmp390Model(B.BaroStream.from_physical([90000.0], [20.0]))
    m.pins(0.0, 0, 1, 0)
    m.pins(100e-9, 0, 0, 1)
    m.pins(200e-9, 0, 1, 1)
    m.pins(210e-9, 0, 1, 0)  # 10 ns after the rising edge (min 20 ns)
    assert [v.code for v in m.violations] == ["t_mosi_hold"]


def test_stuck_miso_faults():
    st = B.BaroStream.from_physical([90000.0, 91000.0], [20.0, 20.0],
                                    faults={0: "stuck_low", 1: "missing"})
    m = B.Bmp390Model(st)
    m.regs[B.REG["PWR_CTRL"]] = B.PWR_CTRL_NORMAL
    m.nvm_reads = 1
    m._load_sample()
    rx, t = _read(m, 0x00, 10, 0.0)
    assert rx[2:] == [0] * 10
    rx, t = _read(m, 0x00, 10, t + 1e-6)
    assert rx[2:] == [0xFF] * 10
