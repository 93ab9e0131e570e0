"""Seed 000's engines on the scheduled float32 datapath: exact cycle counts, and bit-exact
execution of every program in Amaranth simulation against the bit-true interpreter
(fp32_exec.run_bittrue), on random registers and on directed bad-input cases."""

from __future__ import annotations

import numpy as np
import pytest

from navgate.systems.ins_trn.pl.fp32_exec import run_bittrue
from navgate.systems.ins_trn.pl.fp32_program import STATE_REGS, programs, schedule_bounds
from navgate.systems.ins_trn.pl.nav_engines import (
    IMU_WORDS,
    engine_image,
    engine_programs,
    identity_p_registers,
    random_registers,
    reference_calls,
    simulate_calls,
)

#: exact cycles (first issue to last write) of each program on the banked machine with
#: 4 mul + 4 add slots and a misc slot (iterative divider and square root), 8 banks of 2 read
#: ports, split: operand port j reads read port j of a bank (navgate.opflow)
CYCLES = {"propagate": 638, "alt_gate": 55, "alt_apply": 235, "trn_gate": 142,
          "trn_apply": 276}
LAT = {"add": 8, "mul": 5, "div": 28, "sqrt": 27, "cmp": 2, "cvt": 4}  # iterative div/sqrt


def test_cycle_counts_exact_and_above_bounds():
    img = engine_image("ins_engines")
    assert {k: img.cycles(k) for k in CYCLES} == CYCLES
    for key, n in CYCLES.items():
        b = schedule_bounds(engine_programs()[key], LAT, {"add": 4, "mul": 4, "div": 1, "sqrt": 1,
                                                   "cmp": 1, "cvt": 1})
        assert n >= b["bound"]
    # targets: propagate <= 2000 cycles per IMU sample, 2-D update (both halves) <= 450
    assert CYCLES["propagate"] + 1 <= 2000
    assert CYCLES["trn_gate"] + 1 + CYCLES["trn_apply"] + 1 <= 450


def test_schedule_invariants():
    img = engine_image("ins_engines")
    for sp in img.programs.values():
        ready = {}
        seen = set()
        for s in sp.ops:
            for name, _ in s.srcs:
                if name in ready:
                    assert s.issue >= ready[name], (sp.name, s.dst)
            if s.kind != "mov":
                ready[s.dst] = s.ready
            key = (s.unit, s.inst, s.issue)
            assert key not in seen
            seen.add(key)
        # a committed register is written no earlier than its last read in the program
        last_read = {}
        for s in sp.ops:
            for name, _ in s.srcs:
                last_read[name] = max(last_read.get(name, -1), s.issue)
        for s in sp.ops:
            if s.kind == "mov":
                assert s.write >= last_read.get(s.dst, -1)
        for tmp, reg in sp.direct.items():
            w = next(s.write for s in sp.ops if s.dst == tmp)
            assert w >= last_read.get(reg, -1)


def _reference_sequence(regs, calls):
    return reference_calls(regs, calls)


def _check(regs, calls, which="ins_engines"):
    img = engine_image(which)
    got = simulate_calls(img, regs, calls)
    exp = _reference_sequence(regs, calls)
    for (key, _), (g_regs, g_out, cyc), (e_regs, e_out) in zip(calls, got, exp, strict=True):
        assert cyc == img.cycles(key) + 1
        bad = [n for n in g_regs if g_regs[n] != e_regs[n]]
        assert not bad, (key, bad[:8])
        assert g_out == e_out, key
    return got, exp


def test_all_programs_bit_exact_random_amaranth():
    rng = np.random.default_rng(10)
    img = engine_image("ins_engines")
    names = [n for n in img.layout.fixed if not n.startswith("c:")]
    regs = random_registers(rng, names)
    imu = random_registers(rng, IMU_WORDS)
    calls = [("propagate", imu), ("alt_gate", {}), ("alt_apply", {}), ("trn_gate", {}),
             ("trn_apply", {})]
    got, _ = _check(regs, calls)
    # the programs did change the state (not a vacuous comparison)
    assert sum(got[0][0][n] != regs[n] for n in STATE_REGS) > 200


def _plain_state(rng):
    """A state where the update programs are meaningful: P the identity."""
    img = engine_image("ins_engines")
    return identity_p_registers(rng, [n for n in img.layout.fixed if not n.startswith("c:")])


