"""The navigation sequencer (ins_engines under job control) equals the fp32 engine bit for bit
in Amaranth simulation: the PS's register loading through the window, IMU samples, an
applied and a gate-rejected altitude update, an applied TRN update; every state register read
back through the window, the shadow words, status, NIS, and the exact job cycles. Both forms:
the update and calibration inputs as ports, and read at their register words through
``reg_word``/``reg_data`` as ins_trn_top builds it."""

from __future__ import annotations

import numpy as np
import pytest
from amaranth import Module
from amaranth.lib import wiring
from amaranth.lib.wiring import In
from amaranth.sim import Simulator

from navgate.numerics.fp32 import float_to_bits
from navgate.systems.ins_trn.pl.fp32_program import CAL_REGS, STATE_REGS
from navgate.systems.ins_trn.pl.sequencer import SHADOW_WORDS, NavSequencer, job_cycles
from navgate.systems.ins_trn.ps import flight
from navgate.systems.ins_trn.ps.fp32_engine import Fp32Engine
from navgate.systems.ins_trn.ps.navigator import engine_setup
from navgate.trn.dem import Dem


@pytest.fixture(scope="module")
def setup_and_words():
    dem = Dem.default()
    cfg = flight.FlightConfig(duration_s=2.0, seed=3)
    _, _, stream = flight.record_stream(dem, cfg)
    return engine_setup(stream.header, cfg), stream.gyro_words[:3], stream.accel_words[:3]


def _bits(x) -> int:
    return int(np.float32(x).view(np.uint32))


class _RegisterFront(wiring.Component):
    """The sequencer in the mode ``ins_trn_top`` builds (its ALT/TRN/CAL inputs read through
    ``reg_word``/``reg_data`` from the register file, at the map's word addresses) behind the
    ports of the plain one: a register file of those ports answers ``reg_word``."""

    def __init__(self, image):
        from navgate.systems.ins_trn.pl.registers import register_map
        from navgate.systems.ins_trn.pl.top import SEQUENCER_REGISTER_OF

        regmap = register_map()
        self.words = {n: regmap[r].offset >> 2 for n, r in SEQUENCER_REGISTER_OF.items()}
        self.inner = NavSequencer(image, register_words=self.words)
        self.image, self.addr = image, self.inner.addr
        members = {n: mb for n, mb in self.inner.signature.members.items()
                   if n not in ("reg_word", "reg_data")}
        members.update({n: In(32) for n in self.words})
        super().__init__(members)

    def elaborate(self, platform):
        m = Module()
        m.submodules.inner = inner = self.inner
        for name, member in inner.signature.members.items():
            if name in ("reg_word", "reg_data"):
                continue
            if not member.is_port:
                wiring.connect(m, wiring.flipped(getattr(self, name)), getattr(inner, name))
            elif member.flow == In:
                m.d.comb += getattr(inner, name).eq(getattr(self, name))
            else:
                m.d.comb += getattr(self, name).eq(getattr(inner, name))
        with m.Switch(inner.reg_word):
            for name, word in self.words.items():
                with m.Case(word):
                    m.d.comb += inner.reg_data.eq(getattr(self, name))
        return m


