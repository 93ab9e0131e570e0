"""MPU-6500 device module: words, register model, and the bit-level SPI device model (timing
checks and fault injection) driven by a bit-banged master written here from the data sheet."""

import pytest

from navgate.devices import mpu6500 as mpu

HALF = 500.0  # ns: SCLK at 1 MHz


def xfer(dev, tx: bytes, t: float, *, half=HALF, mode=3, setup=HALF, hold=HALF, gap=HALF,
         mosi_late=0.0):
    """One transaction, MSB first; MOSI changes at falling edges (plus ``mosi_late`` ns),
    MISO is read at rising edges. Returns (rx bytes, time after the transaction)."""
    idle = 1 if mode == 3 else 0
    dev.pins(t, 1, idle, 0)
    t += gap
    dev.pins(t, 0, idle, 0)  # CS_N fall
    t += setup
    rx = bytearray()
    sclk = idle
    for byte in tx:
        val = 0
        for k in range(8):
            bit = (byte >> (7 - k)) & 1
            if mode == 3:
                dev.pins(t, 0, 0, 0 if mosi_late else bit)  # falling edge, MOSI changes
                if mosi_late:
                    dev.pins(t + mosi_late, 0, 0, bit)
                t += half
            else:
                dev.pins(t, 0, 0, bit)
                t += half
            miso = dev.pins(t, 0, 1, bit)  # rising edge: both sides sample
            val = (val << 1) | miso
            t += half
            if mode == 0:
                dev.pins(t, 0, 0, bit)
            sclk = 1 if mode == 3 else 0
        rx.append(val)
    t += hold - half if mode == 3 else 0
    dev.pins(t, 1, sclk, 0)  # CS_N rise
    return bytes(rx), t + gap


def burst(dev, t, **kw):
    return xfer(dev, bytes([mpu.SPI_READ | mpu.REG["ACCEL_XOUT_H"]]) + bytes(14), t, **kw)


def who(dev, t, **kw):
    rx, t = xfer(dev, bytes([mpu.SPI_READ | mpu.REG["WHO_AM_I"], 0]), t, **kw)
    return rx[1], t


SAMPLES = [(1, -2, 16384, 1335, 131, -131, 7), (-32768, 32767, 0, 0, -1, 1, 0),
           (100, 200, 300, 400, 500, 600, 700)]


def test_words_encode_decode_and_saturation():
    assert mpu.encode_accel(1.0) == (16384, False)
    assert mpu.encode_accel(-2.5) == (-32768, True)
    assert mpu.encode_gyro(10.0) == (1310, False)
    assert mpu.encode_gyro(1.0, fs_sel=3) == (16, False)  # 16.4 LSB/dps -> 16
    assert mpu.encode_temp(21.0) == (0, False)
    b = mpu.encode_burst(SAMPLES[1])
    assert b[:2] == b"\x80\x00" and b[2:4] == b"\x7f\xff"
    assert tuple(mpu.decode_burst(b).values()) == SAMPLES[1]
    with pytest.raises(ValueError):
        mpu.encode_burst([40000, 0, 0, 0, 0, 0, 0])


@pytest.mark.parametrize("mode", [0, 3])
def test_bus_serves_who_am_i_and_one_sample_per_burst(mode):
    dev = mpu.Mpu6500Bus(SAMPLES)
    t = 0.0
    for k, s in enumerate(SAMPLES):
        w, t = who(dev, t, mode=mode)
        assert w == mpu.WHO_AM_I_VALUE
        rx, t = burst(dev, t, mode=mode)
        assert tuple(mpu.decode_burst(rx[1:]).values()) == s, k
    assert dev.stats.bursts == 3 and dev.stats.who_am_i_reads == 3
    assert dev.violation_count == 0 and dev.stats.underruns == 0
    rx, t = burst(dev, t, mode=mode)  # stream exhausted: last sample repeated, counted
    assert tuple(mpu.decode_burst(rx[1:]).values()) == SAMPLES[-1]
    assert dev.stats.underruns == 1
    # the log holds the bytes as the master saw them
    assert dev.log[0] == (mpu.REG["WHO_AM_I"], True, bytes([0, 0x70]))


def test_bus_writes_registers_but_not_who_am_i():
    dev = mpu.Mpu6500Bus()
    _, t = xfer(dev, bytes([mpu.REG["GYRO_CONFIG"], 1 << 3, 2 << 3]), 0.0)
    assert (dev.regs.gyro_fs, dev.regs.accel_fs) == (1, 2)
    _, t = xfer(dev, bytes([mpu.REG["WHO_AM_I"], 0x12]), t)
    assert who(dev, t)[0] == 0x70


@pytest.mark.parametrize("kw, text", [
    ({"half": 300.0}, "SCLK low for 300 ns"),  # 1.67 MHz: t_LOW, t_HIGH and f_SCLK all fail
    ({"hold": 200.0}, "t_HD.CS"),
    ({"setup": 0.0}, "t_SU.CS"),
    ({"mosi_late": 495.0}, "t_SU.SDI"),
])
def test_bus_flags_timing_violations(kw, text):
    dev = mpu.Mpu6500Bus(SAMPLES)
    who(dev, 0.0, **kw)
    assert dev.violation_count >= 1
    assert any(text in v for v in dev.stats.violations), dev.stats.violations


def test_fast_sclk_allowed_only_for_sensor_reads():
    # 10 MHz SCLK: within the 20 MHz limit for the data registers, beyond 1 MHz for WHO_AM_I
    dev = mpu.Mpu6500Bus(SAMPLES, timing=mpu.SpiTiming(t_low=25, t_high=25, t_hd_cs=50))
    burst(dev, 0.0, half=50.0, setup=50.0, hold=50.0, gap=50.0)
    assert dev.violation_count == 0
    who(dev, 1e6, half=50.0, setup=50.0, hold=50.0, gap=50.0)
    assert any("SCLK period 100 ns (min 1000 ns)" in v for v in dev.stats.violations)


def test_bus_without_timing_checks_accepts_fast_clocks():
    dev = mpu.Mpu6500Bus(SAMPLES, timing=None)
    rx, _ = burst(dev, 0.0, half=1.0, setup=1.0, hold=1.0, gap=1.0)
    assert tuple(mpu.decode_burst(rx[1:]).values()) == SAMPLES[0]
    assert dev.violation_count == 0


@pytest.mark.parametrize("fault, who_value, burst_byte, consumed", [
    ("stuck0", 0x00, 0x00, True),
    ("stuck1", 0xFF, 0xFF, True),
    ("absent", 0xFF, 0xFF, False),  # pull-up
    ("who_am_i", 0x71, None, True),
])
def test_bus_faults(fault, who_value, burst_byte, consumed):
    dev = mpu.Mpu6500Bus(SAMPLES, fault=fault)
    w, t = who(dev, 0.0)
    rx, t = burst(dev, t)
    assert w == who_value
    if burst_byte is None:
        assert tuple(mpu.decode_burst(rx[1:]).values()) == SAMPLES[0]
    else:
        assert set(rx[1:]) == {burst_byte}
    assert dev.stats.bursts == (1 if consumed else 0)
    dev.set_fault(None)  # healed: the stream continues where the part is
    rx, _ = burst(dev, t)
    assert tuple(mpu.decode_burst(rx[1:]).values()) == SAMPLES[1 if consumed else 0]
    with pytest.raises(ValueError):
        dev.set_fault("melted")


def test_absent_pull_down():
    dev = mpu.Mpu6500Bus(SAMPLES, fault="absent", pull=0)
    assert who(dev, 0.0)[0] == 0x00