def test_singular_s_rejected_bit_exact():
    rng = np.random.default_rng(11)
    regs, f = _plain_state(rng)
    for i in range(15):
        regs[f"P{i}_{i}"] = f(0.0)
    calls = [("trn_gate", {"r00": f(0.0), "r01": f(0.0), "r11": f(0.0), "gate": f(9.0)}),
             ("alt_gate", {"r": f(0.0), "gate": f(9.0)})]
    got, _ = _check(regs, calls)
    assert got[0][1]["positive"] == 0 and got[1][1]["positive"] == 0


def test_overflow_to_infinity_bit_exact():
    rng = np.random.default_rng(12)
    regs, f = _plain_state(rng)
    regs["vN"] = f(3.0e38)
    regs["P3_3"] = f(3.0e38)
    regs["q_vel"] = f(3.0e38)
    calls = [("propagate", random_registers(rng, IMU_WORDS))]
    got, _ = _check(regs, calls)
    words = got[0][0]
    assert any(words[n] in (0x7F800000, 0xFF800000) for n in STATE_REGS)


@pytest.mark.slow
def test_update_programs_bit_exact_more_seeds():
    for seed in range(20, 24):
        rng = np.random.default_rng(seed)
        img = engine_image("ins_engines")
        names = [n for n in img.layout.fixed if not n.startswith("c:")]
        regs = random_registers(rng, names)
        calls = [("propagate", random_registers(rng, IMU_WORDS)),
                 ("propagate", random_registers(rng, IMU_WORDS)),
                 ("alt_gate", {}), ("alt_apply", {}), ("trn_gate", {}), ("trn_apply", {})]
        _check(regs, calls)


def _verilator_run(img, seed: int, name: str):
    """Every program of ``img`` on random registers through the emitted Verilog in Verilator
    (the harness: every register and output read back and compared bit for bit); the calls'
    run cycles as measured and as scheduled. The native back end
    (``simulate_native_stream``): its model of the default
    image is the one ``fly --engine rtl`` and test_rtl_engine.py run, so the suite builds
    ins_engines once (issue 32); every input is offered at once and every output taken, as
    the cocotb harness would with no random gaps."""
    from navgate.gateware import verify as V
    from navgate.gateware.native_stream import simulate_native_stream
    from navgate.opflow.machine import ScheduledMachineStream
    from navgate.systems.ins_trn.pl.nav_engines import command_vectors, stream_model

    rng = np.random.default_rng(seed)
    names = [n for n in img.layout.fixed if not n.startswith("c:")]
    regs = random_registers(rng, names)
    calls = [("propagate", random_registers(rng, IMU_WORDS)), ("alt_gate", {}),
             ("alt_apply", {}), ("trn_gate", {}), ("trn_apply", {}),
             ("propagate", random_registers(rng, IMU_WORDS))]
    vec = command_vectors(img, regs, calls)
    res = V.verify(ScheduledMachineStream(img), stream_model(img), vec,
                   backend=simulate_native_stream, name=name, keep_outputs=True)
    res.assert_ok()
    runs = np.flatnonzero(vec["cmd"] == 2)
    return [int(res.outputs["cycles"][k]) for k in runs], [k for k, _ in calls]


def test_ins_engines_bit_exact_verilator():
    """The emitted Verilog of ins_engines (command-stream wrapper) in Verilator through the
    harness: every program on random registers, every register and output read back."""
    cycles, keys = _verilator_run(engine_image("ins_engines"), 5, "ins_engines")
    assert cycles == [CYCLES[k] + 1 for k in keys]


@pytest.mark.slow
def test_ins_engines_true_dual_port_banks_bit_exact_verilator():
    """The true-dual-port bank option (every bank's write port and read port 0 on one
    address; docs/seed000-engines.md §7) on ins_engines in Verilator: every program on
    random registers bit-exact, and every run's cycles those of its schedule."""
    from dataclasses import replace

    from navgate.systems.ins_trn.pl.nav_engines import ENGINE_UNITS

    img = engine_image("ins_engines", replace(ENGINE_UNITS, split_ports=False,
                                              shared_write_port=True))
    cycles, keys = _verilator_run(img, 6, "ins_engines_tdp")
    assert cycles == [img.cycles(k) + 1 for k in keys]
    assert img.cycles("trn_apply") > CYCLES["trn_apply"]  # port-bound (§7)


