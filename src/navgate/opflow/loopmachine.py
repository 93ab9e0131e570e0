"""The loop machine of opflow: a sequencer and datapath in Amaranth, generated from a modulo
schedule (:func:`navgate.opflow.loops.modulo_schedule`), that runs a loop nest bit for bit
like :func:`navgate.opflow.loops.run_nest`.

Structure (module docstring of :mod:`navgate.opflow.loops` for the timing rules):

* **sequencer**: one counter per loop level, an iteration counter, and per address
  generator an index register advanced by strength reduction (on the iteration that carries
  into level ``l`` it adds ``stride_l - sum_{m > l} stride_m (trip_m - 1)``); an iteration
  is issued every II cycles (a phase counter modulo II) while iterations remain;
* **iteration info**: in the cycle after its issue an iteration's addresses (ROM table read
  or the index register) and flags (level conditions, ROM flag tables) are ready; each then
  rides a delay line to the offset of the op that uses it (load addresses, store addresses
  and enables, accumulator resets); a chain of valid bits marks which offsets hold an
  issued iteration;
* **datapath**: the float32 units (:class:`navgate.gateware.fp32.Fp32Mul`,
  :class:`~navgate.gateware.fp32.Fp32Add`, fully pipelined) and each array's read ports,
  every one followed by a delay line of its results; an op's operands are taps of those
  delay lines chosen by the phase (the schedule fixes each op's offset, so each operand's
  age is a constant), constants, or for an accumulator a multiplexer between its initial
  value and the tap that holds its update from the previous iteration;
* **memories**: one :class:`amaranth.lib.memory.Memory` per array (32-bit words, the
  schedule's read ports, one write port; reads not transparent), initial contents given at
  elaboration; while the machine is idle, read port 0 and the write port of every array
  serve the host port (``host_addr`` = array number << ``array_bits`` | word, see
  :meth:`LoopMachine.host_address`; ``host_we``/``host_wdata``; ``host_rdata`` one cycle
  after the address).

Handshake: ``start`` (one cycle, while ``busy`` is low) runs the nest; ``done`` is high for
one cycle ``schedule.cycles + 1`` cycles after the start cycle.
"""

from __future__ import annotations

import numpy as np
from amaranth.hdl import Cat, Const, Module, Mux, Signal, unsigned
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from navgate.gateware.fp32 import Fp32Add, Fp32Mul
from navgate.gateware.parameters import CheckedParameters
from navgate.numerics import fp32 as F
from navgate.opflow.loops import (
    ADDR_READY,
    LoopError,
    LoopSchedule,
    addresses,
    iteration_indices,
)

__all__ = ["LoopMachine", "to_bits", "simulate", "host_write", "host_run", "delay_tap"]


def to_bits(values) -> list:
    """float32 values (float64 holding them; NaN canonical) or uint32 patterns -> words."""
    v = np.asarray(values)
    return [int(x) for x in (v if v.dtype == np.uint32 else F.floats_to_bits(v))]


def _bits(n: int) -> int:
    return max(1, int(n - 1).bit_length())


def delay_tap(m: Module, chains: dict, sig, offset: int):
    """``sig`` (ready at offset :data:`ADDR_READY`) as seen at ``offset``: a tap of its delay
    line, grown in ``m``'s sync domain as far as needed (``chains`` keeps one line per signal,
    shared by every consumer)."""
    chain = chains.setdefault(id(sig), [sig])
    while len(chain) <= offset - ADDR_READY:
        d = Signal.like(chain[-1], name=f"{chain[0].name}_d{len(chain)}")
        m.d.sync += d.eq(chain[-1])
        chain.append(d)
    return chain[offset - ADDR_READY]


