"""Bad input to seed 001's public entry points (issue 31): the integer model
(navgate.systems.tinykalman.model), the IMU-to-words conversion (run), the data path and
serial chip blocks, the chip top and the RTL runners. Each class of bad input is one test:
non-finite words, fractions, words a 16-bit register cannot hold, mismatched shapes, bad
gain shifts, bad flags and types. Each is a ValueError naming the argument; overflow that
the chip itself has (MPU full scale, mag_yz) is counted, not refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navgate.systems.tinykalman import model, run

NAN = float("nan")
LEVEL = (0, 0, 16384)  # ax, ay, az of a level part: +1 g on z


def raises_naming(name, fn, *args, **kwargs):
    with pytest.raises(ValueError) as info:
        fn(*args, **kwargs)
    assert str(info.value).startswith(name), str(info.value)
    return str(info.value)


@pytest.mark.parametrize("value", [NAN, math.inf, -math.inf])
def test_non_finite_words_are_refused(value):
    """NaN once became int64's minimum (a garbage angle, with only a RuntimeWarning)."""
    raises_naming("ay", model.accel_angles, 0, value, 16384)
    raises_naming("meas", model.kalman_step, 0, 0, value)
    raises_naming("gx", model.run_sequence, [0], [0], [16384], [value], [0])
    raises_naming("roll", model.encode_packet, value, 0)


@pytest.mark.parametrize("value", [1.5, -0.5, 100.25])
def test_fractional_words_are_refused_not_truncated(value):
    """1.5 was silently truncated to 1 (encode_packet sent roll = 1)."""
    raises_naming("ax", model.accel_angles, value, 0, 16384)
    raises_naming("rate", model.kalman_step, 0, value, 0)
    raises_naming("pitch", model.encode_packet, 0, value)


@pytest.mark.parametrize("value", [32768, -32769, 40000, 10**6])
def test_words_beyond_16_bits_are_refused(value):
    """ay = 40000 gave roll 12328 (a 17th bit the chip does not have); an angle of 1e6 was
    wrapped without a word."""
    msg = raises_naming("ay", model.accel_angles, 0, value, 16384)
    assert "16-bit signed word [-32768, 32767]" in msg
    raises_naming("angle", model.kalman_step, value, 0, 0)
    raises_naming("gy", model.run_sequence, [0], [0], [16384], [0], [value])


def test_register_ends_are_accepted_and_integral_floats_equal_ints():
    ends = np.array([-32768, -1, 0, 1, 32767])
    as_int = model.accel_angles(ends, ends[::-1], np.full(5, 16384))
    as_float = model.accel_angles(ends.astype(float), ends[::-1].astype(float),
                                  np.full(5, 16384.0))
    for a, b in zip(as_int, as_float, strict=True):
        assert np.array_equal(a, b)
    assert model.kalman_step(32767, 32767, -32768) == model.kalman_step(32767.0, 32767, -32768)


def test_mismatched_shapes_are_named():
    """Three lengths once broadcast into a numpy error, or an IndexError in run_sequence."""
    raises_naming("ay", model.accel_angles, [1, 2, 3], [1, 2], [1, 2, 3])
    raises_naming("gx", model.run_sequence, [0, 1], [0, 1], [16384, 16384], [0], [0, 0])
    raises_naming("valid", model.run_sequence, [0], [0], [16384], [0], [0], valid=[1, 0])
    raises_naming("ax", model.run_sequence, [[0]], [[0]], [[16384]], [[0]], [[0]])
    raises_naming("acc_ms2", run.words_from_imu, np.zeros((4, 2)), np.zeros((4, 3)))
    raises_naming("gyro_rad_s", run.words_from_imu, np.zeros((4, 3)), np.zeros((5, 3)))


@pytest.mark.parametrize("name", ["rate_shift", "k_shift"])
@pytest.mark.parametrize("value", [-1, 16, 99, 1.5, NAN, True])
def test_bad_gain_shifts_are_refused(name, value):
    """k_shift = -1 or 99 returned 0 silently (gain 2^1 or 2^-99); 1.5 was a TypeError.
    The bounds are the gateware's (KalmanSteady: an integer in [0, 15])."""
    raises_naming(name, model.kalman_step, 0, 0, 100, **{name: value})


def test_gain_shift_bounds_match_the_gateware():
    from amaranth.hdl import Fragment

    from navgate.systems.tinykalman.datapath import KalmanSteady

    for k in (0, 15):
        assert model.gain_shift("k_shift", k) == k
        Fragment.get(KalmanSteady(k_shift=k), None)  # accepted by both, and it elaborates
    for k in (-1, 16, True):
        with pytest.raises(ValueError, match="k_shift"):
            KalmanSteady(k_shift=k)
    # the filter at the ends: gain 1 takes the measurement, gain 2^-15 barely moves
    assert model.kalman_step(0, 0, 1000, rate_shift=0, k_shift=0) == 1000
    assert model.kalman_step(0, 0, 32767, k_shift=15) == 0


