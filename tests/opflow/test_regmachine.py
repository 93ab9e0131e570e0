"""opflow's register machine (navgate.opflow.regmachine): the compiler and its
instruction-level model against the sequence executor (run_sequence) on seed 000's programs
and on hand-made nests, the machine in Amaranth's simulator against both (bit for bit, cycle
for cycle), and the programs it refuses."""

from __future__ import annotations

import numpy as np
import pytest

from navgate.opflow import regmachine as RM
from navgate.opflow.ir import const_name
from navgate.opflow.loops import Acc, Addr, Cond, LoopError, LoopNest, LOp, Store
from navgate.opflow.sequence import SequenceProgram, run_sequence
from navgate.systems.ins_trn.pl.register_engine import register_engine

QNAN = 0x7FC00000


def canon(v) -> np.ndarray:
    """uint32 words as the machine keeps them: every NaN the canonical one (the executors'
    NaN), a subnormal the zero of its sign (the host port flushes what it writes; the
    executor keeps the subnormal of a word no segment reads)."""
    v = np.asarray(v)
    b = (v if v.dtype == np.uint32 else np.asarray(v, np.float32).view(np.uint32)).copy()
    nan = ((b >> 23) & 0xFF == 0xFF) & (b & 0x7FFFFF != 0)
    b[nan] = QNAN
    sub = (b >> 23) & 0xFF == 0
    b[sub] &= np.uint32(0x80000000)
    return b


def memories(prog, seed: int, special: bool = False, rom: dict | None = None) -> dict:
    """Random words for every array (NaN, infinities, zeros, subnormals among them with
    ``special``), the words of ``rom`` (array -> {word: value}) set."""
    rng = np.random.default_rng(seed)
    mem = {a: rng.normal(size=w).astype(np.float32) for a, w in prog.arrays.items()}
    if special:  # NaN, infinities, signed zeros, subnormals (flushed) and huge values
        pool = np.array([np.nan, np.inf, -np.inf, 0.0, -0.0, 1e-40, -1e-40, 3e38, -3e38,
                         1.0, -1.0], np.float32)
        for _a, v in mem.items():
            k = rng.random(len(v)) < 0.15
            v[k] = rng.choice(pool, int(k.sum()))
    for a, words in (rom or {}).items():
        for i, x in words.items():
            mem[a][i] = x
    return mem


def seed000_rom() -> dict:
    _, _, lps = register_engine()
    rom: dict = {}
    for lp in lps.values():
        for a, words in lp.rom.items():
            rom.setdefault(a, {}).update(words)
    return rom


def mismatches(prog, ref: dict, got: dict) -> dict:
    bad = {a: int((canon(ref[a]) != canon(got[a])).sum()) for a in prog.arrays}
    return {a: n for a, n in bad.items() if n}


@pytest.fixture(scope="module")
def seed000():
    rp, _, _ = register_engine()
    return rp


#: cycles from start to done of every entry (exact: the compiler's schedule, which the
#: machine runs; asserted below against the machine in simulation)
SEED000_CYCLES = {"propagate": 10417, "alt_gate": 64, "alt_apply": 2082, "trn_gate": 164,
                  "trn_apply": 3844}


def test_seed000_fits_the_machine(seed000):
    rp = seed000
    # one BRAM36 each for the instruction ROM (1024 x 36), the table ROM (4096 x 9) and the
    # data memory (1024 x 32); the register file within the 8-bit register field
    assert len(rp.layout()[0]) <= 1024
    assert len(rp.table) <= 4096
    assert rp.data_words <= 1024
    assert rp.registers <= 256
    assert {e: rp.cycles(e) for e in rp.entries} == SEED000_CYCLES
    # a 400 Hz sample at 100 MHz is 250,000 cycles: an IMU sample and a 2-D update fit
    assert rp.cycles("propagate") + rp.cycles("trn_apply") < 250_000 // 4


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("special", [False, True])
def test_seed000_model_equals_run_sequence(seed000, seed, special):
    rp = seed000
    prog = rp.program
    mem = memories(prog, seed, special)
    for e in prog.entries:
        got, cycles = RM.run_register_program(rp, mem, e)
        assert mismatches(prog, run_sequence(prog, mem, e), got) == {}, e
        assert cycles == rp.cycles(e)


