"""Seed 001 TinyKalman: size of the chip and its blocks (Yosys generic NAND/NOR gates and
xc7z020 resources), the CORDIC at the upstream design's 8-bit/8-stage configuration for
comparison, and the per-sample timing budget. Prints a table and writes
``navgate-out/bench/tinykalman_resources.json``.

Run: ``python benchmarks/tinykalman_resources.py [BLOCK ...]`` (a few minutes: YoWASP Yosys;
block names pick rows, e.g. ``tinykalman_serial_top``).
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

from navgate.gateware.cordic import CordicAtan2Iterative
from navgate.hw.synth import GENERIC_FLOW, SynthesisError, generic_gates, synthesize
from navgate.hw.verilog import emit_verilog
from navgate.systems.tinykalman.datapath import KalmanSteady, TinyKalmanCordic
from navgate.systems.tinykalman.spi import Mpu6500Spi
from navgate.systems.tinykalman.top import TinyKalmanSerialTop, TinyKalmanTop, timing
from navgate.systems.tinykalman.uart import UartTx

BLOCKS = {
    "tinykalman_top": TinyKalmanTop,
    "tinykalman_serial_top": TinyKalmanSerialTop,
    "mpu6500_spi": Mpu6500Spi,
    "tinykalman_cordic": TinyKalmanCordic,  # not a registered block (synth_xilinx aborts)
    "kalman_steady": KalmanSteady,
    "uart_tx": UartTx,
    "cordic_iter_16x16_g0": lambda: CordicAtan2Iterative(16, 16, 16, guard_bits=0),
    "cordic_iter_8x8_upstream_cfg": lambda: CordicAtan2Iterative(8, 8, 16, guard_bits=0),
}


def _retry(fn, *args):
    """YoWASP Yosys has been seen to trap (wasm ``unreachable``) on a heavily loaded machine
    and pass on the next try: one retry."""
    try:
        return fn(*args)
    except SynthesisError as error:
        print(f"  retrying after: {str(error)[:80]}", flush=True)
        return fn(*args)


def main() -> None:
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        only = set(sys.argv[1:])
        for name, factory in BLOCKS.items():
            if only and name not in only:
                continue
            t0 = time.perf_counter()
            text = emit_verilog(factory(), name)
            gen = _retry(generic_gates, text, name, Path(tmp) / name / "generic")
            try:
                xc7 = _retry(synthesize, text, name, "xc7z020", Path(tmp) / name / "xc7")
            except SynthesisError as error:
                xc7 = {k: None for k in ("lut", "ff", "dsp", "carry4", "bram36")}
                xc7["error"] = str(error)[:200]
            rows[name] = {"generic": {k: gen[k] for k in ("cells", "gates", "flops")},
                          "generic_cell_types": gen["cell_types"],
                          "xc7z020": xc7 if "error" in xc7 else {
                              k: xc7[k] for k in ("lut", "ff", "dsp", "carry4", "bram36")},
                          "seconds": round(time.perf_counter() - t0, 1)}
            print(f"{name:30s} generic cells {gen['cells']:6d} (NAND/NOR/NOT {gen['gates']:6d}, "
                  f"flops {gen['flops']:4d})  xc7z020 LUT {xc7['lut']} FF {xc7['ff']} "
                  f"DSP {xc7['dsp']} CARRY4 {xc7['carry4']}", flush=True)
    out = {"flow_generic": GENERIC_FLOW, "blocks": rows, "timing_default": timing()}
    path = Path("navgate-out/bench/tinykalman_resources.json")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2) + "\n")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