class LoopMachine(CheckedParameters, wiring.Component):
    """The machine of one modulo-scheduled loop nest (module docstring)."""

    @classmethod
    def check_parameters(cls, schedule: LoopSchedule, init: dict | None = None) -> None:
        """Refuse, before the component exists, a schedule this one-nest machine cannot run."""
        nest = schedule.nest
        u = schedule.units
        if u.load_latency != 1 or u.operand_stage != 0:
            raise LoopError(f"{nest.name}: the one-nest LoopMachine needs load_latency 1 and "
                            "no operand stage: use navgate.opflow.sequence.SequenceMachine")
        other = sorted({op.kind for op in nest.ops} - {"load", "add", "sub", "mul"})
        if other:
            raise LoopError(f"{nest.name}: the one-nest LoopMachine runs load/add/sub/mul only, "
                            f"not {other}: use navgate.opflow.sequence.SequenceMachine")

    def __init__(self, schedule: LoopSchedule, init: dict | None = None):
        self.schedule = schedule
        nest = schedule.nest
        init = init or {}
        self.memories = {name: Memory(shape=unsigned(32), depth=words,
                                      init=to_bits(init.get(name, np.zeros(words, np.uint32))))
                         for name, words in nest.arrays.items()}
        self.arrays = list(nest.arrays)
        #: host address: array number << array_bits | word
        self.array_bits = _bits(max(nest.arrays.values()))
        aw = self.array_bits + _bits(len(self.arrays))
        super().__init__({"start": In(1), "busy": Out(1), "done": Out(1),
                          "host_addr": In(aw), "host_wdata": In(32), "host_we": In(1),
                          "host_rdata": Out(32)})

    def host_address(self, array: str, word: int) -> int:
        return self.arrays.index(array) << self.array_bits | word

    def elaborate(self, platform):  # noqa: C901 - one generator, read top to bottom
        m = Module()
        s = self.schedule
        nest, ii, depth = s.nest, s.ii, s.depth
        n_iter = nest.iterations
        trips = nest.trips
        levels = len(trips)
        accs = nest.acc_names()
        for name, mem in self.memories.items():
            m.submodules[f"mem_{name}"] = mem

        # ---- sequencer ------------------------------------------------------------------
        running = Signal()
        left = Signal(range(n_iter + 1))
        phase = Signal(_bits(ii))
        nidx = Signal(_bits(n_iter))
        ctr = [Signal(_bits(t), name=f"ctr{lv}") for lv, t in enumerate(trips)]
        issue = Signal()
        m.d.comb += [issue.eq(running & (left != 0) & (phase == 0)), self.busy.eq(running)]
        iv = [issue]  # iv[k]: an iteration was issued k cycles ago
        for k in range(1, depth + 1):
            v = Signal(name=f"iv{k}")
            m.d.sync += v.eq(iv[-1])
            iv.append(v)
        with m.If(running):
            m.d.sync += phase.eq(Mux(phase == ii - 1, 0, phase + 1))
        with m.If(issue):
            m.d.sync += [left.eq(left - 1), nidx.eq(nidx + 1)]
        pending = Cat(*iv[1:depth]) if depth > 1 else Const(0, 1)
        m.d.comb += self.done.eq(running & (left == 0) & (pending == 0))
        with m.If(self.done):
            m.d.sync += running.eq(0)
        with m.If(self.start & ~running):
            m.d.sync += [running.eq(1), left.eq(n_iter), phase.eq(0), nidx.eq(0)]
            m.d.sync += [c.eq(0) for c in ctr]
        is_last = [ctr[lv] == trips[lv] - 1 for lv in range(levels)]

        def deeper_last(lv):  # every level inside lv is at its last index
            return Cat(*is_last[lv + 1:]).all() if lv + 1 < levels else Const(1, 1)

        with m.If(issue):
            for lv in range(levels):
                with m.If(deeper_last(lv)):
                    m.d.sync += ctr[lv].eq(Mux(is_last[lv], 0, ctr[lv] + 1))

        # ---- address generators and iteration info (ready at offset ADDR_READY = 1) ----
        idx = iteration_indices(nest)
        info_cache: dict = {}

        def addr_info(addr, width):
            key = ("addr", addr)
            if key in info_cache:
                return info_cache[key]
            strides = list(addr.strides) or [0] * levels
            lin = addresses(nest, type(addr)(None, addr.strides, addr.offset), idx)
            iw = _bits(int(lin.max()) + 1) + 1
            reg = Signal(iw, name=f"ag{len(info_cache)}")
            delta = [strides[lv] - sum(strides[k] * (trips[k] - 1)
                                       for k in range(lv + 1, levels))
                     for lv in range(levels)]
            with m.If(self.start & ~running):
                m.d.sync += reg.eq(addr.offset)
            with m.Elif(issue):
                for lv in reversed(range(levels)):  # the innermost level not at its last
                    with m.If(deeper_last(lv) & ~is_last[lv]):
                        m.d.sync += reg.eq(reg + (delta[lv] % (1 << iw)))
            if addr.table is None:
                out = Signal(iw, name=f"ai{len(info_cache)}")
                m.d.sync += out.eq(reg)
            else:
                tab = [int(x) for x in nest.tables[addr.table]]
                rom = Memory(shape=unsigned(max(1, _bits(max(tab) + 1))), depth=len(tab),
                             init=tab)
                m.submodules[f"rom{len(info_cache)}_{addr.table}"] = rom
                rp = rom.read_port()
                m.d.comb += rp.addr.eq(reg)
                out = rp.data
            info_cache[key] = out
            return out

        def flag_info(cond):
            key = ("flag", cond)
            if key in info_cache:
                return info_cache[key]
            out = Signal(name=f"fl{len(info_cache)}")
            if cond.kind == "table":
                tab = [int(x != 0) for x in nest.tables[cond.arg]]
                rom = Memory(shape=unsigned(1), depth=len(tab), init=tab)
                m.submodules[f"rom{len(info_cache)}_{cond.arg}"] = rom
                rp = rom.read_port()
                m.d.comb += [rp.addr.eq(nidx), out.eq(rp.data)]
            else:
                lv = int(cond.arg)
                upto = lv + 1 if cond.kind.startswith("at_") else levels
                want = [is_last[k] if cond.kind.endswith("last") else ctr[k] == 0
                        for k in range(lv, upto)]
                m.d.sync += out.eq(Cat(*want).all())
            info_cache[key] = out
            return out

        chains: dict = {}

        def at(sig, offset):
            return delay_tap(m, chains, sig, offset)

        # ---- units and read ports: outputs and their delay lines -----------------------
        by_res: dict = {}
        for op in nest.ops:
            by_res.setdefault(s.resource[op.dst], []).append(op)
        outputs: dict = {}
        cores: dict = {}
        read_ports: dict = {}
        for res, inst in by_res:
            if res[0] == "read":
                mem = self.memories[res[1]]
                rp = mem.read_port(transparent_for=())
                read_ports[(res, inst)] = rp
                outputs[(res, inst)] = rp.data
            else:
                core = Fp32Mul() if res[0] == "mul" else Fp32Add()
                m.submodules[f"{res[0]}{inst}"] = core
                m.d.comb += [core.i.valid.eq(1), core.o.ready.eq(1)]
                cores[(res, inst)] = core
                outputs[(res, inst)] = core.o.payload.r
        hist: dict = {key: [sig] for key, sig in outputs.items()}

        def tap(temp, when):
            """The value of temporary ``temp`` read at offset ``when``."""
            key = s.resource[temp]
            d = when - s.ready[temp]
            assert d >= 0, (temp, when)
            h = hist[key]
            while len(h) <= d:
                r = Signal(32, name=f"h_{key[0][0]}{key[1]}_{len(h)}")
                m.d.sync += r.eq(h[-1])
                h.append(r)
            return h[d]

        def operand(src, when):
            if src.startswith("c:"):
                return Const(int(src[2:], 16), 32)
            if src in accs:
                a = accs[src]
                carried = tap(a.update, when + a.distance * ii)  # distance iterations ago
                return Mux(at(flag_info(a.reset), when), operand(a.init, when), carried)
            return tap(src, when)

        # every tap, delay line and address generator is made here, outside the phase
        # switches below (a register assigned inside a Case would only shift in its phase)
        ins: dict = {}
        for (res, inst), ops in by_res.items():
            for op in ops:
                t = s.time[op.dst]
                if res[0] == "read":
                    width = len(read_ports[(res, inst)].addr)
                    ins[op.dst] = (at(addr_info(op.addr, width), t),)
                else:
                    ins[op.dst] = (operand(op.srcs[0], t), operand(op.srcs[1], t))
        # the host port: while idle, read port 0 and the write port of every array serve
        # host_addr (reads one cycle late on host_rdata)
        ab = self.array_bits
        host_sel = Signal.like(self.host_addr[ab:], name="host_sel")
        m.d.sync += host_sel.eq(self.host_addr[ab:])
        for k, name in enumerate(self.arrays):
            key = (("read", name), 0)
            if key not in read_ports:
                read_ports[key] = self.memories[name].read_port(transparent_for=())
                by_res[key] = []
            rp = read_ports[key]
            with m.If(~running):
                m.d.comb += rp.addr.eq(self.host_addr[:ab])
            with m.If(host_sel == k):
                m.d.comb += self.host_rdata.eq(rp.data)
        for (res, inst), ops in by_res.items():
            if res[0] == "read":
                rp = read_ports[(res, inst)]
                with m.If(running), m.Switch(phase):
                    for op in ops:
                        with m.Case(s.time[op.dst] % ii):
                            m.d.comb += rp.addr.eq(ins[op.dst][0])
                continue
            core = cores[(res, inst)]
            p = core.i.payload
            with m.Switch(phase):
                for op in ops:
                    with m.Case(s.time[op.dst] % ii):
                        a, b = ins[op.dst]
                        m.d.comb += [p.a.eq(a), p.b.eq(b)]
                        if res[0] == "add":
                            m.d.comb += p.sub.eq(op.kind == "sub")

        # ---- stores --------------------------------------------------------------------
        stores_of: dict = {}
        for k, st in enumerate(nest.stores):
            stores_of.setdefault(st.array, []).append(k)
        for k, name in enumerate(self.arrays):
            if name not in stores_of:
                wp = self.memories[name].write_port()
                with m.If(~running):
                    m.d.comb += [wp.en.eq(self.host_we & (self.host_addr[ab:] == k)),
                                 wp.addr.eq(self.host_addr[:ab]), wp.data.eq(self.host_wdata)]
        for array, ks in stores_of.items():
            wp = self.memories[array].write_port()
            with m.If(~running):
                m.d.comb += [wp.en.eq(self.host_we
                                      & (self.host_addr[ab:] == self.arrays.index(array))),
                             wp.addr.eq(self.host_addr[:ab]), wp.data.eq(self.host_wdata)]
            port = {}
            for k in ks:
                st = nest.stores[k]
                t = s.time[("store", k)]
                en = iv[t]
                if st.when is not None:
                    en = en & at(flag_info(st.when), t)
                port[k] = (en, at(addr_info(st.addr, len(wp.addr)), t), tap(st.src, t))
            with m.If(running), m.Switch(phase):
                for k in ks:
                    with m.Case(s.time[("store", k)] % ii):
                        en, addr, dat = port[k]
                        m.d.comb += [wp.en.eq(en), wp.addr.eq(addr), wp.data.eq(dat)]
        return m


