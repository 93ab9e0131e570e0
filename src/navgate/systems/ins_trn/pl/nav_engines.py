"""Seed 000's PL engines on the scheduled float32 datapath.

Reference: seed 000 "INS Mechanization", "Covariance Propagation", "Kalman Update Engine",
"Memory Architecture"; the programs are those of the ``fp32`` engine
(:func:`navgate.systems.ins_trn.pl.fp32_program.programs`), scheduled by
:mod:`navgate.opflow.schedule` onto shared float32 units over one register file that
holds the navigation state, the error-state/bias words, the 120 stored elements of P, their
compensation words, the configuration the PS writes and the per-call inputs.
docs/seed000-engines.md describes the blocks and their figures.

Register contents are float32 bit patterns, except the IMU word inputs ``wg0..2``/``wa0..2``,
which hold the ADIS16500 int16 words as 32-bit two's complement integers (the ``cvt`` unit
converts them exactly, as the bit-true model does).
"""

from __future__ import annotations

from fractions import Fraction
from functools import lru_cache

import numpy as np
from amaranth.sim import Simulator

from navgate.numerics.fp32 import float_to_bits
from navgate.opflow.ir import Program
from navgate.opflow.loopmachine import run_to_done
from navgate.opflow.machine import BankedImage, ScheduledMachineStream
from navgate.opflow.schedule import BankedUnits
from navgate.systems.ins_trn.pl.fp32_program import RESET_MODULE, STATE_REGS, programs

__all__ = ["InsEngines", "KalmanUpdateEngine", "InsMechanization", "CovariancePropagator",
           "split_program", "engine_programs", "command_vectors", "stream_model",
           "ENGINE_UNITS", "PROGRAM_SETS", "fixed_names", "engine_image", "IMU_WORDS",
           "simulate_program", "simulate_calls", "random_registers", "reference_calls",
           "identity_p_registers"]

#: issue slots and banks of the engines (counts chosen against the 2-D update's cycle
#: target); the misc slot (div, sqrt, compare, convert, mov) writes into the eight mul/add
#: banks; split read ports: operand port j of every slot reads read port j of a bank, so
#: that every operand multiplexer has 8 inputs (16 with either port); iterative divider and
#: square root (docs/seed000-engines.md)
ENGINE_UNITS = BankedUnits(mul=4, add=4, read_ports=2, misc_bank=False, iterative=True,
                           split_ports=True)
#: the programs each block runs
PROGRAM_SETS = {
    "ins_engines": ("propagate", "alt_gate", "alt_apply", "trn_gate", "trn_apply"),
    "kalman_update_engine": ("alt_gate", "alt_apply", "trn_gate", "trn_apply"),
    "ins_mechanization": ("mechanization",),
    "covariance_propagator": ("covariance",),
}
#: modules of the propagate program that each split block runs
SPLIT_MODULES = {
    "mechanization": ("imu_calibration", "ins_mechanization"),
    "covariance": ("phi_q_generation", "covariance_propagator"),
}
IMU_WORDS = ("wg0", "wg1", "wg2", "wa0", "wa1", "wa2")


def fixed_names(progs: dict) -> list:
    """Persistent registers: every state register, then every input of ``progs``."""
    names = list(STATE_REGS)
    for p in progs.values():
        names += [n for n in p.inputs if n not in names]
    return names


def _half(prog: Program, modules):
    """(ops, imported temporaries) of the ops in ``modules`` plus the negs they read."""
    by_dst = {op.dst: op for op in prog.ops}
    keep = {op.dst for op in prog.ops if op.module in modules}
    for op in prog.ops:
        if op.module not in modules:
            continue
        for src in op.srcs:
            o = by_dst.get(src)
            while o is not None and o.kind == "neg" and o.dst not in keep:
                keep.add(o.dst)
                o = by_dst.get(o.srcs[0])
    ops = [op for op in prog.ops if op.dst in keep]
    imports = []
    for op in ops:
        for src in op.srcs:
            if src in by_dst and src not in keep and src not in imports:
                imports.append(src)
    return ops, imports


