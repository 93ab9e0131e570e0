"""Seed 000 ``interrupt_gen``: the update and error interrupts to the PS.

Events (one-cycle pulses from the engines and the sensor subsystem) set the pending bits of
IRQ_STATUS (read to clear, in the register bank); the interrupt line to the Zynq's
IRQ_F2P[0] is high while any pending bit is enabled in IRQ_ENABLE (level-sensitive, so a
pending event is never lost between the PS's read and its return from the handler). The
line is registered (no glitches into the PS's interrupt controller).
"""


from amaranth import Cat, Module
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

#: bit positions in IRQ_ENABLE / IRQ_STATUS (docs/seed000-registers.md)
UPDATE, ERROR = 0, 1


class InterruptGenerator(wiring.Component):
    """``set_status`` to the bank's ``set_IRQ_STATUS``; ``status``/``enable`` from its
    ``o_IRQ_STATUS``/``o_IRQ_ENABLE``; ``irq`` to the PS."""

    LATENCY = 2  #: event -> pending bit (bank register) -> irq register
    THROUGHPUT = 1

    update_event: In(1)
    error_event: In(1)
    status: In(2)
    enable: In(2)
    set_status: Out(32)
    irq: Out(1)

    def elaborate(self, platform):
        m = Module()
        m.d.comb += self.set_status.eq(Cat(self.update_event, self.error_event))
        m.d.sync += self.irq.eq((self.status & self.enable).any())
        return m
