"""AXI4-Lite slave register bank, generated from a :class:`navgate.hw.regmap.RegisterMap`.

Follows the AMBA AXI4-Lite rules (ARM IHI 0022, "AMBA AXI and ACE Protocol Specification",
chapters A3 and B1): five independent channels with valid/ready handshakes; a source never
waits for ready before asserting valid, and once valid is high its payload holds until the
handshake. The slave

* accepts AW and W independently and in any order (one-entry buffer each; ``awready`` and
  ``wready`` are high while the buffer is empty), performs the write when both are held and
  the B channel is free, and answers on B: OKAY for a mapped offset (writes to read-only bits
  are ignored), SLVERR for an unmapped one;
* applies byte strobes ``wstrb`` to software-writable fields and to write-1 strobes;
* accepts AR while the R channel is free and answers the next cycle with the read value and
  OKAY, or 0 and SLVERR for an unmapped offset; read-to-clear fields clear on that read (a
  hardware event in the same cycle stays pending);
* holds ``bvalid``/``bresp`` and ``rvalid``/``rdata``/``rresp`` until the master takes them.

Throughput: one write every 3 cycles and one read every 2 cycles at most, ample for a
control bank. Latency: B two cycles after the later of AW and W; R one cycle after AR.

Read path (what the LUTs go to; figures of seed 000's map in docs/seed000-registers.md):

* the read multiplexer is one tree of 2:1 multiplexers per data bit, keyed on the word
  address bits from the least significant, over the registers that have a source for that
  bit; unmapped offsets are don't-cares (a subtree over a single source, or over one source
  repeated, is a wire) because the response register's synchronous reset zeroes the data of
  an unmapped read (a comparator per register and an AND-OR over all registers, what a
  ``case`` statement becomes, cost 1.7 times as many LUTs for seed 000's map);
* the plain 32-bit software registers (no side effect, reset value 0: :func:`ram_registers`)
  are read from a copy in a distributed-RAM memory (one word per register, written with the
  same byte strobes as the flip-flops), which is one source per bit in the tree instead of
  one per register. The RAM index is a linear function of the word address (XORs of at most
  three address bits, :func:`ram_index`). A reset does not clear a RAM, so a flag per
  register records whether it was written since reset: an unwritten one reads 0 (its reset
  value), and the first write after reset writes the bytes its strobe leaves out as 0. The
  flip-flops stay the registers' fabric outputs.

The fabric side has, per register (``NAME`` as in the map): ``i_NAME`` (32-bit input) for
bits the fabric drives, ``o_NAME`` (32-bit output) for the stored software-writable bits,
``p_NAME`` (one-cycle write-1 strobe mask) for ``singlepulse`` fields and ``set_NAME``
(bit mask input) for ``hwset`` fields. The bank is cycle-exact to
:class:`navgate.hw.regmap.RegisterFileModel` at the transaction level.
"""

from __future__ import annotations

import itertools
import math
from functools import cache

from amaranth import Cat, Const, Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from navgate.gateware.parameters import CheckedParameters
from navgate.hw.regmap import OKAY, SLVERR, RegisterMap


