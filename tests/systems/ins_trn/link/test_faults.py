"""Fault injection: seeded, counted, and every injected corruption caught by the decoder."""

from __future__ import annotations

import pytest

from navgate.systems.ins_trn.link import faults, frames


def _run(inj, n=400):
    dec = frames.Decoder()
    got = []
    for seq in range(n):
        for chunk in inj(frames.encode(2, seq, {"seq": seq, "pad": list(range(20))})):
            got += dec.feed(chunk)
    return dec, got


def test_corruption_caught_and_clean_frames_kept():
    inj = faults.FaultInjector(seed=3, flip_rate=1e-3)
    dec, got = _run(inj)
    corrupted = inj.counts["corrupted_frames"]
    assert 0 < corrupted < 400
    assert len(got) == 400 - corrupted  # every clean frame arrives, no corrupted one does
    assert sum(dec.bad.values()) >= corrupted
    assert all(f.body["seq"] == f.seq for f in got)


def test_same_seed_same_faults():
    a = faults.FaultInjector(seed=7, flip_rate=1e-3, truncate=0.05, duplicate=0.05, reorder=0.05)
    b = faults.FaultInjector(seed=7, flip_rate=1e-3, truncate=0.05, duplicate=0.05, reorder=0.05)
    assert [f.seq for f in _run(a)[1]] == [f.seq for f in _run(b)[1]]
    assert a.counts == b.counts and a.counts["reordered"] > 0


def test_duplicate_reorder_drop():
    seqs = [f.seq for f in _run(faults.FaultInjector(seed=1, duplicate=1.0), 10)[1]]
    assert seqs == [s for s in range(10) for _ in (0, 1)]
    inj = faults.FaultInjector(seed=1, reorder=1.0)
    seqs = [f.seq for f in _run(inj, 4)[1]]
    assert seqs == [1, 0, 3, 2]
    inj = faults.FaultInjector(drop=True)
    assert _run(inj, 5)[1] == [] and inj.counts == {"dropped": 5}


def test_bad_rate():
    with pytest.raises(ValueError, match="flip_rate"):
        faults.FaultInjector(flip_rate=2.0)