def split_program(prog: Program, modules, name: str) -> Program:
    """The ops of ``prog`` that belong to ``modules``, as a program of its own: temporaries
    it reads from the other modules become inputs (registers named like the temporaries),
    temporaries the other modules read become outputs, and it commits the registers whose
    values it computes. A ``neg`` of another module that it reads is repeated here (a sign
    flip costs nothing). Run on the same starting state, the two halves of the propagate
    program together give exactly its result (tests/systems/ins_trn/pl/test_engines.py)."""
    modules = set(modules)
    ops, imports = _half(prog, modules)
    keep = {op.dst for op in ops}
    _, other_imports = _half(prog, {op.module for op in prog.ops} - modules)
    outputs = {t: t for t in other_imports if t in keep}
    outputs.update({k: v for k, v in prog.outputs.items() if v in keep})
    commit = {r: t for r, t in prog.commit.items() if t in keep}
    inputs = tuple(n for n in prog.inputs if any(n in op.srcs for op in ops)) + tuple(imports)
    return Program(name, ops=ops, inputs=inputs, commit=commit, outputs=outputs,
                   registers=prog.registers)


def reuse_gate(gate: Program, apply: Program, prefix: str) -> tuple[Program, Program]:
    """The apply half without the work the gate half already did: every op of ``apply``
    that repeats an op of ``gate`` (same kind, same operands after this renaming) reads the
    gate's result instead, which the gate now commits to a register ``<prefix>.<temp>``
    (written in place at no cost). Both programs read the same state and inputs and the
    sequencer writes nothing between them, so the results are those of the original pair
    bit for bit (tests/systems/ins_trn/pl/test_engines.py)."""
    from navgate.opflow.ir import Op

    sig = {(op.kind, op.srcs): op.dst for op in gate.ops if op.kind != "neg"}
    ren: dict = {}
    ops = []
    kept: list = []
    for op in apply.ops:
        srcs = tuple(ren.get(x, x) for x in op.srcs)
        hit = sig.get((op.kind, srcs))
        if hit is not None:
            ren[op.dst] = f"{prefix}.{hit}"
            continue
        ops.append(Op(op.dst, op.kind, srcs, op.module))
    for op in ops:
        for x in op.srcs:
            if x.startswith(prefix + ".") and x not in kept:
                kept.append(x)
    out = {k: ren.get(v, v) for k, v in apply.outputs.items()}
    com = {k: ren.get(v, v) for k, v in apply.commit.items()}
    if any(v.startswith(prefix + ".") for v in list(out.values()) + list(com.values())):
        raise ValueError("an apply output or commit is a gate result")
    new_apply = Program(apply.name, ops=ops, inputs=tuple(apply.inputs) + tuple(kept),
                        commit=com, outputs=out, registers=apply.registers)
    commit = dict(gate.commit)
    commit.update({k: k[len(prefix) + 1:] for k in kept})
    new_gate = Program(gate.name, ops=list(gate.ops), inputs=gate.inputs, commit=commit,
                       outputs=dict(gate.outputs), registers=gate.registers)
    return new_gate, new_apply


def engine_programs() -> dict:
    """The programs the engines run: propagate (and its two halves), and the two update
    pairs with the apply half reusing the gate half's results (:func:`reuse_gate`)."""
    allp = dict(programs(True))
    for g, a in (("alt_gate", "alt_apply"), ("trn_gate", "trn_apply")):
        allp[g], allp[a] = reuse_gate(allp[g], allp[a], g)
    for key, mods in SPLIT_MODULES.items():
        allp[key] = split_program(allp["propagate"], mods, key)
    return allp


#: weights of each program's register reads in the ranking of the registers over the banks
#: (BankedImage.build): the least total cycles of the five programs over the 27 weightings
#: in {1, 2, 3} of propagate, alt_apply and trn_apply (``python
#: benchmarks/bench_bank_weights.py``; docs/seed000-engines.md, "The shorter Joseph form")
RANK_WEIGHTS = {"propagate": 3, "alt_apply": 3, "trn_apply": 1}


