"""Seed 001 TinyKalman: MPU-6500 registers, CORDIC angles, the shift filter, UART packets."""

import math

import numpy as np
import pytest

from navgate.numerics.cordic import cordic_error_bound, cordic_gain
from navgate.systems.tinykalman import model as tk

N = 20000


@pytest.fixture()
def rng():
    return np.random.default_rng(1234)


# ------------------------------------------------------------------------------- MPU-6500


def test_who_am_i_and_config_over_spi():
    dev = tk.Mpu6500()
    assert dev.transfer(bytes([tk.SPI_READ | tk.REG["WHO_AM_I"], 0]))[1] == 0x70
    # write GYRO_CONFIG.FS_SEL = 1 (+-500 dps) and ACCEL_CONFIG.FS_SEL = 2 (+-8 g)
    dev.transfer(bytes([tk.REG["GYRO_CONFIG"], 1 << 3]))
    dev.transfer(bytes([tk.REG["ACCEL_CONFIG"], 2 << 3]))
    assert (dev.gyro_fs, dev.accel_fs) == (1, 2)
    # WHO_AM_I is read-only
    dev.transfer(bytes([tk.REG["WHO_AM_I"], 0x12]))
    assert dev.regs[tk.REG["WHO_AM_I"]] == 0x70


@pytest.mark.parametrize("gfs, afs", [(0, 0), (1, 1), (3, 3)])
def test_burst_scaling_and_saturation(gfs, afs):
    dev = tk.Mpu6500()
    dev.transfer(bytes([tk.REG["GYRO_CONFIG"], gfs << 3, afs << 3]))  # auto-increment
    dev.set_sample([0.5, -1.0, 0.25], [10.0, -100.0, 3.3], temp_c=30.0)
    w = tk.decode_burst(dev.read_burst())
    sa, sg = tk.ACCEL_SENSITIVITY[afs], tk.GYRO_SENSITIVITY[gfs]
    assert (w["ax"], w["ay"], w["az"]) == (round(0.5 * sa), round(-1.0 * sa), round(0.25 * sa))
    assert (w["gx"], w["gy"], w["gz"]) == (round(10 * sg), round(-100 * sg), round(3.3 * sg))
    assert w["temp"] == round(9.0 * 333.87)
    assert dev.saturated == 0
    dev.set_sample([3.0, 0, 0], [0, 0, 300.0])  # beyond +-2 g / +-250 dps at FS 0
    w = tk.decode_burst(dev.read_burst())
    if gfs == 0:
        assert w["ax"] == 32767 and w["gz"] == 32767 and dev.saturated == 2


def test_decode_burst_rejects_wrong_length():
    with pytest.raises(ValueError):
        tk.decode_burst(bytes(13))


# ------------------------------------------------------------------------------- CORDIC


def halving_term(r_half):
    """The roll CORDIC sees (az >>> 1, ay >>> 1): each coordinate moves by < 1 LSB (the
    floor) from (az/2, ay/2), so the vector moves < sqrt(2) and its angle by
    asin(sqrt(2) / (r_half - sqrt(2)))."""
    return math.asin(math.sqrt(2) / (r_half - math.sqrt(2)))


def test_roll_cordic_within_derived_bound(rng):
    """roll_m = atan2(ay, az) within: numerics' worst-case bound for 16 iterations on 16-bit
    inputs of magnitude >= r/2 (16-bit binary angles: residual, table rounding, truncation)
    + the halving term + half an output LSB of rounding of the reference (none: we compare
    exact values). Random words with |(ay, az)| in [8192, 32767] (0.5 g to 2 g)."""
    r = rng.uniform(8192, 32767, N)
    th = rng.uniform(-math.pi, math.pi, N)
    ay = np.round(r * np.sin(th)).astype(np.int64)
    az = np.round(r * np.cos(th)).astype(np.int64)
    roll, _, _, _ = tk.accel_angles(np.zeros(N, np.int64), ay, az)
    err = np.angle(np.exp(1j * (roll * (2 * math.pi / 65536) - np.arctan2(ay, az))))
    r_half = (8192 - 1) / 2
    bound = cordic_error_bound(16, 16, 16, min_magnitude=r_half - math.sqrt(2)) + halving_term(
        r_half)
    assert np.max(np.abs(err)) <= bound
    # a worst-case bound that still means something (< 0.25 deg; measured errors are a few
    # binary-angle LSBs of 0.0055 deg), and the comparison is not trivially exact
    assert bound < math.radians(0.25)
    assert np.max(np.abs(err)) > 2 * math.pi / 65536


