"""The banked machine of navgate's scheduled float32 datapaths: the control word, the
microcode image of a schedule (:class:`BankedImage`), the datapath that executes it
(:class:`BankedMachine`: register banks with one write port each, issue slots, operand
multiplexers, the program counter of a straight-line control store) and the command-stream
wrapper (:class:`ScheduledMachineStream`). Schedules come from :mod:`navgate.opflow.schedule`,
whose docstring describes the machine's timing and port rules.
"""

from __future__ import annotations

from dataclasses import dataclass

from amaranth.hdl import Cat, Module, Mux, Signal, unsigned
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from navgate.gateware.fp32 import (
    Fp32Add,
    Fp32Compare,
    Fp32Div,
    Fp32DivIter,
    Fp32FromInt,
    Fp32Mul,
    Fp32Sqrt,
    Fp32SqrtIter,
)
from navgate.opflow.schedule import (
    MISC_KINDS,
    ONE_BITS,
    BankedLayout,
    BankedUnits,
    _slot_unit,
    allocate_banked,
    assign_banks,
    schedule_banked,
)


class _BankedFields:
    """Bit positions of the control word."""

    def __init__(self, units: BankedUnits, lb: int, n_sources: int, misc_kinds: tuple):
        self.pos: dict = {}
        off = 0
        nb = units.banks
        ports = 1 if units.split_ports else units.read_ports  # per bank, to one operand
        self.sel_bits = max(1, (nb * ports - 1).bit_length())
        self.src_bits = max(1, (n_sources - 1).bit_length())
        self.kind_bits = max(1, (len(misc_kinds) - 1).bit_length())

        def add(key, w):
            nonlocal off
            self.pos[key] = (off, w)
            off += w

        self.shared = units.shared
        for b in range(nb):
            for r in range(units.read_ports):
                add(("ra", b, r), lb)
            add(("we", b), 1)
            if not self.shared(b):  # shared: the write address is port A's (read 0's) field
                add(("wa", b), lb)
            add(("wsrc", b), self.src_bits)
        for slot, _ in enumerate(units.slots()):
            add(("iss", slot), 1)
            for j in range(2):
                add(("sel", slot, j), self.sel_bits)
                add(("flip", slot, j), 1)
        add(("mod", "add"), units.add)  # one sub bit per add slot
        add(("kind",), self.kind_bits)
        add(("wmod",), 1)
        self.width = off
        self.aw = lb + max(1, (nb - 1).bit_length())

    def wa(self, b: int) -> tuple:
        """The field holding bank ``b``'s write address."""
        return ("ra", b, 0) if self.shared(b) else ("wa", b)


