"""Resource, latency and Fmax table of every registered gateware block.

Prints the same markdown table as ``navgate report --timing``: xc7z020 cell counts from
Yosys ``synth_xilinx``, the xc7 logic-only critical path (Yosys ``sta``) and the ECP5 and
Nexus place-and-route Fmax proxies, then every block's xc7 critical path (see
docs/build-flow.md).

    python benchmarks/bench_resources.py [--no-timing] [--out FILE]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from rich.console import Console

from navgate.cli.build import DEFAULT_TARGET, report_markdown


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--no-timing", action="store_true", help="skip place and route")
    parser.add_argument("--target", default=DEFAULT_TARGET)
    parser.add_argument("--out", type=Path, default=None, help="also write the table here")
    args = parser.parse_args()
    table = report_markdown(not args.no_timing, args.target, Console(stderr=True))
    print(table, end="")
    if args.out is not None:
        args.out.write_text(table)


if __name__ == "__main__":
    main()