def test_seed000_constant_words_from_configuration(seed000):
    """The programs' constant words (1.0, -0.0 in F and M) are the data memory's initial
    contents: a run whose host writes everything else equals run_sequence with them."""
    rp = seed000
    prog = rp.program
    rom = seed000_rom()
    assert rom and any(v == 1.0 for w in rom.values() for v in w.values())
    mem = memories(prog, 8, rom=rom)
    given = {a: v for a, v in mem.items() if a not in rom}
    for a, words in rom.items():  # never written: zeros and the constant words
        mem[a] = np.zeros(prog.arrays[a], np.float32)
        for i, x in words.items():
            mem[a][i] = x
    got, _ = RM.run_register_program(rp, given, "propagate")
    assert mismatches(prog, run_sequence(prog, mem, "propagate"), got) == {}
    (hw, _), = RM.simulate_register_machine(rp, given, ["alt_gate"])
    for a, words in rom.items():
        for i, x in words.items():
            assert hw[a][i] == canon(np.float32([x]))[0], (a, i)


def test_seed000_model_runs_twice(seed000):
    """Accumulators re-armed at the end of a nest: a second run starts from init."""
    rp = seed000
    prog = rp.program
    mem = memories(prog, 5)
    once, _ = RM.run_register_program(rp, mem, "propagate")
    twice = run_sequence(prog, run_sequence(prog, mem, "propagate"), "propagate")
    got = {a: np.asarray(v) for a, v in once.items()}
    got, _ = RM.run_register_program(rp, got, "propagate")
    assert mismatches(prog, twice, got) == {}


def test_seed000_machine_updates(seed000):
    """The machine in Amaranth's simulator: the gates and the 1-D update, bit for bit and
    cycle for cycle (the IMU sample and the 2-D update under -m slow)."""
    rp = seed000
    prog = rp.program
    mem = memories(prog, 3, special=True)
    entries = ["alt_gate", "trn_gate", "alt_apply"]
    out = RM.simulate_register_machine(rp, mem, entries)
    cur = {a: np.asarray(v) for a, v in mem.items()}
    for e, (got, cycles) in zip(entries, out, strict=False):
        ref = run_sequence(prog, cur, e)
        assert mismatches(prog, ref, got) == {}, e
        assert cycles == rp.cycles(e)
        cur = got


@pytest.mark.slow
def test_seed000_machine_imu_sample_and_2d_update(seed000):
    rp = seed000
    prog = rp.program
    mem = memories(prog, 4)
    entries = ["propagate", "trn_apply", "propagate"]
    out = RM.simulate_register_machine(rp, mem, entries)
    cur = {a: np.asarray(v) for a, v in mem.items()}
    for e, (got, cycles) in zip(entries, out, strict=False):
        assert mismatches(prog, run_sequence(prog, cur, e), got) == {}, e
        assert cycles == rp.cycles(e)
        cur = got


# ------------------------------------------------------------------ hand-made nests


def _dot_nest(distance: int) -> LoopNest:
    """Four sums of three products each, interleaved over ``distance`` tracks (a chained
    sum as a lane machine wants it), each stored when it ends."""
    sums = [[(i, (i + k) % 6) for k in range(3)] for i in range(4)]
    it_a, it_b, reset, last, dest = [], [], [], [], []
    order = []
    for t in range(3):
        for s in range(4):
            order.append((s, t))
    # iteration n: sum n % distance-track layout; keep it simple with distance 4
    assert distance == 4
    for s_t in order:
        s, t = s_t
        a, b = sums[s][t]
        it_a.append(a)
        it_b.append(b)
        reset.append(int(t == 0))
        last.append(int(t == 2))
        dest.append(s)
    n = len(order)
    return LoopNest("dot", (n,), {"A": 6, "B": 6, "Y": 4},
                    {"ta": it_a, "tb": it_b, "reset": reset, "last": last, "dest": dest},
                    [LOp("a", "load", ("A",), Addr("ta", (1,))),
                     LOp("b", "load", ("B",), Addr("tb", (1,))),
                     LOp("p", "mul", ("a", "b")),
                     LOp("s", "add", ("acc", "p"))],
                    [Acc("acc", const_name(-0.0), "s", Cond("table", "reset"), distance)],
                    [Store("Y", Addr("dest", (1,)), "s", Cond("table", "last"))])