@dataclass
class BankedImage:
    """Everything the banked gateware is generated from: schedules, layout, microcode."""

    units: BankedUnits
    misc_kinds: tuple  #: misc cores built, in select order
    sources: list  #: write-data sources: ("mul", k), ("add", k), (misc kind, 0)
    programs: dict
    layout: BankedLayout
    base: dict
    rom: list
    fields: _BankedFields

    @classmethod
    def build(cls, programs: dict, units: BankedUnits, fixed_names,
              rank_skip: tuple = (), rank_weights: dict | None = None) -> BankedImage:
        """Schedule ``programs`` and lay out the register file. Persistent registers are
        ranked over the banks by their reads (:func:`assign_banks`), not counting the reads
        of ops whose ``module`` is in ``rank_skip`` (ops a client knows to be off every
        critical path, whose reads should not reshuffle the banks of every program); a read
        in program ``key`` counts ``rank_weights[key]`` times (default 1)."""
        fixed_names = list(dict.fromkeys(fixed_names))
        consts = sorted({s for p in programs.values() for op in p.ops for s in op.srcs
                         if s.startswith("c:")})
        names = fixed_names + [c for c in consts if c not in fixed_names]
        nreads: dict = {}
        weights = rank_weights or {}
        for key, p in programs.items():
            for op in p.ops:
                if op.module in rank_skip:
                    continue
                for s in op.srcs:
                    nreads[s] = nreads.get(s, 0) + weights.get(key, 1)
        bank_of = assign_banks(names, units, nreads)
        sched = {k: schedule_banked(p, units, bank_of) for k, p in programs.items()}
        used = {s.unit for sp in sched.values() for s in sp.ops}
        misc_kinds = tuple(k for k in MISC_KINDS if k in used)
        sources = ([("mul", k) for k in range(units.mul)]
                   + [("add", k) for k in range(units.add)] + [("misc", 0)])
        layout = allocate_banked(sched, names, bank_of, units)
        f = _BankedFields(units, layout.local_bits, len(sources), misc_kinds)
        lb = layout.local_bits
        rom: list = []
        base = {}
        for key, sp in sched.items():
            base[key] = len(rom)
            rows = [0] * sp.cycles
            addr = dict(layout.fixed)
            addr.update(layout.temp_addr[key])
            ports: dict = {}  # (cycle, bank) -> {local address: port}
            for s in sp.ops:  # a shared port A writes: the reads of that cycle use port B
                dst = layout.fixed[s.dst] if s.kind == "mov" else addr.get(s.dst)
                if dst is not None and units.shared(dst >> lb):
                    ports[(s.write, dst >> lb)] = {None: 0}

            def put(row, fkey, value, rows=rows):
                off, w = f.pos[fkey]
                assert 0 <= value < (1 << w), (fkey, value)
                assert rows[row] >> off & ((1 << w) - 1) in (0, value), (fkey, row)
                rows[row] |= value << off

            for s in sp.ops:
                su = _slot_unit(s.unit)
                slot = units.slot_of(su, s.inst)
                put(s.issue, ("iss", slot), 1)
                if su == "misc":
                    put(s.issue, ("kind",), misc_kinds.index(s.unit))
                for j, (name, flip) in enumerate(s.srcs):
                    b, a = addr[name] >> lb, addr[name] & ((1 << lb) - 1)
                    if units.split_ports:  # source j on read port j (the scheduler's rule)
                        put(s.issue, ("ra", b, j), a)
                        put(s.issue, ("sel", slot, j), b)
                        put(s.issue, ("flip", slot, j), int(flip))
                        continue
                    used_ports = ports.setdefault((s.issue, b), {})
                    if a not in used_ports:
                        used_ports[a] = len(used_ports)
                        assert used_ports[a] < units.read_ports
                        put(s.issue, ("ra", b, used_ports[a]), a)
                    put(s.issue, ("sel", slot, j), b * units.read_ports + used_ports[a])
                    put(s.issue, ("flip", slot, j), int(flip))
                if s.kind == "sub":
                    off, _ = f.pos[("mod", "add")]
                    rows[s.issue] |= 1 << (off + s.inst)
                # the write source and the compare's le bit are held one row early: the
                # machine registers them, so that the bank's write-data multiplexer and the
                # misc result bus start from flip-flops rather than from the microcode RAM's
                # clock-to-out (a write is never in a program's first cycle)
                assert s.write >= 1
                if s.kind == "le":
                    put(s.write - 1, ("wmod",), 1)
                dst = layout.fixed[s.dst] if s.kind == "mov" else addr.get(s.dst)
                if dst is not None:
                    b = dst >> lb
                    src = sources.index((s.unit, s.inst) if su != "misc" else ("misc", 0))
                    put(s.write, ("we", b), 1)
                    put(s.write, f.wa(b), dst & ((1 << lb) - 1))
                    put(s.write - 1, ("wsrc", b), src)
            rom += rows
        return cls(units, misc_kinds, sources, sched, layout, base, rom, f)

    def cycles(self, key: str) -> int:
        return self.programs[key].cycles

    def spans(self) -> list:
        """(first row, last row) of every program, in program order."""
        return [(self.base[k], self.base[k] + sp.cycles - 1) for k, sp in self.programs.items()]

    def output_addr(self, key: str) -> dict:
        sp = self.programs[key]
        return {n: self.layout.temp_addr[key][t] for n, t in sp.outputs.items()}

    def machine(self, init: dict | None = None):
        return BankedMachine(self, init)


@dataclass
class RowCounter:
    """The signals of :func:`row_counter`."""

    nxt: Signal  #: the row to read next: a synchronous read port's address
    pc: Signal  #: the row whose control word the read port presents now
    last: Signal  #: the running program's last row
    running: Signal
    go: Signal  #: a program starts (``start`` while not running)