def test_bytes_and_bits_arguments():
    raises_naming("data", model.PacketDecoder().feed, "DEAD")
    raises_naming("data", model.decode_stream, [0xDE, 0xAD])
    raises_naming("data", model.uart_frame_bits, "x")
    msg = raises_naming("bits", model.uart_decode_bits, [0, 2, 0, 0, 0, 0, 0, 0, 0, 1])
    assert "at bit 1" in msg  # a level of 2 once decoded as byte 0x02
    raises_naming("burst", model.TinyKalman().step, "x" * 14)
    for who in (-1, 256, 1.5):  # the WHO_AM_I byte the chip read
        raises_naming("who_am_i", model.TinyKalman().step, bytes(14), who_am_i=who)
    assert model.uart_decode_bits(model.uart_frame_bits(b"\xde\xad")) == b"\xde\xad"


def test_overflow_of_the_chip_itself_is_counted_not_refused():
    """Beyond the MPU's full scale (even 1e300 m/s^2) the words saturate and are counted, as
    the part clips; mag_yz beyond 16 bits saturates and is flagged per sample."""
    acc = np.array([[0.0, 0.0, 9.80665], [1e300, -1e300, 1e300]])
    words = run.words_from_imu(acc, np.zeros((2, 3)))
    assert words.saturated == 3
    assert words.words[1, :3].tolist() == [32767, -32768, 32767]
    _, _, mag, sat = model.accel_angles([0, 0], [32767, 0], [32767, 16384])
    assert sat.tolist() == [True, False] and int(mag[0]) > 32767


@pytest.mark.parametrize("kwargs, name", [
    ({"n": 0}, "n"), ({"n": 2.5}, "n"), ({"n": 10, "rate_hz": 0}, "rate_hz"),
    ({"n": 10, "rate_hz": NAN}, "rate_hz"), ({"n": 10, "seed": -1}, "seed"),
])
def test_synthetic_motion_parameters(kwargs, name):
    """rate 0 divided by zero and rate NaN cast NaN to int64 (RuntimeWarnings only)."""
    raises_naming(name, run.synthetic_motion, **kwargs)


def test_words_from_imu_flags():
    raises_naming("frd", run.words_from_imu, np.zeros((1, 3)), np.zeros((1, 3)), frd="no")
    raises_naming("words", run.model_stream, [[0] * 7])


def test_chip_blocks_refuse_non_bool_flags():
    """held_input="x" built a serial block (any truthy string), "no" gave a misleading
    message about the angle block."""
    from navgate.systems.tinykalman.datapath import TinyKalmanDatapath
    from navgate.systems.tinykalman.serial import TinyKalmanSerialCordic, TinyKalmanSerialDatapath

    for cls in (TinyKalmanSerialCordic, TinyKalmanSerialDatapath):
        raises_naming(f"{cls.__name__}: held_input", cls, held_input="x")
        raises_naming(f"{cls.__name__}: spi_fed", cls, held_input=True, spi_fed=1.5)
    raises_naming("TinyKalmanDatapath: held_input", TinyKalmanDatapath, held_input="no")
    raises_naming("TinyKalmanDatapath: angles_cls", TinyKalmanDatapath, angles_cls=int)


def test_rtl_runners_refuse_bad_counts_and_flags():
    from navgate.systems.tinykalman import rtl_sim

    words = run.synthetic_motion(3)
    for n in (0, -1, 2.5):
        raises_naming("n_samples", rtl_sim.run_amaranth, words.bursts(), n)
    bad = words.bursts()
    bad[1] = (*bad[1][:6], 1.5)  # a fraction (encode_burst truncated it mid-simulation)
    raises_naming("samples", rtl_sim.run_amaranth, bad, 3)
    raises_naming("samples", rtl_sim.run_amaranth, [b[:6] for b in words.bursts()], 3)
    raises_naming("ok", rtl_sim.datapath_inputs, words, ok=[1])
    raises_naming("ok", rtl_sim.datapath_inputs, words, ok=[1, 2, 1])
    d = rtl_sim.datapath_inputs(words, ok=np.array([True, False, True]))
    assert d["ok"].tolist() == [1, 0, 1]


def test_chip_timing_functions_check_the_chip_parameters():
    """timing(spi_div=0) divided by zero, timing(baud_div=1.5) and min_sample_period(-1, 4)
    returned figures, spi_cycles(0) said 1 clock, lfsr_timer(0) built a timer, and
    expected_stream(log, -1) dropped the last sample: each now names its argument."""
    from navgate.systems.tinykalman import rtl_sim, spi, top

    raises_naming("Mpu6500Spi: spi_div", top.timing, spi_div=0)
    raises_naming("UartPacketTx: baud_div", top.timing, baud_div=1.5)
    raises_naming("TinyKalman: sample_period", top.timing, sample_period=10)
    raises_naming("clk_hz", top.timing, clk_hz=0)
    raises_naming("Mpu6500Spi: spi_div", top.min_sample_period, -1, 4)
    raises_naming("UartPacketTx: baud_div", top.min_sample_period, 2, 0)
    raises_naming("Mpu6500Spi: spi_div", spi.spi_cycles, 0)
    raises_naming("Mpu6500Spi: spi_div", spi.spi_cycles, math.nan)
    for period in (0, 1, 2.5):
        raises_naming("lfsr_timer: period", top.lfsr_timer, period)
    raises_naming("n_samples", rtl_sim.expected_stream, [], -1)
    assert top.timing()["slack_cycles"] == 100_000 - top.timing()["busy_cycles"] > 0
