"""Block RAM floors of seed 000's ``ins_engines`` (issue 10: at most 4 BRAM36; issue 12: the
whole ``ins_trn_top`` at most 11), computed from the engines' own image
(:func:`navgate.systems.ins_trn.engines.engine_image`): how much block RAM any machine needs
that runs the fp32 engine's op programs from a straight-line schedule (one control word, or
one op entry, per scheduled op: the architecture issue 10 asks for), against the targets.
docs/seed000-engines.md §6 discusses the figures.

Three floors, each independent of how the schedule is encoded:

* **Operand bandwidth.** The 2-D update (``trn_gate`` + ``trn_apply``, plus one cycle per
  call) must finish in 450 cycles. With ``m`` multipliers and ``a`` adders it takes at least
  ``max(critical path, ceil(mul ops / m), ceil(add ops / a))`` cycles. Every unit reads two
  32-bit operands a cycle; a RAMB18E1 gives one 36-bit read port (simple dual port), so
  ``m + a`` units fed from block RAM need ``m + a`` BRAM36.
* **Control, per op.** A straight-line schedule names every op's two source words and its
  destination word among the register file's words: ``ceil(log2(words))`` bits each, plus
  the op kind and the two sign flips, summed over every op of every program.
* **Control, per row.** The microcode as built: rows x width, and the sum over its fields of
  each field's order-0 entropy over the rows (what an ideal coder of each field separately
  would need), plus the rows that are all zero, only write, or issue an op.

    python benchmarks/bench_bram_floor.py [--json out.json]

Prints tables and writes a JSON summary (default ``bench_bram_floor.json``).
"""

from __future__ import annotations

import argparse
import json
import math
from collections import Counter

from navgate.gateware.banked import OPERAND_STAGES, OVERHEAD, _slot_unit
from navgate.systems.ins_trn.engines import ENGINE_UNITS, engine_image

BRAM36_BITS = 36 * 1024  #: one RAMB36E1 (32 kbit data + 4 kbit parity, all usable as data)
UPDATE_2D_TARGET = 450
ENGINES_TARGET = 4.0
TOP_TARGET = 11.0
TOP_OTHER_BRAM36 = 0.5  #: the profile FIFO (64 x 128 bits, one RAMB18E1), measured
#: LUT figures measured by ``bench_top_resources.py --parts`` at commit adc625f (LUT RAM
#: counted as Vivado counts slice LUTs), to weigh banks moved into distributed RAM
TOP_LUT_MEASURED = 11_800
TOP_LUT_TARGET = 12_000


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