def assert_model_and_machine(prog, rp, mem, entry: str = "run") -> None:
    """The instruction-level model and the machine in Amaranth's simulator run ``entry``
    as run_sequence does, the machine in the program's cycles."""
    ref = run_sequence(prog, mem, entry)
    got, _ = RM.run_register_program(rp, mem, entry)
    assert mismatches(prog, ref, got) == {}
    (hw, cycles), = RM.simulate_register_machine(rp, mem, [entry])
    assert mismatches(prog, ref, hw) == {} and cycles == rp.cycles(entry)


def _dot_memories() -> dict:
    """The dot nest's words: mixed signs and magnitudes, products that overflow."""
    return {"A": np.float32([1.5, -2.0, 3.25, 1e20, -1e20, 7.0]),
            "B": np.float32([2.0, 0.5, -1.0, 1e20, 3.0, -0.125]), "Y": np.zeros(4, np.float32)}


def test_chains_are_serialised_and_exact():
    nest = _dot_nest(4)
    perm = RM.serialize_chains(nest)
    # each sum's three iterations consecutive, in their order
    assert [int(x) for x in perm] == [0, 4, 8, 1, 5, 9, 2, 6, 10, 3, 7, 11]
    prog = SequenceProgram("dot", dict(nest.arrays), {"dot": nest}, {"run": ("dot",)})
    rp = RM.compile_program(prog)
    mem = _dot_memories()
    got, _ = RM.run_register_program(rp, mem, "run")
    assert mismatches(prog, run_sequence(prog, mem, "run"), got) == {}
    (hw, cycles), = RM.simulate_register_machine(rp, mem, ["run"])
    assert mismatches(prog, run_sequence(prog, mem, "run"), hw) == {}
    assert cycles == rp.cycles("run")


def test_unrolled_copies_exact_and_faster():
    """The dot nest's four interleaved sums as four copies in one iteration (the machine
    steps n by 4, every table shared by the copies at offsets 0..3): the same words, in
    fewer cycles than the serialised chains; copies that do not divide the iterations, or
    do not match the accumulators' distance, are refused."""
    nest = _dot_nest(4)
    prog = SequenceProgram("dot", dict(nest.arrays), {"dot": nest}, {"run": ("dot",)})
    mem = _dot_memories()
    serial = RM.compile_program(prog)
    rp = RM.compile_program(prog, unroll={"dot": 4})
    assert rp.blocks["dot"].trips == 3 and rp.blocks["dot"].step == 4
    assert len(rp.table) <= len(serial.table)  # the copies share the tables
    assert rp.cycles("run") < serial.cycles("run")
    assert_model_and_machine(prog, rp, mem)
    with pytest.raises(LoopError, match="divide"):
        RM.compile_program(prog, unroll={"dot": 5})
    with pytest.raises(LoopError, match="distance"):
        RM.compile_program(prog, unroll={"dot": 2})
    with pytest.raises(LoopError, match="unknown segments"):
        RM.compile_program(prog, unroll={"nope": 2})


def test_accumulators_on_two_chain_structures_are_refused():
    nest = _dot_nest(4)
    nest.accs.append(Acc("acc2", const_name(0.0), "p", Cond("table", "last"), 1))
    with pytest.raises(LoopError, match="one chain structure"):
        RM.serialize_chains(nest)


