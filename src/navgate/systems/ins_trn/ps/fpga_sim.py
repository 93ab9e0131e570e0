"""The ``fpga-sim`` engine: the whole of seed 000's PL (``ins_trn_top``) in Verilator, driven
by the PS side through its AXI4-Lite registers, with the IMU on its SPI pins.

Reference: seed 000 "System Architecture" / "Data Flow". The co-simulation top
(:class:`InsTrnSimTop`) is ``ins_trn_top`` with an ADIS16500 emulator in HDL on its IMU pins
(:class:`navgate.systems.ins_trn.pl.sensors.adis16500_emulator.Adis16500Emulator`): the IMU words
of the flight's record stream are pushed into the emulator, which raises data-ready and
answers the top's burst reads bit by bit; ``spi_master_imu`` (data-ready paced, IMU_CFG.dr_sync)
checks the checksum and hands the raw words to the sequencer, which runs the ``propagate``
program on the engines. The barometer and the ranger go through the BMP390 and TF-Luna
emulators on their pins, and the profile DMA writes into a 1 KiB memory that stands for DDR.
Python stays out of the per-cycle path: the model runs in a persistent native Verilator
process (:class:`navgate.gateware.native_axi.NativeAxiSim`) that takes batches of bus commands.

The PS side is :class:`navgate.systems.ins_trn.ps.pl_registers.RegisterEngine`, the same class
the ``board`` engine flies the Zynq's fabric with; this module gives it a :class:`SimFabric`:
:class:`navgate.hw.regmap.Registers` over :class:`navgate.gateware.native_axi.NativeAxiBus`.
Each engine call is one ``regs.deferred()`` block, sent as one batch (one round trip to the
native process): :meth:`Registers.wait_until` becomes the simulation's in-process poll and
:meth:`Registers.read_later` answers are filled in when the batch comes back. The
simulation's own extras, which a board has not, stay at bus level: ``bus.push`` (samples into
the device emulators) and ``bus.wait`` (the ``irq`` line).

The result equals the ``fp32`` engine's bit for bit (tests/systems/ins_trn/ps/test_fpga_sim.py).
"""

from __future__ import annotations

import contextlib

import numpy as np
from amaranth import Module, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from navgate.gateware import verify as V
from navgate.gateware.axi4 import axi4_write_signature
from navgate.gateware.axi_lite import axi_lite_signature
from navgate.gateware.native_axi import (
    AxiResponseError,
    NativeAxiBus,
    NativeAxiError,
    NativeAxiSim,
)
from navgate.hw.regmap import Reading, Registers
from navgate.systems.ins_trn.pl.registers import register_map
from navgate.systems.ins_trn.pl.sensors.adis16500_emulator import SAMPLE_LAYOUT as IMU_SAMPLE
from navgate.systems.ins_trn.pl.sensors.adis16500_emulator import Adis16500Emulator
from navgate.systems.ins_trn.pl.sensors.bmp390_emulator import SAMPLE_LAYOUT as BARO_SAMPLE
from navgate.systems.ins_trn.pl.sensors.bmp390_emulator import Bmp390Emulator
from navgate.systems.ins_trn.pl.sensors.tfluna_emulator import SAMPLE_LAYOUT as LIDAR_SAMPLE
from navgate.systems.ins_trn.pl.sensors.tfluna_emulator import TfLunaEmulator
from navgate.systems.ins_trn.pl.top import InsTrnTop
from navgate.systems.ins_trn.ps.pl_interface import EngineSetup
from navgate.systems.ins_trn.ps.pl_registers import (
    LIDAR_BIT_CYCLES,
    LIDAR_TEMP_WORD,
    Fabric,
    PlRegisterError,
    RegisterEngine,
)

__all__ = ["InsTrnSimTop", "FpgaSimEngine", "FpgaSimError", "SimFabric", "start_sim"]


class FpgaSimError(PlRegisterError):
    """The co-simulation failed or answered unexpectedly."""


#: the co-simulation's "DDR": the DMA target memory, readable at this AXI offset
DMA_WINDOW = 0x800
DMA_WORDS = 256


