"""The console conventions of the command line: result tables on stdout, progress, notes and
"wrote ..." lines on stderr (:func:`consoles`); ``--quiet`` hides table and progress, never
errors or warnings. The Numba compile note is printed only when Numba compiles
(:func:`numba_note`); :func:`hardware_line` is the one line of a simulated PL's counts.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator


def consoles(quiet: bool = False):
    """(stdout console for result tables, stderr console for progress/notes); quiet hides
    both (errors and warnings are printed by :func:`navgate.cli.main`, not through them)."""
    from rich.console import Console

    return Console(quiet=quiet), Console(stderr=True, quiet=quiet, soft_wrap=True)


@contextlib.contextmanager
def numba_note(console) -> Iterator[None]:
    """Within the block, print the compile note once, and only when Numba starts compiling a
    kernel (Numba's ``numba:compile`` event), so that a cached run prints nothing and a
    first run's bar standing still says why."""
    try:
        from numba.core import event
    except ImportError:  # pragma: no cover
        yield
        return
    shown = []

    class _Note(event.Listener):
        def on_start(self, ev):
            if not shown:
                shown.append(True)
                console.print("compiling Numba kernels (first run only, up to a minute; "
                              "cached afterwards)", style="dim")

        def on_end(self, ev):
            pass

    with event.install_listener("numba:compile", _Note()):
        yield


def hardware_line(hw: dict) -> str:
    """One line of a PL's counts (summary "hardware"): a simulated one's cycles, or the
    board's fabric's events."""
    if "update_interrupts" in hw:
        if "simulated_cycles" in hw:
            head = (f"{hw['simulated_cycles'] / 1e6:.1f} M cycles simulated "
                    f"({hw['cycles_per_imu_sample']:,.0f} per IMU sample), ")
        else:
            head = f"the board's fabric over {hw.get('board_bus', 'its bus')}: "
        return (head + f"{hw['update_interrupts']:,} update interrupts, "
                f"{hw['profile_dmas']:,} profile DMAs, "
                f"{hw['baro_samples_through_pins']:,} barometer samples and "
                f"{hw['ranger_frames_through_pins']:,} ranger frames through the pins")
    return (f"{hw['engine_cycles'] / 1e6:.1f} M engine cycles "
            f"({hw['engine_cycles_per_imu_sample']:,.0f} per IMU sample)")