def row_counter(m: Module, spans: list, start, prog) -> RowCounter:
    """The program counter of a straight-line control store: ``start`` while not running
    loads the first row of program ``prog`` (``spans[prog] = (first, last)``), the counter
    then steps a row a cycle and stops after the last row. Addressing a synchronous read
    port with ``nxt`` makes its data the control word of row ``pc``."""
    rw = max(1, max(last for _, last in spans).bit_length())
    pc = Signal(rw)
    last = Signal(rw)
    running = Signal()
    base_sel = Signal(rw)
    last_sel = Signal(rw)
    with m.Switch(prog):
        for i, (first, end) in enumerate(spans):
            with m.Case(i):
                m.d.comb += [base_sel.eq(first), last_sel.eq(end)]
    go = Signal()
    nxt = Signal(rw)
    m.d.comb += [go.eq(start & ~running),
                 nxt.eq(Mux(go, base_sel, Mux(running & (pc != last), pc + 1, pc)))]
    with m.If(go):
        m.d.sync += [running.eq(1), pc.eq(base_sel), last.eq(last_sel)]
    with m.Elif(running):
        m.d.sync += pc.eq(nxt)
        with m.If(pc == last):
            m.d.sync += running.eq(0)
    return RowCounter(nxt, pc, last, running, go)


def _or_all(terms):
    out = terms[0]
    for t in terms[1:]:
        out = out | t
    return out


