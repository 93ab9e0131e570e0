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
    rom, overrides = image.translation()
    # the one output address the two applies share (dx7 of the TRN update, dx12 of the
    # altitude update) is told apart by the last update kind
    assert overrides


def test_updates_accepted_and_rejected_bit_exact(image):
    rng = np.random.default_rng(21)
    names = [n for n in image.layout.fixed if not n.startswith("c:")]
    regs, f = identity_p_registers(rng, names)
    # correlations that make dx12 of the altitude update and dx7 of the TRN update non-zero
    # and different: the two share one banked output address
    regs.update({"P2_12": f(0.1), "P0_7": f(0.2), "P1_7": f(-0.05)})
    calls = [("alt_gate", {"h_meas": f(regs_h := 1.5), "r": f(4.0), "gate": f(9.0)}),
             ("alt_apply", {}),
             ("trn_gate", {"y0": f(3.0), "y1": f(-2.0), "r00": f(25.0), "r01": f(1.0),
                           "r11": f(16.0), "gate": f(9.0)}),
             ("trn_apply", {}),
             ("trn_gate", {"r00": f(0.0), "r01": f(0.0), "r11": f(0.0), "gate": f(1e-9)})]
    assert regs_h == 1.5
    got = check(regs, calls, image)
    dx12, dx7 = got[1][1]["dx12"], got[3][1]["dx7"]
    assert dx12 != 0 and dx7 != 0 and dx12 != dx7


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