async def host_write(ctx, dut, memories: dict) -> None:
    """Testbench step: write ``memories`` (array -> float32 values or uint32 patterns) through
    the host port of an idle loop or sequence machine."""
    for name, values in memories.items():
        for i, w in enumerate(to_bits(values)):
            ctx.set(dut.host_we, 1)
            ctx.set(dut.host_addr, dut.host_address(name, i))
            ctx.set(dut.host_wdata, w)
            await ctx.tick()
    ctx.set(dut.host_we, 0)


async def run_to_done(ctx, dut, limit: int) -> int:
    """Testbench step: pulse ``start`` (the program or entry already selected), return the
    cycles from the start cycle to ``done`` (``RuntimeError`` past ``limit``)."""
    ctx.set(dut.start, 1)
    await ctx.tick()
    ctx.set(dut.start, 0)
    n = 1
    while not ctx.get(dut.done):
        await ctx.tick()
        n += 1
        if n > limit:
            raise RuntimeError(f"no done within {limit} cycles of the start")
    return n


async def host_read(ctx, dut, arrays: dict) -> dict:
    """Testbench step: every array of ``arrays`` (name -> words) read through the host port
    of an idle machine (array -> uint32 words)."""
    got = {}
    for name, words in arrays.items():
        vals = []
        for i in range(words):
            ctx.set(dut.host_addr, dut.host_address(name, i))
            await ctx.tick()
            vals.append(ctx.get(dut.host_rdata))
        got[name] = np.array(vals, np.uint32)
    return got