@pytest.mark.parametrize("through_registers", [True, False])
def test_sequencer_equals_fp32_engine(setup_and_words, through_registers):
    """``through_registers``: as ins_trn_top builds it (the inputs read at their register
    words); otherwise one port per input."""
    setup, gw, aw = setup_and_words
    model = Fp32Engine(setup)
    m = model.m
    image = __import__("navgate.systems.ins_trn.pl.nav_engines",
                       fromlist=["engine_image"]).engine_image("ins_engines")
    dut = _RegisterFront(image) if through_registers else NavSequencer(image)
    addr = dut.addr
    loads = [(a, float_to_bits(m.regs[m.index[n]]) if n in m.index else 0)
             for n, a in addr.items() if not n.startswith("c:") and n not in CAL_REGS]
    cal = {n: float_to_bits(m.get(n)) for n in CAL_REGS}  # through CAL_APPLY
    gate1 = float(model._gate[1])
    gate2 = float(model._gate[2])
    alt_cases = [(setup.nav0[2] + 3.0, 4.0), (setup.nav0[2] + 900.0, 0.01)]  # applied, gated
    trn = dict(y0=12.0, y1=-7.5, r00=400.0, r01=20.0, r11=300.0, lag=0.25, gate=gate2)
    trn_far = dict(trn, y0=5000.0, y1=4000.0, r00=1.0, r01=0.0, r11=1.0, lag=0.0)
    log = {}

    async def bench(ctx):
        async def wait_idle():
            n = 0
            while ctx.get(dut.busy) or n < 2:
                await ctx.tick()
                n += 1

        for a, v in loads:
            ctx.set(dut.eng_addr, a)
            ctx.set(dut.eng_wdata, v)
            ctx.set(dut.eng_write, 1)
            await ctx.tick()
            ctx.set(dut.eng_write, 0)
            await ctx.tick().repeat(3)
        for n, v in cal.items():
            ctx.set(getattr(dut, n), v)
        ctx.set(dut.cal_apply, 1)
        await ctx.tick()
        ctx.set(dut.cal_apply, 0)
        n = 1
        while ctx.get(dut.busy):
            await ctx.tick()
            n += 1
        log["cal_cycles"] = n
        ctx.set(dut.enable, 1)
        cycles = []
        for g, a in zip(gw, aw, strict=True):
            for f, w in zip(("gx", "gy", "gz", "ax", "ay", "az"), list(g) + list(a),
                            strict=True):
                ctx.set(getattr(dut.imu.payload, f), int(w) & 0xFFFFFFFF)
            ctx.set(dut.imu.valid, 1)
            n = 0
            while not ctx.get(dut.imu.ready):
                await ctx.tick()
            await ctx.tick()
            ctx.set(dut.imu.valid, 0)
            n = 1
            while not ctx.get(dut.update):
                await ctx.tick()
                n += 1
            cycles.append(n)
            log.setdefault("shadow", []).append([ctx.get(dut.shadow[k])
                                                 for k in range(len(SHADOW_WORDS))])
        log["imu_cycles"] = cycles
        ctx.set(dut.enable, 0)
        async def update(kind, inputs):
            """Write an update's inputs, strobe its start; (status, NIS, cycles to update)."""
            for k, v in inputs.items():
                ctx.set(getattr(dut, f"{kind}_{k}"), _bits(v))
            ctx.set(getattr(dut, f"{kind}_start"), 1)
            await ctx.tick()
            ctx.set(getattr(dut, f"{kind}_start"), 0)
            n = 1
            while not ctx.get(dut.update):
                await ctx.tick()
                n += 1
            await ctx.tick()
            status, nis = getattr(dut, f"{kind}_status"), getattr(dut, f"{kind}_nis")
            log.setdefault(kind, []).append((ctx.get(status), ctx.get(nis), n))

        for h, r in alt_cases:
            await update("alt", {"h_meas": h, "r": r, "gate": gate1})
        for case in (trn, trn_far):  # applied, then rejected by the gate
            await update("trn", case)
        await wait_idle()
        got = {}
        for name in STATE_REGS:
            ctx.set(dut.eng_addr, addr[name])
            ctx.set(dut.eng_read, 1)
            await ctx.tick()
            ctx.set(dut.eng_read, 0)
            await ctx.tick().repeat(4)
            got[name] = ctx.get(dut.eng_rdata)
        log["regs"] = got

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()

    # the model: the same calls on the fp32 engine
    shadows = []
    for g, a in zip(gw, aw, strict=True):
        model.propagate(np.array([g]), np.array([a]))
        shadows.append([float_to_bits(m.get(n)) for n in SHADOW_WORDS])
    assert log["shadow"] == shadows
    img = dut.image
    assert log["imu_cycles"] == [job_cycles(img, "imu")] * 3 == [680] * 3
    assert log["cal_cycles"] == job_cycles(img, "cal")
    outcomes = [model._update("baro", "alt_gate", "alt_apply", 1, h_meas=h, r=r)
                for h, r in alt_cases]
    assert outcomes[0].accepted and not outcomes[1].accepted
    assert log["alt"][0][0] == 0b010 and log["alt"][1][0] == 0b110
    assert [a[2] for a in log["alt"]] == [337, 67]
    for (_status, nis, n), out, applied in zip(log["alt"], outcomes, (True, False), strict=True):
        assert nis == _bits(out.nis)
        assert n == job_cycles(img, "alt", applied)
    out = model.update_trn(np.array([trn["y0"], trn["y1"]]),
                           np.array([[trn["r00"], trn["r01"]], [trn["r01"], trn["r11"]]]),
                           trn["lag"])
    assert out.accepted and log["trn"][0][0] == 0b010 and log["trn"][0][1] == _bits(out.nis)
    assert log["trn"][0][2] == job_cycles(img, "trn") == 469
    far = model.update_trn(np.array([trn_far["y0"], trn_far["y1"]]), np.eye(2), 0.0)
    assert not far.accepted and "gate" in far.reason
    assert log["trn"][1][0] == 0b110 and log["trn"][1][1] == _bits(far.nis)
    assert log["trn"][1][2] == job_cycles(img, "trn", applied=False) == 158
    want = {n: float_to_bits(m.get(n)) for n in STATE_REGS}
    diff = [n for n in STATE_REGS if want[n] != log["regs"][n]]
    assert not diff, diff[:8]