@lru_cache(maxsize=8)
def engine_image(which: str = "ins_engines", units: BankedUnits = ENGINE_UNITS) -> BankedImage:
    allp = engine_programs()
    progs = {k: allp[k] for k in PROGRAM_SETS[which]}
    # the compensation resets read each cP once per update, off every critical path:
    # ranking them would move the registers of every program to other banks
    return BankedImage.build(progs, units, fixed_names(progs), rank_skip=(RESET_MODULE,),
                             rank_weights=RANK_WEIGHTS)


def simulate_calls(image: BankedImage, regs: dict, calls, vcd: str | None = None,
                   write_first: bool = False):
    """Run a sequence of programs in one Amaranth simulation: the register file starts from
    ``regs`` (name -> 32-bit word; with ``write_first`` written through the host port first,
    for a machine without initial register contents); each call ``(key, inputs)`` writes its
    inputs through the host port, starts program ``key``, waits for ``done`` and reads every
    persistent register and the program's outputs back through the host port. Returns one
    (registers: name -> word, outputs: name -> word, cycles from start to done) per call."""
    init = {image.layout.fixed[n]: int(v) & 0xFFFFFFFF for n, v in regs.items()}
    dut = image.machine() if write_first else image.machine(init)
    names = [n for n in image.layout.fixed if not n.startswith("c:")]
    results: list = []

    async def bench(ctx):
        for key, inputs in ([(None, regs)] if write_first else []) + list(calls):
            for name, v in inputs.items():
                ctx.set(dut.host_we, 1)
                ctx.set(dut.host_waddr, image.layout.fixed[name])
                ctx.set(dut.host_wdata, int(v) & 0xFFFFFFFF)
                await ctx.tick()
            ctx.set(dut.host_we, 0)
            if key is None:  # the initial registers only
                continue
            ctx.set(dut.prog, dut.keys.index(key))
            n = await run_to_done(ctx, dut, 10 * image.cycles(key) + 100)
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


def reference_calls(regs: dict, calls) -> list:
    """What ``calls`` (as :func:`simulate_calls`) give in the bit-true interpreter: one
    (registers: name -> word, outputs: name -> word) per call; the IMU words are int16 in
    32-bit two's complement."""
    from navgate.opflow.execute import run_bittrue

    regs = dict(regs)
    out = []
    allp = engine_programs()
    for key, inputs in calls:
        regs.update(inputs)
        p = allp[key]
        state = {n: regs[n] for n in regs if n not in p.inputs}
        ins = {}
        for n in p.inputs:
            w = regs[n]
            ins[n] = (float(w - (1 << 32) if w >= 1 << 31 else w) if n in IMU_WORDS
                      else np.uint32(w))
        new, outs, _ = run_bittrue(p, state, ins)
        regs.update({k: int(v[0]) for k, v in new.items()})
        regs.update({k: int(v[0]) for k, v in outs.items() if k in regs})
        out.append((dict(regs), {k: int(v[0]) for k, v in outs.items()}))
    return out


def simulate_program(image: BankedImage, key: str, regs: dict):
    """One program from ``regs`` (inputs included): (registers, outputs, cycles)."""
    return simulate_calls(image, regs, [(key, {})])[0]


def random_registers(rng: np.random.Generator, names) -> dict:
    """Random float32 words of moderate magnitude (sign, exponent in [-8, 8], mantissa)."""
    out = {}
    for n in names:
        if n in IMU_WORDS:
            out[n] = int(rng.integers(-32768, 32768)) & 0xFFFFFFFF
            continue
        out[n] = float_to_bits(rng.uniform(1.0, 2.0) * 2.0 ** rng.integers(-8, 9)
                               * (1 if rng.random() < 0.5 else -1))
    return out


