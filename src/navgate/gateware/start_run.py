"""A start/done core behind one input and one output stream (valid/ready), with its cycles
measured: the verification wrapper of every circuit that starts on a strobe and signals done.

Many circuits start on a one-cycle strobe and raise a done flag when their results are valid
(a filter's frame, an attitude solve); verification harnesses and co-simulation engines drive
them through streams. :func:`start_run_respond` builds that wrapper's control once:

``IDLE``
    ``i.ready`` high; an accepted payload is held in ``held`` (returned) for the whole run.
preparation steps
    For each ``(flag, strobe)`` of ``steps``, in order: if the held payload's ``flag`` field
    is set, one cycle with ``strobe`` high (a reset, a parameter load, a state init).
``START``
    one cycle with ``start`` high; the cycle counter starts at 1.
``RUN``
    the counter counts until ``done``; ``cycles`` (returned) then holds the count of cycles
    from ``START`` to the cycle before ``done`` (``inclusive=False``) or to ``done`` itself
    (``inclusive=True``).
settle cycles
    ``settle`` idle cycles (a core whose flags are pipelined past ``done``).
``OUT``
    ``o.valid`` high until ``o.ready``; then back to ``IDLE``.

The caller wires ``held`` into the core and the core's results (and ``cycles``) into
``o.payload`` with combinational statements.
"""

from __future__ import annotations

from amaranth.hdl import Module, Signal

__all__ = ["start_run_respond"]


def start_run_respond(m: Module, i, o, *, start, done, width: int,
                      steps: tuple = (), inclusive: bool = False, settle: int = 0):
    """Add the wrapper's state machine to ``m``; returns ``(held, cycles)`` (see the module
    docstring). ``i``/``o`` are the stream interfaces, ``start`` the core's start strobe,
    ``done`` its done flag, ``width`` the counter width, ``steps`` the ``(flag, strobe)``
    preparation steps."""
    held = Signal(i.payload.shape(), name="held")
    count = Signal(width, name="count")
    cycles = Signal(width, name="cycles")
    step_states = [f"STEP_{flag.upper()}" for flag, _ in steps]

    def go_from(k: int, source) -> None:
        """Next state after step ``k - 1`` (or IDLE for k = 0): the first later step whose
        flag is set in ``source``, else START."""
        if k == len(steps):
            m.next = "START"
            return
        flag = steps[k][0]
        with m.If(getattr(source, flag)):
            m.next = step_states[k]
        with m.Else():
            go_from(k + 1, source)

    with m.FSM(name="start_run"):
        with m.State("IDLE"):
            m.d.comb += i.ready.eq(1)
            with m.If(i.valid):
                m.d.sync += held.eq(i.payload)
                go_from(0, i.payload)
        for k, (_flag, strobe) in enumerate(steps):
            with m.State(step_states[k]):
                m.d.comb += strobe.eq(1)
                go_from(k + 1, held)
        with m.State("START"):
            m.d.comb += start.eq(1)
            m.d.sync += count.eq(1)
            m.next = "RUN"
        with m.State("RUN"):
            m.d.sync += count.eq(count + 1)
            with m.If(done):
                m.d.sync += cycles.eq(count + 1 if inclusive else count)
                m.next = "SETTLE_0" if settle else "OUT"
        for s in range(settle):
            with m.State(f"SETTLE_{s}"):
                m.next = f"SETTLE_{s + 1}" if s + 1 < settle else "OUT"
        with m.State("OUT"):
            m.d.comb += o.valid.eq(1)
            with m.If(o.ready):
                m.next = "IDLE"
    return held, cycles
