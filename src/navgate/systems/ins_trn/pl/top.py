"""Seed 000 ``ins_trn_top``: the whole PL of the INS/TRN design on the Zynq-7020.

Reference: seed 000 "Module Hierarchy" and "Data Flow". The blocks and how they are wired:

    PS (AXI4-Lite GP0) -> ins_trn_regs (registers.rdl) -> control, configuration, status
    ADIS16500 pins -> sensor_subsystem (spi_master_imu, DR-paced or timed; raw words) ->
        nav_sequencer -> ins_engines (calibration, mechanization, covariance propagation,
        altitude and TRN Kalman updates on the shared float32 units) -> shadow words ->
        nav_output_formatter (POS/VEL/QUAT, Euler angles, NAV_FLAGS) -> registers
    BMP390 pins -> spi_master_baro (INT-paced or timed) -> baro_compensation -> BARO_PRESS
    TF-Luna RX -> uart_rx_lidar -> LIDAR_DATA (the PS turns both into the altitude update and
        the terrain profile; docs/seed000-top.md)
    altitude_profile_manager: timestamp_correlator (each ranger frame's INS position and IMU
        sample count) + the PS's terrain height (PROF_ENTRY_H, PROF_PUSH) -> 64 x 128-bit
        FIFO -> DMA to DDR over an AXI4 write master
    interrupt_gen -> irq (IRQ_F2P); status LEDs

One clock domain (``sync``, 100 MHz): the engines meet the seed's time budget at 100 MHz
(680 cycles per IMU sample, 6.8 us of the 2.5 ms period). :class:`ZyboInsTrnTop` adds
``clk_rst_gen`` (MMCME2_BASE 125 -> 100 MHz and the reset sequence) for the board;
:class:`InsTrnTop` is the design a simulation or a block design clocks directly.

Register fields that configure blocks whose ports differ from the map:

- LIDAR_CFG.baud_div (clocks per bit, 868 for 115200 baud) -> the receiver's 16x oversampling
  tick divider ``baud_div // 16 - 1`` (868 -> 53, the receiver's reset value; baud rates are
  set to within one 16-clock step);
- IMU_CFG.dr_sync selects data-ready pacing of the IMU bursts (the seed's timer otherwise);
- COV_DIAG_k are the stored diagonal words of P (without their compensation words, which
  are below the words' last bit); COV_POS/VEL/ATT are the square roots of P00 + P11,
  P33 + P44 + P55 and P66 + P77 + P88 in float32, computed by the output formatter (on its
  adder, with an iterative square root) after every read-back.
"""

from __future__ import annotations

from amaranth import Cat, ClockDomain, ClockSignal, Module, ResetInserter, Signal
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware.axi4 import axi4_write_signature
from navgate.gateware.axi_lite import axi_lite_signature
from navgate.systems.ins_trn.pl.fp32_program import N_STATES, p_reg
from navgate.systems.ins_trn.pl.registers import register_map
from navgate.systems.ins_trn.pl.sequencer import (
    IMU_FIELDS,
    SHADOW_WORDS,
    NavSequencer,
    job_cycles,
)

__all__ = ["InsTrnTop", "ZyboInsTrnTop", "PIN_PORTS", "CAL_REGISTER_OF",
           "InsTrnTopCompact"]

#: the top's pin ports (board pins; docs/seed000-top.md)
PIN_PORTS = ("imu_sclk", "imu_mosi", "imu_miso", "imu_cs_n", "imu_dr",
             "baro_sclk", "baro_mosi", "baro_miso", "baro_cs_n", "baro_int",
             "lidar_rx", "lidar_tx")


#: the ranger's silence timeout (bit times): 320 ms at 115200 baud, three frame periods of
#: a 10 Hz ranger (the receiver's own default, 20 ms, suits only the TF-Luna's 100 Hz)
LIDAR_TIMEOUT_BITS = 36_864

#: calibration register of the map -> engine calibration word (CAL_APPLY copies them)
CAL_REGISTER_OF = {
    **{f"CAL_{sensor}_LSB": f"cal_{s}_lsb" for sensor, s in (("GYRO", "g"), ("ACCEL", "a"))},
    **{f"CAL_{sensor}_BIAS_{'XYZ'[j]}": f"cal_{s}_b{j}"
       for sensor, s in (("GYRO", "g"), ("ACCEL", "a")) for j in range(3)},
    **{f"CAL_{sensor}_M_{3 * i + j}": f"cal_{s}_m{i}{j}"
       for sensor, s in (("GYRO", "g"), ("ACCEL", "a")) for i in range(3) for j in range(3)},
}