def axi_lite_signature(addr_width: int, data_width: int = 32) -> wiring.Signature:
    """The AXI4-Lite signature seen from the master (flip it for a slave)."""
    return wiring.Signature({
        "awaddr": Out(addr_width), "awprot": Out(3), "awvalid": Out(1), "awready": In(1),
        "wdata": Out(data_width), "wstrb": Out(data_width // 8), "wvalid": Out(1),
        "wready": In(1),
        "bresp": In(2), "bvalid": In(1), "bready": Out(1),
        "araddr": Out(addr_width), "arprot": Out(3), "arvalid": Out(1), "arready": In(1),
        "rdata": In(data_width), "rresp": In(2), "rvalid": In(1), "rready": Out(1),
    })


class AxiLiteRegisterBank(CheckedParameters, wiring.Component):
    """AXI4-Lite register bank of a SystemRDL map (see the module docstring)."""

    LATENCY = 2
    THROUGHPUT = 1 / 3
    #: read the plain 32-bit registers from a distributed-RAM copy when the map has at least
    #: this many (a 64-deep copy costs 12 RAM64M, 48 LUTs of distributed RAM)
    RAM_MIN = 8

    @classmethod
    def check_parameters(cls, regmap: RegisterMap, fabric_reads: tuple[str, ...] = ()) -> None:
        """Every fabric read must be a register of the RAM copy (before the bank exists)."""
        if fabric_reads:
            mirrored, _rows = _mirror(regmap, cls.RAM_MIN)
            names = {r.name for r in mirrored}
            missing = [n for n in fabric_reads if n not in names]
            if missing:
                raise ValueError("fabric reads need registers of the RAM copy (plain 32-bit "
                                 f"read-write, reset 0): {', '.join(missing)}")

    def __init__(self, regmap: RegisterMap, fabric_reads: tuple[str, ...] = ()):
        self.regmap = regmap
        #: registers the fabric reads through a second read port of the RAM copy
        #: (``fr_word`` = word address, ``fr_data`` = the register's value, combinational):
        #: for a block that reads one of many registers at a time, instead of a multiplexer
        #: of their ``o_`` outputs (whose flip-flops synthesis then removes if nothing else
        #: reads them). Each must be a register of the RAM copy.
        self.fabric_reads = tuple(fabric_reads)
        members = {"axi": In(axi_lite_signature(regmap.address_width))}
        if self.fabric_reads:
            members["fr_word"] = In(regmap.address_width - 2)
            members["fr_data"] = Out(32)
        for reg in regmap.registers:
            if reg.hw_input_mask:
                members[f"i_{reg.name}"] = In(32)
            if reg.outputs_to_fabric:
                members[f"o_{reg.name}"] = Out(32)
            if reg.pulse_mask:
                members[f"p_{reg.name}"] = Out(32)
            if reg.hw_set_mask:
                members[f"set_{reg.name}"] = In(32)
        super().__init__(wiring.Signature(members))
        #: the write buffers' state (AW held, W held), exposed for the formal proof
        self.channel_state = {"aw_full": Signal(name="aw_full"), "w_full": Signal(name="w_full")}

    def write_artifacts(self, out_dir, name: str):
        """The C header (``NAME.h``) and Markdown docs (``NAME.md``) of the map, from its
        SystemRDL source (called by ``navgate build``)."""
        from pathlib import Path

        from navgate.hw.regmap import export_c_header, export_markdown

        if self.regmap.source is None:
            return []
        out_dir = Path(out_dir)
        return [export_c_header(self.regmap.source, out_dir / f"{name}.h"),
                export_markdown(self.regmap.source, out_dir / f"{name}.md")]

    def elaborate(self, platform):
        m = Module()
        axi = self.axi
        regmap = self.regmap
        word_bits = regmap.address_width - 2
        mirrored, rows = _mirror(regmap, self.RAM_MIN)
        mirrored_names = {r.name for r in mirrored}

        storage = {}
        for reg in regmap.registers:
            if reg.storage_mask:
                storage[reg.name] = Signal(32, name=f"r_{reg.name}",
                                           init=reg.reset_value & reg.storage_mask)
                if reg.outputs_to_fabric:
                    m.d.comb += getattr(self, f"o_{reg.name}").eq(
                        storage[reg.name] & reg.storage_mask)

        # ---------------------------------------------------------------- write channels
        aw_full = self.channel_state["aw_full"]
        aw_word = Signal(word_bits)
        w_full = self.channel_state["w_full"]
        w_data = Signal(32)  # the write data with the bytes that wstrb leaves out zeroed
        w_strb = Signal(4)
        m.d.comb += [axi.awready.eq(~aw_full), axi.wready.eq(~w_full)]
        with m.If(axi.awvalid & ~aw_full):
            m.d.sync += [aw_full.eq(1), aw_word.eq(axi.awaddr[2:])]
        with m.If(axi.wvalid & ~w_full):
            m.d.sync += [w_full.eq(1), w_strb.eq(axi.wstrb)]
            for lane in range(4):
                # the zeroing maps onto the flip-flops' synchronous reset
                m.d.sync += w_data[8 * lane:8 * lane + 8].eq(
                    Mux(axi.wstrb[lane], axi.wdata[8 * lane:8 * lane + 8], 0))

        bvalid = Signal()
        bresp = Signal(2)
        m.d.comb += [axi.bvalid.eq(bvalid), axi.bresp.eq(bresp)]
        with m.If(bvalid & axi.bready):
            m.d.sync += bvalid.eq(0)
        do_write = Signal()
        m.d.comb += do_write.eq(aw_full & w_full & ~bvalid)
        byte_mask = Signal(32)
        m.d.comb += byte_mask.eq(Cat(*[w_strb[i].replicate(8) for i in range(4)]))
        mapped_w = Signal()
        m.d.comb += mapped_w.eq(Cat(*[aw_word == (r.offset >> 2)
                                      for r in regmap.registers]).any())

        # ---------------------------------------------------------------- read channels
        rvalid = Signal()
        rdata = Signal(32)
        rresp = Signal(2)
        m.d.comb += [axi.rvalid.eq(rvalid), axi.rdata.eq(rdata), axi.rresp.eq(rresp),
                     axi.arready.eq(~rvalid)]
        with m.If(rvalid & axi.rready):
            m.d.sync += rvalid.eq(0)
        do_read = Signal()
        m.d.comb += do_read.eq(axi.arvalid & ~rvalid)
        ar_word = Signal(word_bits)
        m.d.comb += ar_word.eq(axi.araddr[2:])

        # ---------------------------------------------------------------- per register
        written = {}
        for reg in regmap.registers:
            word = reg.offset >> 2
            hit_w = Signal(name=f"hit_w_{reg.name}")
            m.d.comb += hit_w.eq(do_write & (aw_word == word))
            if reg.pulse_mask:
                pulse = getattr(self, f"p_{reg.name}")
                m.d.sync += pulse.eq(0)
                with m.If(hit_w):
                    m.d.sync += pulse.eq(w_data & reg.pulse_mask)
            if reg.name in mirrored_names:
                written[reg.name] = Signal(name=f"written_{reg.name}")
                with m.If(hit_w):
                    m.d.sync += written[reg.name].eq(1)
            if reg.name in storage:
                value = storage[reg.name]
                if not (reg.read_clear_mask or reg.hw_set_mask):
                    # plain software storage: per byte lane, a clock enable and the write data
                    # (maps onto the flip-flops' CE pins, no logic per bit)
                    for lane in range(4):
                        lane_mask = (reg.sw_write_mask >> (8 * lane)) & 0xFF
                        if not lane_mask:
                            continue
                        bits = slice(8 * lane, 8 * lane + 8)
                        with m.If(hit_w & w_strb[lane]):
                            if lane_mask == 0xFF:
                                m.d.sync += value[bits].eq(w_data[bits])
                            else:
                                m.d.sync += value[bits].eq((value[bits] & ~lane_mask)
                                                           | (w_data[bits] & lane_mask))
                    continue
                nxt = Signal(32, name=f"next_{reg.name}")
                m.d.comb += nxt.eq(value)
                if reg.sw_write_mask:
                    keep = Signal(32, name=f"wkeep_{reg.name}")
                    m.d.comb += keep.eq(byte_mask & reg.sw_write_mask)
                    with m.If(hit_w):
                        m.d.comb += nxt.eq((value & ~keep) | (w_data & keep))
                cleared = Signal(32, name=f"clr_{reg.name}")
                if reg.read_clear_mask:
                    hit_r = Signal(name=f"hit_r_{reg.name}")
                    m.d.comb += hit_r.eq(do_read & (ar_word == word))
                    m.d.comb += cleared.eq(nxt & ~Mux1(hit_r, reg.read_clear_mask))
                else:
                    m.d.comb += cleared.eq(nxt)
                if reg.hw_set_mask:
                    hw_set = getattr(self, f"set_{reg.name}")
                    m.d.sync += value.eq(cleared | (hw_set & reg.hw_set_mask))
                else:
                    m.d.sync += value.eq(cleared)

        # ------------------------------------------- read copy of the mirrored registers
        ram_data = None
        unwritten_r = None
        if mirrored:
            words = [r.offset >> 2 for r in mirrored]
            ram = Memory(shape=32, depth=1 << len(rows), init=[])
            m.submodules.read_copy = ram
            wp = ram.write_port(granularity=8)
            rp = ram.read_port(domain="comb")
            written_w = Signal()
            m.d.comb += written_w.eq(_as_value(mux_tree(
                aw_word, {r.offset >> 2: written[r.name] for r in mirrored}, word_bits)))
            hit_mirrored = Signal()
            m.d.comb += hit_mirrored.eq(do_write & Cat(*[aw_word == w for w in words]).any())
            m.d.comb += [
                wp.addr.eq(index_of(aw_word, rows)),
                wp.data.eq(w_data),
                # the first write after reset also writes the bytes it leaves out (as 0)
                wp.en.eq(hit_mirrored.replicate(4) & (w_strb | (~written_w).replicate(4))),
                rp.addr.eq(index_of(ar_word, rows)),
            ]
            ram_data = [rp.data[b] for b in range(32)]
            unwritten_r = Signal()
            leaves = {r.offset >> 2: 0 for r in regmap.registers}
            leaves.update({r.offset >> 2: ~written[r.name] for r in mirrored})
            m.d.comb += unwritten_r.eq(_as_value(mux_tree(ar_word, leaves, word_bits)))
            if self.fabric_reads:
                # the fabric's read port: the same copy at another address (a register not
                # written since reset reads 0, as on the bus)
                fp = ram.read_port(domain="comb")
                unwritten_f = Signal()
                m.d.comb += [
                    fp.addr.eq(index_of(self.fr_word, rows)),
                    unwritten_f.eq(_as_value(mux_tree(
                        self.fr_word, {regmap[n].offset >> 2: ~written[n]
                                       for n in self.fabric_reads}, word_bits))),
                    self.fr_data.eq(Mux(unwritten_f, 0, fp.data)),
                ]

        # ------------------------------------------- read multiplexer (registered response)
        mapped_r = Signal()
        m.d.comb += mapped_r.eq(Cat(*[ar_word == (r.offset >> 2)
                                      for r in regmap.registers]).any())
        read_bits = []
        for b in range(32):
            leaves = {}
            for reg in regmap.registers:
                word = reg.offset >> 2
                if reg.name in mirrored_names:
                    leaves[word] = ram_data[b]
                elif not (reg.read_mask >> b) & 1:
                    leaves[word] = 0
                elif (reg.storage_mask >> b) & 1:
                    leaves[word] = storage[reg.name][b]
                elif (reg.hw_input_mask >> b) & 1:
                    leaves[word] = getattr(self, f"i_{reg.name}")[b]
                else:
                    leaves[word] = (reg.constant_value >> b) & 1
            read_bits.append(_as_value(mux_tree(ar_word, leaves, word_bits)))
        zero = ~mapped_r if unwritten_r is None else ~mapped_r | unwritten_r
        with m.If(do_read):
            # unmapped offsets are don't-cares of the multiplexer: the flip-flops'
            # synchronous reset zeroes them
            m.d.sync += [rvalid.eq(1), rresp.eq(Mux(mapped_r, OKAY, SLVERR)),
                         rdata.eq(Mux(zero, 0, Cat(*read_bits)))]

        with m.If(do_write):
            m.d.sync += [bvalid.eq(1), bresp.eq(SLVERR), aw_full.eq(0), w_full.eq(0)]
            with m.If(mapped_w):
                m.d.sync += bresp.eq(OKAY)
        return m


def Mux1(select, mask: int):
    """``mask`` where ``select`` is 1, else 0 (a 32-bit AND with the replicated select)."""
    return select.replicate(32) & Const(mask, 32)


def _mirror(regmap: RegisterMap, ram_min: int) -> tuple[tuple, tuple | None]:
    """(registers of the RAM copy, its index rows), or ((), None) without a copy."""
    mirrored = ram_registers(regmap)
    rows = ram_index(tuple(r.offset >> 2 for r in mirrored),
                     regmap.address_width - 2) if mirrored else None
    if len(mirrored) < ram_min or rows is None:
        return (), None
    return mirrored, rows


def ram_registers(regmap: RegisterMap) -> tuple:
    """Registers whose read value can come from a distributed-RAM copy: 32 stored bits that
    software writes and reads, no side effect, reset value 0 (the copy of a register not
    written since reset reads 0)."""
    return tuple(r for r in regmap.registers
                 if r.storage_mask == r.sw_write_mask == r.read_mask == 0xFFFF_FFFF
                 and not (r.read_clear_mask or r.hw_set_mask or r.pulse_mask)
                 and r.reset_value == 0)


@cache
def ram_index(words: tuple[int, ...], nbits: int) -> tuple[int, ...] | None:
    """A linear index of ``words``: one row (a mask of word-address bits, whose parity is
    one index bit) per index bit, ``ceil(log2(len(words)))`` rows, distinct indices for
    all ``words``; None if none is found. Rows of one address bit are preferred, then XORs
    of two, then of three (each a wire or one small LUT). Depth-first search, pruned when a
    class of words that share the index so far cannot be split by the rows left, and
    bounded (a map it gives up on is read without the RAM copy)."""
    n = max(1, math.ceil(math.log2(len(words))))
    for terms in (1, 2, 3):
        candidates = [sum(1 << i for i in c) for k in range(1, terms + 1)
                      for c in itertools.combinations(range(nbits), k)]
        budget = [20_000]
        found = _search(words, candidates, n, 0, (), budget)
        if found is not None:
            return found
    return None


def _search(words, candidates, n, start, rows, budget):
    if len(rows) == n:
        return rows
    left = n - len(rows) - 1
    for i in range(start, len(candidates)):
        budget[0] -= 1
        if budget[0] < 0:
            return None
        trial = rows + (candidates[i],)
        sizes: dict[tuple, int] = {}
        for w in words:
            key = tuple(bin(w & r).count("1") & 1 for r in trial)
            sizes[key] = sizes.get(key, 0) + 1
        if max(sizes.values()) > (1 << left):
            continue
        found = _search(words, candidates, n, i + 1, trial, budget)
        if found is not None:
            return found
    return None


def index_of(word, rows):
    """The RAM index of ``word`` (a signal) under the linear index ``rows``."""
    return Cat(*[Cat(*[word[i] for i in range(len(word)) if r >> i & 1]).xor()
                 for r in rows])


def _as_value(leaf):
    return Const(leaf, 1) if isinstance(leaf, int) else leaf


def _mux_group(sel, members: dict):
    """A multiplexer on the bits of ``sel`` over ``members`` (key -> leaf); keys that are
    missing are don't-cares. Splits on the highest bit that tells members apart."""
    leaves = list(members.values())
    first = leaves[0]
    if all(leaf is first or (isinstance(leaf, int) and isinstance(first, int) and leaf == first)
           for leaf in leaves):
        return first
    for i in reversed(range(len(sel))):
        ones = {k: v for k, v in members.items() if k >> i & 1}
        zeros = {k: v for k, v in members.items() if not k >> i & 1}
        if ones and zeros:
            return Mux(sel[i], _as_value(_mux_group(sel, ones)),
                       _as_value(_mux_group(sel, zeros)))
    raise AssertionError("distinct keys always differ in a bit")


def mux_tree(sel, leaves: dict, nbits: int, step: int = 2):
    """One bit selected by ``sel`` from ``leaves`` (key -> 1-bit value or 0/1), keys missing
    from ``leaves`` being don't-cares: a tree of ``2**step``-input multiplexers on ``step``
    bits of ``sel`` at a time, from the least significant; a group whose members are all
    the same leaf (or a single one) is that leaf, with no logic."""
    entries = dict(leaves)
    lo = 0
    while lo < nbits and len(entries) > 1:
        k = min(step, nbits - lo)
        groups: dict[int, dict] = {}
        for key, leaf in entries.items():
            groups.setdefault(key >> k, {})[key & ((1 << k) - 1)] = leaf
        entries = {g: _mux_group(sel[lo:lo + k], members) for g, members in groups.items()}
        lo += k
    if not entries:
        return 0
    (leaf,) = entries.values()
    return leaf


async def sim_response(ctx, axi) -> int:
    """Amaranth testbench, master side of ``axi``: take the next B response (BREADY high until
    BVALID is sampled); its BRESP."""
    ctx.set(axi.bready, 1)
    while True:
        _, _, bvalid, bresp = await ctx.tick().sample(axi.bvalid, axi.bresp)
        if bvalid:
            break
    ctx.set(axi.bready, 0)
    return bresp


async def sim_write(ctx, axi, offset: int, data: int, strb: int = 0xF) -> int:
    """Amaranth testbench, master side of ``axi``: one write with AW and W in the same cycle
    (a slave that takes both at once, as :class:`AxiLiteRegisterBank` does), then its B
    response; BRESP."""
    ctx.set(axi.awaddr, offset)
    ctx.set(axi.wdata, data)
    ctx.set(axi.wstrb, strb)
    ctx.set(axi.awvalid, 1)
    ctx.set(axi.wvalid, 1)
    await ctx.tick()
    ctx.set(axi.awvalid, 0)
    ctx.set(axi.wvalid, 0)
    return await sim_response(ctx, axi)
