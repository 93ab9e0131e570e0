"""The ``fpga-sim`` engine: the whole of seed 000's PL (``ins_trn_top``) in Verilator, driven
by the PS side through its AXI4-Lite registers, with the IMU on its SPI pins.

Reference: seed 000 "System Architecture" / "Data Flow". The co-simulation top
(:class:`InsTrnSimTop`) is ``ins_trn_top`` with an ADIS16500 emulator in HDL on its IMU pins
(:class:`navgate.systems.ins_trn.pl.sensors.adis16500_emulator.Adis16500Emulator`): the IMU words
of the flight's record stream are pushed into the emulator, which raises data-ready and
answers the top's burst reads bit by bit; ``spi_master_imu`` (data-ready paced, IMU_CFG.dr_sync)
checks the checksum and hands the raw words to the sequencer, which runs the ``propagate``
program on the engines. Python stays out of the per-cycle path: the model runs in a
persistent native Verilator process (:class:`navgate.gateware.native_axi.NativeAxiSim`) that
takes batches of bus commands.

The PS side is the ``fp32`` engine's (:class:`Fp32Engine`), talking to the PL only through
registers, with the board's driver: :class:`navgate.hw.regmap.Registers` over
:class:`navgate.gateware.native_axi.NativeAxiBus`, by register and field name. On a board
the same calls run over :class:`navgate.hw.bus.DevMemBus` or :class:`navgate.hw.bus.PynqBus`
(docs/seed000-registers.md, "One driver, three buses"). Each engine call is one
``regs.deferred()`` block, sent as one batch (one round trip to the native process):
:meth:`Registers.wait_until` becomes the simulation's in-process poll and
:meth:`Registers.read_later` answers are filled in when the batch comes back. The
simulation's own extras, which a board has not, stay at bus level: ``bus.push`` (samples into
the device emulators) and ``bus.wait`` (the ``irq`` line). The register accesses:

- set-up: the calibration through CAL_* and CAL_APPLY; the other engine registers (noise,
  initial state, P0) through the engine register window (ENG_ADDR/ENG_WDATA/ENG_CMD); the
  reference point (REF_*), IMU_CFG
  (fastest SCLK, data-ready pacing, enabled), IRQ_ENABLE.update, CTRL.enable;
- IMU samples: pushed into the emulator; the PS waits until ENG_STATUS counts them
  (propagations) and the sequencer is idle;
- altitude and TRN updates: ALT_* / TRN_* registers (the fix as the innovation, its
  covariance, lag and chi-square gate), the start strobe, then the update interrupt
  (IRQ_STATUS, read to clear), the status and NIS registers; the gate flags and the
  correction words through the window;
- state reads (``read_nav``, ``read_cov_diag``, ...): the raw state and compensation words
  through the window (the PS recovers geodetic position in float64 from them, as with the
  ``fp32`` engine), cached until the next engine job.

The result equals the ``fp32`` engine's bit for bit (tests/systems/ins_trn/ps/test_fpga_sim.py).
- the altitude profile (:mod:`navgate.systems.ins_trn.ps.pl_profile`): every accepted terrain
  height pushed into the profile FIFO with the position and time the PL's timestamp
  correlator latched at its ranger frame (PROF_ENTRY_H, PROF_PUSH); for each correlation the
  newest entries by DMA into the co-simulation's DDR (PROF_ADDR/PROF_COUNT/PROF_CTRL, the
  update interrupt at the DMA's end), read back from DDR;
- the barometer through the BMP390 emulator's pins (BARO_PRESS) and the ranger through the
  TF-Luna emulator's UART (LIDAR_DATA).
"""

from __future__ import annotations

