"""Seed 000 altitude_profile_manager (navgate.systems.ins_trn.profile_manager): the FIFO keeps
the newest 64 entries, the DMA writes the newest min(PROF_COUNT, fill) oldest first in legal
AXI3 bursts (at most 16 beats, no 4 KB crossing) to a memory model with random back-pressure,
and an overrun is flagged; in Amaranth simulation and in Verilator with cocotbext-axi's
AXI RAM model."""

from __future__ import annotations

import random

import pytest
from amaranth.sim import Simulator

from navgate.gateware.axi4 import BOUNDARY, MAX_BEATS, plan_bursts
from navgate.systems.ins_trn.profile_manager import AltitudeProfileManager, pack_entry


def _entry(rng, k):
    return {"h_terrain": rng.getrandbits(32), "pos_n": rng.getrandbits(32),
            "pos_e": rng.getrandbits(32), "time": (1000 + 100 * k) & 0xFFFFFF,
            "valid": rng.getrandbits(1), "reserved": 0}


def _as_int(e):
    return pack_entry(e["h_terrain"], e["pos_n"], e["pos_e"], e["time"], e["valid"])


def run_profile(pushes_between, dma_requests, seed=0, ready_prob=0.6, push_during=0):
    """Push entries, start DMAs; returns what memory saw and the expected contents."""
    dut = AltitudeProfileManager()
    rng = random.Random(seed)
    memory: dict[int, int] = {}
    bursts: list[tuple[int, int]] = []
    results = []
    pushed: list[int] = []

    async def push(ctx, k):
        e = _entry(rng, k)
        ctx.set(dut.entry.payload, e)
        ctx.set(dut.entry.valid, 1)
        await ctx.tick()
        ctx.set(dut.entry.valid, 0)
        pushed.append(_as_int(e))

    async def slave(ctx):
        axi = dut.axi
        while True:
            ctx.set(axi.awready, rng.random() < ready_prob)
            _, _, awvalid, awready, addr, length = await ctx.tick().sample(
                axi.awvalid, axi.awready, axi.awaddr, axi.awlen)
            if not (awvalid and awready):
                continue
            ctx.set(axi.awready, 0)
            bursts.append((addr, length + 1))
            for beat in range(length + 1):
                while True:
                    ctx.set(axi.wready, rng.random() < ready_prob)
                    _, _, wvalid, wready, wdata, wlast = await ctx.tick().sample(
                        axi.wvalid, axi.wready, axi.wdata, axi.wlast)
                    if wvalid and wready:
                        break
                assert wlast == (beat == length)
                memory[addr + 4 * beat] = wdata
            ctx.set(axi.wready, 0)
            for _ in range(rng.randrange(4)):
                await ctx.tick()
            ctx.set(axi.bvalid, 1)
            ctx.set(axi.bresp, 0)
            while True:
                _, _, bready = await ctx.tick().sample(axi.bready)
                if bready:
                    break
            ctx.set(axi.bvalid, 0)

    async def testbench(ctx):
        k = 0
        for n_push, (address, count) in zip(pushes_between, dma_requests, strict=True):
            for _ in range(n_push):
                await push(ctx, k)
                k += 1
            snapshot = list(pushed)
            ctx.set(dut.dma_address, address)
            ctx.set(dut.dma_count, count)
            ctx.set(dut.dma_start, 1)
            await ctx.tick()
            ctx.set(dut.dma_start, 0)
            for _ in range(push_during):
                await push(ctx, k)
                k += 1
            while True:
                _, _, done, error, overrun = await ctx.tick().sample(
                    dut.done, dut.error, dut.overrun)
                if done:
                    break
            fill = min(len(snapshot), 64)
            n = min(count, fill)
            expected = snapshot[len(snapshot) - n:]
            got = []
            for i in range(n):
                words = [memory.get(address + 16 * i + 4 * w) for w in range(4)]
                got.append(None if None in words else
                           words[0] | words[1] << 32 | words[2] << 64 | words[3] << 96)
            results.append({"expected": expected, "got": got, "error": error,
                            "overrun": overrun, "fill": ctx.get(dut.fill)})

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.add_testbench(slave, background=True)
    sim.run()
    return results, bursts