def test_straight_line_with_every_kind_and_flipped_store():
    body = [LOp("x", "load", ("R",), Addr(None, (), 0)),
            LOp("y", "load", ("R",), Addr(None, (), 1)),
            LOp("s", "add", ("x", "y")), LOp("d", "sub", ("x", "y")),
            LOp("q", "div", ("s", "d")), LOp("r", "sqrt", ("q",)),
            LOp("l", "lt", ("x", "y")), LOp("e", "le", ("y", "x")),
            LOp("nq", "neg", ("q",)), LOp("m", "mul", ("nq", "r"))]
    stores = [Store("R", Addr(None, (), 0), "m"), Store("R", Addr(None, (), 1), "x"),
              Store("D", Addr(None, (), 0), "nq"), Store("D", Addr(None, (), 1), "l"),
              Store("D", Addr(None, (), 2), "e")]
    nest = LoopNest("seg", (), {"R": 2, "D": 4}, {}, body, [], stores)
    other = LoopNest("touch", (2,), {"D": 4}, {}, [LOp("v", "load", ("D",), Addr(None, (1,)))],
                     [], [Store("D", Addr(None, (1,), 2), "v")])
    prog = SequenceProgram("kinds", {"R": 2, "D": 4}, {"seg": nest, "touch": other},
                           {"run": ("seg", "touch")})
    rp = RM.compile_program(prog)
    assert rp.reg_arrays == {"R": 0} and "D" in rp.data_arrays
    for x, y in [(9.0, 4.0), (-1.0, 0.0), (np.nan, 1.0), (np.inf, np.inf), (0.0, -0.0)]:
        mem = {"R": np.float32([x, y]), "D": np.float32([1, 2, 3, 4])}
        ref = run_sequence(prog, mem, "run")
        got, _ = RM.run_register_program(rp, mem, "run")
        assert mismatches(prog, ref, got) == {}, (x, y)
    (hw, cycles), = RM.simulate_register_machine(rp, mem, ["run"])
    assert mismatches(prog, ref, hw) == {}
    assert cycles == rp.cycles("run")


def test_programs_the_machine_cannot_hold_are_refused(seed000):
    prog = seed000.program
    with pytest.raises(LoopError, match="registers"):
        RM.compile_program(prog, max_registers=64)
    big = SequenceProgram("big", {"A": 2000}, {"s": LoopNest("s", (), {"A": 2000}, {},
                          [LOp("x", "load", ("A",), Addr(None, (), 0))], [],
                          [Store("A", Addr(None, (), 1), "x")])}, {"run": ("s",)})
    with pytest.raises(LoopError, match="data words"):
        RM.compile_program(big, reg_arrays=[])
    cond = LoopNest("c", (2,), {"R": 2}, {"f": [1, 0]},
                    [LOp("x", "load", ("R",), Addr(None, (), 0))], [],
                    [Store("R", Addr(None, (), 1), "x", Cond("table", "f"))])
    with pytest.raises(LoopError, match="register-file array"):
        RM.compile_program(SequenceProgram("c", {"R": 2}, {"c": cond}, {"run": ("c",)}),
                           reg_arrays=["R"])


def test_seed000_machine_in_verilator_cocotb(seed000, tmp_path):
    """The emitted Verilog of the seed-000 register machine in Verilator, driven by cocotb
    (the entry-point machine bench navgate.opflow.sequence_cocotb: host writes, runs, host
    reads): the gates and both updates, the same words and cycles as the executor."""
    from navgate.opflow.loopmachine import verilate_entries

    rp = seed000
    prog = rp.program
    dut = RM.RegisterMachine(rp)
    mem = memories(prog, 9, rom=seed000_rom())
    runs = ["alt_gate", "alt_apply", "trn_gate", "trn_apply"]
    status = verilate_entries(dut, "register_machine", prog.arrays,
                              {a: canon(v) for a, v in mem.items()}, runs,
                              lambda e: 2 * rp.cycles(e), tmp_path)
    want = mem
    for entry, (got, cycles) in zip(runs, status, strict=True):
        want = run_sequence(prog, want, entry)
        assert cycles == rp.cycles(entry), entry
        words = np.concatenate([got[a] for a in prog.arrays])
        expect = np.concatenate([canon(want[a]) for a in prog.arrays])
        assert np.array_equal(canon(words), expect), entry