#: sequencer input -> the register it reads (through the register bank's RAM copy)
SEQUENCER_REGISTER_OF = {
    "alt_h_meas": "ALT_MEAS", "alt_r": "ALT_VAR", "alt_gate": "ALT_GATE",
    "trn_y0": "TRN_POS_N", "trn_y1": "TRN_POS_E", "trn_r00": "TRN_COV_NN",
    "trn_r01": "TRN_COV_NE", "trn_r11": "TRN_COV_EE", "trn_lag": "TRN_LAG",
    "trn_gate": "TRN_GATE",
    **{word: reg for reg, word in CAL_REGISTER_OF.items()},
}


def _field(reg: str, name: str):
    for r in register_map().registers:
        if r.name == reg:
            for f in r.fields:
                if f.name == name:
                    return f.lsb, f.width
    raise KeyError(f"{reg}.{name}")


def _bits(value, reg, name):
    lsb, width = _field(reg, name)
    return value[lsb:lsb + width]


def _register_artifacts(out_dir, name: str) -> list:
    """The C header and Markdown documentation of the register map, from its SystemRDL."""
    from pathlib import Path

    from navgate.hw.regmap import export_c_header, export_markdown
    from navgate.systems.ins_trn.pl.registers import RDL_PATH

    out_dir = Path(out_dir)
    return [export_c_header(RDL_PATH, out_dir / f"{name}_regs.h"),
            export_markdown(RDL_PATH, out_dir / f"{name}_regs.md")]


