"""Seed 000 on the register machine (navgate.systems.ins_trn.pl.register_engine) behind the
banked engine's ports: the adapter core (address translation, int16 IMU words converted,
registered writes and start) in Amaranth's simulator against the bit-true interpreter of the
fp32 programs, call after call, with the banked image's addresses."""

from __future__ import annotations

import numpy as np
import pytest
from amaranth.hdl import Module, Signal
from amaranth.sim import Simulator

from navgate.systems.ins_trn.pl.fp32_program import STATE_REGS
from navgate.systems.ins_trn.pl.nav_engines import (
    IMU_WORDS,
    identity_p_registers,
    reference_calls,
    simulate_calls,
)
from navgate.systems.ins_trn.pl.register_engine import int16_to_fp32, register_engine_image


def check(regs, calls, image):
    got = simulate_calls(image, regs, calls, write_first=True)
    exp = reference_calls(regs, calls)
    # the IMU word registers hold the float32 of the int16 written (the boundary's cvt):
    # they read back as that word, checked below
    held = {n for n in regs if image.new_address(n) is not None and n not in IMU_WORDS}
    for (key, _), (g_regs, g_out, cyc), (e_regs, e_out) in zip(calls, got, exp, strict=True):
        assert cyc == image.cycles(key) + 1, key
        bad = [n for n in held if g_regs[n] != e_regs[n]]
        assert not bad, (key, bad[:8])
        assert g_out == e_out, key
        for n in IMU_WORDS:
            w = e_regs[n]
            assert g_regs[n] == int(np.float32(w - (1 << 32) if w >= 1 << 31 else w)
                                    .view(np.uint32)), n
    return got


@pytest.fixture(scope="module")
def image():
    return register_engine_image()


def test_every_banked_register_the_programs_use_is_held(image):
    unheld = [n for n in image.layout.fixed if not n.startswith("c:")
              and image.new_address(n) is None]
    # only the banked engine's own gate-to-apply registers are not the register machine's
    assert unheld and all(n.startswith(("alt_gate.", "trn_gate.")) for n in unheld)
    rom, shared = image.translation()
    # output addresses the banked scheduler gives to names of several programs (a dx word of
    # each apply, a gate's flag and a dx word): the core follows the last program run
    assert shared and all(len(set(words.values())) > 1 for words in shared.values())


def _shared_names(image):
    """(banked address, [(program, output name), ...]) of the shared output addresses."""
    _, shared = image.translation()
    return [(a, [(k, n) for k in words for n, b in image.output_addr(k).items() if b == a])
            for a, words in shared.items()]


def test_updates_accepted_and_rejected_bit_exact(image):
    rng = np.random.default_rng(21)
    names = [n for n in image.layout.fixed if not n.startswith("c:")]
    regs, f = identity_p_registers(rng, names)
    # correlations of the measured states with the others, so that every dx word of both
    # updates is non-zero (the shared output addresses are checked with different values)
    for r in (0, 1, 2):
        for j in range(3, 15):
            regs[f"P{r}_{j}"] = f(rng.uniform(-0.03, 0.03))
    calls = [("alt_gate", {"h_meas": f(regs_h := 1.5), "r": f(4.0), "gate": f(9.0)}),
             ("alt_apply", {}),
             ("trn_gate", {"y0": f(3.0), "y1": f(-2.0), "r00": f(25.0), "r01": f(1.0),
                           "r11": f(16.0), "gate": f(9.0)}),
             ("trn_apply", {}),
             ("trn_gate", {"r00": f(0.0), "r01": f(0.0), "r11": f(0.0), "gate": f(1e-9)})]
    assert regs_h == 1.5
    got = check(regs, calls, image)
    for a, writers in _shared_names(image):
        seen = {}
        for (key, _), (_, out, _) in zip(calls, got, strict=True):
            for k, n in writers:
                if k == key:
                    seen[k, n] = out[n]
        assert len(seen) == len(writers), (a, writers)
        assert len(set(seen.values())) == len(seen) and 0 not in seen.values(), (a, seen)


@pytest.mark.slow
def test_imu_sample_bit_exact(image):
    rng = np.random.default_rng(22)
    names = [n for n in image.layout.fixed if not n.startswith("c:")]
    regs, _ = identity_p_registers(rng, names)
    imu = {n: int(v) & 0xFFFFFFFF for n, v in zip(IMU_WORDS, [-32768, 32767, 0, -1, 1, 12345],
                                                  strict=True)}
    got = check(regs, [("propagate", imu)], image)
    assert sum(got[0][0][n] != regs[n] for n in STATE_REGS) > 100


def test_int16_conversion_exact():
    m = Module()
    w = Signal(32)
    out = int16_to_fp32(m, w)
    values = [-32768, -32767, -1, 0, 1, 2, 3, 255, 256, 12345, 32767, -12345, -2, 1024]

    async def bench(ctx):
        for v in values:
            ctx.set(w, v & 0xFFFFFFFF)
            await ctx.delay(1e-9)
            assert ctx.get(out) == int(np.float32(v).view(np.uint32)), v

    sim = Simulator(m)
    sim.add_testbench(bench)
    sim.run()


def test_compact_top_and_its_board_variant_carry_the_register_machine():
    """``navgate build ins_trn_top_compact [--target zybo-z7-20]``: the top and the Zybo
    variant carry the register engine, with the banked top's ports and IMU job timing taken
    from the register machine (not elaborated here: the flights elaborate it)."""
    from navgate.gateware.verify import not_elaborated
    from navgate.systems import BLOCKS
    from navgate.systems.ins_trn.pl.sequencer import job_cycles
    from navgate.systems.ins_trn.pl.top import InsTrnTop, InsTrnTopCompact, ZyboInsTrnTop

    top = InsTrnTopCompact()
    banked = InsTrnTop()
    assert top.engine == "register" and top.image is register_engine_image()
    assert top.signature.members.keys() == banked.signature.members.keys()
    assert top.IMU_CYCLES == job_cycles(register_engine_image(), "imu") > banked.IMU_CYCLES
    board = InsTrnTopCompact.for_target("zybo-z7-20")
    assert isinstance(board, ZyboInsTrnTop) and board.inner.engine == "register"
    with pytest.raises(KeyError, match="arty"):
        InsTrnTopCompact.for_target("arty")
    assert BLOCKS["ins_trn_top_compact"][0].endswith(":InsTrnTopCompact")
    for component in (top, banked, board):
        not_elaborated(component)