async def host_run(ctx, dut, arrays: dict, limit: int) -> tuple[dict, int]:
    """Testbench step: :func:`run_to_done`, then :func:`host_read` of ``arrays`` from the
    cycle after ``done``. Returns (array -> uint32 words, cycles)."""
    n = await run_to_done(ctx, dut, limit)
    await ctx.tick()
    return await host_read(ctx, dut, arrays), n


def simulate(schedule: LoopSchedule, memories: dict, runs: int = 1, init: dict | None = None):
    """Run the machine of ``schedule`` in Amaranth's simulator: write ``memories`` (array ->
    float32 values or uint32 patterns) through the host port, then ``runs`` times start the
    nest, count the cycles from the start cycle to ``done`` and read every array back through
    the host port. Returns one (array -> uint32 words, cycles) per run."""
    from amaranth.sim import Simulator

    dut = LoopMachine(schedule, init)
    out: list = []

    async def bench(ctx):
        await host_write(ctx, dut, memories)
        for _ in range(runs):
            out.append(await host_run(ctx, dut, schedule.nest.arrays,
                                      10 * schedule.cycles + 100))

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    return out


def simulate_entries(dut, arrays: dict, memories: dict, entries: list, limit) -> list:
    """Amaranth simulation of an entry-point machine (the sequence or the register machine:
    ``entry``, ``start``, ``done`` and the host port): write ``memories`` through the host
    port, then for each item of ``entries`` (an entry name, or (entry, memories to write
    first or None)) start it, count the cycles from the start cycle to ``done`` (at most
    ``limit(entry)``) and read every array of ``arrays`` back. Returns one (array -> uint32
    words, cycles) per entry run."""
    from amaranth.sim import Simulator

    out: list = []

    async def bench(ctx):
        await host_write(ctx, dut, memories)
        for item in entries:
            entry, mems = (item, None) if isinstance(item, str) else item
            if mems:
                await host_write(ctx, dut, mems)
            ctx.set(dut.entry, dut.entry_index(entry))
            try:
                out.append(await host_run(ctx, dut, arrays, limit(entry)))
            except RuntimeError as e:
                raise RuntimeError(f"entry {entry}: {e}") from None

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    return out


