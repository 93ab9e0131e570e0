"""ADIS16500 facts, burst encoding and the bit-level SPI slave model (timing checks, faults)."""

import math

import numpy as np
import pytest

from navgate.devices import adis16500 as A
from navgate.devices.spi import drive_transfer

HALF = 0.5e-6  # 1 MHz burst clock


def _burst(model, t0, **kw):
    args = dict(t0=t0, half=HALF, cs_setup=A.T_CS_SETUP, cs_hold=HALF)
    args.update(kw)
    return drive_transfer(model, [A.BURST_CMD] + [0] * A.BURST_WORDS, 16, **args)


def _stream(n=4, seed=0, **kw):
    rng = np.random.default_rng(seed)
    return A.ImuStream(rng.integers(-32768, 32768, (n, 3)), rng.integers(-32768, 32768, (n, 3)),
                       **kw)


def test_lsb_values_kept_for_the_simulator():
    assert A.GYRO_LSB_RAD_S == 0.00625 * math.pi / 180
    assert A.ACCEL_LSB_M_S2 == pytest.approx(1.25e-3 * 9.80665)
    assert A.DATASHEET_GYRO_LSB_RAD_S / A.GYRO_LSB_RAD_S == pytest.approx(16.0)


def test_checksum_is_the_byte_sum_of_the_nine_words():
    words = A.burst_words([[0x0102, 0x0304, -1]], [[0, 0, 0x7FFF]], temp=0x0A0B, diag=0x8001,
                          cntr=0x1234)
    w = [int(x) for x in words[0]]
    byte_sum = sum((x & 0xFF) + (x >> 8) for x in w[:9]) & 0xFFFF
    assert w[9] == byte_sum == (0x80 + 0x01 + 1 + 2 + 3 + 4 + 0xFF + 0xFF + 0x7F + 0xFF
                                + 0x0A + 0x0B + 0x12 + 0x34)
    d = A.decode_burst(words)
    assert d["checksum_ok"][0] and d["gyro"][0].tolist() == [0x0102, 0x0304, -1]
    bad = words.copy()
    bad[0, 3] ^= 1
    assert not A.decode_burst(bad)["checksum_ok"][0]


def test_encode_rounds_and_saturates():
    w, sat = A.encode_gyro(np.array([0.4, -0.6, 1e9]) * A.GYRO_LSB_RAD_S)
    assert w.tolist() == [0, -1, 32767] and sat == 1
    assert A.decode_accel(A.encode_accel([9.80665])[0])[0] == pytest.approx(9.80665,
                                                                            abs=A.ACCEL_LSB_M_S2)


def test_model_serves_bursts_in_order_with_a_correct_master():
    st = _stream(3)
    m = A.Adis16500Model(st)
    t = 0.0
    for k in range(3):
        rx, t = _burst(m, t)
        assert rx[1:] == [int(x) for x in st.words[k]]
        t += A.T_STALL
    assert m.violations == [] and m.served == [0, 1, 2]
    assert [int(x) for x in st.words[:, 8]] == [1, 2, 3]  # DATA_CNTR


def test_register_read_answers_in_the_next_frame():
    m = A.Adis16500Model(_stream(1))
    _, t = drive_transfer(m, [A.REG["PROD_ID"] << 8], 16, t0=0, half=HALF, cs_setup=A.T_CS_SETUP,
                          cs_hold=HALF)
    rx, _ = drive_transfer(m, [0], 16, t0=t + A.T_STALL, half=HALF, cs_setup=A.T_CS_SETUP,
                           cs_hold=HALF)
    assert rx == [A.PROD_ID]


@pytest.mark.parametrize("fault, check", [
    ("bad_checksum", lambda rx, w: rx[:9] == w[:9] and rx[9] == (w[9] + 1) & 0xFFFF),
    ("stuck_low", lambda rx, w: rx == [0] * 10),
    ("stuck_high", lambda rx, w: rx == [0xFFFF] * 10),
    ("missing", lambda rx, w: rx == [0xFFFF] * 10),
])
def test_faults(fault, check):
    st = _stream(2, faults={0: fault})
    m = A.Adis16500Model(st)
    rx, t = _burst(m, 0.0)
    assert check(rx[1:], [int(x) for x in st.words[0]])
    rx, _ = _burst(m, t + A.T_STALL)  # the next sample is clean
    assert rx[1:] == [int(x) for x in st.words[1]]
    with pytest.raises(ValueError):
        A.ImuStream(np.zeros((1, 3)), np.zeros((1, 3)), faults={0: "gremlins"})


# Each data-sheet limit, violated by a deliberately wrong master (and only that one).
@pytest.mark.parametrize("code, kw", [
    ("f_sclk", dict(half=0.24e-6)),  # 2.08 MHz burst clock
    ("t_cs_setup", dict(cs_setup=150e-9)),
    ("t_mosi_setup", dict(mosi_lead=20e-9)),
    ("t_low", dict(low=0.3e-6, half=0.9e-6)),  # duty cycle: 300 ns low
    ("t_high", dict(low=0.9e-6, half=0.3e-6)),  # duty cycle: 300 ns high
    ("partial_word", dict(bits=16 * 5 + 3)),
])
def test_model_rejects_timing_violations(code, kw):
    m = A.Adis16500Model(_stream(1))
    _burst(m, 0.0, **kw)
    codes = {v.code for v in m.violations}
    assert code in codes, m.violations
    clock = {"f_sclk", "t_high", "t_low"}  # a fast clock breaks its period and duty limits
    assert codes <= ({code} | clock if code in clock else {code})


def test_model_rejects_stall_cpol_and_hold_violations():
    m = A.Adis16500Model(_stream(2))
    _, t = _burst(m, 0.0)
    _burst(m, t + 10e-6)  # CS_N high only 10 us < tSTALL
    assert [v.code for v in m.violations] == ["t_cs_high"]
    m = A.Adis16500Model(_stream(1))
    _burst(m, 0.0, cpol=0)
    assert "cpol" in {v.code for v in m.violations}
    # MOSI changing 20 ns after the rising edge violates tDHD = 50 ns
    m = A.Adis16500Model(_stream(1))
    m.pins(0.0, 0, 1, 0)
    m.pins(1e-6, 0, 0, 1)
    m.pins(1.5e-6, 0, 1, 1)
    m.pins(1.52e-6, 0, 1, 0)
    assert "t_mosi_hold" in {v.code for v in m.violations}
