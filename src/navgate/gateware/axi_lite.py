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

The fabric side has, per register (``NAME`` as in the map): ``i_NAME`` (32-bit input) for
bits the fabric drives, ``o_NAME`` (32-bit output) for the stored software-writable bits,
``p_NAME`` (one-cycle write-1 strobe mask) for ``singlepulse`` fields and ``set_NAME``
(bit mask input) for ``hwset`` fields. The bank is cycle-exact to
:class:`navgate.hw.regmap.RegisterFileModel` at the transaction level.
"""

from __future__ import annotations

from amaranth import Cat, Const, Module, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

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


class AxiLiteRegisterBank(wiring.Component):
    """AXI4-Lite register bank of a SystemRDL map (see the module docstring)."""

    LATENCY = 2
    THROUGHPUT = 1 / 3

    def __init__(self, regmap: RegisterMap):
        self.regmap = regmap
        members = {"axi": In(axi_lite_signature(regmap.address_width))}
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
        w_data = Signal(32)
        w_strb = Signal(4)
        m.d.comb += [axi.awready.eq(~aw_full), axi.wready.eq(~w_full)]
        with m.If(axi.awvalid & ~aw_full):
            m.d.sync += [aw_full.eq(1), aw_word.eq(axi.awaddr[2:])]
        with m.If(axi.wvalid & ~w_full):
            m.d.sync += [w_full.eq(1), w_data.eq(axi.wdata), w_strb.eq(axi.wstrb)]

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
        for reg in regmap.registers:
            word = reg.offset >> 2
            hit_w = Signal(name=f"hit_w_{reg.name}")
            hit_r = Signal(name=f"hit_r_{reg.name}")
            m.d.comb += [hit_w.eq(do_write & (aw_word == word)),
                         hit_r.eq(do_read & (ar_word == word))]
            if reg.pulse_mask:
                pulse = getattr(self, f"p_{reg.name}")
                m.d.sync += pulse.eq(0)
                with m.If(hit_w):
                    m.d.sync += pulse.eq(w_data & byte_mask & reg.pulse_mask)
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
                    m.d.comb += cleared.eq(nxt & ~Mux1(hit_r, reg.read_clear_mask))
                else:
                    m.d.comb += cleared.eq(nxt)
                if reg.hw_set_mask:
                    hw_set = getattr(self, f"set_{reg.name}")
                    m.d.sync += value.eq(cleared | (hw_set & reg.hw_set_mask))
                else:
                    m.d.sync += value.eq(cleared)

        # read mux (registered response)
        with m.If(do_read):
            m.d.sync += [rvalid.eq(1), rdata.eq(0), rresp.eq(SLVERR)]
            with m.Switch(ar_word):
                for reg in regmap.registers:
                    with m.Case(reg.offset >> 2):
                        parts = Const(reg.constant_value & reg.read_mask, 32)
                        if reg.name in storage:
                            parts = parts | (storage[reg.name] & (reg.storage_mask
                                                                  & reg.read_mask))
                        if reg.hw_input_mask:
                            parts = parts | (getattr(self, f"i_{reg.name}")
                                             & (reg.hw_input_mask & reg.read_mask))
                        m.d.sync += [rdata.eq(parts), rresp.eq(OKAY)]

        with m.If(do_write):
            m.d.sync += [bvalid.eq(1), bresp.eq(SLVERR), aw_full.eq(0), w_full.eq(0)]
            with m.If(mapped_w):
                m.d.sync += bresp.eq(OKAY)
        return m


def Mux1(select, mask: int):
    """``mask`` where ``select`` is 1, else 0 (a 32-bit AND with the replicated select)."""
    return select.replicate(32) & Const(mask, 32)