class InsTrnSimTop(wiring.Component):
    """``ins_trn_top`` with the device emulators on its pins (ADIS16500 fed by ``imu_feed``,
    BMP390 by ``baro_feed``, TF-Luna by ``lidar_feed``) and the DMA master writing into a 1 KiB
    memory that stands for DDR (:class:`_DmaMemory`). The AXI4-Lite port is one bit wider
    than the bank's: reads at :data:`DMA_WINDOW` and above return that memory's words (the
    PS's view of DDR);
    everything else goes to the bank. The window is read-only and the co-simulation's PS never
    writes there (writes are decoded by the bank's 11 address bits)."""

    def __init__(self, engine: str = "banked"):
        self.engine = engine
        self.top = InsTrnTop(engine=engine)
        super().__init__({
            "axi": In(axi_lite_signature(register_map().address_width + 1)),
            "imu_feed": In(stream.Signature(IMU_SAMPLE)),
            "lidar_feed": In(stream.Signature(LIDAR_SAMPLE)),
            "baro_feed": In(stream.Signature(BARO_SAMPLE)),
            "irq": Out(1),
        })

    def elaborate(self, platform):
        m = Module()
        m.submodules.top = top = self.top
        m.submodules.imu = emu = Adis16500Emulator()
        m.submodules.ddr = ddr = _DmaMemory()
        m.submodules.lidar = lidar = TfLunaEmulator()
        wiring.connect(m, wiring.flipped(self.lidar_feed), lidar.samples)
        m.d.comb += [lidar.cfg_bit_cycles.eq(LIDAR_BIT_CYCLES), top.lidar_rx.eq(lidar.tx)]
        m.submodules.baro = baro = Bmp390Emulator()
        wiring.connect(m, wiring.flipped(self.baro_feed), baro.samples)
        m.d.comb += [baro.sclk.eq(top.baro_sclk), baro.mosi.eq(top.baro_mosi),
                     baro.cs_n.eq(top.baro_cs_n), top.baro_miso.eq(baro.miso | ~baro.miso_oe),
                     top.baro_int.eq(baro.int_pin)]
        wiring.connect(m, top.dma, ddr.axi)
        wiring.connect(m, wiring.flipped(self.imu_feed), emu.samples)
        m.d.comb += [
            emu.sclk.eq(top.imu_sclk), emu.mosi.eq(top.imu_mosi), emu.cs_n.eq(top.imu_cs_n),
            top.imu_miso.eq(emu.miso | ~emu.miso_oe), top.imu_dr.eq(emu.dr),
            self.irq.eq(top.irq),
        ]
        # AXI4-Lite: write channels and AR/R to the bank, except reads of the DDR window
        a, b = self.axi, top.axi
        aw = len(b.awaddr)
        m.d.comb += [
            b.awaddr.eq(a.awaddr[:aw]), b.awprot.eq(a.awprot), b.awvalid.eq(a.awvalid),
            a.awready.eq(b.awready), b.wdata.eq(a.wdata), b.wstrb.eq(a.wstrb),
            b.wvalid.eq(a.wvalid), a.wready.eq(b.wready), a.bresp.eq(b.bresp),
            a.bvalid.eq(b.bvalid), b.bready.eq(a.bready),
            b.araddr.eq(a.araddr[:aw]), b.arprot.eq(a.arprot),
        ]
        window = a.araddr[aw]
        mem_rvalid = Signal()
        busy = Signal()  # a read of either side is outstanding
        m.d.comb += [busy.eq(b.rvalid | mem_rvalid),
                     b.arvalid.eq(a.arvalid & ~window & ~mem_rvalid),
                     ddr.raddr.eq(a.araddr[2:2 + (DMA_WORDS - 1).bit_length()]),
                     ddr.rload.eq(a.arvalid & window & ~busy)]
        with m.If(window):
            m.d.comb += a.arready.eq(~busy)
        with m.Else():
            m.d.comb += a.arready.eq(b.arready & ~mem_rvalid)
        with m.If(a.arvalid & window & ~busy):
            m.d.sync += mem_rvalid.eq(1)
        with m.Elif(mem_rvalid & a.rready):
            m.d.sync += mem_rvalid.eq(0)
        with m.If(mem_rvalid):
            m.d.comb += [a.rvalid.eq(1), a.rdata.eq(ddr.rdata), a.rresp.eq(0)]
        with m.Else():
            m.d.comb += [a.rvalid.eq(b.rvalid), a.rdata.eq(b.rdata), a.rresp.eq(b.rresp),
                         b.rready.eq(a.rready)]
        return m


class _DmaMemory(wiring.Component):
    """An AXI4 write slave over :data:`DMA_WORDS` 32-bit words (incrementing bursts of any
    length; the address wraps inside the memory) with a read port: ``rload`` loads the word
    at ``raddr`` into ``rdata``, which holds it until the next load."""

    def __init__(self):
        bits = (DMA_WORDS - 1).bit_length()
        super().__init__({"axi": In(axi4_write_signature()), "raddr": In(bits),
                          "rload": In(1), "rdata": Out(32)})

    def elaborate(self, platform):
        m = Module()
        m.submodules.mem = mem = Memory(shape=32, depth=DMA_WORDS, init=[])
        wr = mem.write_port()
        rd = mem.read_port(domain="comb")
        ax = self.axi
        bits = (DMA_WORDS - 1).bit_length()
        addr = Signal(bits)
        in_burst = Signal()
        bvalid = Signal()
        m.d.comb += [rd.addr.eq(self.raddr), ax.awready.eq(~in_burst & ~bvalid),
                     ax.wready.eq(in_burst), ax.bvalid.eq(bvalid), ax.bresp.eq(0),
                     ax.bid.eq(0), wr.addr.eq(addr), wr.data.eq(ax.wdata),
                     wr.en.eq(ax.wvalid & in_burst)]
        with m.If(self.rload):
            m.d.sync += self.rdata.eq(rd.data)
        with m.If(ax.awvalid & ax.awready):
            m.d.sync += [addr.eq(ax.awaddr[2:2 + bits]), in_burst.eq(1)]
        with m.If(ax.wvalid & in_burst):
            m.d.sync += addr.eq(addr + 1)
            with m.If(ax.wlast):
                m.d.sync += [in_burst.eq(0), bvalid.eq(1)]
        with m.If(bvalid & ax.bready):
            m.d.sync += bvalid.eq(0)
        return m


