"""The float32 engines' profile in the PL's entry format (pl_profile) against the float64
profile buffer: the same checks and entries, fields within their float32 / millisecond
rounding, corrections applied only to the entries they postdate, restarts, wrap-around."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navgate.systems.ins_trn.pl_profile import (
    TIME_WRAP_MS,
    PlProfileBuffer,
    ProfileFifoModel,
    decode_entries,
    entry_words,
)
from navgate.systems.ins_trn.profile_manager import pack_entry
from navgate.trn.profile import ProfileBuffer


def _pair(spacing=30.0):
    return ProfileBuffer(min_spacing_m=spacing), PlProfileBuffer(ProfileFifoModel(64),
                                                                 min_spacing_m=spacing)


def _sample(k, t0=1000.0, speed=50.0, dt=0.7):
    """A straight track at ``speed`` m/s heading north-east, one sample every ``dt`` s."""
    t = t0 + k * dt
    return dict(time=t, h_baro=800.0 + 3.0 * math.sin(k), slant_range=300.0 + 5.0 * math.cos(k),
                range_valid=True, roll=0.02, pitch=-0.01,
                pos_n=-4000.0 + speed * 0.8 * (t - t0), pos_e=2500.0 + speed * 0.6 * (t - t0))


def _half_ulp(x):
    return 0.5 * np.spacing(np.abs(np.asarray(x, np.float32))).astype(np.float64)


def test_entry_words_are_the_pl_format():
    w = entry_words(123.456, -9876.5, 4321.25, 12.3456)
    assert w[0] == int(np.float32(123.456).view(np.uint32))
    assert w[1] == int(np.float32(-9876.5).view(np.uint32))
    assert w[3] == 12346 | 1 << 24  # whole milliseconds, valid bit 24
    assert pack_entry(*w[:3], w[3] & 0xFFFFFF, 1) == sum(x << 32 * i for i, x in enumerate(w))
    h, n, e, t = decode_entries(np.array([w]), now_s=20.0)
    assert (h[0], n[0], e[0]) == (float(np.float32(123.456)), -9876.5, 4321.25)
    assert t[0] == pytest.approx(12.346, abs=1e-12)


def test_time_stamps_unwrap_against_the_correlation_time():
    wrap_s = TIME_WRAP_MS / 1000.0  # 4.66 h
    t_entry = 3 * wrap_s - 2.5  # just before the third wrap
    w = entry_words(0.0, 0.0, 0.0, t_entry)
    _, _, _, t = decode_entries(np.array([w]), now_s=3 * wrap_s + 1.0)
    assert t[0] == pytest.approx(t_entry, abs=5e-4)  # the stamp 2.5 s before the wrap


def test_profile_equals_float64_buffer_within_float32_rounding():
    ref, pl = _pair()
    for k in range(90):  # more than the 64 entries: the FIFO keeps the newest
        assert ref.add(**_sample(k)) == pl.add(**_sample(k))
    a, b = ref.snapshot(), pl.snapshot(now=_sample(89)["time"])
    assert len(a) == len(b) == 64 == pl.count
    for f in ("h_terrain", "pos_n", "pos_e"):
        x, y = getattr(a, f), getattr(b, f)
        assert np.all(np.abs(x - y) <= _half_ulp(x)), f
        assert not np.array_equal(x, y)  # really the float32 entries
    assert np.all(np.abs(a.time - b.time) <= 5e-4)


def test_corrections_move_only_the_entries_they_postdate():
    ref, pl = _pair()
    fixes = {20: (12.0, -7.0, 0.3, -0.2), 45: (-3.0, 4.0, -0.1, 0.05)}
    for k in range(60):
        s = _sample(k)
        ref.add(**s), pl.add(**s)
        if k in fixes:
            ref.shift(*fixes[k], now=s["time"])
            pl.shift(*fixes[k], now=s["time"])
    a, b = ref.snapshot(), pl.snapshot(now=_sample(59)["time"])
    # tolerance: the float32 rounding of the stored position, and the velocity correction
    # times the time stamp's rounding to a millisecond
    dv = sum(abs(f[2]) + abs(f[3]) for f in fixes.values())
    for f in ("pos_n", "pos_e"):
        x, y = getattr(a, f), getattr(b, f)
        assert np.all(np.abs(x - y) <= _half_ulp(x) + dv * 5e-4 + 1e-9), f
    # entries after the last fix carry no correction, entries before both carry both
    raw = _pair()[1]
    for k in range(60):
        raw.add(**_sample(k))
    c = raw.snapshot(now=_sample(59)["time"])
    assert np.array_equal(b.pos_n[46:], c.pos_n[46:])
    assert np.all(b.pos_n[:21] != c.pos_n[:21])


def test_restart_after_a_gap_reads_only_the_new_profile():
    ref, pl = _pair()
    for k in range(10):
        ref.add(**_sample(k)), pl.add(**_sample(k))
    late = [_sample(k, t0=1100.0) for k in range(3)]  # 100 s later: a gap
    for s in late:
        ref.add(**s), pl.add(**s)
    assert pl.count == len(ref.snapshot()) == 3
    b = pl.snapshot(now=late[-1]["time"])
    assert np.allclose(b.time, [s["time"] for s in late], atol=5e-4)
    assert pl.counts == ref.counts and pl.counts["profile restarted after a gap"] == 1