class BankedMachine(wiring.Component):
    """Executes the programs of a :class:`BankedImage`. ``start`` with ``prog`` (program
    number, in the image's order) while not ``busy`` starts a program; ``done`` is high for
    one cycle exactly ``cycles(prog) + 1`` cycles after ``start``. Host access while idle:
    ``host_we``/``host_waddr``/``host_wdata`` write a register, ``host_raddr`` ->
    ``host_rdata`` (one cycle later) reads one; host addresses are the layout's flat
    addresses."""

    def __init__(self, image: BankedImage, init: dict | None = None):
        self.image = image
        self.init = dict(init or {})
        self.keys = list(image.programs)
        aw = image.fields.aw
        super().__init__({
            "start": In(1), "prog": In(range(max(2, len(self.keys)))),
            "busy": Out(1), "done": Out(1),
            "host_we": In(1), "host_waddr": In(aw), "host_wdata": In(32),
            "host_raddr": In(aw), "host_rdata": Out(32),
        })

    def elaborate(self, platform):
        m = Module()
        img = self.image
        f = img.fields
        u = img.units
        lay = img.layout
        lb = lay.local_bits
        nb = u.banks
        inits = [[0] * max(2, lay.bank_depth[b]) for b in range(nb)]
        for flat, v in list(lay.const_init.items()) + list(self.init.items()):
            b, a = lay.split(flat)
            if a < len(inits[b]):
                inits[b][a] = v
        m.submodules.rom = rom = Memory(shape=unsigned(f.width), depth=len(img.rom),
                                        init=img.rom)
        seq = row_counter(m, img.spans(), self.start, self.prog)
        running = seq.running
        rp = rom.read_port()
        m.d.comb += [self.busy.eq(running), rp.addr.eq(seq.nxt)]
        m.d.sync += self.done.eq(running & (seq.pc == seq.last))
        ctl = Signal(f.width)
        m.d.comb += ctl.eq(rp.data)
        gated = {k for k in f.pos if k[0] in ("we", "iss")}

        def fld(*key):
            off, w = f.pos[key]
            if key in gated:  # no issue and no write while idle
                return ctl[off:off + w] & running
            return ctl[off:off + w]

        # one cycle later: operand selects, flips, issue bits, sub bits, misc kind
        def late(sig, name):
            r = Signal(len(sig), name=name)
            m.d.sync += r.eq(sig)
            return r

        host_bank = self.host_raddr[lb:]
        host_bank_q = Signal(len(host_bank))
        m.d.sync += host_bank_q.eq(host_bank)
        # bank read data
        rdata = []
        wports = []
        for b in range(nb):
            mem = Memory(shape=unsigned(32), depth=max(2, lay.bank_depth[b]), init=inits[b])
            m.submodules[f"bank{b}"] = mem
            wp = mem.write_port()
            wports.append(wp)
            if u.shared(b):
                # port A: write port and read port 0 on one address (one true-dual-port RAM)
                host_we = self.host_we & ~running & (self.host_waddr[lb:] == b)
                addr_a = Signal(lb, name=f"addr_a{b}")
                m.d.comb += [addr_a.eq(Mux(running, fld("ra", b, 0),
                                           Mux(host_we, self.host_waddr[:lb],
                                               self.host_raddr[:lb]))),
                             wp.en.eq(fld("we", b) | host_we), wp.addr.eq(addr_a)]
            ports = []
            for r in range(u.read_ports):
                p = mem.read_port()
                if r == 0 and u.shared(b):
                    a = addr_a
                else:
                    a = fld("ra", b, r)
                    if r == 0:
                        a = Mux(running, a, self.host_raddr[:lb])
                m.d.comb += p.addr.eq(a)
                ports.append(p.data)
            rdata.append(ports)
        flat_ports = [d for ports in rdata for d in ports]
        with m.Switch(host_bank_q):
            for b in range(nb):
                with m.Case(b):
                    m.d.comb += self.host_rdata.eq(rdata[b][0])

        def operand(slot, j):
            sel = late(fld("sel", slot, j), f"sel{slot}_{j}")
            flip = late(fld("flip", slot, j), f"flip{slot}_{j}")
            v = Signal(32, name=f"op{slot}_{j}")
            inputs = [ports[j] for ports in rdata] if u.split_ports else flat_ports
            with m.Switch(sel):
                for k, d in enumerate(inputs):
                    with m.Case(k):
                        m.d.comb += v.eq(d)
            out = Signal(32, name=f"opr{slot}_{j}")
            m.d.sync += out.eq(v ^ Cat(Signal(31), flip))
            return out

        src_res = {}
        mod_off, _ = f.pos[("mod", "add")]
        for slot, (unit, k) in enumerate(u.slots()):
            a, bop = operand(slot, 0), operand(slot, 1)
            iss = late(late(fld("iss", slot), f"iss{slot}a"), f"iss{slot}")
            if unit == "mul":
                core = Fp32Mul()
                m.d.comb += [core.i.valid.eq(iss), core.o.ready.eq(1),
                             core.i.payload.a.eq(a), core.i.payload.b.eq(bop)]
                m.submodules[f"mul{k}"] = core
                src_res[("mul", k)] = core.o.payload.r
            elif unit == "add":
                core = Fp32Add()
                sub = late(late(ctl[mod_off + k], f"sub{k}a"), f"sub{k}")
                m.d.comb += [core.i.valid.eq(iss), core.o.ready.eq(1),
                             core.i.payload.a.eq(a), core.i.payload.b.eq(bop),
                             core.i.payload.sub.eq(sub)]
                m.submodules[f"add{k}"] = core
                src_res[("add", k)] = core.o.payload.r
            else:
                kind = late(late(fld("kind"), "misc_kind_a"), "misc_kind")
                misc_terms = []
                for ki, name in enumerate(img.misc_kinds):
                    v = Signal(name=f"{name}_valid")
                    m.d.comb += v.eq(iss & (kind == ki))
                    if name == "mov":
                        core = _Mov()
                        m.d.comb += [core.a.eq(a), core.valid_i.eq(v)]
                        res = core.r
                        res_valid = core.valid_o
                    else:
                        div, sqrt = ((Fp32DivIter, Fp32SqrtIter) if u.iterative
                                     else (Fp32Div, Fp32Sqrt))
                        core = {"div": div, "sqrt": sqrt, "cmp": Fp32Compare,
                                "cvt": lambda: Fp32FromInt(32)}[name]()
                        m.d.comb += [core.i.valid.eq(v), core.o.ready.eq(1)]
                        if name == "cvt":
                            m.d.comb += core.i.payload.x.eq(a)
                        elif name == "sqrt":
                            m.d.comb += core.i.payload.a.eq(a)
                        else:
                            m.d.comb += [core.i.payload.a.eq(a), core.i.payload.b.eq(bop)]
                        if name == "cmp":
                            o = core.o.payload
                            res = Signal(32, name="cmp_res")
                            # the le bit, held one row early in the microcode: a
                            # flip-flop, not the ROM's clock-to-out, before the bus
                            le = Signal(name="cmp_le")
                            m.d.sync += le.eq(fld("wmod"))
                            m.d.comb += res.eq(Mux(o.lt | (le & o.equal), ONE_BITS, 0))
                        else:
                            res = core.o.payload.r
                        res_valid = core.o.valid
                    m.submodules[name] = core
                    misc_terms.append(Mux(res_valid, res, 0))
                misc_res = Signal(32, name="misc_res")
                m.d.comb += misc_res.eq(_or_all(misc_terms))
                src_res[("misc", 0)] = misc_res
        for b in range(nb):
            wp = wports[b]
            data = Signal(32, name=f"wdata{b}")
            wsrc = Signal(len(fld("wsrc", b)), name=f"wsrc{b}")
            m.d.sync += wsrc.eq(fld("wsrc", b))  # the microcode holds it one row early
            with m.Switch(wsrc):
                for k, key in enumerate(img.sources):
                    with m.Case(k):
                        m.d.comb += data.eq(src_res[key])
            if not u.shared(b):
                host = self.host_we & ~running & (self.host_waddr[lb:] == b)
                m.d.comb += [wp.en.eq(fld("we", b) | host),
                             wp.addr.eq(Mux(running, fld("wa", b), self.host_waddr[:lb]))]
            m.d.comb += wp.data.eq(Mux(running, data, self.host_wdata))
        return m