def sim_verilog(top: InsTrnSimTop) -> str:
    """The co-simulation top's Verilog (module ``dut``), emitted once per version of the
    gateware: from navgate's Verilog cache (:func:`navgate.cache.cached_verilog`, keyed by
    the contents of every source file of the navgate package and the Amaranth version, and
    the carried engine unless it is the banked one). Emitting it takes tens of seconds."""
    params = {} if top.engine == "banked" else {"engine": top.engine}
    return V.emit_verilog(top, "dut", design="InsTrnSimTop", params=params)


class SimFabric(Fabric):
    """The Verilated fabric for :class:`RegisterEngine`: the driver over
    :class:`NativeAxiBus`, each engine job one batch, the sensors' words pushed into the
    emulators, the ``irq`` line waited for in clock cycles, the DMA's "DDR" read through the
    AXI window at :data:`DMA_WINDOW`."""

    error = FpgaSimError
    dma_address = 0

    def __init__(self, sim: NativeAxiSim):
        super().__init__(Registers(register_map(), NativeAxiBus(sim)))
        self.sim = sim

    @contextlib.contextmanager
    def job(self):
        try:
            with self.regs.deferred():
                yield self.regs
        except (NativeAxiError, AxiResponseError) as exc:
            raise FpgaSimError(str(exc)) from None

    def feed_imu(self, w) -> None:
        self.regs.bus.push("imu_feed", imu_fields(w))

    def feed_baro(self, uncomp_press: int, uncomp_temp: int) -> None:
        self.regs.bus.push("baro_feed", {"up": uncomp_press, "ut": uncomp_temp})

    def feed_ranger(self, dist: int, strength: int) -> None:
        self.regs.bus.push("lidar_feed", {"dist": dist, "strength": strength,
                                          "temp": LIDAR_TEMP_WORD})

    def wait_interrupt(self, limit: int) -> Reading:
        self.regs.bus.wait("irq", limit)
        return self.regs.read_later("IRQ_STATUS")

    def dma_words(self, count: int) -> list[Reading]:
        # DDR is not a register: the co-simulation's PS reads it through the AXI window
        return [self.regs.bus.read_later(DMA_WINDOW + 4 * k) for k in range(count)]

    def stats(self) -> dict:
        return {"simulated_cycles": self.sim.cycles, "bus_batches": self.sim.batches,
                "bus_commands": self.sim.commands}

    def close(self) -> None:
        self.sim.close()


def imu_fields(w) -> dict:
    """The ADIS16500 emulator's stream fields for n x 6 IMU words (gx gy gz ax ay az)."""
    n = w.shape[0]
    return {"gx": w[:, 0], "gy": w[:, 1], "gz": w[:, 2], "ax": w[:, 3], "ay": w[:, 4],
            "az": w[:, 5], "temp": np.zeros(n, np.int64), "diag": np.zeros(n, np.int64)}


def start_sim(engine: str = "banked", **options) -> NativeAxiSim:
    """The native co-simulation of :class:`InsTrnSimTop` carrying the PL engine ``engine``
    (its streams and ``irq`` watched)."""
    top = InsTrnSimTop(engine)
    return NativeAxiSim(top, streams=("imu_feed", "lidar_feed", "baro_feed"), watch=("irq",),
                        verilog=sim_verilog(top), **options)


class FpgaSimEngine(RegisterEngine):
    """The whole PL in Verilator behind the PlEngine interface (module docstring)."""

    name = "fpga-sim"

    def __init__(self, setup: EngineSetup, *, check_pd: bool = False):
        if check_pd:  # refused before the simulation starts
            raise ValueError("check_pd needs the whole of P after every sample, which the "
                             f"{self.name} engine does not read back (use the fp32 engine)")
        self.sim = start_sim(self.pl_engine)
        super().__init__(setup, SimFabric(self.sim))

    @property
    def cycles(self) -> int:
        return self.sim.cycles


class FpgaSimCompactEngine(FpgaSimEngine):
    """``fpga-sim`` with ``ins_trn_top_compact``: the whole PL carrying the register machine
    (docs/opflow-register-machine.md); the same PS, register map and bus traffic."""

    name = "fpga-sim-compact"
    pl_engine = "register"