def test_pitch_magnitude_approximation_within_derived_bound(rng):
    """pitch_m vs atan2(-ax, sqrt(ay^2 + az^2)), |a| in [8192, 23170] (0.5 g .. 1.41 g).

    Terms (radians):
    1. gain mismatch: y is scaled by c_y = 0.8125 and x by K_16 / 2, so the CORDIC sees
       tan(p') = (c_y / (K/2)) tan(p); max_p |atan(c tan p) - p| = atan((1-c)/(2 sqrt(c)))
       (at tan p = 1/sqrt(c)), with c = 0.8125 / (K/2);
    2. y truncation: (ax>>>1) + (ax>>>2) + (ax>>>4) is 0.8125 ax minus < 3 LSB;
    3. magnitude error of the roll CORDIC: its input halving moves the vector < sqrt(2), then
       each of the 15 truncated steps adds a vector < sqrt(2), each amplified by at most K by
       the remaining steps: |mag - K |(ay, az)|/2| < K sqrt(2) 16; the final cos(residual)
       factor is > 1 - 1e-9. Terms 2 and 3 move the pitch input by d < 3 + 16 sqrt(2) K,
       turning it by <= asin(d / (r_p - d)) with r_p the pitch input magnitude;
    4. the pitch CORDIC's own worst case for magnitude >= r_p - d.
    """
    K = cordic_gain(16)
    c = 0.8125 / (K / 2)
    gain_term = math.atan((1 - c) / (2 * math.sqrt(c)))
    r = rng.uniform(8192, 23170, N)
    pitch = rng.uniform(-math.pi / 2, math.pi / 2, N)
    roll = rng.uniform(-math.pi, math.pi, N)
    ax = np.round(-r * np.sin(pitch)).astype(np.int64)
    ay = np.round(r * np.cos(pitch) * np.sin(roll)).astype(np.int64)
    az = np.round(r * np.cos(pitch) * np.cos(roll)).astype(np.int64)
    _, pm, _, sat = tk.accel_angles(ax, ay, az)
    assert not sat.any()
    want = np.arctan2(-ax, np.hypot(ay, az))
    err = np.abs(pm * (2 * math.pi / 65536) - want)
    r_p = 0.8125 * 8192 - 3  # smallest pitch-input magnitude (both inputs ~ K/2 |a|)
    d = 3 + 16 * math.sqrt(2) * K
    bound = (gain_term + math.asin(d / (r_p - d))
             + cordic_error_bound(16, 16, 16, min_magnitude=r_p - d))
    assert np.max(err) <= bound
    # the approximation is visible: at 45 deg the gain term dominates
    assert np.max(err) > 0.5 * gain_term
    assert bound < math.radians(1.0)


# ------------------------------------------------------------------------------- filter


def test_static_convergence_to_the_floor_window():
    """Constant measurement, zero rate: e = meas - angle obeys e' = e - floor(e / 64), which
    stops exactly when 0 <= e <= 63 (floor(e/64) = 0) and keeps moving otherwise. From
    e0 = 20000 it needs at most 64 ln(20000 / 64) + 64 ~ 432 steps."""
    angle = 0
    for meas in (20000, -15000, 5):
        for _ in range(500):
            angle = int(tk.kalman_step(angle, 0, meas))
        e = meas - angle
        assert 0 <= e <= 63


def test_wraparound_takes_the_short_way():
    """Binary angles wrap: at 179 deg estimate, a -179 deg measurement is 2 deg away, and the
    16-bit innovation makes the estimate move forward through 180 deg, not back through 0."""
    a = round(179 * tk.BAM_PER_DEG)
    m = round(-179 * tk.BAM_PER_DEG)
    a1 = int(tk.kalman_step(a, 0, m))
    assert a1 > a or a1 < 0  # moved toward +180 (or wrapped past it)
    for _ in range(2000):
        a = int(tk.kalman_step(a, 0, m))
    assert 0 <= int(tk._wrap16(m - a)) <= 63


def tilt_profile(rate_dps=10.0, hold_s=3.0, ramp_s=3.0, hz=100.0):
    """A level sensor tilting in roll at rate_dps for ramp_s, then holding: MPU words."""
    dev = tk.Mpu6500()
    n_ramp, n_hold = int(ramp_s * hz), int(hold_s * hz)
    rows = []
    for k in range(n_ramp + n_hold):
        moving = k < n_ramp
        roll = math.radians(rate_dps * min(k + 1, n_ramp) / hz)
        g = (0.0, math.sin(roll), math.cos(roll))
        dev.set_sample(g, (rate_dps if moving else 0.0, 0.0, 0.0))
        w = tk.decode_burst(dev.read_burst())
        rows.append((w["ax"], w["ay"], w["az"], w["gx"], w["gy"]))
    return np.array(rows), n_ramp