def identity_p_registers(rng: np.random.Generator, names) -> tuple[dict, object]:
    """Random registers (:func:`random_registers`) where the updates are meaningful: P the
    identity, its compensation words zero. Returns (registers, float -> word: the
    :func:`~navgate.numerics.fp32.float_to_bits` a PS driver writes)."""
    regs = random_registers(rng, names)
    for n in STATE_REGS:
        if n.startswith("P") or n.startswith("cP"):
            regs[n] = float_to_bits(0.0)
    for i in range(15):
        regs[f"P{i}_{i}"] = float_to_bits(1.0)
    return regs, float_to_bits


def random_program_state(rng: np.random.Generator, key: str) -> tuple[dict, dict]:
    """(state, inputs) as numbers for program ``key`` of :func:`programs`: every state register
    and input a :func:`random_registers` word, an int16 IMU word as its integer value (the
    ``cvt`` source), any other word as its float32 value."""
    prog = programs()[key]
    state = {}
    for n, w in random_registers(rng, list(STATE_REGS) + list(prog.inputs)).items():
        if n in IMU_WORDS:
            state[n] = float(w - (1 << 32) if w >= 1 << 31 else w)
        else:
            state[n] = float(np.uint32(w).view(np.float32))
    return state, {n: state.pop(n) for n in prog.inputs}


#: the directed cases of :func:`directed_program_state`
DIRECTED_CASES = ("zero_rows", "huge_tiny", "nan_inf", "zero_all", "imu_extremes")


def directed_program_state(rng: np.random.Generator, key: str, case: str) -> tuple[dict, dict]:
    """A :func:`random_program_state` with a directed edge case written into it: ``zero_rows``
    (rows 3..5 and 9 of P zero with both signs, their compensation words -0), ``huge_tiny``
    (elements of P near the float32 maximum and minimum, so products overflow and underflow;
    a tiny dt for ``propagate``), ``nan_inf`` (NaN and infinities in P, cP and the velocity),
    ``zero_all`` (P all -0, cP all +0), ``imu_extremes`` (the int16 words' ends)."""
    from navgate.systems.ins_trn.pl.fp32_program import CP_REGS, P_REGS

    if case not in DIRECTED_CASES:
        raise ValueError(f"case must be one of {DIRECTED_CASES}, got {case!r}")
    state, inputs = random_program_state(rng, key)
    upper = [(i, j) for i in range(15) for j in range(i, 15)]
    if case == "zero_rows":
        for n, (i, j) in enumerate(upper):
            if i in (3, 4, 5, 9) or j in (3, 4, 5, 9):
                state[P_REGS[n]] = 0.0 if (i + j) % 2 else -0.0
                state[CP_REGS[n]] = -0.0
    elif case == "huge_tiny":
        for n, (i, j) in enumerate(upper):
            state[P_REGS[n]] = (3e38 if (i * 7 + j) % 3 == 0 else
                                1e-30 if (i + j) % 3 == 1 else state[P_REGS[n]])
        if key == "propagate":
            state["dt"] = 1e-20
    elif case == "nan_inf":
        state[P_REGS[20]] = float("nan")
        state[CP_REGS[50]] = float("inf")
        state[P_REGS[7]] = float("-inf")
        state["vN"] = float("nan")
    elif case == "zero_all":
        for n in range(len(upper)):
            state[P_REGS[n]] = -0.0
            state[CP_REGS[n]] = 0.0
    else:  # imu_extremes
        for k, n in enumerate(IMU_WORDS):
            if n in inputs:
                inputs[n] = float(-32768 if k % 2 else 32767)
    return state, inputs


def command_vectors(image: BankedImage, regs: dict, calls) -> dict:
    """Input arrays for :class:`ScheduledMachineStream`: write every register of ``regs``,
    then per call ``(key, inputs)``: write the inputs, run ``key``, read every persistent
    register and the program's outputs."""
    from navgate.opflow.machine import CMD_READ, CMD_START, CMD_WRITE

    keys = list(image.programs)
    rows = [(CMD_WRITE, image.layout.fixed[n], int(v) & 0xFFFFFFFF, 0) for n, v in regs.items()]
    names = [n for n in image.layout.fixed if not n.startswith("c:")]
    for key, inputs in calls:
        rows += [(CMD_WRITE, image.layout.fixed[n], int(v) & 0xFFFFFFFF, 0)
                 for n, v in inputs.items()]
        rows.append((CMD_START, 0, 0, keys.index(key)))
        rows += [(CMD_READ, image.layout.fixed[n], 0, 0) for n in names]
        rows += [(CMD_READ, a, 0, 0) for a in image.output_addr(key).values()]
    arr = np.array(rows, dtype=np.int64)
    return {"cmd": arr[:, 0], "addr": arr[:, 1], "data": arr[:, 2], "prog": arr[:, 3]}


