"""Checks shared by the tests that fly a simulated PL engine (``rtl``, ``fpga-sim``) against
the fp32 engine, which it must equal bit for bit: the ``against_fp32`` fixture."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from navgate.numerics.fp32 import float_to_bits
from navgate.systems.ins_trn.pl.fp32_program import STATE_REGS
from navgate.systems.ins_trn.ps import flight
from navgate.systems.ins_trn.ps.navigator import Navigator, engine_setup
from navgate.systems.ins_trn.ps.pl_interface import make_engine
from navgate.trn.dem import Dem


def _same_word(x: float, y: float) -> bool:
    return float_to_bits(x) == float_to_bits(y) or (math.isnan(x) and math.isnan(y))


def same_registers(engs: dict, name: str):
    """Every state register (nav, compensation, biases, P and its compensation words) of the
    ``name`` engine is the fp32 engine's word."""
    a, b = engs["fp32"].m, engs[name].m
    diff = [n for n in STATE_REGS if not _same_word(a.get(n), b.get(n))]
    assert not diff, diff[:8]


def fly(name: str, duration: float, seed: int = 1, **options):
    """The default mission (INS+TRN) through the fp32 engine and the ``name`` engine (made
    with the keyword arguments ``options``): every logged state, sigma and P_NE word, every
    update and fix decision and every register at the end equal; (stream, cfg, the ``name``
    run, {engine name: engine})."""
    dem = Dem.default()
    cfg = flight.FlightConfig(duration_s=duration, seed=seed)
    _, _, stream = flight.record_stream(dem, cfg)
    runs, engs = {}, {}
    for eng_name in ("fp32", name):
        eng = make_engine(eng_name, engine_setup(stream.header, cfg),
                          **(options if eng_name == name else {}))
        nav = Navigator(eng, cfg, t0=stream.header["t0"], dem=dem, use_trn=True)
        runs[eng_name], engs[eng_name] = nav.run(stream), eng
    a, b = runs["fp32"], runs[name]
    assert np.array_equal(a.nav, b.nav) and np.array_equal(a.sigma, b.sigma)
    assert np.array_equal(a.p_ne, b.p_ne)
    assert a.accepted == b.accepted and a.rejected == b.rejected
    assert [f["applied"] for f in a.fixes] == [f["applied"] for f in b.fixes]
    same_registers(engs, name)
    assert a.hardware == {} and b.hardware
    return stream, cfg, b, engs


def directed_updates(engs: dict, name: str):
    """After a flight: TRN updates applied, rejected by the gate and with a singular S (their
    outcomes, NIS and corrections equal, every register after each), then the integrity
    monitor's covariance inflation (a PS register write)."""
    cases = [((3.0, -2.0), np.diag([25.0, 25.0]), 0.05),
             ((5000.0, 4000.0), np.diag([1.0, 1.0]), 0.0),
             ((1.0, 1.0), np.full((2, 2), 1e12), 0.0)]  # S rounds to singular
    reasons = []
    for y, cov, lag in cases:
        a = engs["fp32"].update_trn(np.array(y), cov, lag)
        b = engs[name].update_trn(np.array(y), cov, lag)
        assert a.accepted == b.accepted and a.reason == b.reason
        assert _same_word(a.nis, b.nis)
        assert np.array_equal(a.correction, b.correction)
        reasons.append(a.reason if not a.accepted else "applied")
        same_registers(engs, name)
    assert reasons[0] == "applied" and "gate" in reasons[1] and "positive" in reasons[2], \
        reasons
    for eng in engs.values():
        eng.inflate_p_horizontal(np.array([[400.0, 10.0], [10.0, 300.0]]))
    same_registers(engs, name)


@pytest.fixture
def against_fp32():
    """``fly``, ``directed_updates`` and ``same_registers`` above."""
    return SimpleNamespace(fly=fly, directed_updates=directed_updates,
                           same_registers=same_registers)
