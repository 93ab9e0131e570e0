"""Seed 000 interrupt_gen with the register bank: an event sets IRQ_STATUS, the line follows
IRQ_ENABLE, a read clears it, and an event arriving in the cycle of the read is kept."""

from __future__ import annotations

from amaranth import Module
from amaranth.sim import Simulator

from navgate.gateware.axi_lite import AxiLiteRegisterBank, sim_write
from navgate.systems.ins_trn.pl.interrupts import InterruptGenerator
from navgate.systems.ins_trn.pl.registers import register_map


def test_interrupt_line_follows_pending_and_enabled_bits():
    regmap = register_map()
    bank = AxiLiteRegisterBank(regmap)
    irq = InterruptGenerator()
    m = Module()
    m.submodules.bank, m.submodules.irq = bank, irq
    m.d.comb += [bank.set_IRQ_STATUS.eq(irq.set_status), irq.status.eq(bank.o_IRQ_STATUS),
                 irq.enable.eq(bank.o_IRQ_ENABLE)]
    axi = bank.axi
    seen = {}

    async def write(ctx, offset, value):
        await sim_write(ctx, axi, offset, value)

    async def read(ctx, offset, event_now=False):
        ctx.set(axi.araddr, offset)
        ctx.set(axi.arvalid, 1)
        if event_now:
            ctx.set(irq.update_event, 1)
        await ctx.tick()
        ctx.set(irq.update_event, 0)
        ctx.set(axi.arvalid, 0)
        ctx.set(axi.rready, 1)
        _, _, data = await ctx.tick().sample(axi.rdata)
        ctx.set(axi.rready, 0)
        return data

    async def testbench(ctx):
        status = regmap["IRQ_STATUS"].offset
        ctx.set(irq.update_event, 1)
        await ctx.tick()
        ctx.set(irq.update_event, 0)
        await ctx.tick().repeat(2)
        seen["masked"] = ctx.get(irq.irq)  # pending but not enabled
        await write(ctx, regmap["IRQ_ENABLE"].offset, 0b11)
        await ctx.tick().repeat(2)
        seen["enabled"] = ctx.get(irq.irq)
        seen["first read"] = await read(ctx, status, event_now=True)
        await ctx.tick().repeat(2)
        seen["after read with event"] = ctx.get(irq.irq)
        seen["second read"] = await read(ctx, status)
        await ctx.tick().repeat(2)
        seen["after second read"] = ctx.get(irq.irq)
        ctx.set(irq.error_event, 1)
        await ctx.tick()
        ctx.set(irq.error_event, 0)
        await ctx.tick().repeat(2)
        seen["error"] = (ctx.get(irq.irq), await read(ctx, status))

    sim = Simulator(m)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()
    assert seen == {"masked": 0, "enabled": 1, "first read": 0b01,
                    "after read with event": 1, "second read": 0b01,
                    "after second read": 0, "error": (1, 0b10)}