def stream_model(image: BankedImage):
    """Bit-true model of :class:`ScheduledMachineStream` over ``image`` (the register file as
    a dict, each run by :func:`navgate.systems.ins_trn.pl.fp32_exec.run_bittrue`)."""
    from navgate.opflow.machine import CMD_READ, CMD_WRITE
    from navgate.systems.ins_trn.pl.fp32_exec import run_bittrue

    keys = list(image.programs)
    allp = engine_programs()
    by_addr = {a: n for n, a in image.layout.fixed.items()}

    def model(seen: dict) -> dict:
        mem = {a: 0 for a in range(image.layout.depth)}
        mem.update(image.layout.const_init)
        data_out, cycles = [], []
        for cmd, addr, word, prog in zip(seen["cmd"], seen["addr"], seen["data"],
                                         seen["prog"], strict=True):
            cmd, addr, word = int(cmd), int(addr), int(word)
            if cmd == CMD_WRITE:
                mem[addr] = word
                data_out.append(0)
                cycles.append(0)
            elif cmd == CMD_READ:
                data_out.append(mem[addr])
                cycles.append(0)
            else:
                key = keys[int(prog)]
                p = allp[key]
                regs = {n: mem[image.layout.fixed[n]] for n in by_addr.values()
                        if not n.startswith("c:")}
                state = {n: v for n, v in regs.items() if n not in p.inputs}
                inputs = {}
                for n in p.inputs:
                    w = regs[n]
                    inputs[n] = (float(w - (1 << 32) if w >= 1 << 31 else w)
                                 if n in IMU_WORDS else np.uint32(w))
                new, outs, _ = run_bittrue(p, state, inputs)
                for n, v in new.items():
                    mem[image.layout.fixed[n]] = int(v[0])
                for n, a in image.output_addr(key).items():
                    mem[a] = int(outs[n][0])
                data_out.append(0)
                cycles.append(image.cycles(key) + 1)
        return {"data": np.array(data_out, dtype=np.int64),
                "cycles": np.array(cycles, dtype=np.int64)}

    return model


class _EngineBlock(ScheduledMachineStream):
    """A block of seed 000's engines: :class:`ScheduledMachineStream` over the image of
    ``WHICH``. ``LATENCY``: command accepted -> result valid for its longest program
    (``cycles + 2``); ``THROUGHPUT``: one such program per ``cycles + 3`` cycles."""

    WHICH = "ins_engines"

    def __init__(self):
        image = engine_image(self.WHICH)
        super().__init__(image)
        longest = max(image.cycles(k) for k in image.programs)
        self.LATENCY = longest + 2
        self.THROUGHPUT = Fraction(1, longest + 3)
        self.program_cycles = {k: image.cycles(k) for k in image.programs}


class InsEngines(_EngineBlock):
    """Seed 000 ins_mechanization + covariance_propagator + kalman_update_engine on one pool
    of float32 units with the state memory (propagate, altitude and TRN updates)."""

    WHICH = "ins_engines"


class KalmanUpdateEngine(_EngineBlock):
    """Seed 000 kalman_update_engine: 1-D altitude and 2-D TRN updates (gate and apply)."""

    WHICH = "kalman_update_engine"


class InsMechanization(_EngineBlock):
    """Seed 000 ins_mechanization (with imu_calibration): one IMU sample."""

    WHICH = "ins_mechanization"


class CovariancePropagator(_EngineBlock):
    """Seed 000 phi_q_generation + covariance_propagator: one IMU sample of P."""

    WHICH = "covariance_propagator"
