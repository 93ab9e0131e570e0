"""Altitude profile buffer: seed-000 validity checks, circular order, INS-correction shifts."""

import math

import numpy as np

from navgate.trn.profile import (
    ACCEPTED,
    REJECT_BARO,
    REJECT_NOT_MOVING,
    REJECT_RANGER,
    REJECT_TILT,
    ProfileBuffer,
)


def offer(buf, t, n, e=0.0, h_baro=1000.0, rng=300.0, valid=True, roll=0.0, pitch=0.0):
    return buf.add(time=t, h_baro=h_baro, slant_range=rng, range_valid=valid, roll=roll,
                   pitch=pitch, pos_n=n, pos_e=e)


def test_terrain_height_is_baro_minus_agl_with_tilt_correction():
    buf = ProfileBuffer()
    roll = math.radians(10)
    assert offer(buf, 0.0, 0.0, rng=300.0 / math.cos(roll), roll=roll) == ACCEPTED
    assert buf.snapshot().h_terrain[0] == 700.0


def test_validity_checks_are_applied_and_counted():
    buf = ProfileBuffer(min_spacing_m=30.0)
    assert offer(buf, 0.0, 0.0) == ACCEPTED
    assert offer(buf, 0.1, 10.0) == REJECT_NOT_MOVING
    assert offer(buf, 0.2, 40.0, h_baro=math.nan) == REJECT_BARO
    assert offer(buf, 0.3, 40.0, valid=False) == REJECT_RANGER
    assert offer(buf, 0.4, 40.0, rng=math.nan) == REJECT_RANGER
    assert offer(buf, 0.5, 40.0, roll=math.radians(25)) == REJECT_TILT
    assert offer(buf, 0.6, 40.0) == ACCEPTED
    assert buf.counts == {ACCEPTED: 2, REJECT_NOT_MOVING: 1, REJECT_BARO: 1, REJECT_RANGER: 2,
                          REJECT_TILT: 1}


def test_circular_buffer_keeps_the_newest_64_in_order():
    buf = ProfileBuffer()
    for k in range(100):
        offer(buf, k * 0.5, k * 30.0, h_baro=1000.0 + k)
    snap = buf.snapshot()
    assert len(snap) == 64 and buf.count == 64
    assert np.array_equal(snap.time, np.arange(36, 100) * 0.5)
    assert snap.track_length_m == 63 * 30.0


def test_gap_restarts_the_profile():
    buf = ProfileBuffer(max_gap_s=5.0)
    for k in range(10):
        offer(buf, k * 0.5, k * 30.0)
    offer(buf, 20.0, 2000.0)
    assert buf.count == 1


def test_shift_applies_a_lagged_correction():
    buf = ProfileBuffer()
    for k in range(5):
        offer(buf, float(k), k * 30.0)
    buf.shift(-10.0, 4.0, d_vnorth=-1.0, d_veast=0.0, now=4.0)
    snap = buf.snapshot()
    # sample at time t moves by d - (now - t) d_v
    assert np.allclose(snap.pos_n, np.arange(5) * 30.0 - 10.0 + (4.0 - np.arange(5)) * 1.0)
    assert np.allclose(snap.pos_e, 4.0)
