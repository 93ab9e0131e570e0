"""The output formatter and the barometer compensation on one shared adder and multiplier
(shared_units.py, as ins_trn_top wires them): both streams fed at once with random gaps and
stalls, every output equal to its bit-true model, and the arbitration exercised both ways
(each block made to wait for the other)."""

from __future__ import annotations

import numpy as np
from amaranth import Module
from amaranth.lib import stream, wiring
from amaranth.lib.wiring import In, Out
from amaranth.sim import Simulator

from navgate.devices import bmp390 as B
from navgate.systems.ins_trn.pl import output_formatter as F
from navgate.systems.ins_trn.pl.sensors import baro_compensation as BC
from navgate.systems.ins_trn.pl.shared_units import (
    SHARED_CORES,
    arbitrate,
    share_units,
    unit_port,
)


class _Pair(wiring.Component):
    """Formatter + compensation sharing the units under the top's rule (the formatter's
    pending request is its input's ``valid``)."""

    def __init__(self):
        super().__init__({
            "fmt_i": In(stream.Signature(F.IN_LAYOUT)),
            "fmt_o": Out(stream.Signature(F.OUT_LAYOUT)),
            "baro_i": In(stream.Signature(BC.IN_LAYOUT)),
            "baro_o": Out(stream.Signature(BC.OUT_LAYOUT)),
            "fmt_waits": Out(1), "baro_waits": Out(1), "fmt_idle": Out(1),
        })

    def elaborate(self, platform):
        m = Module()
        m.submodules.fmt = fmt = F.NavOutputFormatter(shared_units=True)
        m.submodules.comp = comp = BC.BaroCompensation(shared_units=True)
        fmt_valid, grant = arbitrate(m, fmt.i.ready, self.fmt_i.valid, comp.busy)
        m.d.comb += [fmt.i.payload.eq(self.fmt_i.payload), fmt.i.valid.eq(fmt_valid),
                     self.fmt_i.ready.eq(fmt.i.ready & fmt_valid), comp.grant.eq(grant),
                     self.fmt_waits.eq(self.fmt_i.valid & comp.busy),
                     self.fmt_idle.eq(fmt.i.ready),
                     self.baro_waits.eq(self.baro_i.valid & ~grant)]
        wiring.connect(m, wiring.flipped(self.baro_i), comp.i)
        wiring.connect(m, fmt.o, wiring.flipped(self.fmt_o))
        wiring.connect(m, comp.o, wiring.flipped(self.baro_o))
        share_units(m, {u: unit_port(fmt, u) for u in SHARED_CORES},
                    {u: unit_port(comp, u) for u in SHARED_CORES}, comp.busy)
        return m


def _fmt_vectors(n, rng):
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    words = {f"q{i}": np.float32(q[:, i]).view(np.uint32) for i in range(4)}
    for name in ("pN", "pE", "h", "vN", "vE", "vD", "ref_alt"):
        words[name] = np.float32(rng.uniform(-1e4, 1e4, n)).view(np.uint32)
    for name in F.COV_FIELDS:
        words[name] = np.float32(10.0 ** rng.uniform(-6, 6, n)).view(np.uint32)
    return words


def test_formatter_and_baro_compensation_share_units_bit_exact():
    rng = np.random.default_rng(5)
    n_fmt, n_baro = 24, 6
    fv = _fmt_vectors(n_fmt, rng)
    want_fmt = F.formatter_bittrue({k: fv[k] for k in F.IN_FIELDS})
    want_fmt.update(F.sigma_bittrue({k: fv[k] for k in F.COV_FIELDS}))
    up, ut = B.encode(rng.uniform(*B.PRESSURE_RANGE_PA, n_baro),
                      rng.uniform(*B.TEMPERATURE_RANGE_C, n_baro))
    want_p, want_t = B.compensate_fp32(up, ut)
    nvm = int.from_bytes(B.nvm_bytes(), "little")
    dut = _Pair()
    got_fmt, got_baro, waits, changed = [], [], {"fmt": 0, "baro": 0}, {"fmt": 0}

    async def feed_fmt(ctx):
        for k in range(n_fmt):
            for _ in range(int(rng.integers(0, 400))):
                await ctx.tick()
            for name in F.IN_FIELDS + F.COV_FIELDS:
                ctx.set(getattr(dut.fmt_i.payload, name), int(fv[name][k]))
            ctx.set(dut.fmt_i.valid, 1)
            await ctx.tick().until(dut.fmt_i.ready)
            ctx.set(dut.fmt_i.valid, 0)

    async def feed_baro(ctx):
        for k in range(n_baro):
            for _ in range(int(rng.integers(0, 200))):
                await ctx.tick()
            ctx.set(dut.baro_i.payload.up, int(up[k]))
            ctx.set(dut.baro_i.payload.ut, int(ut[k]))
            ctx.set(dut.baro_i.payload.nvm, nvm)
            ctx.set(dut.baro_i.valid, 1)
            await ctx.tick().until(dut.baro_i.ready)
            ctx.set(dut.baro_i.valid, 0)

    async def collect(ctx):
        ctx.set(dut.fmt_o.ready, 1)
        ctx.set(dut.baro_o.ready, 1)
        while len(got_fmt) < n_fmt or len(got_baro) < n_baro:
            await ctx.tick()
            waits["fmt"] += ctx.get(dut.fmt_waits)
            waits["baro"] += ctx.get(dut.baro_waits)
            held = {w: ctx.get(getattr(dut.fmt_o.payload, w))
                    for w in F.OUT_WORDS + F.SIGMA_WORDS + ("flags",)}
            if ctx.get(dut.fmt_o.valid):
                got_fmt.append(held)
            elif got_fmt and ctx.get(dut.fmt_idle):
                # the top's registers show the words held after an output until the next
                # input: the compensation's results must never reach them
                changed["fmt"] += held != got_fmt[-1]
            if ctx.get(dut.baro_o.valid):
                got_baro.append((ctx.get(dut.baro_o.payload.p), ctx.get(dut.baro_o.payload.t)))

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(feed_fmt, background=True)
    sim.add_testbench(feed_baro, background=True)
    sim.add_testbench(collect)
    sim.run()
    for k, g in enumerate(got_fmt):
        assert g == {w: int(want_fmt[w][k]) for w in g}, k
    assert got_baro == [(int(p), int(t)) for p, t in zip(want_p, want_t, strict=True)]
    # both sides had to wait for the other at least once
    assert waits["fmt"] > 0 and waits["baro"] > 0, waits
    assert changed["fmt"] == 0
