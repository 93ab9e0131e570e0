"""Cost of per-slot op-stream control for seed 000's ``ins_engines``, against the row
microcode it would replace: the one route to issue 12's 11 BRAM36 that
``bench_bram_floor.py`` finds (with banks double-pumped) needs this control, and its LUT
decide whether the top stays within its 12,000. docs/seed000-engines.md §6.

What is synthesised (Yosys ``synth_xilinx``, xc7z020, navgate.hw.synth) is **control only,
a costing sketch** that the engines do not use and that is not simulated: the real streams
of ``engine_image("ins_engines")`` (one block RAM per issue slot, an entry per op: two
sources and a destination as bank and local address, flips, kind), a 9-bit issue mask a
row, a pointer per slot that steps when its slot issues, each bank read port's address
chosen among the slots whose source is in that bank (AND-OR), each op's destination carried
down a delay line of its latency (a timing wheel for the misc slot, whose kinds differ), and
each bank's write enable, address and (registered, one cycle early) source chosen from the
delay lines. Against it: the row microcode as built, a ``Memory`` of the image's rows with
the same program counter, synthesised alone.

    python benchmarks/bench_stream_control.py [--local-bits 8 7] [--json out.json]

``--local-bits`` 7 drops each address's top local bit, as banks of at most 128 words would
(sizing only). A few minutes a synthesis. Prints a table and writes a JSON summary
(default ``bench_stream_control.json``).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from amaranth.hdl import Const, Module, Mux, Signal, unsigned
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from navgate.hw.synth import synthesize
from navgate.hw.verilog import emit_verilog
from navgate.opflow.machine import _or_all, row_counter
from navgate.opflow.schedule import OPERAND_STAGES, _slot_unit
from navgate.systems.ins_trn.pl.nav_engines import engine_image

BANK_BITS = 3
KIND_BITS = 3
POINTER_BITS = 11


def streams_of(img, local_bits: int) -> dict:
    """Per slot: entries (srcs, kind, dst, latency) in issue order, each program's first
    entry per slot, and the issue mask rows of all programs."""
    u, lay = img.units, img.layout
    n_slots = len(u.slots())
    misc_kinds = list(img.misc_kinds) + ["le"]
    keep = (1 << local_bits) - 1
    streams = [[] for _ in range(n_slots)]
    base = {}
    mask = []

    def split(flat):
        return flat >> lay.local_bits, flat & ((1 << lay.local_bits) - 1) & keep

    for key, sp in img.programs.items():
        base[key] = [len(st) for st in streams]
        rows = [0] * sp.cycles
        addr = dict(lay.fixed)
        addr.update(lay.temp_addr[key])
        for s in sorted(sp.ops, key=lambda s: s.issue):
            slot = u.slot_of(_slot_unit(s.unit), s.inst)
            rows[s.issue] |= 1 << slot
            srcs = [(*split(addr[n]), int(f)) for n, f in s.srcs]
            srcs += [(0, 0, 0)] * (2 - len(srcs))
            dst = lay.fixed[s.dst] if s.kind == "mov" else addr.get(s.dst)
            kind = (misc_kinds.index("le" if s.kind == "le" else s.unit)
                    if slot == n_slots - 1 else int(s.kind == "sub"))
            streams[slot].append((srcs, kind, None if dst is None else split(dst), s.lat))
        mask += rows
    return {"streams": streams, "base": base, "mask": mask}


class StreamControlSketch(wiring.Component):
    """Control outputs of the engines' machine, driven from per-slot op streams."""

    def __init__(self, img, local_bits: int):
        self.img = img
        self.lb = local_bits
        self.data = streams_of(img, local_bits)
        u = img.units
        self.n_slots = len(u.slots())
        self.aw = BANK_BITS + local_bits
        self.entry_bits = 2 * (self.aw + 1) + KIND_BITS + self.aw + 1
        lb, nb, ns = local_bits, u.banks, self.n_slots
        super().__init__({
            "start": In(1), "prog": In(3), "busy": Out(1),
            "ra": Out(unsigned(lb)).array(nb, 2),
            "sel": Out(unsigned(BANK_BITS)).array(ns, 2), "flip": Out(1).array(ns, 2),
            "iss": Out(1).array(ns), "kind": Out(KIND_BITS).array(ns),
            "we": Out(1).array(nb), "wa": Out(unsigned(lb)).array(nb),
            "wsrc": Out(4).array(nb),
        })

    def encode(self, entry) -> int:
        srcs, kind, dst, _ = entry
        v, off = 0, 0
        for bank, local, flip in srcs:
            v |= ((bank << self.lb | local) | flip << self.aw) << off
            off += self.aw + 1
        v |= kind << off
        off += KIND_BITS
        if dst is not None:
            v |= ((dst[0] << self.lb | dst[1]) | 1 << self.aw) << off
        return v

    def elaborate(self, platform):
        m = Module()
        img, lb, aw, ns = self.img, self.lb, self.aw, self.n_slots
        streams, base, mask_rows = self.data["streams"], self.data["base"], self.data["mask"]
        m.submodules.mask = mask_rom = Memory(shape=unsigned(ns), depth=len(mask_rows),
                                              init=mask_rows)
        seq = row_counter(m, img.spans(), self.start, self.prog)
        running, go = seq.running, seq.go
        ptr_base = [Signal(POINTER_BITS, name=f"ptr_base{s}") for s in range(ns)]
        with m.Switch(self.prog):
            for i, k in enumerate(img.programs):
                with m.Case(i):
                    m.d.comb += [ptr_base[s].eq(base[k][s]) for s in range(ns)]
        mask_port = mask_rom.read_port()
        m.d.comb += [self.busy.eq(running), mask_port.addr.eq(seq.nxt)]
        issue = Signal(ns)
        m.d.comb += issue.eq(mask_port.data & running.replicate(ns))
        entries, wheels = [], []
        for s in range(ns):
            init = [self.encode(e) for e in streams[s]]
            mem = Memory(shape=unsigned(self.entry_bits), depth=max(2, len(init)),
                         init=init or [0])
            m.submodules[f"stream{s}"] = mem
            port = mem.read_port()
            ptr, ptr_next = Signal(POINTER_BITS, name=f"ptr{s}"), Signal(POINTER_BITS)
            m.d.comb += [ptr_next.eq(Mux(go, ptr_base[s], Mux(issue[s], ptr + 1, ptr))),
                         port.addr.eq(ptr_next)]
            m.d.sync += ptr.eq(ptr_next)
            e = port.data
            entries.append(e)
            off = 0
            for j in range(2):
                m.d.comb += [self.sel[s][j].eq(e[off + lb:off + aw]),
                             self.flip[s][j].eq(e[off + aw])]
                off += aw + 1
            kind = e[off:off + KIND_BITS]
            off += KIND_BITS
            dst = e[off:off + aw + 1]  # local, bank, valid
            m.d.comb += [self.iss[s].eq(issue[s]), self.kind[s].eq(kind)]
            # timing wheel: an op of latency L is written OPERAND_STAGES + L cycles after
            # issue; stage 0 is the write cycle
            lat_of_kind = {}
            for e_ in streams[s]:
                lat_of_kind.setdefault(e_[1], e_[3])
            depth = max(lat_of_kind.values(), default=0) + OPERAND_STAGES
            stages = [Signal(aw + 1, name=f"dst{s}_{i}") for i in range(max(2, depth))]
            for i, st in enumerate(stages):
                shifted = stages[i + 1] if i + 1 < len(stages) else Const(0, aw + 1)
                kinds = [k for k, lat in lat_of_kind.items() if lat + OPERAND_STAGES - 1 == i]
                if not kinds:
                    m.d.sync += st.eq(shifted)
                    continue
                hit = issue[s] & dst[aw]
                if len(set(lat_of_kind.values())) > 1:
                    hit = hit & _or_all([kind == k for k in kinds])
                m.d.sync += st.eq(Mux(hit, dst, shifted))
            wheels.append(stages)
        for b in range(img.units.banks):
            for j in range(2):
                off = j * (aw + 1)
                m.d.comb += self.ra[b][j].eq(_or_all([
                    Mux(issue[s] & (entries[s][off + lb:off + aw] == b),
                        entries[s][off:off + lb], 0) for s in range(ns)]))
            hits = [w[0][aw] & (w[0][lb:aw] == b) for w in wheels]
            early = [w[1][aw] & (w[1][lb:aw] == b) for w in wheels]
            wsrc = Signal(4, name=f"wsrc{b}")
            m.d.sync += wsrc.eq(_or_all([Mux(h, s, 0) for s, h in enumerate(early)]))
            m.d.comb += [self.we[b].eq(_or_all(hits)), self.wsrc[b].eq(wsrc),
                         self.wa[b].eq(_or_all([Mux(h, w[0][:lb], 0)
                                            for h, w in zip(hits, wheels, strict=True)]))]
        return m