import contextlib
import weakref

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
from navgate.hw.regmap import Registers
from navgate.numerics.fp32 import bits_to_float, float_to_bits
from navgate.systems.ins_trn.pl.fp32_exec import to_f32
from navgate.systems.ins_trn.pl.fp32_program import CAL_REGS, N_STATES, NAV_REGS, p_reg
from navgate.systems.ins_trn.pl.nav_engines import engine_image
from navgate.systems.ins_trn.pl.registers import register_map
from navgate.systems.ins_trn.pl.sensors.adis16500_emulator import SAMPLE_LAYOUT as IMU_SAMPLE
from navgate.systems.ins_trn.pl.sensors.adis16500_emulator import Adis16500Emulator
from navgate.systems.ins_trn.pl.sensors.bmp390_emulator import SAMPLE_LAYOUT as BARO_SAMPLE
from navgate.systems.ins_trn.pl.sensors.bmp390_emulator import Bmp390Emulator
from navgate.systems.ins_trn.pl.sensors.tfluna_emulator import SAMPLE_LAYOUT as LIDAR_SAMPLE
from navgate.systems.ins_trn.pl.sensors.tfluna_emulator import TfLunaEmulator
from navgate.systems.ins_trn.pl.top import CAL_REGISTER_OF, InsTrnTop
from navgate.systems.ins_trn.ps.fp32_engine import Fp32Engine
from navgate.systems.ins_trn.ps.pl_interface import EngineSetup, UpdateOutcome, check_imu_words
from navgate.systems.ins_trn.ps.pl_profile import VALID_BIT

__all__ = ["InsTrnSimTop", "FpgaSimEngine", "FpgaSimError"]


class FpgaSimError(RuntimeError):
    """The co-simulation failed or answered unexpectedly."""


#: UART bit time of the ranger emulator and LIDAR_CFG.baud_div in the co-simulation (cycles)
LIDAR_BIT_CYCLES = 32
#: the TF-Luna temperature word the emulator sends (25 degC: (25 + 256) * 8)
LIDAR_TEMP_WORD = 2248

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

    def __init__(self):
        self.top = InsTrnTop()
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
    the contents of every source file of the navgate package and the Amaranth version;
    ``InsTrnSimTop`` takes no parameters). Emitting it takes tens of seconds."""
    return V.emit_verilog(top, "dut", design="InsTrnSimTop", params={})


#: state words the navigator reads at every log row and ranger record, fetched in one batch
HOT_WORDS = (NAV_REGS + ("cN", "cE", "cD", "cvN", "cvE", "cvD", "cq0", "cq1", "cq2", "cq3")
             + tuple(p_reg(i, i) for i in range(N_STATES))
             + tuple("c" + p_reg(i, i) for i in range(N_STATES))
             + (p_reg(0, 1), "c" + p_reg(0, 1)))


class _WindowMachine:
    """The PS's view of the engine registers through the window, shaped like the part of
    ``fp32_exec.Machine`` the ``fp32`` engine's read methods use (``get``, ``set``)."""

    def __init__(self, engine: FpgaSimEngine, ps_machine):
        self.e = engine
        self.ps = ps_machine  # the PS's set-up values (register names and the index)
        self.cache: dict[str, float] = {}

    def __getattr__(self, name):
        return getattr(self.ps, name)

    def get(self, name: str) -> float:
        if name not in self.cache:
            names = [n for n in HOT_WORDS if n not in self.cache] if name in HOT_WORDS \
                else [name]
            for n, bits in zip(names, self.e.window_read(names), strict=True):
                self.cache[n] = bits_to_float(bits)
        return self.cache[name]

    def set(self, name: str, value: float) -> None:
        v = to_f32(value)
        self.e.window_write([(name, float_to_bits(v))])
        self.cache[name] = v