class _Mov(wiring.Component):
    """One-cycle register (the commit copy)."""

    LATENCY = 1

    def __init__(self):
        super().__init__({"a": In(32), "valid_i": In(1), "r": Out(32), "valid_o": Out(1)})

    def elaborate(self, platform):
        m = Module()
        m.d.sync += [self.r.eq(self.a), self.valid_o.eq(self.valid_i)]
        return m


CMD_WRITE, CMD_READ, CMD_START = 0, 1, 2


class ScheduledMachineStream(wiring.Component):
    """The machine of ``image`` (the banked machine of
    :mod:`navgate.opflow.machine`) behind one command stream (for the verification harness and
    the ``rtl`` engine). Input payload ``{cmd, addr, data, prog}``: ``cmd`` 0 writes ``data``
    to register ``addr``, 1 reads register ``addr``, 2 runs program ``prog``. One output
    ``{data, cycles}`` per command: the word read (0 otherwise) and, for a run, the cycles
    from start to done (``cycles(prog) + 1``). A write or read takes 2 cycles + the
    handshake, a run ``cycles + 2``."""

    LATENCY = 3
    THROUGHPUT = 0.5

    def __init__(self, image, init: dict | None = None):
        from amaranth.lib import data, stream

        self.image = image
        self.init = init
        aw = image.fields.aw
        pw = max(1, (len(image.programs) - 1).bit_length())
        self.in_layout = data.StructLayout({"cmd": 2, "addr": aw, "data": 32, "prog": pw})
        self.out_layout = data.StructLayout({"data": 32, "cycles": 16})
        super().__init__({"i": In(stream.Signature(self.in_layout)),
                          "o": Out(stream.Signature(self.out_layout))})

    def elaborate(self, platform):
        m = Module()
        core = self.image.machine(self.init)
        m.submodules.core = core
        res = Signal(32)
        cyc = Signal(16)
        p = self.i.payload
        m.d.comb += [core.host_waddr.eq(p.addr), core.host_wdata.eq(p.data),
                     core.host_raddr.eq(p.addr), core.prog.eq(p.prog),
                     self.o.payload.data.eq(res), self.o.payload.cycles.eq(cyc)]
        with m.FSM():
            with m.State("IDLE"):
                m.d.comb += self.i.ready.eq(1)
                with m.If(self.i.valid):
                    with m.Switch(p.cmd):
                        with m.Case(CMD_WRITE):
                            m.d.comb += core.host_we.eq(1)
                            m.d.sync += [res.eq(0), cyc.eq(0)]
                            m.next = "RESP"
                        with m.Case(CMD_READ):
                            m.d.sync += cyc.eq(0)
                            m.next = "READ"
                        with m.Default():
                            m.d.comb += core.start.eq(1)
                            m.d.sync += [res.eq(0), cyc.eq(1)]
                            m.next = "RUN"
            with m.State("READ"):
                m.d.sync += res.eq(core.host_rdata)
                m.next = "RESP"
            with m.State("RUN"):
                m.d.sync += cyc.eq(cyc + 1)
                with m.If(core.done):
                    m.d.sync += cyc.eq(cyc)
                    m.next = "RESP"
            with m.State("RESP"):
                m.d.comb += self.o.valid.eq(1)
                with m.If(self.o.ready):
                    m.next = "IDLE"
        return m