def test_split_halves_compose_to_propagate():
    """ins_mechanization then covariance_propagator (each from the same starting state, the
    exported temporaries passed on) give the propagate program's result bit for bit."""
    allp = engine_programs()
    rng = np.random.default_rng(4)
    regs = random_registers(rng, STATE_REGS)
    imu = {n: float(rng.integers(-32768, 32768)) for n in IMU_WORDS}
    full, _, _ = run_bittrue(allp["propagate"], dict(regs), imu)
    m_new, m_out, _ = run_bittrue(allp["mechanization"], dict(regs), imu)
    cov_in = {n: np.uint32(m_out[n][0]) for n in allp["covariance"].inputs}
    c_new, _, _ = run_bittrue(allp["covariance"], dict(regs), cov_in)
    assert set(allp["mechanization"].commit).isdisjoint(allp["covariance"].commit)
    assert len(allp["mechanization"].commit) + len(allp["covariance"].commit) == \
        len(allp["propagate"].commit)
    comb = dict(regs)
    comb.update({k: int(m_new[k][0]) for k in allp["mechanization"].commit})
    comb.update({k: int(c_new[k][0]) for k in allp["covariance"].commit})
    assert {n: int(full[n][0]) for n in STATE_REGS} == comb
    assert sum(comb[n] != regs[n] for n in STATE_REGS) > 200


def test_mechanization_block_bit_exact_amaranth():
    img = engine_image("ins_mechanization")
    assert img.cycles("mechanization") == 513
    rng = np.random.default_rng(13)
    names = [n for n in img.layout.fixed if not n.startswith("c:")]
    _check(random_registers(rng, names), [("mechanization", {})], "ins_mechanization")


@pytest.mark.slow
def test_covariance_block_bit_exact_amaranth():
    img = engine_image("covariance_propagator")
    assert img.cycles("covariance") == 479
    rng = np.random.default_rng(14)
    names = [n for n in img.layout.fixed if not n.startswith("c:")]
    _check(random_registers(rng, names), [("covariance", {})], "covariance_propagator")


@pytest.mark.parametrize("pair", [("alt_gate", "alt_apply"), ("trn_gate", "trn_apply")])
def test_reuse_gate_bit_identical(pair):
    """The apply half reading the gate half's committed results gives the original apply
    half's registers and outputs bit for bit."""
    g, a = pair
    orig, new = programs(), engine_programs()
    assert len(new[a].ops) < len(orig[a].ops)
    rng = np.random.default_rng(7)
    names = list(dict.fromkeys(list(orig[g].inputs) + list(orig[a].inputs)))
    regs = random_registers(rng, list(STATE_REGS) + names)
    ins = {n: np.uint32(regs[n]) for n in names}
    state = {n: regs[n] for n in STATE_REGS}
    exp_state, exp_out, _ = run_bittrue(orig[a], state, {n: ins[n] for n in orig[a].inputs})
    g_state, _, _ = run_bittrue(new[g], state, {n: ins[n] for n in new[g].inputs})
    ins2 = dict(ins)
    ins2.update({n: np.uint32(g_state[n][0]) for n in new[a].inputs if n not in ins})
    got_state, got_out, _ = run_bittrue(new[a], state,
                                        {n: ins2[n] for n in new[a].inputs})
    assert {k: int(v[0]) for k, v in got_state.items()} == \
        {k: int(v[0]) for k, v in exp_state.items()}
    assert {k: int(v[0]) for k, v in got_out.items()} == \
        {k: int(v[0]) for k, v in exp_out.items()}


@pytest.mark.filterwarnings("ignore:.*created but never used")
def test_engine_blocks_document_latency_and_throughput():
    """The four engine blocks are in navgate build's registry and document LATENCY and
    THROUGHPUT from their schedules."""
    from fractions import Fraction

    from amaranth.hdl import Fragment

    from navgate.hw.blocks import all_blocks
    from navgate.systems.ins_trn.pl import nav_engines as engines
    factories = {"ins_engines": engines.InsEngines,
                 "kalman_update_engine": engines.KalmanUpdateEngine,
                 "ins_mechanization": engines.InsMechanization,
                 "covariance_propagator": engines.CovariancePropagator}
    assert set(factories) <= set(all_blocks())
    longest = {"ins_engines": CYCLES["propagate"], "kalman_update_engine": 274,
               "ins_mechanization": 513, "covariance_propagator": 479}
    for name, factory in sorted(factories.items()):
        c = factory()
        assert c.LATENCY == longest[name] + 2
        assert Fraction(c.THROUGHPUT) == Fraction(1, longest[name] + 3)
        assert hasattr(c, "i") and hasattr(c, "o")
        c._MustUse__silence = True  # built for its figures only, not elaborated
    Fragment.get(engines.KalmanUpdateEngine(), None)