class _DmaProfileFifo:
    """The PL's profile FIFO through the registers: an accepted sample is pushed with
    PROF_ENTRY_H and PROF_PUSH (the PL's timestamp correlator supplies the position and time
    it latched at the ranger frame; they are read back from PROF_SAMPLE_N/E/T and must be
    the words the PS's model expects); a read starts the DMA of the newest entries into the
    co-simulation's DDR (PROF_ADDR = 0, PROF_COUNT, PROF_CTRL.start), waits for the update
    interrupt and reads the words back from DDR (:data:`DMA_WINDOW`)."""

    def __init__(self, engine: FpgaSimEngine):
        self.e = engine
        self.dmas = 0  #: profile DMA transfers made

    def push(self, words) -> None:
        with self.e._job() as regs:
            out = [regs.read_later(r) for r in ("PROF_SAMPLE_N", "PROF_SAMPLE_E",
                                                "PROF_SAMPLE_T")]
            regs.write("PROF_ENTRY_H", int(words[0]))
            regs.write("PROF_PUSH", push=1)
        latched = (out[0].value, out[1].value, out[2].value | VALID_BIT)
        if latched != tuple(words[1:]):
            raise FpgaSimError(f"timestamp correlator latched {latched}, the PS expected "
                               f"{tuple(words[1:])}")

    def read(self, count: int) -> np.ndarray:
        e = self.e
        if not 0 < count <= DMA_WORDS // 4:
            raise FpgaSimError(f"profile DMA of {count} entries (1-{DMA_WORDS // 4})")
        with e._job() as regs:
            regs.read_later("IRQ_STATUS")  # clear what is pending (read to clear)
            regs.write("PROF_ADDR", 0)
            regs.write("PROF_COUNT", count)
            regs.write("PROF_CTRL", start=1)
            regs.bus.wait("irq", 100_000)
            irq, prof = regs.read_later("IRQ_STATUS"), regs.read_later("PROF_STATUS")
            # DDR is not a register: the co-simulation's PS reads it through the AXI window
            ddr = [regs.bus.read_later(DMA_WINDOW + 4 * k) for k in range(4 * count)]
        irq_status, status = irq.value, prof.value
        if irq_status != 1 or status & 1:
            raise FpgaSimError(f"profile DMA of {count} entries: IRQ_STATUS {irq_status:#x} "
                               f"(update only expected), PROF_STATUS {status:#x}")
        self.dmas += 1
        e.interrupts += 1
        return np.array([r.value for r in ddr], np.uint32).reshape(count, 4)


