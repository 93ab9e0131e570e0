"""Block RAM budget of seed 000's ``ins_engines`` (issue 10: at most 4 BRAM36; issue 12: the
whole ``ins_trn_top`` at most 11), worked out from the engines' own image
(:func:`navgate.systems.ins_trn.pl.nav_engines.engine_image`) for machines that run the fp32
engine's op programs from a straight-line schedule (one control word, or one op entry, per
scheduled op), against the targets. docs/seed000-engines.md §6 discusses the figures.

* **Operands.** The 2-D update (``trn_gate`` + ``trn_apply``, plus one cycle per call) must
  finish in 450 cycles. With ``m`` multipliers and ``a`` adders it takes at least
  ``max(critical path, ceil(mul ops / m) + tail, ceil(add ops / a) + tail)`` cycles per
  call. A RAMB18E1 gives one 36-bit read port (simple dual port) at one access a cycle, so
  a machine whose units read their operands from their own block RAM ports needs
  ``m + a`` BRAM36 of banks; whatever the routing, the distinct words the update reads, over
  450 cycles, need ``ceil(reads / 450)`` such ports (the bandwidth floor). Running the banks
  at twice the clock (double pumping) halves either figure.
* **Control, per op.** A schedule that names every op's two source words and its
  destination among the register file's words: ``ceil(log2(words))`` bits each, plus the
  op kind and the two sign flips, summed over every op of every program. An encoding with
  implied destinations or forwarded operands could be smaller.
* **Control, per row.** The microcode as built: rows x width, and the sum over its fields of
  each field's order-0 entropy over the rows, plus the rows that are all zero, only write,
  or issue an op.
* **Control, per slot.** One op stream per issue slot (sources and destination as bank and
  local address, flips, kind), a slot's next entry read when a 9-bit issue mask (one row a
  cycle, in its own block RAM) says it issues, each stream in block RAM: entries, widths,
  and the RAMB36E1 count at 1,024 x 36 per RAMB36 (two streams may share one as its two
  true-dual-port ports), for the local addresses as laid out and for banks of at most 128
  words.

    python benchmarks/bench_bram_floor.py [--json out.json]

Prints tables and writes a JSON summary (default ``bench_bram_floor.json``).
"""

from __future__ import annotations

import argparse
import json
import math
from collections import Counter

from navgate.opflow.schedule import OPERAND_STAGES, OVERHEAD, _slot_unit
from navgate.systems.ins_trn.pl.nav_engines import ENGINE_UNITS, engine_image

BRAM36_BITS = 36 * 1024  #: one RAMB36E1 (32 kbit data + 4 kbit parity, all usable as data)
UPDATE_2D_TARGET = 450
ENGINES_TARGET = 4.0
TOP_TARGET = 11.0
TOP_OTHER_BRAM36 = 0.5  #: the profile FIFO (64 x 128 bits, one RAMB18E1), measured
#: LUT figures measured by ``bench_top_resources.py --parts`` at commit adc625f (LUT RAM
#: counted as Vivado counts slice LUTs), to weigh banks moved into distributed RAM
TOP_LUT_MEASURED = 11_800
TOP_LUT_TARGET = 12_000
ENGINES_LUT_MEASURED = 6_356
ENGINES_LUT_TARGET = 8_000


def critical_path(sp) -> int:
    """Cycles of ``sp`` with unlimited units: each op issues as soon as its in-program
    sources are readable (issue + latency + OVERHEAD), the program ends at its last write."""
    ready: dict = {}
    end = 0
    for s in sorted(sp.ops, key=lambda s: s.issue):
        start = max([ready.get(n, 0) for n, _ in s.srcs], default=0)
        if s.kind != "mov":  # a mov's destination is a register: ops read its old value
            ready[s.dst] = start + s.lat + OVERHEAD
        end = max(end, start + OPERAND_STAGES + s.lat + 1)
    return end