def test_dma_moves_the_newest_entries_in_legal_bursts():
    # 10 entries then 4 of them; 80 pushes (wraps) then all 64; a window crossing 4 KB
    # ... and one whose 4 KB boundary falls inside what would be a 16-beat burst
    results, bursts = run_profile([10, 70, 5, 0],
                                  [(0x1000, 4), (0x2000, 64), (0x2FC0, 40), (0x4FE0, 6)])
    for r in results:
        assert r["got"] == r["expected"] and not r["error"] and not r["overrun"]
    assert [r["fill"] for r in results] == [10, 64, 64, 64]
    assert all(beats <= MAX_BEATS for _, beats in bursts)
    assert all(a // BOUNDARY == (a + 4 * b - 1) // BOUNDARY for a, b in bursts)
    assert bursts == (plan_bursts(0x1000, 16) + plan_bursts(0x2000, 256)
                      + plan_bursts(0x2FC0, 160) + plan_bursts(0x4FE0, 24))
    assert (0x2FC0, 16) in bursts  # exactly 16 beats up to the boundary at 0x3000
    assert (0x4FE0, 8) in bursts and (0x5000, 16) in bursts  # split at 0x5000


def test_count_zero_and_empty_fifo_finish_at_once():
    results, bursts = run_profile([0, 3], [(0x100, 5), (0x100, 0)])
    assert results[0]["got"] == [] and results[1]["got"] == [] and bursts == []


def test_a_push_into_an_unread_slot_is_flagged():
    results, _ = run_profile([64], [(0x0, 64)], push_during=3, ready_prob=0.3)
    assert results[0]["overrun"] and results[0]["error"]
    ok, _ = run_profile([64], [(0x0, 60)], push_during=3, ready_prob=0.3)
    assert not ok[0]["overrun"] and ok[0]["got"] == ok[0]["expected"]


def test_plan_bursts():
    assert plan_bursts(0xFF0, 8) == [(0xFF0, 4), (0x1000, 4)]
    assert plan_bursts(0, 40) == [(0, 16), (64, 16), (128, 8)]
    with pytest.raises(AssertionError):
        assert plan_bursts(0, 1) == []


def test_profile_dma_in_verilator_with_the_axi_ram_model(tmp_path):
    import json

    from navgate.gateware.verify import run_cocotb

    job = {"seed": 3, "rounds": 25, "status": str(tmp_path / "status.json")}
    (tmp_path / "job.json").write_text(json.dumps(job))
    run_cocotb(AltitudeProfileManager(), "navgate.systems.ins_trn.profile_manager_cocotb",
               top="altitude_profile_manager",
               env={"NAVGATE_PROFILE_JOB": str(tmp_path / "job.json")}, work_dir=tmp_path / "sim")
    status = json.loads((tmp_path / "status.json").read_text())
    assert status["mismatches"] == [] and status["violations"] == []
    assert status["rounds"] == 25 and status["entries_checked"] > 400
    assert status["bursts"] > 100


def test_timestamp_correlator_latches_position_and_time_at_each_frame():
    """The correlator holds the position words and sample count of the last frame pulse,
    whatever the inputs do between frames (300 random cycles against a model)."""
    from navgate.systems.ins_trn.profile_manager import TimestampCorrelator

    dut = TimestampCorrelator()
    rng = random.Random(4)
    seen = []

    async def bench(ctx):
        want = (0, 0, 0)
        for _ in range(300):
            frame = rng.random() < 0.1
            n, e, k = rng.getrandbits(32), rng.getrandbits(32), rng.getrandbits(24)
            ctx.set(dut.frame, frame)
            ctx.set(dut.pos_n, n)
            ctx.set(dut.pos_e, e)
            ctx.set(dut.samples, k)
            await ctx.tick()
            if frame:
                want = (n, e, k)
            got = (ctx.get(dut.sample_n), ctx.get(dut.sample_e), ctx.get(dut.sample_t))
            assert got == want
            seen.append(frame)

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    assert 10 < sum(seen) < 60