def test_filter_on_a_tilt_profile():
    """Ramp at 10 deg/s, 100 Hz: the true increment is delta = 0.1 deg = 18.2 binary-angle
    LSB per sample, but the gyro word (1310) >>> 6 adds r = 20 LSB: the shift bakes in a
    1.12x scale error. The lag e = meas - angle then obeys e' = e + delta - r -
    floor((e + delta - r)/64), whose fixed points lie in [63 (delta - r), 63 (delta - r) + 63]
    (the floor window) -- the estimate *leads* the truth by ~1/3 deg. The CORDIC measurement
    error (< 0.015 deg = 3 LSB here, previous test's bound) widens that by 3 LSB either side.
    After the ramp: back into [0, 63] (+-3) of the measurement."""
    rows, n_ramp = tilt_profile()
    roll, pitch, roll_m, pitch_m = tk.run_sequence(*rows.T)
    delta = 0.1 * tk.BAM_PER_DEG
    r = 1310 >> 6
    lo, hi = 63 * (delta - r) - 3, 63 * (delta - r) + 63 + 3
    e_ramp = roll_m[n_ramp - 40:n_ramp] - roll[n_ramp - 40:n_ramp]  # after 260 samples
    assert np.all((e_ramp >= lo) & (e_ramp <= hi))
    assert np.mean(e_ramp) < -50  # the lead is real, not within the floor window
    e_hold = roll_m[-50:] - roll[-50:]
    assert np.all((e_hold >= -3) & (e_hold <= 66))
    assert np.all(np.abs(pitch[-50:]) <= 66)
    # and the steady estimate is the 30 deg tilt
    assert abs(tk.bam_to_deg(roll[-1]) - 30.0) < 0.4


def test_filter_smooths_accelerometer_noise():
    """With white accelerometer noise and no motion, the estimate is a first-order low-pass
    of the measurement with pole 63/64: its noise variance is (1/64)^2 / (1 - (63/64)^2)
    = 1/127 of the input's, i.e. sigma / 11.3 (plus the <= 64 LSB floor bias window)."""
    rng = np.random.default_rng(5)
    n = 20000
    sigma_g = 0.02
    ax = np.round(rng.normal(0, sigma_g, n) * 16384).astype(np.int64)
    ay = np.round(rng.normal(0, sigma_g, n) * 16384).astype(np.int64)
    az = np.round((1 + rng.normal(0, sigma_g, n)) * 16384).astype(np.int64)
    roll, _, roll_m, _ = tk.run_sequence(ax, ay, az, np.zeros(n, np.int64), np.zeros(n,
                                                                                    np.int64))
    s_in = np.std(roll_m[1000:])
    s_out = np.std(roll[1000:])
    ratio = s_in / s_out
    # expected sqrt(127) = 11.3; the estimate of a std from 19000 correlated samples (effective
    # ~19000/127 = 150 independent) has relative sd 1/sqrt(2*150) = 6 %; allow 4 sd = 24 %
    assert 11.27 * 0.76 < ratio < 11.27 * 1.24


def test_device_step_matches_vectorised_sequence():
    rows, _ = tilt_profile(rate_dps=25.0, hold_s=0.5, ramp_s=1.0)
    roll, pitch, _, _ = tk.run_sequence(*rows.T)
    dev = tk.TinyKalman()
    stream = b""
    for ax, ay, az, gx, gy in rows:
        burst = b"".join(int(v).to_bytes(2, "big", signed=True)
                         for v in (ax, ay, az, 0, gx, gy, 0))
        stream += dev.step(burst)
    decoded, stats = tk.decode_stream(stream)
    assert stats.packets == len(rows) and stats.skipped_bytes == 0
    assert [d[0] for d in decoded] == roll.tolist()
    assert [d[1] for d in decoded] == pitch.tolist()


# ------------------------------------------------------------------------------- UART


def test_packet_layout():
    assert tk.encode_packet(16384, -1) == bytes([0xDE, 0xAD, 0x40, 0x00, 0xFF, 0xFF])
    with pytest.raises(ValueError):
        tk.encode_packet(40000, 0)


def test_decoder_resync_and_chunking(rng):
    words = [(int(a), int(b)) for a, b in rng.integers(-32768, 32768, (200, 2))]
    words[10] = (-8531, -8531)  # 0xDEAD inside the payload
    stream = b"".join(tk.encode_packet(*w) for w in words)
    noisy = b"\x01\x02\xde" + stream + b"\xde\xad\x00"
    dec = tk.PacketDecoder()
    got = []
    cuts = sorted(rng.integers(0, len(noisy), 40).tolist())
    for a, b in zip([0] + cuts, cuts + [len(noisy)], strict=True):
        got += dec.feed(noisy[a:b])
    dec.close()
    assert got == words
    assert dec.stats.skipped_bytes == 3
    assert dec.stats.trailing_bytes == 3


def test_uart_8n1_bits_and_timing():
    pkt = tk.encode_packet(1234, -4321)
    bits = tk.uart_frame_bits(pkt)
    assert len(bits) == 60 and bits[0] == 0 and bits[9] == 1
    assert bits[1:9] == [0, 1, 1, 1, 1, 0, 1, 1]  # 0xDE LSB first
    assert tk.uart_decode_bits(bits) == pkt
    assert len(bits) / tk.BAUD < 0.010  # fits in the 100 Hz sample period
    bad = list(bits)
    bad[9] = 0
    with pytest.raises(ValueError):
        tk.uart_decode_bits(bad)
