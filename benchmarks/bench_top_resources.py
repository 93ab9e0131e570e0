"""Resources of seed 000's ``ins_trn_top`` and of its parts on the xc7z020 (Yosys).

Synthesises the core top (``InsTrnTop``) and, each on its own, the parts that make up most
of it, with the project's flow (``navgate.hw.synth.synthesize``: Yosys ``synth_xilinx
-flatten``); then, with ``--widemux N``, the top once more with ``-widemux N`` (wide
multiplexers onto the slices' MUXF7/MUXF8, as Vivado maps them; a comparison, not the
project's flow). Prints a markdown table; writes the figures as JSON with ``--json``.
The xc7 logic-only critical path (``timing_xc7``) is given for the top and the engines. About
3 minutes per synthesis of the top on one core.

    python benchmarks/bench_top_resources.py [--parts] [--zybo] [--widemux 5] [--json F]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from navgate.hw.synth import SynthesisError, synthesize, timing_xc7
from navgate.hw.verilog import emit_verilog


def _parts():
    from navgate.systems.ins_trn.pl.nav_engines import InsEngines
    from navgate.systems.ins_trn.pl.output_formatter import NavOutputFormatter
    from navgate.systems.ins_trn.pl.profile_manager import AltitudeProfileManager
    from navgate.systems.ins_trn.pl.registers import register_bank
    from navgate.systems.ins_trn.pl.sensors.sensor_subsystem import SensorSubsystem

    return {
        "ins_engines": InsEngines,
        "register bank (AxiLiteRegisterBank of registers.rdl)": register_bank,
        "sensor subsystem (no calibration, own float units)":
            lambda: SensorSubsystem(calibrate=False),
        "output formatter (own float units)": NavOutputFormatter,
        "altitude profile manager": AltitudeProfileManager,
    }


def _memory(cells):
    return " + ".join(f"{v} {k}" for k, v in sorted(cells.items())
                      if k.startswith(("RAMB", "RAM32", "RAM64", "RAM128"))) or "-"


def _row(name, r, path=None):
    return (f"| {name} | {r['lut']:,} | {r['ff']:,} | {r['dsp']} | {r['bram36']} | "
            f"{_memory(r['cells'])} | {'-' if path is None else f'{path:.3f} ns'} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", action="store_true", help="also each part on its own")
    parser.add_argument("--zybo", action="store_true", help="also the Zybo Z7-20 variant")
    parser.add_argument("--widemux", type=int, default=None,
                        help="also the top with synth_xilinx -widemux N")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    from navgate.systems.ins_trn.pl.top import InsTrnTop, ZyboInsTrnTop

    runs = [("ins_trn_top (core)", InsTrnTop, None, True)]
    if args.zybo:
        runs.append(("ins_trn_top, Zybo Z7-20 variant", ZyboInsTrnTop, None, False))
    if args.widemux is not None:
        runs.append((f"ins_trn_top (core), -widemux {args.widemux}", InsTrnTop, args.widemux,
                     True))
    if args.parts:
        runs += [(name, make, None, name == "ins_engines") for name, make in _parts().items()]
    rows, out = [], {}
    with tempfile.TemporaryDirectory() as tmp:
        for k, (name, make, widemux, timed) in enumerate(runs):
            t0 = time.time()
            wd = Path(tmp) / f"run{k}"
            try:
                r = synthesize(emit_verilog(make(), "top"), "top", "xc7z020", wd,
                               widemux=widemux)
            except SynthesisError as exc:  # -widemux has crashed Yosys (a wasm trap) once
                print(f"{name}: synthesis failed: {str(exc)[:200]}", flush=True)
                continue
            path = timing_xc7("top", wd)["path_ns"] if timed else None
            rows.append(_row(name, r, path))
            out[name] = {**{key: r[key] for key in ("lut", "ff", "dsp", "carry4", "bram36")},
                         "memory": _memory(r["cells"]), "path_ns": path, "flow": r["flow"],
                         "seconds": round(time.time() - t0, 1)}
            print(f"{name}: {out[name]}", flush=True)
    print("\n| design | LUT | FF | DSP48E1 | BRAM36 | memory cells | xc7 logic path |")
    print("|---|---:|---:|---:|---:|---|---:|")
    print("\n".join(rows))
    if args.json is not None:
        args.json.write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