def test_commit_follows_every_read_of_its_word():
    """A rotation of register-file words (each store reads a word another store commits):
    every commit waits for every read of its word, the later stores' reads included."""
    body = [LOp(f"x{i}", "load", ("R",), Addr(None, (), i)) for i in range(4)]
    stores = [Store("R", Addr(None, (), i), f"x{(i + 1) % 4}") for i in range(4)]
    stores.append(Store("D", Addr(None, (), 0), "x0"))
    nest = LoopNest("rot", (), {"R": 4, "D": 2}, {}, body, [], stores)
    touch = LoopNest("touch", (2,), {"D": 2}, {}, [LOp("v", "load", ("D",), Addr(None, (1,)))],
                     [], [Store("D", Addr(None, (1,)), "v")])
    prog = SequenceProgram("rot", {"R": 4, "D": 2}, {"rot": nest, "touch": touch},
                           {"run": ("rot",)})
    rp = RM.compile_program(prog)
    mem = {"R": np.float32([1, 2, 3, 4]), "D": np.float32([0, 0])}
    ref = run_sequence(prog, mem, "run")
    assert list(ref["R"]) == [2, 3, 4, 1] and ref["D"][0] == 1
    got, _ = RM.run_register_program(rp, mem, "run")
    assert mismatches(prog, ref, got) == {}
    (hw, _), = RM.simulate_register_machine(rp, mem, ["run"])
    assert mismatches(prog, ref, hw) == {}


def test_conditional_store_beyond_the_table_range_is_refused():
    n = 20
    nest = LoopNest("hi", (n,), {"A": 100, "Y": 600}, {"odd": [k % 2 for k in range(n)]},
                    [LOp("v", "load", ("A",), Addr(None, (1,)))], [],
                    [Store("Y", Addr(None, (1,), 500), "v", Cond("table", "odd"))])
    prog = SequenceProgram("hi", {"A": 100, "Y": 600}, {"hi": nest}, {"run": ("hi",)})
    with pytest.raises(LoopError, match="table entries hold at most 510"):
        RM.compile_program(prog)


def test_accumulators_restored_after_a_reset_mid_run():
    """A reset in the middle of a chained sum: the accumulator re-armed at the end of its
    nest gets its init word back, so the next run is the executor's again."""
    from amaranth.hdl import Module, ResetInserter, Signal
    from amaranth.sim import Simulator

    from navgate.opflow.loopmachine import host_read, host_run, host_write

    nest = _dot_nest(4)
    prog = SequenceProgram("dot", dict(nest.arrays), {"dot": nest}, {"run": ("dot",)})
    rp = RM.compile_program(prog)
    assert rp.acc_restore  # the chained sum's accumulator is re-armed at the end
    mem = {"A": np.float32([1.5, -2.0, 3.25, 4.0, -1.0, 7.0]),
           "B": np.float32([2.0, 0.5, -1.0, 8.0, 3.0, -0.125]), "Y": np.zeros(4, np.float32)}
    dut = RM.RegisterMachine(rp)
    rst = Signal()
    top = Module()
    top.submodules.dut = ResetInserter(rst)(dut)
    seen: dict = {}

    async def bench(ctx):
        await host_write(ctx, dut, mem)
        ctx.set(dut.entry, 0)
        ctx.set(dut.start, 1)
        await ctx.tick()
        ctx.set(dut.start, 0)
        for _ in range(40):  # into the second term of the first sum
            await ctx.tick()
        ctx.set(rst, 1)
        await ctx.tick()
        ctx.set(rst, 0)
        while ctx.get(dut.busy):  # the restore
            await ctx.tick()

    async def bench_all(ctx):
        await bench(ctx)
        seen["left"] = await host_read(ctx, dut, prog.arrays)
        seen["run"] = await host_run(ctx, dut, prog.arrays, 2 * rp.cycles("run") + 100)

    sim = Simulator(top)
    sim.add_clock(1e-8)
    sim.add_testbench(bench_all)
    sim.run()
    got, cycles = seen["run"]
    assert cycles == rp.cycles("run")
    assert mismatches(prog, run_sequence(prog, seen["left"], "run"), got) == {}