def update_2d(img) -> dict:
    """Cycle bounds of the 2-D update by unit counts, fewest units within 450, and the
    distinct words it reads (each (cycle, word) once: ops sharing a read count once)."""
    progs = [img.programs["trn_gate"], img.programs["trn_apply"]]
    n = Counter(_slot_unit(s.unit) for sp in progs for s in sp.ops)
    paths = [critical_path(sp) for sp in progs]
    lat = {s.unit: s.lat for sp in progs for s in sp.ops}
    per_call = [(path, Counter(s.unit for s in sp.ops))
                for sp, path in zip(progs, paths, strict=True)]
    table = {}
    best = None
    for m in range(1, 7):
        for a in range(1, 7):
            # per call: the last of ceil(n / units) issues writes OPERAND_STAGES + L later;
            # and one cycle per call (start)
            bound = sum(max(path,
                            -(-c["mul"] // m) + OPERAND_STAGES + lat["mul"],
                            -(-c["add"] // a) + OPERAND_STAGES + lat["add"]) + 1
                        for path, c in per_call)
            table[(m, a)] = bound
            if bound <= UPDATE_2D_TARGET and (best is None or m + a < sum(best)):
                best = (m, a)
    reads = sum(len({(s.issue, name) for s in sp.ops for name, _ in s.srcs}) for sp in progs)
    return {"mul_ops": n["mul"], "add_ops": n["add"], "misc_ops": n["misc"],
            "critical_path": sum(paths) + len(progs), "bounds": table, "fewest_units": best,
            "distinct_reads": reads, "read_ports_bandwidth": -(-reads // UPDATE_2D_TARGET)}


def per_op_bits(img) -> dict:
    words = sum(img.layout.bank_depth)
    aw = math.ceil(math.log2(words))
    kinds = {s.kind for sp in img.programs.values() for s in sp.ops}
    kw = math.ceil(math.log2(len(kinds)))
    ops = sum(len(sp.ops) for sp in img.programs.values())
    bits = sum(aw * (len(s.srcs) + 1) + kw + len(s.srcs)
               for sp in img.programs.values() for s in sp.ops)
    return {"ops": ops, "words": words, "address_bits": aw, "kinds": len(kinds), "bits": bits}


def row_stats(img) -> dict:
    f = img.fields
    rom = img.rom
    issue_mask = 0
    for k, (off, w) in f.pos.items():
        if k[0] not in ("we", "wa", "wsrc", "wmod"):
            issue_mask |= ((1 << w) - 1) << off
    zero = sum(1 for r in rom if r == 0)
    issuing = sum(1 for r in rom if r & issue_mask)
    entropy = 0.0
    for off, w in f.pos.values():
        counts = Counter(r >> off & ((1 << w) - 1) for r in rom)
        entropy += -sum(c / len(rom) * math.log2(c / len(rom)) for c in counts.values())
    return {"rows": len(rom), "width": f.width, "bits": len(rom) * f.width,
            "zero_rows": zero, "write_only_rows": len(rom) - zero - issuing,
            "issue_rows": issuing, "entropy_bits_per_row": entropy,
            "entropy_bits": entropy * len(rom)}


def slot_streams(img, local_bits: int) -> dict:
    """Per-slot op streams: entries and widths, and RAMB36E1 at 1,024 x 36 each, two
    streams (or pieces of streams) to a RAMB36 at most (its two ports)."""
    u = img.units
    n_misc = len(img.misc_kinds) + 1  # the compare's lt and le are two kinds
    addr = max(1, (u.banks - 1).bit_length()) + local_bits
    entries = Counter()
    widths = {}
    for sp in img.programs.values():
        for s in sp.ops:
            entries[u.slot_of(_slot_unit(s.unit), s.inst)] += 1
    for slot, (unit, _) in enumerate(u.slots()):
        kind = {"mul": 0, "add": 1}.get(unit, math.ceil(math.log2(n_misc)))
        widths[slot] = 2 * addr + (addr + 1) + 2 + kind  # sources, destination + valid
    rows = len(img.rom)
    mask_bits = rows * len(widths)
    bits = sum(entries[s] * widths[s] for s in widths) + mask_bits
    total = sum(entries.values())
    if max(widths.values()) <= 36:
        # at least ceil(entries / 1024) RAMB36, and a port for each stream or piece
        ramb36 = max(-(-total // 1024), -(-len(widths) // 2))
    else:
        ramb36 = None  # wider than a port: 72-bit simple dual port, 512 entries a RAMB36
    return {"local_bits": local_bits, "entries": [entries[s] for s in sorted(widths)],
            "widths": [widths[s] for s in sorted(widths)], "issue_mask_bits": mask_bits,
            "bits": bits, "ramb36_streams": ramb36,
            # the 9-bit issue mask: 1,402 x 9 fits one RAMB18E1 (2,048 x 9)
            "bram36": None if ramb36 is None else ramb36 + 0.5}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", default="bench_bram_floor.json")
    args = ap.parse_args()
    img = engine_image("ins_engines")
    u = ENGINE_UNITS
    upd = update_2d(img)
    per_op = per_op_bits(img)
    rows = row_stats(img)

    print("Programs (ops by slot kind, cycles as scheduled, critical path with unlimited "
          "units)")
    print(f"{'program':10s} {'mul':>5s} {'add':>5s} {'misc':>5s} {'cycles':>7s} {'path':>5s}")
    progs = {}
    for k, sp in img.programs.items():
        n = Counter(_slot_unit(s.unit) for s in sp.ops)
        path = critical_path(sp)
        progs[k] = {"mul": n["mul"], "add": n["add"], "misc": n["misc"],
                    "cycles": sp.cycles, "critical_path": path}
        print(f"{k:10s} {n['mul']:5d} {n['add']:5d} {n['misc']:5d} {sp.cycles:7d} {path:5d}")

    print(f"\n2-D update: {upd['mul_ops']} mul + {upd['add_ops']} add + {upd['misc_ops']} misc "
          f"ops, critical path {upd['critical_path']} cycles; cycle bound by units "
          f"(target <= {UPDATE_2D_TARGET}):")
    print("mul\\add " + "".join(f"{a:6d}" for a in range(1, 7)))
    for m in range(1, 7):
        print(f"{m:7d} " + "".join(f"{upd['bounds'][(m, a)]:6d}" for a in range(1, 7)))
    fm, fa = upd["fewest_units"]
    unit_banks = fm + fa
    bw_ports = upd["read_ports_bandwidth"]
    print(f"fewest units within {UPDATE_2D_TARGET}: {fm} mul + {fa} add -> "
          f"{2 * unit_banks} read ports of 32 bits, one per operand -> {unit_banks} BRAM36 "
          f"(this machine: {u.mul} + {u.add} units, {2 * u.banks} RAMB18E1 = {u.banks} BRAM36)")
    print(f"distinct words read by the 2-D update: {upd['distinct_reads']} -> at least "
          f"{bw_ports} read ports over {UPDATE_2D_TARGET} cycles -> {bw_ports / 2} BRAM36 "
          f"(bandwidth floor); double-pumped: {unit_banks / 2} and {bw_ports / 4}")

    per_op_b36 = per_op["bits"] / BRAM36_BITS
    print(f"\nControl, per op: {per_op['ops']} ops; {per_op['words']} register words "
          f"({per_op['address_bits']}-bit addresses); {per_op['kinds']} kinds -> "
          f"{per_op['bits'] / 1000:.1f} kbit = {per_op_b36:.2f} BRAM36")
    rom_b36 = rows["bits"] / BRAM36_BITS
    ent_b36 = rows["entropy_bits"] / BRAM36_BITS
    print(f"Control, per row: {rows['rows']} x {rows['width']} = {rows['bits'] / 1000:.1f} kbit "
          f"({rom_b36:.2f} BRAM36 of bits); {rows['zero_rows']} zero rows, "
          f"{rows['write_only_rows']} write-only rows, {rows['issue_rows']} rows issue an op; "
          f"field entropy {rows['entropy_bits_per_row']:.1f} bits/row = "
          f"{rows['entropy_bits'] / 1000:.1f} kbit ({ent_b36:.2f} BRAM36)")
    streams = {}
    for lbits in sorted({img.layout.local_bits, 7}, reverse=True):
        st = slot_streams(img, lbits)
        streams[lbits] = st
        fit = ("wider than a 36-bit port" if st["bram36"] is None
               else f"{st['ramb36_streams']} RAMB36 + 0.5 for the issue mask = {st['bram36']}")
        print(f"Control, per slot ({lbits}-bit local addresses"
              f"{', as laid out' if lbits == img.layout.local_bits else ', banks <= 128 words'}):"
              f" entries {st['entries']}, widths {sorted(set(st['widths']))}, "
              f"{st['bits'] / 1000:.1f} kbit with the mask; {fit} BRAM36")

    words = per_op["words"]
    per_bank = -(-words // unit_banks)
    lutram = unit_banks * 2 * 32 * -(-per_bank // 64)
    print(f"\nBanks in distributed RAM instead: {words} words over {unit_banks} banks "
          f"({per_bank} words each), two read ports of 32 bits: at least {lutram} LUT6 "
          f"(one 64 x 1 LUT per bit, per read port, per 64 words), "
          f"{lutram // unit_banks} a bank. Measured with the banks in block RAM: top "
          f"{TOP_LUT_MEASURED:,} LUT (target <= {TOP_LUT_TARGET:,}), engines "
          f"{ENGINES_LUT_MEASURED:,} (target <= {ENGINES_LUT_TARGET:,})")

    best_streams = min(st["bram36"] for st in streams.values() if st["bram36"] is not None)
    cases = {
        "this machine by bits (synthesised: 21, 21.5)": u.banks + rom_b36,
        "banks for the fewest units, per-op control": unit_banks + per_op_b36,
        "double-pumped banks, per-slot streams": u.banks / 2 + best_streams,
        "bandwidth floor, double-pumped, per-op": bw_ports / 4 + per_op_b36,
    }
    print(f"\nBlock RAM, BRAM36 (engines; the top adds {TOP_OTHER_BRAM36} for the profile FIFO):")
    print(f"{'':44s} {'engines':>8s} {'top':>6s}")
    for name, v in cases.items():
        print(f"{name:44s} {v:8.2f} {v + TOP_OTHER_BRAM36:6.2f}")
    print(f"{'target':44s} {ENGINES_TARGET:8.1f} {TOP_TARGET:6.1f}")
    print("(per-slot streams packed two to a RAMB36E1 by hand; bench_stream_control.py "
          "synthesises that control and measures its LUT and block RAM)")
    summary = {"units": {"mul": u.mul, "add": u.add, "banks": u.banks},
               "programs": progs,
               "update_2d": {**{k: v for k, v in upd.items() if k != "bounds"},
                             "bounds": {f"{m}x{a}": v for (m, a), v in upd["bounds"].items()}},
               "per_op": per_op, "rows": rows,
               "slot_streams": {str(k): v for k, v in streams.items()},
               "banks_in_lutram": {"words_per_bank": per_bank, "lut_floor": lutram},
               "bram36": {"engines": cases,
                          "top": {k: v + TOP_OTHER_BRAM36 for k, v in cases.items()}},
               "targets": {"engines_bram36": ENGINES_TARGET, "top_bram36": TOP_TARGET,
                           "engines_lut": ENGINES_LUT_TARGET, "top_lut": TOP_LUT_TARGET},
               "measured_lut": {"engines": ENGINES_LUT_MEASURED, "top": TOP_LUT_MEASURED}}
    with open(args.json, "w") as fh:
        json.dump(summary, fh, indent=2)
    print(f"\nsummary: {args.json}")


if __name__ == "__main__":
    main()
