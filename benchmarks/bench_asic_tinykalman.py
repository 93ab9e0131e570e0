"""Seed 001 TinyKalman in the IHP SG13G2 standard cells: pre-layout area, cells,
flip-flops, the smallest TinyTapeout IHP tile at 65 % density and the longest path against the
10 MHz clock, for the chip and its blocks, with :func:`navgate.hw.asic.synthesize_asic` (the
flow of ``navgate build BLOCK --asic sg13g2``). Prints a table and writes
``navgate-out/bench/bench_asic_tinykalman.json``.

Run from the checkout root (the Liberty file is ``../shared/asic``, or give its path as the
first argument): ``python benchmarks/bench_asic_tinykalman.py`` (about half a minute).
Rows: the parallel chip (``tinykalman_top``) and the serial chip (``tinykalman_serial_top``,
the bit-serial CORDIC and filter of :mod:`navgate.systems.tinykalman.serial`) and their
blocks (``serial_cordic``, ``serial_datapath``: as stream blocks, with their own input
registers, which the chip does without).
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

from navgate.hw.asic import TILES, default_liberty, synthesize_asic
from navgate.hw.verilog import emit_verilog
from navgate.systems.tinykalman.datapath import KalmanSteady, TinyKalmanCordic
from navgate.systems.tinykalman.serial import TinyKalmanSerialCordic, TinyKalmanSerialDatapath
from navgate.systems.tinykalman.spi import Mpu6500Spi
from navgate.systems.tinykalman.top import TinyKalmanSerialTop, TinyKalmanTop
from navgate.systems.tinykalman.uart import UartTx

BLOCKS = {
    "tinykalman_top": TinyKalmanTop,
    "tinykalman_serial_top": TinyKalmanSerialTop,
    "serial_cordic": TinyKalmanSerialCordic,
    "serial_datapath": TinyKalmanSerialDatapath,
    "mpu6500_spi": Mpu6500Spi,
    "tinykalman_cordic": TinyKalmanCordic,
    "kalman_steady": KalmanSteady,
    "uart_tx": UartTx,
}


def main() -> None:
    liberty = Path(sys.argv[1]) if len(sys.argv) > 1 and sys.argv[1] != "-" else default_liberty()
    if not liberty.is_file():
        sys.exit(f"Liberty file not found: {liberty}")
    rows = {}
    header = (f"{'block':20s} {'area um2':>10s} {'cells':>6s} {'FF':>4s} {'seq %':>6s} "
              f"{'1x1 %':>6s} {'1x2 %':>6s} {'tile':>5s} {'path ns':>8s} {'slack ns':>9s} "
              f"{'s':>5s}")
    print(header)
    print("-" * len(header))
    with tempfile.TemporaryDirectory() as tmp:
        only = set(sys.argv[2:])  # optional block names after the Liberty path
        for name, factory in BLOCKS.items():
            if only and name not in only:
                continue
            t0 = time.perf_counter()
            got = synthesize_asic(emit_verilog(factory(), name), name, Path(tmp) / name, liberty)
            got["seconds"] = round(time.perf_counter() - t0, 1)
            rows[name] = got
            path = got["timing"]
            print(f"{name:20s} {got['area_um2']:10.1f} {got['cells']:6d} {got['flip_flops']:4d} "
                  f"{100 * got['sequential_area_um2'] / got['area_um2']:6.1f} "
                  f"{got['tile_percent']['1x1']:6.1f} {got['tile_percent']['1x2']:6.1f} "
                  f"{got['tile'] or '-':>5s} {path['longest_path_ns']:8.3f} "
                  f"{path['slack_ns']:9.3f} {got['seconds']:5.1f}", flush=True)
    print("\ntiles (um2): " + ", ".join(f"{k} {w * h:,.0f}" for k, (w, h) in TILES.items())
          + "; fit at 65 % density; longest path: Liberty NLDM pass, pre-layout, ideal clock")
    out = Path("navgate-out/bench/bench_asic_tinykalman.json")
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"liberty": liberty.name, "blocks": rows}, indent=2,
                              default=str) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