# ------------------------------------------------------------------ overlapped blocks


def _random_nest(rng, trips: int, distance: int, rich: bool = False) -> LoopNest:
    """A random nest over input arrays A and B (linear and table addresses), the float32
    kinds the machine has, one chained sum over ``distance`` tracks (random resets after
    the first ``distance`` iterations), an always-store of a result per iteration and a
    conditional store of the sum to unique words. ``rich``: the sum's store falls on
    random iterations (so its reset is a conditional ``mov``, not the re-arm at a store),
    a second accumulator starts from an op's value, and an op reads the first accumulator
    after its update is computed."""
    na = 11
    arrays = {"A": na, "B": na, "Y": trips, "Z": trips + 3, "W": trips, "V": trips}
    tables = {"ta": rng.integers(0, na, trips).tolist(),
              "tb": rng.integers(0, na, trips).tolist()}
    reset = [1] * distance + (rng.random(trips - distance) < 0.35).astype(int).tolist()
    # the sum is stored where the next iteration of its track resets (or at the end)
    last = [int(n + distance >= trips or reset[n + distance]) for n in range(trips)]
    if rich:
        last = (rng.random(trips) < 0.5).astype(int).tolist()
    tables.update(reset=reset, last=last, dest=[n + 3 for n in range(trips)])
    ops = [LOp("a", "load", ("A",), Addr(None, (1,), 0) if trips <= na else Addr("ta", (1,))),
           LOp("b", "load", ("B",), Addr("tb", (1,))),
           LOp("c", "load", ("A",), Addr(None, (), int(rng.integers(0, na))))]
    vals = ["a", "b", "c", const_name(float(np.float32(rng.normal())))]
    kinds = ["add", "sub", "mul", "mul", "add", "div", "sqrt", "neg", "lt", "le"]
    for i in range(int(rng.integers(4, 10))):
        k = str(rng.choice(kinds))
        x, y = (str(rng.choice(vals)) for _ in range(2))
        srcs = (x,) if k in ("sqrt", "neg") else (x, y)
        ops.append(LOp(f"t{i}", k, srcs))
        vals.append(f"t{i}")
    ops.append(LOp("p", "mul", (vals[-1], "b")))
    ops.append(LOp("s", "add", ("acc", "p")))
    accs = [Acc("acc", const_name(-0.0), "s", Cond("table", "reset"), distance)]
    stores = [Store("Y", Addr(None, (1,), 0), vals[-1]),
              Store("Z", Addr("dest", (1,)), "s", Cond("table", "last"))]
    if rich:
        ops.append(LOp("i2", "mul", ("a", "c")))
        ops.append(LOp("s2", "sub", ("acc2", str(rng.choice(vals)))))
        ops.append(LOp("r", "mul", ("acc", "s")))  # the accumulator read after its update
        accs.append(Acc("acc2", "i2", "s2", Cond("table", "reset"), distance))
        stores += [Store("W", Addr(None, (1,), 0), "s2"), Store("V", Addr(None, (1,), 0), "r")]
    return LoopNest("rnd", (trips,), arrays, tables, ops, accs, stores)


def _random_memories(rng, prog) -> dict:
    pool = np.array([np.nan, np.inf, -np.inf, 0.0, -0.0, 1e-40, 3e38, 1.0, -1.0], np.float32)
    mem = {}
    for a, w in prog.arrays.items():
        v = rng.normal(size=w).astype(np.float32)
        k = rng.random(w) < 0.1
        v[k] = rng.choice(pool, int(k.sum()))
        mem[a] = v
    return mem


def _random_program(seed: int):
    """Seed -> (program, copies): nests of the second half of the seeds are ``rich``."""
    rng = np.random.default_rng(seed)
    distance = int(rng.choice([1, 2, 3]))
    trips = distance * int(rng.integers(1, 9))
    nest = _random_nest(rng, trips, distance, rich=seed % 2 == 1)
    return SequenceProgram("rnd", dict(nest.arrays), {"rnd": nest}, {"run": ("rnd",)}), \
        distance, rng