class FpgaSimEngine(Fp32Engine):
    """The whole PL in Verilator behind the PlEngine interface (module docstring)."""

    name = "fpga-sim"
    needs_imu_words = True

    def __init__(self, setup: EngineSetup, *, check_pd: bool = False):
        if check_pd:
            raise ValueError("check_pd needs the whole of P after every sample, which the "
                             "fpga-sim engine does not read back (use the fp32 engine)")
        super().__init__(setup, check_pd=False)
        self.image = engine_image("ins_engines")
        self.addr = self.image.layout.fixed
        top = InsTrnSimTop()
        self.sim = NativeAxiSim(top, streams=("imu_feed", "lidar_feed", "baro_feed"),
                                watch=("irq",), verilog=sim_verilog(top))
        #: the driver, as on the board (there over DevMemBus or PynqBus)
        self.regs = Registers(register_map(), NativeAxiBus(self.sim))
        self.baro_samples = 0
        self.lidar_frames = 0
        self._finalizer = weakref.finalize(self, self.sim.close)
        self.propagations = 0
        self.interrupts = 0
        self._load()
        self.m = _WindowMachine(self, self.m)

    # -- bus ------------------------------------------------------------------------------------
    @contextlib.contextmanager
    def _job(self):
        """One engine job's register accesses, sent as one batch (one round trip) when the
        block ends; a bus error, SLVERR or timeout is an :class:`FpgaSimError`."""
        try:
            with self.regs.deferred():
                yield self.regs
        except (NativeAxiError, AxiResponseError) as exc:
            raise FpgaSimError(str(exc)) from None

    def _wait_idle(self) -> None:
        self.regs.wait_until("ENG_STATUS", busy=0, limit=100_000)

    def _window_put(self, name: str, bits: int) -> None:
        regs = self.regs
        regs.write("ENG_ADDR", self.addr[name])
        regs.write("ENG_WDATA", bits)
        regs.write("ENG_CMD", write=1)

    def window_write(self, items) -> None:
        with self._job():
            for name, bits in items:
                self._window_put(name, bits)
            self._wait_idle()

    def window_read(self, names) -> list[int]:
        regs = self.regs
        out = []
        with self._job():
            for name in names:
                regs.write("ENG_ADDR", self.addr[name] if isinstance(name, str) else int(name))
                regs.write("ENG_CMD", read=1)
                self._wait_idle()
                out.append(regs.read_later("ENG_RDATA"))
        return [r.value for r in out]

    def _load(self):
        ps = self.m
        items = [(n, float_to_bits(ps.regs[ps.index[n]]) if n in ps.index else 0)
                 for n in self.addr if not n.startswith("c:") and n not in CAL_REGS]
        ref = self.setup.reference
        with self._job() as regs:
            regs.write("CTRL", enable=0)
            for name, bits in items:
                self._window_put(name, bits)
            # the calibration through the seed's CAL_* registers and CAL_APPLY
            for reg, word in CAL_REGISTER_OF.items():
                regs.write(reg, float_to_bits(ps.get(word)))
            regs.write("CAL_APPLY", apply=1)
            self._wait_idle()
            regs.write("REF_LAT", float_to_bits(ref.lat0))
            regs.write("REF_LON", float_to_bits(ref.lon0))
            regs.write("REF_ALT", float_to_bits(ref.h0))
            regs.write("IMU_CFG", spi_div=0, enable=1, dr_sync=1)  # fastest SCLK, DR-paced
            regs.write("BARO_CFG", spi_div=2, enable=1, int_sync=1)  # fastest SCLK, INT-paced
            regs.write("IRQ_ENABLE", update=1, error=0)
            regs.write("CTRL", enable=1)
            self._wait_idle()

    # -- engine calls -----------------------------------------------------------------------------
    def propagate(self, gyro_words, accel_words) -> None:
        gw, aw = check_imu_words(gyro_words, accel_words)
        words = np.concatenate([gw, aw], axis=1)
        if not (np.all(np.isfinite(words)) and np.all(words == np.round(words))
                and words.min(initial=0) >= -32768 and words.max(initial=0) <= 32767):
            raise FpgaSimError("the fpga-sim engine needs the IMU's int16 output words "
                               "(the ideal sensors' float words have no SPI encoding)")
        w = words.astype(np.int64)
        n = w.shape[0]
        self.propagations += n
        with self._job() as regs:
            regs.bus.push("imu_feed", {"gx": w[:, 0], "gy": w[:, 1], "gz": w[:, 2],
                                       "ax": w[:, 3], "ay": w[:, 4], "az": w[:, 5],
                                       "temp": np.zeros(n, np.int64),
                                       "diag": np.zeros(n, np.int64)})
            regs.wait_until("ENG_STATUS", propagations=self.propagations & 0xFFFFFF, busy=0,
                            limit=4000 * n + 100_000)
        self.m.cache.clear()
        self.samples += n

    def _update(self, kind, gate_key, apply_key, dof, **inputs) -> UpdateOutcome:
        gate = self._gate[dof]
        if dof == 1:
            regs = {"ALT_MEAS": inputs["h_meas"], "ALT_VAR": inputs["r"], "ALT_GATE": gate}
            ctrl, status, nis_reg = "ALT_CTRL", "ALT_STATUS", "ALT_NIS"
        else:
            regs = {"TRN_POS_N": inputs["y0"], "TRN_POS_E": inputs["y1"],
                    "TRN_COV_NN": inputs["r00"], "TRN_COV_NE": inputs["r01"],
                    "TRN_COV_EE": inputs["r11"], "TRN_LAG": inputs["lag"], "TRN_GATE": gate}
            ctrl, status, nis_reg = "TRN_CTRL", "TRN_STATUS", "TRN_NIS"
        with self._job() as bus_regs:
            bus_regs.read_later("IRQ_STATUS")  # clear what is pending (read to clear)
            for r, v in regs.items():
                bus_regs.write(r, float_to_bits(to_f32(v)))
            bus_regs.write(ctrl, start=1)
            bus_regs.bus.wait("irq", 100_000)
            out = [bus_regs.read_later(r) for r in ("IRQ_STATUS", status, nis_reg)]
        irq_status, st, nis_bits = (r.value for r in out)
        if not irq_status & 1 or st & 0b011 != 0b010:
            raise FpgaSimError(f"{ctrl}: no update interrupt or not done "
                               f"(IRQ_STATUS {irq_status:#x}, {status} {st:#x})")
        self.interrupts += 1
        nis = bits_to_float(nis_bits)
        outs = self.image.output_addr(gate_key)
        if st & 0b100:
            positive = self.window_read([outs["positive"]])[0]
            self._count(self.rejected, kind)
            reason = ("innovation covariance not positive" if positive != 0x3F800000
                      else "rejected by chi-square gate")
            return UpdateOutcome(False, nis, np.zeros(15), reason)
        self.m.cache.clear()
        dx_addr = self.image.output_addr(apply_key)
        dx = self.window_read([dx_addr[f"dx{i}"] for i in range(15)])
        self._count(self.accepted, kind)
        return UpdateOutcome(True, nis,
                             np.array([bits_to_float(b) for b in dx]))

    def _profile_fifo(self):
        return _DmaProfileFifo(weakref.proxy(self))

    def prepare_baro(self, uncomp_press, uncomp_temp) -> None:
        """Nothing ahead of time: every sample goes through the pins when its record comes."""

    def read_baro(self, uncomp_press: int, uncomp_temp: int) -> float:
        """The sample through the BMP390 emulator, the SPI pins, ``spi_master_baro`` (INT
        paced) and ``baro_compensation``: push the ADC words, wait until BARO_SAMPLES counts
        the sample, read BARO_PRESS."""
        self.baro_samples += 1
        with self._job() as regs:
            regs.bus.push("baro_feed", {"up": int(uncomp_press), "ut": int(uncomp_temp)})
            regs.wait_until("BARO_SAMPLES", count=self.baro_samples & 0xFFFFFFFF,
                            limit=100_000)
            press = regs.read_later("BARO_PRESS")
        return bits_to_float(press.value)

    def read_ranger(self, dist: int, strength: int) -> tuple[int, int]:
        """The frame through the TF-Luna emulator, the UART pin and ``uart_rx_lidar``: push
        it, wait until LIDAR_FRAMES counts it, read LIDAR_DATA."""
        first = not self.lidar_frames
        self.lidar_frames += 1
        with self._job() as regs:
            if first:  # the ranger's receiver is enabled with its first frame
                regs.write("LIDAR_CFG", baud_div=LIDAR_BIT_CYCLES, enable=1)
            regs.bus.push("lidar_feed", {"dist": int(dist), "strength": int(strength),
                                         "temp": LIDAR_TEMP_WORD})
            regs.wait_until("LIDAR_FRAMES", count=self.lidar_frames & 0xFFFFFFFF,
                            limit=200 * LIDAR_BIT_CYCLES + 10_000)
            data = regs.read_later("LIDAR_DATA")
        word = data.value
        return word & 0xFFFF, word >> 16

    def read_cov(self):
        p = np.empty((15, 15))
        for i in range(15):
            for j in range(i, 15):
                p[i, j] = p[j, i] = self._p(i, j)
        return p

    @property
    def cycles(self) -> int:
        return self.sim.cycles

    def hardware_stats(self) -> dict:
        return {"simulated_cycles": self.sim.cycles,
                "cycles_per_imu_sample": self.sim.cycles / max(self.samples, 1),
                "update_interrupts": self.interrupts,
                "profile_dmas": self.profile.fifo.dmas,
                "profile_entries_pushed": self.profile.pushes,
                "baro_samples_through_pins": self.baro_samples,
                "ranger_frames_through_pins": self.lidar_frames,
                "bus_batches": self.sim.batches, "bus_commands": self.sim.commands}

    def close(self):
        self._finalizer()
