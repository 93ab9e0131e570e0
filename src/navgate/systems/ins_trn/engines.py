"""Seed 000's PL engines on the scheduled float32 datapath.

Reference: seed 000 "INS Mechanization", "Covariance Propagation", "Kalman Update Engine",
"Memory Architecture"; the programs are those of the ``fp32`` engine
(:func:`navgate.systems.ins_trn.fp32_engine.programs`), scheduled by
:mod:`navgate.gateware.scheduled` onto shared float32 units over one register file that
holds the navigation state, the error-state/bias words, the 120 stored elements of P, their
compensation words, the configuration the PS writes and the per-call inputs.
docs/seed000-engines.md describes the blocks and their figures.

Register contents are float32 bit patterns, except the IMU word inputs ``wg0..2``/``wa0..2``,
which hold the ADIS16500 int16 words as 32-bit two's complement integers (the ``cvt`` unit
converts them exactly, as the bit-true model does).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from amaranth.sim import Simulator

from navgate.gateware.scheduled import MachineImage, ScheduledMachine, Units
from navgate.systems.ins_trn.fp32_engine import programs
from navgate.systems.ins_trn.fp32_program import STATE_REGS

__all__ = ["ENGINE_UNITS", "PROGRAM_SETS", "fixed_names", "engine_image", "IMU_WORDS",
           "word_bits", "simulate_program", "simulate_calls", "random_registers"]

#: unit instances of the engines (counts chosen against the cycle targets and the DSP budget)
ENGINE_UNITS = Units(mul=4, add=4)
#: the programs each block runs
PROGRAM_SETS = {
    "ins_engines": ("propagate", "alt_gate", "alt_apply", "trn_gate", "trn_apply"),
    "kalman_update_engine": ("alt_gate", "alt_apply", "trn_gate", "trn_apply"),
    "propagation_engine": ("propagate",),
}
IMU_WORDS = ("wg0", "wg1", "wg2", "wa0", "wa1", "wa2")


def fixed_names(progs: dict) -> list:
    """Persistent registers: every state register, then every program input."""
    names = list(STATE_REGS)
    for p in progs.values():
        names += [n for n in p.inputs if n not in names]
    return names


@lru_cache(maxsize=8)
def engine_image(which: str = "ins_engines", units: Units = ENGINE_UNITS) -> MachineImage:
    allp = programs(True)
    progs = {k: allp[k] for k in PROGRAM_SETS[which]}
    return MachineImage.build(progs, units, fixed_names(allp))


def word_bits(name: str, value) -> int:
    """The register word for an input value: IMU words as two's complement integers."""
    if name in IMU_WORDS:
        return int(value) & 0xFFFFFFFF
    return int(value) & 0xFFFFFFFF


def simulate_calls(image: MachineImage, regs: dict, calls, vcd: str | None = None):
    """Run a sequence of programs in one Amaranth simulation: the register file starts from
    ``regs`` (name -> 32-bit word); each call ``(key, inputs)`` writes its inputs through the
    host port, starts program ``key``, waits for ``done`` and reads every persistent register
    and the program's outputs back through the host port. Returns one (registers: name ->
    word, outputs: name -> word, cycles from start to done) per call."""
    init = {image.layout.fixed[n]: int(v) & 0xFFFFFFFF for n, v in regs.items()}
    dut = ScheduledMachine(image, init=init)
    names = [n for n in image.layout.fixed if not n.startswith("c:")]
    results: list = []

    async def bench(ctx):
        for key, inputs in calls:
            for name, v in inputs.items():
                ctx.set(dut.host_we, 1)
                ctx.set(dut.host_waddr, image.layout.fixed[name])
                ctx.set(dut.host_wdata, int(v) & 0xFFFFFFFF)
                await ctx.tick()
            ctx.set(dut.host_we, 0)
            ctx.set(dut.prog, dut.keys.index(key))
            ctx.set(dut.start, 1)
            await ctx.tick()
            ctx.set(dut.start, 0)
            n = 1
            while not ctx.get(dut.done):
                await ctx.tick()
                n += 1
            got = {}
            out_addr = image.output_addr(key)
            targets = [(n_, image.layout.fixed[n_]) for n_ in names] + \
                [("out:" + k, a) for k, a in out_addr.items()]
            for name, addr in targets:
                ctx.set(dut.host_raddr, addr)
                await ctx.tick()
                got[name] = ctx.get(dut.host_rdata)
            state = {k: v for k, v in got.items() if not k.startswith("out:")}
            outs = {k[4:]: v for k, v in got.items() if k.startswith("out:")}
            results.append((state, outs, n))

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    if vcd:
        with sim.write_vcd(vcd):
            sim.run()
    else:
        sim.run()
    return results


def simulate_program(image: MachineImage, key: str, regs: dict):
    """One program from ``regs`` (inputs included): (registers, outputs, cycles)."""
    return simulate_calls(image, regs, [(key, {})])[0]


def random_registers(rng: np.random.Generator, names) -> dict:
    """Random float32 words of moderate magnitude (sign, exponent in [-8, 8], mantissa)."""
    out = {}
    for n in names:
        if n in IMU_WORDS:
            out[n] = int(rng.integers(-32768, 32768)) & 0xFFFFFFFF
            continue
        v = np.float32(rng.uniform(1.0, 2.0) * 2.0 ** rng.integers(-8, 9)
                       * (1 if rng.random() < 0.5 else -1))
        out[n] = int(v.view(np.uint32))
    return out