@pytest.mark.parametrize("seed", range(60))
def test_overlapped_random_nests_model_exact(seed):
    """Random nests compiled as software pipelines (with and without copies): the
    instruction-level model equals run_sequence word for word, in the block's cycles, and
    never in more cycles than the same nest without overlap (the compiler keeps the plain
    block where the pipeline's prologue and epilogue cost more than they save); a kernel
    holds each of the block's items in one row, and the register file is the chosen
    block's."""
    prog, distance, rng = _random_program(seed)
    for copies in sorted({1, distance}):
        unroll = {"rnd": copies} if copies > 1 else {}
        plain = RM.compile_program(prog, unroll=unroll)
        rp = RM.compile_program(prog, unroll=unroll, overlap=True)
        blk = rp.blocks["rnd"]
        assert sum(r.kind != "nop" for r in blk.rows) == blk.ops
        if not blk.overlapped:
            assert rp.registers == plain.registers and rp.cycles("run") == plain.cycles("run")
        for k in range(3):
            mem = _random_memories(rng, prog)
            ref = run_sequence(prog, mem, "run")
            got, cycles = RM.run_register_program(rp, mem, "run")
            assert mismatches(prog, ref, got) == {}, (copies, k)
            assert cycles == rp.cycles("run")
        assert rp.cycles("run") <= plain.cycles("run")


#: seeds of pipelined random nests (odd: rich) for the machine: together 1 to 3 stages, as
#: many iterations as stages (2 x 2, 3 x 3), the divider and the square root, tails (one
#: of 19 cycles: writes landing in the next kernel iteration), conditional resets, an
#: accumulator started from an op, one read after its update
MACHINE_SEEDS = [12, 25, 37, 49, 51, 54, 57]


@pytest.mark.parametrize("seed", MACHINE_SEEDS)
def test_overlapped_random_nests_machine_exact(seed):
    """The machine in Amaranth's simulator runs the overlapped random nests as the model:
    the prologue's and the epilogue's missing iterations issue nothing, the kernel repeats,
    the tail drains; run twice (the accumulators' registers as the first run left them)."""
    prog, distance, rng = _random_program(seed)
    rp = RM.compile_program(prog, unroll={"rnd": distance} if distance > 1 else {},
                            overlap=True)
    assert rp.blocks["rnd"].overlapped
    mem = _random_memories(rng, prog)
    ref = run_sequence(prog, mem, "run")
    out = RM.simulate_register_machine(rp, mem, ["run", "run"])
    assert mismatches(prog, ref, out[0][0]) == {}
    assert mismatches(prog, run_sequence(prog, ref, "run"), out[1][0]) == {}
    assert [c for _, c in out] == [rp.cycles("run")] * 2


def test_overlapped_dot_nest_prologue_epilogue_and_faster():
    """The dot nest software-pipelined: the kernel is II cycles of rows, stages > 1 (the
    iterations in flight), kernel iterations = iterations + stages - 1; the same words in
    fewer cycles than without overlap, in the model and the machine; a second entry after
    it starts on a machine that has drained."""
    nest = _dot_nest(4)
    tail = LoopNest("tail", (4,), {"Y": 4, "W": 4}, {},
                    [LOp("y", "load", ("Y",), Addr(None, (1,))),
                     LOp("z", "mul", ("y", "y"))], [], [Store("W", Addr(None, (1,)), "z")])
    arrays = {**nest.arrays, "W": 4}
    prog = SequenceProgram("dot", arrays, {"dot": nest, "tail": tail},
                           {"run": ("dot", "tail")})
    mem = {**_dot_memories(),
           "W": np.zeros(4, np.float32)}
    plain = RM.compile_program(prog)
    rp = RM.compile_program(prog, overlap=True)
    blk = rp.blocks["dot"]
    assert blk.overlapped and blk.stages > 1
    assert blk.trips == blk.valid_trips + blk.stages - 1 == 12 + blk.stages - 1
    assert sum(r.count if r.kind == "nop" else 1 for r in blk.rows[:blk.kernel_rows]) \
        == blk.cycles
    assert {r.back for r in blk.rows} == set(range(blk.stages))
    assert rp.cycles("run") < plain.cycles("run")
    assert_model_and_machine(prog, rp, mem)
    with pytest.raises(LoopError, match="overlap names unknown"):
        RM.compile_program(prog, overlap=["nope"])


