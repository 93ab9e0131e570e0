"""cocotb test that serves command batches to the Verilator model of ``ins_engines`` (used by
:mod:`navgate.systems.ins_trn.rtl_engine`).

The parent process writes one line per batch into the FIFO named by ``NAVGATE_RTL_CMD``:
space-separated tokens ``<payload hex>/<wait>``, each a packed input payload of
:class:`navgate.gateware.scheduled.ScheduledMachineStream` and the exact number of cycles
from the edge that accepts it to the cycle its response is valid (write 1, read 2, run
``cycles + 2``: the wrapper's timing); for every command the response payload (hex) is
written, space-separated, as one line to ``NAVGATE_RTL_RSP``. ``quit`` ends the simulation.
The command is driven after a rising edge and accepted at the next; the simulation then
advances to the middle of the response cycle in one timer step (no per-cycle Python), checks
``o.valid`` (an error line ``!...`` otherwise) and takes the response at the next edge.
"""

import os

import cocotb
from cocotb.clock import Clock
from cocotb.triggers import RisingEdge, Timer


@cocotb.test()
async def serve(dut):
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
    await RisingEdge(clk)
    fin = open(os.environ["NAVGATE_RTL_CMD"])
    fout = open(os.environ["NAVGATE_RTL_RSP"], "w")
    while True:
        line = fin.readline()
        if not line or line.strip() == "quit":
            break
        outs = []
        error = None
        for tok in line.split():
            word, wait = tok.split("/")
            i_payload.value = int(word, 16)
            i_valid.value = 1
            await RisingEdge(clk)
            if not int(i_ready.value):
                error = f"command {len(outs)} not accepted"
                break
            i_valid.value = 0
            await Timer(10 * int(wait) - 5, unit="ns")
            if not int(o_valid.value):
                error = f"no response to command {len(outs)} after {wait} cycles"
                break
            outs.append(o_payload.value.to_unsigned())
            await RisingEdge(clk)
        if error:
            fout.write("!" + error + "\n")
            fout.flush()
            continue
        fout.write(" ".join(format(v, "x") for v in outs) + "\n")
        fout.flush()
    fin.close()
    fout.close()