class InsTrnTop(wiring.Component):
    """Seed 000's PL (module docstring): AXI4-Lite slave ``axi``, DMA master ``dma``,
    interrupt ``irq``, sensor pins and four status LEDs, in the ``sync`` domain."""

    #: the block's name and the PL engine it carries unless told otherwise
    #: (register_engine.PL_ENGINES: the banked datapath, or the register machine of
    #: ``ins_trn_top_compact``; the register map and the PS are the same)
    NAME = "ins_trn_top"
    ENGINE = "banked"

    def __init__(self, *, tick_cycles: int = 100, engine: str | None = None):
        from navgate.systems.ins_trn.pl.register_engine import pl_engine_image

        self.tick_cycles = tick_cycles
        engine = engine or self.ENGINE
        self.engine = engine
        self.image = pl_engine_image(engine)
        regmap = register_map()
        members = {
            "axi": In(axi_lite_signature(regmap.address_width)),
            "dma": Out(axi4_write_signature()),
            "irq": Out(1),
            "led": Out(4),
            "imu_sclk": Out(1, init=1), "imu_mosi": Out(1), "imu_miso": In(1, init=1),
            "imu_cs_n": Out(1, init=1), "imu_dr": In(1),
            "baro_sclk": Out(1, init=1), "baro_mosi": Out(1), "baro_miso": In(1, init=1),
            "baro_cs_n": Out(1, init=1), "baro_int": In(1),
            "lidar_rx": In(1, init=1), "lidar_tx": Out(1, init=1),
        }
        super().__init__(members)
        seq_cycles = job_cycles(self.image, "imu")
        #: AXI read latency of the bank; an IMU sample's job (sequencer) in :attr:`IMU_CYCLES`
        self.LATENCY = 2
        self.IMU_CYCLES = seq_cycles
        self.THROUGHPUT = 1 / seq_cycles

    @classmethod
    def for_target(cls, board: str):
        """The board variant (``navgate build ins_trn_top --target zybo-z7-20``), built in
        place of the generic top."""
        if board != "zybo-z7-20":
            raise KeyError(f"{cls.NAME} has no variant for board {board!r}")
        return ZyboInsTrnTop(engine=cls.ENGINE)

    def write_artifacts(self, out_dir, name: str, target: str | None = None):
        """The register map's C header and documentation (``NAME_regs.h``/``.md``)."""
        return _register_artifacts(out_dir, name)

    def elaborate(self, platform):
        from navgate.gateware.axi_lite import AxiLiteRegisterBank
        from navgate.systems.ins_trn.pl.interrupts import InterruptGenerator
        from navgate.systems.ins_trn.pl.output_formatter import (
            COV_FIELDS,
            OUT_WORDS,
            REGISTER_OF,
            SIGMA_REGISTER_OF,
            NavOutputFormatter,
        )
        from navgate.systems.ins_trn.pl.output_formatter import (
            IN_FIELDS as FMT_IN,
        )
        from navgate.systems.ins_trn.pl.profile_manager import (
            AltitudeProfileManager,
            TimestampCorrelator,
        )
        from navgate.systems.ins_trn.pl.sensors.sensor_subsystem import SensorSubsystem
        from navgate.systems.ins_trn.pl.shared_units import (
            SHARED_CORES,
            arbitrate,
            share_units,
            unit_port,
        )

        m = Module()
        regmap = register_map()
        regs = AxiLiteRegisterBank(regmap, fabric_reads=tuple(SEQUENCER_REGISTER_OF.values()))
        m.submodules.regs = regs
        wiring.connect(m, wiring.flipped(self.axi), regs.axi)

        ctrl = regs.o_CTRL
        enable = _bits(ctrl, "CTRL", "enable")
        engine_reset = _bits(ctrl, "CTRL", "reset")

        # ------------------------------------------------------------ sensors
        sensors = SensorSubsystem(self.tick_cycles, calibrate=False, shared_baro_units=True,
                                  lidar_timeout_bits=LIDAR_TIMEOUT_BITS)
        m.submodules.sensors = sensors
        # the last barometer sample and ranger frame, for the PS
        baro_p, baro_t, baro_count = Signal(32), Signal(32), Signal(32)
        with m.If(sensors.baro.valid):
            m.d.sync += [baro_p.eq(sensors.baro.payload.p), baro_t.eq(sensors.baro.payload.t),
                         baro_count.eq(baro_count + 1)]
        lidar_dist, lidar_strength = Signal(16), Signal(16)
        lidar_count = Signal(32)
        with m.If(sensors.lidar.valid):
            m.d.sync += [lidar_dist.eq(sensors.lidar.payload.dist),
                         lidar_strength.eq(sensors.lidar.payload.strength),
                         lidar_count.eq(lidar_count + 1)]
        baud_div = _bits(regs.o_LIDAR_CFG, "LIDAR_CFG", "baud_div")
        tick_div = Signal(8)
        with m.If(baud_div[4:] > 256):
            m.d.comb += tick_div.eq(255)
        with m.Elif(baud_div[4:] != 0):
            m.d.comb += tick_div.eq(baud_div[4:] - 1)
        m.d.comb += [
            self.imu_sclk.eq(sensors.imu_sclk), self.imu_mosi.eq(sensors.imu_mosi),
            self.imu_cs_n.eq(sensors.imu_cs_n), sensors.imu_miso.eq(self.imu_miso),
            sensors.imu_dr.eq(self.imu_dr),
            self.baro_sclk.eq(sensors.baro_sclk), self.baro_mosi.eq(sensors.baro_mosi),
            self.baro_cs_n.eq(sensors.baro_cs_n), sensors.baro_miso.eq(self.baro_miso),
            sensors.baro_int.eq(self.baro_int),
            sensors.lidar_rx.eq(self.lidar_rx), self.lidar_tx.eq(1),
            sensors.imu_cfg.eq(regs.o_IMU_CFG[:10]),
            sensors.baro_cfg.eq(regs.o_BARO_CFG[:10]),
            sensors.lidar_cfg.eq(Cat(tick_div, _bits(regs.o_LIDAR_CFG, "LIDAR_CFG", "enable"))),
            sensors.update_rate.eq(regs.o_UPDATE_RATE[:16]),
            sensors.baro_rate.eq(regs.o_BARO_RATE[:16]),
            sensors.baro.ready.eq(1), sensors.lidar.ready.eq(1),
            regs.i_BARO_PRESS.eq(baro_p), regs.i_BARO_TEMP.eq(baro_t),
            regs.i_BARO_SAMPLES.eq(baro_count),
            regs.i_LIDAR_DATA.eq(Cat(lidar_dist, lidar_strength)),
            regs.i_LIDAR_FRAMES.eq(lidar_count),
            regs.i_SAMPLE_COUNT.eq(sensors.imu_samples),
            regs.i_ERROR_COUNT.eq(sensors.imu_errors + sensors.baro_errors
                                  + sensors.lidar_errors),
        ]

        # ------------------------------------------------------------ engines
        seq = NavSequencer(self.image, register_words={
            n: regmap[r].offset >> 2 for n, r in SEQUENCER_REGISTER_OF.items()})
        m.d.comb += [regs.fr_word.eq(seq.reg_word), seq.reg_data.eq(regs.fr_data)]
        seq = ResetInserter(engine_reset)(seq)
        m.submodules.sequencer = seq
        raw = sensors.imu.payload
        for f in IMU_FIELDS:
            m.d.comb += getattr(seq.imu.payload, f).eq(getattr(raw, f))
        m.d.comb += [seq.imu.valid.eq(sensors.imu.valid), sensors.imu.ready.eq(seq.imu.ready),
                     seq.enable.eq(enable & ~engine_reset)]
        raw_regs = ("RAW_GYRO_X", "RAW_GYRO_Y", "RAW_GYRO_Z",
                    "RAW_ACCEL_X", "RAW_ACCEL_Y", "RAW_ACCEL_Z")
        raw_hold = [Signal(32, name=f"raw_{k}") for k in range(6)]
        with m.If(sensors.imu.valid & sensors.imu.ready):
            for k, f in enumerate(IMU_FIELDS):
                m.d.sync += raw_hold[k].eq(getattr(raw, f))
        for reg, hold in zip(raw_regs, raw_hold, strict=True):
            m.d.comb += getattr(regs, f"i_{reg}").eq(hold)

        m.d.comb += [
            seq.eng_addr.eq(_bits(regs.o_ENG_ADDR, "ENG_ADDR", "addr")),
            seq.eng_wdata.eq(regs.o_ENG_WDATA),
            seq.eng_write.eq(_bits(regs.p_ENG_CMD, "ENG_CMD", "write")),
            seq.eng_read.eq(_bits(regs.p_ENG_CMD, "ENG_CMD", "read")),
            regs.i_ENG_RDATA.eq(seq.eng_rdata),
            regs.i_ENG_STATUS.eq(Cat(seq.busy, Signal(7), seq.propagations)),
            seq.trn_start.eq(_bits(regs.p_TRN_CTRL, "TRN_CTRL", "start")),
            seq.alt_start.eq(_bits(regs.p_ALT_CTRL, "ALT_CTRL", "start")),
            regs.i_TRN_STATUS.eq(seq.trn_status), regs.i_TRN_NIS.eq(seq.trn_nis),
            regs.i_ALT_STATUS.eq(seq.alt_status), regs.i_ALT_NIS.eq(seq.alt_nis),
        ]
        m.d.comb += seq.cal_apply.eq(_bits(regs.p_CAL_APPLY, "CAL_APPLY", "apply"))
        shadow = {n: seq.shadow[k] for k, n in enumerate(SHADOW_WORDS)}
        for i in range(3):
            m.d.comb += [getattr(regs, f"i_BIAS_A{'XYZ'[i]}").eq(shadow[f"ba{i}"]),
                         getattr(regs, f"i_BIAS_G{'XYZ'[i]}").eq(shadow[f"bg{i}"])]
        for i in range(N_STATES):
            m.d.comb += getattr(regs, f"i_COV_DIAG_{i}").eq(shadow[p_reg(i, i)])

        # ------------------------------------------------------------ outputs
        # the formatter and baro_compensation share one adder and one multiplier
        # (shared_units.py), a whole vector at a time: the compensation starts only while the
        # formatter is idle with nothing pending, the formatter only while the compensation
        # is idle; a grant, once used, lasts until the compensation is done
        fmt = NavOutputFormatter(shared_units=True)
        m.submodules.formatter = fmt
        fmt_pending = Signal()
        with m.If(seq.shadow_valid):
            m.d.sync += fmt_pending.eq(1)
        with m.Elif(fmt.i.valid & fmt.i.ready):
            m.d.sync += fmt_pending.eq(0)
        fmt_valid, baro_grant = arbitrate(m, fmt.i.ready, fmt_pending, sensors.baro_busy)
        m.d.comb += sensors.baro_grant.eq(baro_grant)
        share_units(m, {u: unit_port(fmt, u) for u in SHARED_CORES},
                    {u: unit_port(sensors, u, "baro_") for u in SHARED_CORES},
                    sensors.baro_busy)
        for f in FMT_IN:
            src = regs.o_REF_ALT if f == "ref_alt" else shadow[f]
            m.d.comb += getattr(fmt.i.payload, f).eq(src)
        for f in COV_FIELDS:  # diag<k>: P's diagonal word k, for COV_POS/VEL/ATT
            k = int(f.removeprefix("diag"))
            m.d.comb += getattr(fmt.i.payload, f).eq(shadow[p_reg(k, k)])
        m.d.comb += [fmt.i.valid.eq(fmt_valid), fmt.o.ready.eq(1)]
        for w in OUT_WORDS:
            m.d.comb += getattr(regs, f"i_{REGISTER_OF[w]}").eq(getattr(fmt.o.payload, w))
        for w, reg in SIGMA_REGISTER_OF.items():
            m.d.comb += getattr(regs, f"i_{reg}").eq(getattr(fmt.o.payload, w))
        m.d.comb += regs.i_NAV_FLAGS.eq(fmt.o.payload.flags)

        # ------------------------------------------------------------ profile DMA
        prof = AltitudeProfileManager()
        m.submodules.profile = prof
        corr = TimestampCorrelator()  # the ranger frame's INS position and time
        m.submodules.correlator = corr
        wiring.connect(m, prof.axi, wiring.flipped(self.dma))
        # the FIFO takes one entry every four cycles (block RAM, one 32-bit word a cycle); a
        # PROF_PUSH sooner than that (the PS writing PROF_PUSH twice within three cycles,
        # without PROF_ENTRY_H between) is not stored and raises the error interrupt
        push = Signal()
        push_lost = Signal()
        m.d.comb += [push.eq(_bits(regs.p_PROF_PUSH, "PROF_PUSH", "push")),
                     push_lost.eq(push & ~prof.entry.ready)]
        m.d.comb += [
            corr.frame.eq(sensors.lidar.valid), corr.pos_n.eq(shadow["pN"]),
            corr.pos_e.eq(shadow["pE"]), corr.samples.eq(seq.propagations),
            regs.i_PROF_SAMPLE_N.eq(corr.sample_n), regs.i_PROF_SAMPLE_E.eq(corr.sample_e),
            regs.i_PROF_SAMPLE_T.eq(corr.sample_t),
            prof.entry.valid.eq(push),
            prof.entry.payload.h_terrain.eq(regs.o_PROF_ENTRY_H),
            prof.entry.payload.pos_n.eq(corr.sample_n),
            prof.entry.payload.pos_e.eq(corr.sample_e),
            prof.entry.payload.time.eq(corr.sample_t),
            prof.entry.payload.valid.eq(1),
            prof.dma_start.eq(_bits(regs.p_PROF_CTRL, "PROF_CTRL", "start")),
            prof.dma_address.eq(regs.o_PROF_ADDR),
            prof.dma_count.eq(_bits(regs.o_PROF_COUNT, "PROF_COUNT", "count")),
            regs.i_PROF_STATUS.eq(Cat(prof.busy, Signal(7), prof.fill)),
        ]

        # ------------------------------------------------------------ interrupts, status
        # errors of the enabled sensors only (a disabled ranger times out, by design)
        enabled = Cat(_bits(regs.o_IMU_CFG, "IMU_CFG", "enable"),
                      _bits(regs.o_BARO_CFG, "BARO_CFG", "enable"),
                      _bits(regs.o_LIDAR_CFG, "LIDAR_CFG", "enable"))
        live_error = Signal(3)
        sensor_error = Signal(3)
        m.d.comb += live_error.eq(sensors.sensor_error & enabled)
        m.d.sync += sensor_error.eq(live_error)
        error_event = Signal()
        m.d.comb += error_event.eq((live_error & ~sensor_error).any()
                                   | (prof.done & prof.error) | push_lost)
        sticky_error = Signal()
        with m.If(engine_reset):
            m.d.sync += sticky_error.eq(0)
        with m.Elif(error_event):
            m.d.sync += sticky_error.eq(1)
        irqgen = InterruptGenerator()
        m.submodules.irq = irqgen
        m.d.comb += [
            irqgen.update_event.eq(seq.update | prof.done),
            irqgen.error_event.eq(error_event),
            regs.set_IRQ_STATUS.eq(irqgen.set_status),
            irqgen.status.eq(regs.o_IRQ_STATUS[:2]),
            irqgen.enable.eq(regs.o_IRQ_ENABLE[:2]),
            self.irq.eq(irqgen.irq),
            regs.i_STATUS.eq(Cat(enable & ~engine_reset, sticky_error)),
        ]
        trn_led = Signal(24)  # TRN update: a visible 168 ms flash
        with m.If(seq.update & seq.trn_status[1]):
            m.d.sync += trn_led.eq(1)
        with m.Elif(trn_led != 0):
            m.d.sync += trn_led.eq(trn_led + 1)
        m.d.comb += self.led.eq(Cat(enable & ~engine_reset, sticky_error,
                                    ~sensors.sensor_error[0] & enable, trn_led != 0))
        return m