def update_2d_floor(img) -> dict:
    """Fewest mul + add units that a 2-D update in 450 cycles needs, by the bound above."""
    progs = [img.programs["trn_gate"], img.programs["trn_apply"]]
    n = Counter(_slot_unit(s.unit) for sp in progs for s in sp.ops)
    paths = [critical_path(sp) for sp in progs]
    lat = {s.unit: s.lat for sp in progs for s in sp.ops}
    table = {}
    best = None
    for m in range(1, 7):
        for a in range(1, 7):
            # per call: the last of ceil(n / units) issues writes OPERAND_STAGES + L later
            bound = len(progs)  # one cycle per call (start)
            for sp, path in zip(progs, paths, strict=True):
                c = Counter(s.unit for s in sp.ops)
                bound += max(path,
                             -(-c["mul"] // m) + OPERAND_STAGES + lat["mul"],
                             -(-c["add"] // a) + OPERAND_STAGES + lat["add"])
            table[(m, a)] = bound
            if bound <= UPDATE_2D_TARGET and (best is None or m + a < sum(best)):
                best = (m, a)
    return {"mul_ops": n["mul"], "add_ops": n["add"], "misc_ops": n["misc"],
            "critical_path": sum(paths) + len(progs), "bounds": table, "fewest_units": best}


def per_op_bits(img) -> dict:
    words = sum(img.layout.bank_depth)
    aw = math.ceil(math.log2(words))
    kinds = {s.kind for sp in img.programs.values() for s in sp.ops}
    kw = math.ceil(math.log2(len(kinds)))
    bits = 0
    ops = 0
    for sp in img.programs.values():
        for s in sp.ops:
            ops += 1
            bits += aw * (len(s.srcs) + 1) + kw + len(s.srcs)
    return {"ops": ops, "words": words, "address_bits": aw, "kinds": len(kinds),
            "bits": bits}


def row_stats(img) -> dict:
    f = img.fields
    rom = img.rom
    write_keys = [k for k in f.pos if k[0] in ("we", "wa", "wsrc")]
    issue_mask = 0
    for k, (off, w) in f.pos.items():
        if k not in write_keys and k != ("wmod",):
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


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", default="bench_bram_floor.json")
    args = ap.parse_args()
    img = engine_image("ins_engines")
    u = ENGINE_UNITS
    upd = update_2d_floor(img)
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
          f"ops, critical path {upd['critical_path']} cycles; cycle floor by units "
          f"(target <= {UPDATE_2D_TARGET}):")
    print("mul\\add " + "".join(f"{a:6d}" for a in range(1, 7)))
    for m in range(1, 7):
        print(f"{m:7d} " + "".join(f"{upd['bounds'][(m, a)]:6d}" for a in range(1, 7)))
    fm, fa = upd["fewest_units"]
    bank_floor = fm + fa
    print(f"fewest units within {UPDATE_2D_TARGET}: {fm} mul + {fa} add -> "
          f"{2 * bank_floor} read ports of 32 bits -> {bank_floor} BRAM36 of banks "
          f"(this machine: {u.mul} + {u.add} units, {u.banks} banks, "
          f"{2 * u.banks} RAMB18E1 = {u.banks} BRAM36)")

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

    words = per_op["words"]
    per_bank = -(-words // bank_floor)
    lutram = bank_floor * 2 * 32 * -(-per_bank // 64)
    print(f"Banks in distributed RAM instead: {words} words over {bank_floor} banks "
          f"({per_bank} words each), two read ports of 32 bits: at least {lutram} LUT6 "
          f"(one 64 x 1 LUT per bit, per read port, per 64 words); the top, measured at "
          f"{TOP_LUT_MEASURED:,} LUT with its banks in block RAM, would need "
          f"{TOP_LUT_MEASURED + lutram:,} (target <= {TOP_LUT_TARGET:,})")

    floor = bank_floor + per_op_b36
    print("\nFloors, straight-line control, banks in block RAM (BRAM36):")
    print(f"{'':34s} {'floor':>7s} {'target':>7s}")
    print(f"{'ins_engines':34s} {floor:7.2f} {ENGINES_TARGET:7.1f}")
    print(f"{'ins_engines, control alone':34s} {per_op_b36:7.2f} {ENGINES_TARGET:7.1f}")
    print(f"{'ins_trn_top':34s} {floor + TOP_OTHER_BRAM36:7.2f} {TOP_TARGET:7.1f}")
    print(f"{'ins_trn_top, banks in LUT RAM':34s} {per_op_b36 + TOP_OTHER_BRAM36:7.2f} "
          f"{TOP_TARGET:7.1f}  (LUT {TOP_LUT_MEASURED + lutram:,} > {TOP_LUT_TARGET:,})")
    summary = {"units": {"mul": u.mul, "add": u.add, "banks": u.banks},
               "programs": progs,
               "update_2d": {**{k: v for k, v in upd.items() if k != "bounds"},
                             "bounds": {f"{m}x{a}": v for (m, a), v in upd["bounds"].items()}},
               "per_op": per_op, "rows": rows,
               "banks_in_lutram": {"words_per_bank": per_bank, "lut_floor": lutram,
                                   "top_lut": TOP_LUT_MEASURED + lutram,
                                   "top_lut_target": TOP_LUT_TARGET},
               "floor_bram36": {"banks": bank_floor, "control_per_op": per_op_b36,
                                "control_rom_bits": rom_b36, "control_entropy": ent_b36,
                                "ins_engines": floor,
                                "ins_trn_top": floor + TOP_OTHER_BRAM36},
               "targets_bram36": {"ins_engines": ENGINES_TARGET, "ins_trn_top": TOP_TARGET}}
    with open(args.json, "w") as fh:
        json.dump(summary, fh, indent=2)
    print(f"\nsummary: {args.json}")


if __name__ == "__main__":
    main()