class RowMicrocode(wiring.Component):
    """The row microcode as built: a ROM of the image's rows and its program counter."""

    def __init__(self, img):
        self.img = img
        super().__init__({"start": In(1), "prog": In(3), "busy": Out(1),
                          "ctl": Out(img.fields.width)})

    def elaborate(self, platform):
        m = Module()
        img = self.img
        m.submodules.rom = rom = Memory(shape=unsigned(img.fields.width), depth=len(img.rom),
                                        init=img.rom)
        seq = row_counter(m, img.spans(), self.start, self.prog)
        port = rom.read_port()
        m.d.comb += [self.busy.eq(seq.running), port.addr.eq(seq.nxt), self.ctl.eq(port.data)]
        return m


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--local-bits", type=int, nargs="*", default=[8, 7])
    ap.add_argument("--json", default="bench_stream_control.json")
    args = ap.parse_args()
    img = engine_image("ins_engines")
    designs = {"row microcode (as built)": (RowMicrocode(img), None)}
    for lb in args.local_bits:
        sketch = StreamControlSketch(img, lb)
        designs[f"per-slot streams, {lb}-bit local"] = (sketch, sketch)
    summary = {}
    print(f"{'control':34s} {'LUT':>6s} {'FF':>6s} {'BRAM36':>7s}  memories")
    for name, (design, sketch) in designs.items():
        with tempfile.TemporaryDirectory() as wd:
            r = synthesize(emit_verilog(design, "top"), "top", "xc7z020", Path(wd))
        mems = {k: v for k, v in r["cells"].items() if k.startswith(("RAM", "SRL"))}
        extra = ({} if sketch is None else
                 {"entry_bits": sketch.entry_bits,
                  "entries": [len(st) for st in sketch.data["streams"]]})
        summary[name] = {"lut": r["lut"], "ff": r["ff"], "bram36": r["bram36"],
                         "cells": mems, **extra}
        print(f"{name:34s} {r['lut']:6d} {r['ff']:6d} {r['bram36']:7.1f}  {mems}", flush=True)
    with open(args.json, "w") as fh:
        json.dump(summary, fh, indent=2)
    print(f"summary: {args.json}")


if __name__ == "__main__":
    main()
