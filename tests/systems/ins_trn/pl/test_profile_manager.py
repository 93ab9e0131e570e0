"""Seed 000 altitude_profile_manager (navgate.systems.ins_trn.pl.profile_manager): the FIFO keeps
the newest 64 entries, the DMA writes the newest min(PROF_COUNT, fill) oldest first in legal
AXI3 bursts (at most 16 beats, no 4 KB crossing) to a memory model with random back-pressure,
and an overrun is flagged; in Amaranth simulation and in Verilator with cocotbext-axi's
AXI RAM model."""

from __future__ import annotations

import random

import pytest
from amaranth.sim import Simulator

from navgate.gateware.axi4 import BOUNDARY, MAX_BEATS, plan_bursts
from navgate.systems.ins_trn.pl.profile_manager import AltitudeProfileManager, pack_entry


def _entry(rng, k):
    return {"h_terrain": rng.getrandbits(32), "pos_n": rng.getrandbits(32),
            "pos_e": rng.getrandbits(32), "time": (1000 + 100 * k) & 0xFFFFFF,
            "valid": rng.getrandbits(1), "reserved": 0}


def _as_int(e):
    return pack_entry(e["h_terrain"], e["pos_n"], e["pos_e"], e["time"], e["valid"])


async def _push(ctx, dut, e):
    """Offer one entry on the stream and hold it until it is taken (``entry.ready``)."""
    ctx.set(dut.entry.payload, e)
    ctx.set(dut.entry.valid, 1)
    while True:
        _, _, ready = await ctx.tick().sample(dut.entry.ready)
        if ready:
            break
    ctx.set(dut.entry.valid, 0)


def _slave(dut, rng, memory, bursts, ready_prob):
    """An AXI write slave with random back-pressure on AW and W that stores the words and
    checks WLAST; answers OKAY after a random delay."""

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

    return slave


def _axi_rules(dut, stats):
    """Every cycle: once AWVALID or WVALID is high it stays high, with the same payload, until
    the handshake (AXI A3.2.1); counts W beats and the cycles of a burst (from its AW
    handshake to its WLAST beat) with WVALID low in ``stats``."""

    async def monitor(ctx):
        axi = dut.axi
        stats.update(beats=0, w_bubbles=0)
        held_aw = held_w = None
        in_burst = False
        while True:
            _, _, awv, awr, awaddr, awlen, wv, wr, wdata, wlast = await ctx.tick().sample(
                axi.awvalid, axi.awready, axi.awaddr, axi.awlen,
                axi.wvalid, axi.wready, axi.wdata, axi.wlast)
            if held_aw is not None:
                assert awv and (awaddr, awlen) == held_aw, "AW changed before its handshake"
            if held_w is not None:
                assert wv and (wdata, wlast) == held_w, "W changed before its handshake"
            held_aw = (awaddr, awlen) if awv and not awr else None
            held_w = (wdata, wlast) if wv and not wr else None
            if in_burst and not wv:
                stats["w_bubbles"] += 1
            if wv and wr:
                stats["beats"] += 1
                if wlast:
                    in_burst = False
            if awv and awr:
                in_burst = True

    return monitor


def run_profile(pushes_between, dma_requests, seed=0, ready_prob=0.6, push_during=0,
                stats=None):
    """Push entries, start DMAs (pushing ``push_during`` more right after each start, an int
    or one per DMA); returns what memory saw and the expected contents."""
    dut = AltitudeProfileManager()
    if isinstance(push_during, int):
        push_during = [push_during] * len(dma_requests)
    rng = random.Random(seed)
    memory: dict[int, int] = {}
    bursts: list[tuple[int, int]] = []
    results = []
    pushed: list[int] = []

    async def push(ctx, k):
        e = _entry(rng, k)
        await _push(ctx, dut, e)
        pushed.append(_as_int(e))

    slave = _slave(dut, rng, memory, bursts, ready_prob)

    async def testbench(ctx):
        k = 0
        for n_push, (address, count), n_during in zip(pushes_between, dma_requests,
                                                      push_during, strict=True):
            for _ in range(n_push):
                await push(ctx, k)
                k += 1
            snapshot = list(pushed)
            ctx.set(dut.dma_address, address)
            ctx.set(dut.dma_count, count)
            ctx.set(dut.dma_start, 1)
            await ctx.tick()
            ctx.set(dut.dma_start, 0)
            for _ in range(n_during):
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
    sim.add_testbench(_axi_rules(dut, {} if stats is None else stats), background=True)
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



# ---------------------------------------------------------------- the block-RAM boundary


def test_whole_wrapped_buffer_under_w_backpressure_streams_without_bubbles():
    """101 pushes put the oldest of the 64 entries in slot 37, so the snapshot runs through
    word address 255 -> 0 of the RAM; W stalls at random (W data must hold, AXI A3.2.1), and
    the block-RAM read path never leaves W idle inside a burst (one word read per beat)."""
    for ready_prob in (0.25, 1.0):
        stats = {}
        results, bursts = run_profile([101], [(0x3F40, 64)], seed=5, ready_prob=ready_prob,
                                      stats=stats)
        r = results[0]
        assert r["got"] == r["expected"] and len(r["got"]) == 64 and not r["error"]
        assert bursts == plan_bursts(0x3F40, 256)
        assert stats == {"beats": 256, "w_bubbles": 0}