def verilate_entries(dut, top: str, arrays: dict, memories: dict, runs: list, limit,
                     work_dir) -> list:
    """The emitted Verilog of an entry-point machine (sequence or register machine) in
    Verilator, driven by cocotb (:mod:`navgate.opflow.sequence_cocotb`): ``memories``
    written through the host port, then each run (an entry name, or (entry, memories to
    write first or None)) started, its cycles counted to ``done`` (at most ``limit(entry)``)
    and every word of ``arrays`` read back. Returns one (array -> uint32 words, cycles) per
    run, as :func:`simulate_entries`."""
    import json
    from pathlib import Path

    from navgate.gateware.verify import run_cocotb

    work_dir = Path(work_dir)
    work_dir.mkdir(parents=True, exist_ok=True)

    def writes(ms):
        return [[dut.host_address(a, i), w] for a, v in (ms or {}).items()
                for i, w in enumerate(to_bits(v))]

    items = [(r, None) if isinstance(r, str) else r for r in runs]
    reads = [(a, i) for a, words in arrays.items() for i in range(words)]
    job = {"writes": writes(memories), "reads": [dut.host_address(a, i) for a, i in reads],
           "runs": [{"entry": dut.entry_index(e), "writes": writes(w), "limit": limit(e)}
                    for e, w in items],
           "status": str(work_dir / "status.json")}
    (work_dir / "job.json").write_text(json.dumps(job))
    run_cocotb(dut, "navgate.opflow.sequence_cocotb", top=top,
               env={"NAVGATE_SEQ_JOB": str(work_dir / "job.json")}, work_dir=work_dir / "sim")
    out = []
    for got in json.loads((work_dir / "status.json").read_text()):
        words = np.array(got["words"], np.uint32)
        split, k = {}, 0
        for a, n in arrays.items():
            split[a] = words[k:k + n]
            k += n
        out.append((split, got["cycles"]))
    return out