def test_modulo_schedule_respects_the_machine():
    """Every overlapped block of seed 000: at most one issue and one register write per
    cycle modulo II, the divider and the square root INTERVAL apart modulo II, each row's
    stage below the block's stages; II never below the block's issues (the one issue slot
    is the bound the software pipeline reaches)."""
    rp, _, _ = register_engine()
    for name, blk in rp.blocks.items():
        if not blk.overlapped:
            continue
        assert blk.cycles >= blk.ops, name
        writes, units = set(), {}
        c = 0
        for row in blk.rows[:blk.kernel_rows]:
            if row.kind == "nop":
                c += row.count
                continue
            assert row.back % blk.step == 0 and row.back // blk.step < blk.stages
            if row.kind != "store":
                w = (c + RM.write_delay(row.kind)) % blk.cycles
                assert w not in writes, name
                writes.add(w)
            u = RM.UNIT_OF.get(row.kind)
            if u in RM.INTERVAL:
                for i in range(RM.INTERVAL[u]):
                    assert (c + i) % blk.cycles not in units.setdefault(u, set()), name
                    units[u].add((c + i) % blk.cycles)
            c += 1
        assert c == blk.cycles, name


def test_pipeline_long_recurrence_and_a_small_register_file():
    """A recurrence of sixteen dependent additions: the II search goes up to the plain
    block's cycles (it once stopped far below and refused the nest), and the pipeline is
    never slower than the plain block. The dot nest in a register file too small for its
    fastest pipeline's temporaries: the search keeps a slower pipeline that fits (once the
    whole pipeline was dropped for the plain block, and before that the compile failed)."""
    ops = [LOp("x", "load", ("A",), Addr(None, (1,)))]
    prev = "acc"
    for i in range(16):
        ops.append(LOp(f"s{i}", "add", (prev, "x")))
        prev = f"s{i}"
    nest = LoopNest("rec", (8,), {"A": 8, "Y": 8}, {}, ops,
                    [Acc("acc", const_name(0.0), prev, Cond("first", 0))],
                    [Store("Y", Addr(None, (1,)), prev)])
    prog = SequenceProgram("rec", dict(nest.arrays), {"rec": nest}, {"run": ("rec",)})
    plain = RM.compile_program(prog)
    rp = RM.compile_program(prog, overlap=True)
    blk = rp.blocks["rec"]
    assert blk.cycles > 16 * (RM.write_delay("add") + 1) - 16  # II bound by the recurrence
    assert rp.cycles("run") <= plain.cycles("run")
    mem = {"A": np.float32(np.arange(8) + 0.5), "Y": np.zeros(8, np.float32)}
    got, _ = RM.run_register_program(rp, mem, "run")
    assert mismatches(prog, run_sequence(prog, mem, "run"), got) == {}

    dot = _dot_nest(4)
    prog = SequenceProgram("dot", dict(dot.arrays), {"dot": dot}, {"run": ("dot",)})
    plain = RM.compile_program(prog)
    small = plain.registers
    free = RM.compile_program(prog, overlap=True)
    assert free.registers > small
    # the II search keeps the cheapest pipeline whose registers fit: a longer II here
    rp = RM.compile_program(prog, overlap=True, max_registers=small)
    assert rp.blocks["dot"].overlapped and rp.registers == small
    assert free.cycles("run") < rp.cycles("run") < plain.cycles("run")
    mem = _dot_memories()
    got, _ = RM.run_register_program(rp, mem, "run")
    assert mismatches(prog, run_sequence(prog, mem, "run"), got) == {}
    with pytest.raises(LoopError, match="registers"):
        RM.compile_program(prog, overlap=True, max_registers=small - 1)