class ZyboInsTrnTop(wiring.Component):
    """:class:`InsTrnTop` with ``clk_rst_gen`` for the Digilent Zybo Z7-20: the 125 MHz
    oscillator ``clk_in`` and the reset button ``rst_btn`` (active high) in; the AXI ports go to
    the block design's Zynq PS7 (M_AXI_GP0 for ``axi``, S_AXI_HP0 for ``dma``, IRQ_F2P[0])."""

    def __init__(self, engine: str = "banked"):
        self.inner = InsTrnTop(engine=engine)
        # clk_sys: the fabric clock (the MMCM's 100 MHz), out to the block design, which clocks
        # the PS7's AXI ports and the interconnects with it: the bus then runs in the register
        # bank's own domain, with no crossing in the fabric (vivado.py)
        members = {"clk_in": In(1), "rst_btn": In(1), "clk_sys": Out(1)}
        for name, member in self.inner.signature.members.items():
            members[name] = member
        super().__init__(members)
        self.LATENCY = self.inner.LATENCY
        self.THROUGHPUT = self.inner.THROUGHPUT

    def write_artifacts(self, out_dir, name: str, target: str | None = None):
        """The C header and register docs, the XDC of the pins, a filelist, and the Vivado
        project script with its block-design wrapper (:mod:`.vivado`)."""
        from pathlib import Path

        from navgate.systems.ins_trn.pl.board import write_xdc

        out_dir = Path(out_dir)
        made = _register_artifacts(out_dir, name)
        pins = ["clk_in", "rst_btn"] + [p for p in PIN_PORTS if p != "lidar_tx"] + \
            ["lidar_tx"] + [f"led[{i}]" for i in range(4)]
        made.append(write_xdc(out_dir / f"{name}.xdc", pins))
        filelist = out_dir / f"{name}.f"
        filelist.write_text(
            f"# {name} for the Digilent Zybo Z7-20 (xc7z020clg400-1), generated by navgate\n"
            f"# top module: {name}; constraints: {name}.xdc; register map: {name}_regs.h\n"
            f"{name}.v\n")
        made.append(filelist)
        from navgate.systems.ins_trn.pl.vivado import write_vivado

        made += write_vivado(out_dir, name)  # reads the emitted NAME.v beside it
        return made

    def elaborate(self, platform):
        from navgate.systems.ins_trn.pl.clocking import ClockResetGenerator

        m = Module()
        m.domains.sync = ClockDomain("sync")  # driven by clk_rst_gen
        m.submodules.clk_rst = crg = ClockResetGenerator(define_domain=False)
        m.d.comb += [crg.clk_in.eq(self.clk_in), crg.ext_rst_n.eq(~self.rst_btn),
                     self.clk_sys.eq(ClockSignal("sync"))]
        m.submodules.top = top = self.inner
        for name, member in top.signature.members.items():
            if member.is_signature:
                wiring.connect(m, getattr(top, name), wiring.flipped(getattr(self, name)))
            elif member.flow == In:
                m.d.comb += getattr(top, name).eq(getattr(self, name))
            else:
                m.d.comb += getattr(self, name).eq(getattr(top, name))
        return m


class InsTrnTopCompact(InsTrnTop):
    """``navgate build ins_trn_top_compact [--target zybo-z7-20]``: ``ins_trn_top`` carrying
    the register machine (docs/opflow-register-machine.md) in place of the banked engines;
    the same ports, register map and board files."""

    NAME = "ins_trn_top_compact"
    ENGINE = "register"
