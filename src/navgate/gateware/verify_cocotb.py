"""Generic cocotb test that streams vectors through a DUT (used by ``verify``).

Loaded by cocotb inside the Verilator simulation started from
``navgate.gateware.verify.simulate_verilator``; the job file named by the
environment variable ``NAVGATE_VERIFY_JOB`` gives the vector file, the output
file and the handshake randomisation.  The ports are the ones Amaranth emits
for a component with stream members ``i`` and ``o``: ``clk``, ``rst``,
``i__payload``, ``i__valid``, ``i__ready``, ``o__payload``, ``o__valid``,
``o__ready``.

Each cycle: after the rising edge the inputs are driven, then in the read-only
phase the handshake signals are sampled; a transfer happens at the next rising
edge when valid and ready are both high.  The semantics match
``verify.simulate_amaranth`` exactly (same seeded random sequence).
"""

import json
import os
import random

import cocotb
from cocotb.clock import Clock
from cocotb.triggers import ReadOnly, RisingEdge


@cocotb.test()
async def stream_vectors(dut):
    job = json.loads(open(os.environ["NAVGATE_VERIFY_JOB"]).read())
    status_path = os.path.join(os.path.dirname(job["outputs"]), "status.json")
    with open(job["inputs"]) as fh:
        packed = [int(tok, 16) for tok in fh.read().split()]
    n = len(packed)
    valid_prob = job["valid_prob"]
    ready_prob = job["ready_prob"]
    gaps = valid_prob < 1.0
    stalls = ready_prob < 1.0
    idle_limit = job["idle_limit"]
    rng = random.Random(job["seed"])

    clk = dut.clk
    i_payload, i_valid, i_ready = dut.i__payload, dut.i__valid, dut.i__ready
    o_payload, o_valid, o_ready = dut.o__payload, dut.o__valid, dut.o__ready

    Clock(clk, 10, unit="ns").start()
    dut.rst.value = 1
    i_valid.value = 0
    o_ready.value = 1
    for _ in range(2):
        await RisingEdge(clk)
    dut.rst.value = 0

    outs = []
    k = 0
    cycle = 0
    idle = 0
    first_in = None
    latency = None
    pending = False
    held = None
    error = None
    while len(outs) < n:
        await RisingEdge(clk)
        if not pending:
            if k < n and (not gaps or rng.random() < valid_prob):
                i_payload.value = packed[k]
                i_valid.value = 1
                pending = True
            else:
                i_valid.value = 0
        ready = 1
        if stalls:
            ready = 1 if rng.random() < ready_prob else 0
            o_ready.value = ready
        await ReadOnly()
        ir = int(i_ready.value)
        ov = int(o_valid.value)
        val = o_payload.value.to_unsigned() if ov else None
        if held is not None:
            if not ov or val != held:
                error = f"stream rule violated at cycle {cycle}: output dropped or changed"
                break
            held = None
        if pending and ir:
            if first_in is None:
                first_in = cycle
            k += 1
            pending = False
        if ov:
            if latency is None and first_in is not None:
                latency = cycle - first_in
            if ready:
                outs.append(val)
                idle = 0
            else:
                held = val
        idle += 1
        cycle += 1
        if idle > idle_limit:
            error = f"no output for {idle_limit} cycles after {len(outs)} of {n} results"
            break

    digits = max(1, (job["out_width"] + 3) // 4)
    with open(job["outputs"], "w") as fh:
        fh.write("\n".join(format(v, f"0{digits}x") for v in outs))
        fh.write("\n")
    with open(status_path, "w") as fh:
        json.dump({"cycles": cycle, "latency": latency, "error": error}, fh)
