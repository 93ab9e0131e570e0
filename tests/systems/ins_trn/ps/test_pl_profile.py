"""The float32 engines' profile in the PL's entry format (pl_profile) against the float64
profile buffer: the same checks and entries, fields within their float32 rounding, time
stamps exact (IMU sample counts), corrections applied only to the entries they postdate,
restarts, wrap-around of the 24-bit time stamp."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navgate.systems.ins_trn.pl.profile_manager import pack_entry
from navgate.systems.ins_trn.ps.pl_profile import (
    TIME_WRAP,
    PlProfileBuffer,
    ProfileFifoModel,
    decode_entries,
    entry_words,
)
from navgate.trn.profile import ProfileBuffer

T0, DT = 1000.0, 1.0 / 400.0
EVERY = 280  #: IMU samples between ranger samples (0.7 s)


def time_of(k):
    return T0 + int(k) * DT


def _pair(spacing=30.0):
    return ProfileBuffer(min_spacing_m=spacing), PlProfileBuffer(ProfileFifoModel(64), time_of,
                                                                 min_spacing_m=spacing)


def _bits(x):
    return int(np.float32(x).view(np.uint32))


def _sample(j, k0=0, speed=50.0):
    """Ranger sample j of a straight track at ``speed`` m/s heading north-east: the profile
    checks' arguments and the correlator's sample (position words, IMU sample count)."""
    k = k0 + j * EVERY
    t = time_of(k)
    pn, pe = -4000.0 + speed * 0.8 * (t - T0), 2500.0 + speed * 0.6 * (t - T0)
    checks = dict(time=t, h_baro=800.0 + 3.0 * math.sin(j), slant_range=300.0 + 5 * math.cos(j),
                  range_valid=True, roll=0.02, pitch=-0.01, pos_n=pn, pos_e=pe)
    return checks, (_bits(pn), _bits(pe), k)


def _feed(ref, pl, j, **kw):
    checks, sample = _sample(j, **kw)
    a, b = ref.add(**checks), pl.add(sample=sample, **checks)
    assert a == b
    return checks, sample


def _half_ulp(x):
    return 0.5 * np.spacing(np.abs(np.asarray(x, np.float32))).astype(np.float64)


def test_entry_words_are_the_pl_format():
    w = entry_words(123.456, (_bits(-9876.5), _bits(4321.25), 24_000))
    assert w == (_bits(123.456), _bits(-9876.5), _bits(4321.25), 24_000 | 1 << 24)
    assert pack_entry(*w[:3], w[3] & 0xFFFFFF, 1) == sum(x << 32 * i for i, x in enumerate(w))
    h, n, e, t = decode_entries(np.array([w]), now_samples=30_000, time_of=time_of)
    assert (h[0], n[0], e[0]) == (float(np.float32(123.456)), -9876.5, 4321.25)
    assert t[0] == time_of(24_000)  # exactly the record time of sample count 24,000


def test_time_stamps_unwrap_against_the_sample_count():
    k = 3 * TIME_WRAP - 1000  # 1000 samples before the third wrap of the 24-bit field
    w = entry_words(0.0, (0, 0, k))
    assert w[3] & 0xFFFFFF == TIME_WRAP - 1000
    _, _, _, t = decode_entries(np.array([w]), now_samples=3 * TIME_WRAP + 500, time_of=time_of)
    assert t[0] == time_of(k)


def test_profile_equals_float64_buffer_within_float32_rounding():
    ref, pl = _pair()
    for j in range(90):  # more than the 64 entries: the FIFO keeps the newest
        _feed(ref, pl, j)
    a, b = ref.snapshot(), pl.snapshot(now_samples=89 * EVERY)
    assert len(a) == len(b) == 64 == pl.count
    for f in ("h_terrain", "pos_n", "pos_e"):
        x, y = getattr(a, f), getattr(b, f)
        assert np.all(np.abs(x - y) <= _half_ulp(x)), f
        assert not np.array_equal(x, y)  # really the float32 entries
    assert np.array_equal(a.time, b.time)


def test_corrections_move_only_the_entries_they_postdate():
    ref, pl = _pair()
    fixes = {20: (12.0, -7.0, 0.3, -0.2), 45: (-3.0, 4.0, -0.1, 0.05)}
    for j in range(60):
        checks, _ = _feed(ref, pl, j)
        if j in fixes:
            ref.shift(*fixes[j], now=checks["time"])
            pl.shift(*fixes[j], now=checks["time"])
    a, b = ref.snapshot(), pl.snapshot(now_samples=59 * EVERY)
    # the stored words are the float32 roundings; the corrections are applied in float64 in
    # both, in the same order, with the same (exact) time stamps
    for f in ("pos_n", "pos_e"):
        x, y = getattr(a, f), getattr(b, f)
        raw = np.array([_sample(j)[0][f] for j in range(60)])
        assert np.all(np.abs(x - y) <= _half_ulp(raw) * (1 + 1e-9) + 1e-9), f
    # entries after the last fix carry no correction, entries before both carry both
    _, raw = _pair()
    for j in range(60):
        checks, sample = _sample(j)
        raw.add(sample=sample, **checks)
    c = raw.snapshot(now_samples=59 * EVERY)
    assert np.array_equal(b.pos_n[46:], c.pos_n[46:])
    assert np.all(b.pos_n[:21] != c.pos_n[:21])
    lag = time_of(20 * EVERY) - c.time[:21]
    assert b.pos_n[:21] - c.pos_n[:21] == pytest.approx(12.0 - 0.3 * lag - 3.0 + 0.1 * (
        time_of(45 * EVERY) - c.time[:21]), abs=1e-9)


def test_restart_after_a_gap_reads_only_the_new_profile():
    ref, pl = _pair()
    for j in range(10):
        _feed(ref, pl, j)
    late = [_feed(ref, pl, j, k0=40_000)[0] for j in range(3)]  # 100 s later: a gap
    assert pl.count == len(ref.snapshot()) == 3
    b = pl.snapshot(now_samples=40_000 + 2 * EVERY)
    assert np.array_equal(b.time, [s["time"] for s in late])
    assert pl.counts == ref.counts and pl.counts["profile restarted after a gap"] == 1