def test_pushes_during_a_dma_go_to_free_slots():
    """A full buffer, a DMA of the newest 40: 24 pushes during it land in the 24 slots outside
    the snapshot (no overrun, the snapshot unchanged), and a DMA of 64 afterwards returns the
    newest 64 including them."""
    results, _ = run_profile([64, 0], [(0x0, 40), (0x800, 64)], push_during=[24, 0],
                             ready_prob=0.3, seed=6)
    for r in results:
        assert r["got"] == r["expected"] and not r["overrun"] and not r["error"]
    assert results[0]["fill"] == results[1]["fill"] == 64


def _timed_bench(prefill, start_offset, count, ready_prob=1.0, seed=0):
    """Fill the FIFO with ``prefill`` entries, then offer one more and pulse ``dma_start``
    ``start_offset`` cycles after the cycle it is accepted (0: the same cycle); returns the
    entries pushed, the words the DMA wrote (one int per entry), the overrun flag and the
    cycles (relative to the first acceptance) at which the stream took each entry."""
    dut = AltitudeProfileManager()
    rng = random.Random(seed)
    memory: dict[int, int] = {}
    out = {}

    async def bench(ctx):
        pushed, taken = [], []
        cycle = 0
        entries = [_entry(rng, k) for k in range(prefill + 1)]
        ctx.set(dut.entry.valid, 1)
        for k, e in enumerate(entries):  # valid held high: back to back
            ctx.set(dut.entry.payload, e)
            while True:
                if k == prefill and start_offset == 0:
                    ctx.set(dut.dma_count, count)
                    ctx.set(dut.dma_start, 1)
                _, _, ready, fill = await ctx.tick().sample(dut.entry.ready, dut.fill)
                ctx.set(dut.dma_start, 0)
                cycle += 1
                if ready:
                    taken.append(cycle)
                    assert ctx.get(dut.fill) == min(k + 1, 64)  # counted the next cycle
                    break
                assert ctx.get(dut.fill) == fill
            pushed.append(_as_int(e))
        ctx.set(dut.entry.valid, 0)
        if start_offset:
            for _ in range(start_offset - 1):  # the push was accepted in the cycle before
                await ctx.tick()
            ctx.set(dut.dma_count, count)
            ctx.set(dut.dma_start, 1)
            await ctx.tick()
            ctx.set(dut.dma_start, 0)
        while True:
            _, _, done, overrun = await ctx.tick().sample(dut.done, dut.overrun)
            if done:
                break
        n = len(memory) // 4
        got = [memory[16 * i] | memory[16 * i + 4] << 32 | memory[16 * i + 8] << 64
               | memory[16 * i + 12] << 96 for i in range(n)]
        out.update(pushed=pushed, got=got, overrun=overrun, taken=taken)

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.add_testbench(_slave(dut, rng, memory, [], ready_prob), background=True)
    sim.add_testbench(_axi_rules(dut, {}), background=True)
    sim.run()
    return out


def test_entry_stream_takes_one_entry_every_four_cycles():
    """Entries offered back to back are taken every fourth cycle (the documented THROUGHPUT),
    each counted in ``fill`` the cycle after (LATENCY), and all 64 newest come back intact."""
    out = _timed_bench(prefill=69, start_offset=1, count=64)
    gaps = [b - a for a, b in zip(out["taken"][:-1], out["taken"][1:], strict=True)]
    assert gaps == [1 / AltitudeProfileManager.THROUGHPUT] * 69 == [4] * 69
    assert out["got"] == out["pushed"][-64:] and not out["overrun"]


def test_dma_started_while_the_last_entry_is_being_written():
    """A DMA started 1-3 cycles after a push (words 1-3 still on their way into the RAM)
    includes that entry, read last and intact, with the fastest slave; a DMA started in the
    cycle the push is accepted takes the snapshot before it, and flags an overrun only when
    that snapshot is the whole buffer (the push overwrites its oldest slot)."""
    for prefill, count in ((0, 1), (5, 3), (70, 64)):
        for offset in (1, 2, 3):
            out = _timed_bench(prefill, offset, count)
            assert out["got"] == out["pushed"][-count:] and not out["overrun"]
    out = _timed_bench(70, 0, 63)
    assert out["got"] == out["pushed"][-64:-1] and not out["overrun"]
    out = _timed_bench(70, 0, 64)
    # the new entry overwrote the snapshot's oldest slot as it was read: flagged
    assert out["overrun"] and out["got"][1:] == out["pushed"][-64:-1]
    out = _timed_bench(5, 0, 10)
    assert out["got"] == out["pushed"][:5] and not out["overrun"]

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
    run_cocotb(AltitudeProfileManager(), "navgate.systems.ins_trn.pl.profile_manager_cocotb",
               top="altitude_profile_manager",
               env={"NAVGATE_PROFILE_JOB": str(tmp_path / "job.json")}, work_dir=tmp_path / "sim")
    status = json.loads((tmp_path / "status.json").read_text())
    assert status["mismatches"] == [] and status["violations"] == []
    assert status["rounds"] == 25 and status["entries_checked"] > 400
    assert status["bursts"] > 100


def test_timestamp_correlator_latches_position_and_time_at_each_frame():
    """The correlator holds the position words and sample count of the last frame pulse,
    whatever the inputs do between frames (300 random cycles against a model)."""
    from navgate.systems.ins_trn.pl.profile_manager import TimestampCorrelator

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
