"""cocotb test of a Verilated entry-point machine: the sequence machine
(navgate.opflow.sequence.SequenceMachine) or the register machine
(navgate.opflow.regmachine.RegisterMachine), which share the host port and the handshake.

Loaded inside the simulator by :func:`navgate.gateware.verify.run_cocotb`; the job file named
by ``NAVGATE_SEQ_JOB`` gives the host writes (address -> word) to make first, then the runs:
each an entry number and the host writes to make before it. Like
:func:`navgate.opflow.sequence.simulate_sequence`, each run pulses ``start``, counts the
cycles from the start cycle to ``done`` and reads back the words at the job's read
addresses; the status JSON (``status`` in the job) lists, per run, the cycles and the words.
"""

import json
import os

import cocotb
from cocotb.clock import Clock
from cocotb.triggers import FallingEdge

# Inputs are set and outputs sampled just after a falling edge; awaiting the next falling
# edge passes exactly one rising edge: the "set, tick, get" of Amaranth's simulator.


async def _write(dut, writes):
    for addr, word in writes:
        dut.host_we.value = 1
        dut.host_addr.value = addr
        dut.host_wdata.value = word
        await FallingEdge(dut.clk)
    dut.host_we.value = 0


@cocotb.test()
async def sequence_machine(dut):
    job = json.loads(open(os.environ["NAVGATE_SEQ_JOB"]).read())
    Clock(dut.clk, 10, unit="ns").start()
    dut.rst.value = 1
    dut.start.value = 0
    dut.host_we.value = 0
    dut.host_addr.value = 0
    dut.host_wdata.value = 0
    dut.entry.value = 0
    for _ in range(2):
        await FallingEdge(dut.clk)
    dut.rst.value = 0
    await FallingEdge(dut.clk)
    await _write(dut, job["writes"])
    out = []
    for run in job["runs"]:
        await _write(dut, run["writes"])
        dut.entry.value = run["entry"]
        dut.start.value = 1
        await FallingEdge(dut.clk)
        dut.start.value = 0
        n = 1
        while not int(dut.done.value):
            await FallingEdge(dut.clk)
            n += 1
            if n > run["limit"]:
                raise AssertionError(f"entry {run['entry']} not done in {n} cycles")
        await FallingEdge(dut.clk)
        words = []
        for addr in job["reads"]:
            dut.host_addr.value = addr
            await FallingEdge(dut.clk)
            words.append(int(dut.host_rdata.value))
        out.append({"cycles": n, "words": words})
    with open(job["status"], "w") as f:
        json.dump(out, f)
