"""The PS side of seed 000 over the real register interface of ``ins_trn_top``: one engine class
for every way to the fabric (the Verilated top, ``fpga-sim``; the Zynq's PL, ``board``).

Reference: seed 000 "System Architecture" / "Data Flow" and its AXI register map
(docs/seed000-registers.md). :class:`RegisterEngine` is the ``fp32`` engine's PS side
(:class:`Fp32Engine`) talking to the PL only through registers, with the board's driver
(:class:`navgate.hw.regmap.Registers`, by register and field name). What differs between a
simulation and a board is a :class:`Fabric`: the driver's bus, how an engine job is sent
(one batch in the simulation, access by access on a board), where the sensors' samples come
from (pushed into the device emulators on the simulated pins; on a board the real sensors
on the Pmods), how the PS waits for the interrupt and where the profile DMA writes. The
register accesses:

- set-up: CTRL.reset (a board's fabric keeps running between flights), the calibration
  through CAL_* and CAL_APPLY; the other engine registers (noise, initial state, P0) through
  the engine register window (ENG_ADDR/ENG_WDATA/ENG_CMD); the reference point (REF_*),
  IMU_CFG (fastest SCLK, data-ready pacing, enabled), BARO_CFG, IRQ_ENABLE.update,
  CTRL.enable; the sample counters as they stand then (the counts the PS waits for are
  counted from them);
- IMU samples: from the fabric's sensors; the PS waits until ENG_STATUS counts them
  (propagations) and the sequencer is idle;
- altitude and TRN updates: ALT_* / TRN_* registers (the fix as the innovation, its
  covariance, lag and chi-square gate), the start strobe, then the update interrupt
  (IRQ_STATUS, read to clear), the status and NIS registers; the gate flags and the
  correction words through the window;
- state reads (``read_nav``, ``read_cov_diag``, ...): the raw state and compensation words
  through the window (the PS recovers geodetic position in float64 from them, as with the
  ``fp32`` engine), cached until the next engine job;
- the altitude profile (:mod:`navgate.systems.ins_trn.ps.pl_profile`): every accepted terrain
  height pushed into the profile FIFO with the position and time the PL's timestamp
  correlator latched at its ranger frame (PROF_ENTRY_H, PROF_PUSH); for each correlation the
  newest entries by DMA (PROF_ADDR/PROF_COUNT/PROF_CTRL, the update interrupt at the DMA's
  end), read back from the DMA buffer;
- the barometer (BARO_SAMPLES, BARO_PRESS) and the ranger (LIDAR_FRAMES, LIDAR_DATA).

With the sensors' words from the flight's record stream (the simulation, or a stand-in for
the board) the result equals the ``fp32`` engine's bit for bit
(tests/systems/ins_trn/ps/test_fpga_sim.py, test_board_engine.py).
"""

from __future__ import annotations

import contextlib
import weakref

import numpy as np

from navgate.hw.regmap import Reading, Registers, RegisterTimeout
from navgate.numerics.fp32 import bits_to_float, float_to_bits
from navgate.systems.ins_trn.pl.fp32_exec import to_f32
from navgate.systems.ins_trn.pl.fp32_program import CAL_REGS, N_STATES, NAV_REGS, p_reg
from navgate.systems.ins_trn.pl.register_engine import PL_ENGINES, pl_engine_image
from navgate.systems.ins_trn.pl.sequencer import job_cycles
from navgate.systems.ins_trn.pl.top import CAL_REGISTER_OF
from navgate.systems.ins_trn.ps.fp32_engine import Fp32Engine
from navgate.systems.ins_trn.ps.pl_interface import EngineSetup, UpdateOutcome, check_imu_words
from navgate.systems.ins_trn.ps.pl_profile import VALID_BIT

__all__ = ["RegisterEngine", "Fabric", "PlRegisterError", "HOT_WORDS", "DMA_ENTRIES",
           "LIDAR_BIT_CYCLES", "LIDAR_TEMP_WORD"]


class PlRegisterError(RuntimeError):
    """The fabric failed or answered unexpectedly (a bus error, a wait that ran out, a
    register that does not hold what the PS expects)."""


#: UART bit time of the ranger (LIDAR_CFG.baud_div; the co-simulation's emulator runs at it)
LIDAR_BIT_CYCLES = 32
#: the TF-Luna temperature word the emulator sends (25 degC: (25 + 256) * 8)
LIDAR_TEMP_WORD = 2248
#: the most profile entries one DMA moves (the co-simulation's 1 KiB "DDR")
DMA_ENTRIES = 64

#: state words the navigator reads at every log row and ranger record, fetched in one batch
HOT_WORDS = (NAV_REGS + ("cN", "cE", "cD", "cvN", "cvE", "cvD", "cq0", "cq1", "cq2", "cq3")
             + tuple(p_reg(i, i) for i in range(N_STATES))
             + tuple("c" + p_reg(i, i) for i in range(N_STATES))
             + (p_reg(0, 1), "c" + p_reg(0, 1)))


class Fabric:
    """The way to one ``ins_trn_top``: :attr:`regs` (the driver over the bus) and what a bus
    alone does not say. Subclasses: :class:`navgate.systems.ins_trn.ps.fpga_sim.SimFabric`,
    :class:`navgate.systems.ins_trn.ps.board_engine.BoardFabric`."""

    #: the error :meth:`job` raises (a subclass of :class:`PlRegisterError`)
    error = PlRegisterError
    #: the byte address the profile DMA writes to (PROF_ADDR)
    dma_address = 0
    #: the LIDAR_CFG.baud_div the PS sets (clocks per UART bit)
    lidar_baud_div = LIDAR_BIT_CYCLES
    #: the sensors run by themselves (a board's): a count the PS waits for may be passed
    live = False

    def __init__(self, regs: Registers):
        self.regs = regs

    @contextlib.contextmanager
    def job(self):
        """One engine job's register accesses (yields :attr:`regs`); a bus error or a wait
        that runs out is :attr:`error`."""
        try:
            yield self.regs
        except (OSError, RegisterTimeout) as exc:
            raise self.error(str(exc)) from None

    def feed_imu(self, words: np.ndarray) -> None:
        """The IMU's n x 6 int16 words (gx gy gz ax ay az) for the fabric to read."""

    def feed_baro(self, uncomp_press: int, uncomp_temp: int) -> None:
        """One barometer sample (the BMP390's ADC words)."""

    def feed_ranger(self, dist: int, strength: int) -> None:
        """One ranger frame."""

    def wait_interrupt(self, limit: int) -> Reading:
        """Wait for the interrupt (at most ``limit`` cycles or polls); IRQ_STATUS, read (and
        so cleared) after it."""
        raise NotImplementedError

    def dma_words(self, count: int) -> list[Reading]:
        """The first ``count`` 32-bit words of the DMA buffer (after a DMA)."""
        raise NotImplementedError

    def stats(self) -> dict:
        return {}

    def close(self) -> None:
        """Release the fabric (end the simulation, unmap the board)."""


def wait_count(regs: Registers, name: str, field: str, count: int, live: bool, *,
               limit: int, **others: int) -> Reading:
    """Wait until the counter ``name.field`` reaches ``count`` (and the ``others`` fields hold
    their values). Fed sensors (the simulation, the stand-in) stop at the count: the value
    itself is waited for (in the bus's own time). Live sensors count on while the PS works:
    the count reached or passed, modulo the field's width, ends the wait (at most ``limit``
    reads, else :class:`RegisterTimeout`)."""
    if not live:
        return regs.wait_until(name, limit=limit, **{field: count}, **others)
    width = next(f.width for f in regs.regmap[name].fields if f.name == field)
    value = None
    for _ in range(int(limit)):
        value = regs.read(name)
        got = regs.decode(name, value)
        if ((got[field] - count) % (1 << width) < 1 << (width - 1)
                and all(got[k] == v for k, v in others.items())):
            return Reading(value)
    raise RegisterTimeout(f"{name}.{field} did not reach {count} in {limit} reads "
                          f"(last {value:#x})")


class _WindowMachine:
    """The PS's view of the engine registers through the window, shaped like the part of
    ``fp32_exec.Machine`` the ``fp32`` engine's read methods use (``get``, ``set``)."""

    def __init__(self, engine: RegisterEngine, ps_machine):
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
    fabric's DMA buffer (PROF_ADDR, PROF_COUNT, PROF_CTRL.start), waits for the update
    interrupt and reads the words back from the buffer."""

    def __init__(self, engine: RegisterEngine):
        self.e = engine
        self.dmas = 0  #: profile DMA transfers made
        #: entries the correlator latched at another sample than the PS read (live sensors)
        self.latched_apart = 0

    def push(self, words) -> None:
        e = self.e
        with e.fabric.job() as regs:
            out = [regs.read_later(r) for r in ("PROF_SAMPLE_N", "PROF_SAMPLE_E",
                                                "PROF_SAMPLE_T")]
            regs.write("PROF_ENTRY_H", int(words[0]))
            regs.write("PROF_PUSH", push=1)
        samples = (out[2].value - e.base_counts["propagations"]) & 0xFFFFFF
        latched = (out[0].value, out[1].value, samples | VALID_BIT)
        if latched != tuple(words[1:]):
            if not e.fabric.live:
                raise e.fabric.error(f"timestamp correlator latched {latched}, the PS "
                                     f"expected {tuple(words[1:])}")
            # live sensors: the fabric moved on between the PS's read and the frame; the
            # entry is what the correlator latched (its purpose), the difference counted
            self.latched_apart += 1

    def read(self, count: int) -> np.ndarray:
        e = self.e
        fabric = e.fabric
        if not 0 < count <= DMA_ENTRIES:
            raise fabric.error(f"profile DMA of {count} entries (1-{DMA_ENTRIES})")
        with fabric.job() as regs:
            regs.read_later("IRQ_STATUS")  # clear what is pending (read to clear)
            regs.write("PROF_ADDR", fabric.dma_address)
            regs.write("PROF_COUNT", count)
            regs.write("PROF_CTRL", start=1)
            irq = fabric.wait_interrupt(100_000)
            prof = regs.read_later("PROF_STATUS")
            ddr = fabric.dma_words(4 * count)
        irq_status, status = irq.value, prof.value
        if irq_status != 1 or status & 1:
            raise fabric.error(f"profile DMA of {count} entries: IRQ_STATUS {irq_status:#x} "
                               f"(update only expected), PROF_STATUS {status:#x}")
        self.dmas += 1
        e.interrupts += 1
        words = np.array([r.value for r in ddr], np.uint32).reshape(count, 4)
        # the entries' time stamps count from the fabric's propagations at set-up
        base = e.base_counts["propagations"]
        words[:, 3] = (words[:, 3] & ~np.uint32(0xFFFFFF)) \
            | ((words[:, 3] - np.uint32(base)) & np.uint32(0xFFFFFF))
        return words


class RegisterEngine(Fp32Engine):
    """The whole PL behind the PlEngine interface, through its registers on ``fabric``
    (module docstring). Subclasses make the fabric: ``fpga-sim``, ``board``."""

    needs_imu_words = True
    #: the PL engine the fabric carries (register_engine.PL_ENGINES): its cycles; its
    #: register and output addresses are the banked engine's either way
    pl_engine = "banked"

    def __init__(self, setup: EngineSetup, fabric: Fabric, *, check_pd: bool = False):
        if check_pd:
            raise ValueError(f"check_pd needs the whole of P after every sample, which the "
                             f"{self.name} engine does not read back (use the fp32 engine)")
        self.fabric = fabric
        #: the driver, as on the board (by register and field name)
        self.regs = fabric.regs
        #: the fabric's sample counters at set-up (a board's keep counting between flights)
        self.base_counts = {"propagations": 0, "baro": 0, "lidar": 0}
        super().__init__(setup, check_pd=False)
        self.image = pl_engine_image(self.pl_engine)
        self.addr = self.image.layout.fixed
        self.baro_samples = 0
        self.lidar_frames = 0
        self.propagations = 0
        self.interrupts = 0
        self._finalizer = weakref.finalize(self, fabric.close)
        self._load()
        self.m = _WindowMachine(self, self.m)

    # -- bus ------------------------------------------------------------------------------------
    def _job(self):
        """One engine job's register accesses (one batch in the simulation); a bus error,
        SLVERR or timeout is the fabric's error."""
        return self.fabric.job()

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
            regs.write("CTRL", enable=0, reset=1)  # the sequencer and its counters from zero
            regs.write("CTRL", enable=0, reset=0)
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
            counts = [regs.read_later(r) for r in ("ENG_STATUS", "BARO_SAMPLES",
                                                   "LIDAR_FRAMES")]
        self.base_counts = {"propagations": counts[0].value >> 8, "baro": counts[1].value,
                            "lidar": counts[2].value}

    # -- engine calls -----------------------------------------------------------------------------
    def propagate(self, gyro_words, accel_words) -> None:
        gw, aw = check_imu_words(gyro_words, accel_words)
        words = np.concatenate([gw, aw], axis=1)
        if not (np.all(np.isfinite(words)) and np.all(words == np.round(words))
                and words.min(initial=0) >= -32768 and words.max(initial=0) <= 32767):
            raise self.fabric.error(f"the {self.name} engine needs the IMU's int16 output "
                                    "words (the ideal sensors' float words have no SPI "
                                    "encoding)")
        w = words.astype(np.int64)
        n = w.shape[0]
        self.propagations += n
        count = (self.base_counts["propagations"] + self.propagations) & 0xFFFFFF
        with self._job() as regs:
            self.fabric.feed_imu(w)
            # per sample: the SPI burst (under 4,000 cycles) and the sequencer's IMU job on
            # the slowest engine a fabric may carry (the PS code and the register map are
            # the same for both: a board PS flies either bitstream)
            per_sample = 4000 + max(job_cycles(pl_engine_image(k), "imu")
                                    for k in PL_ENGINES)
            wait_count(regs, "ENG_STATUS", "propagations", count, self.fabric.live,
                       limit=per_sample * n + 100_000, busy=0)
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
            irq = self.fabric.wait_interrupt(100_000)
            out = [irq] + [bus_regs.read_later(r) for r in (status, nis_reg)]
        irq_status, st, nis_bits = (r.value for r in out)
        if not irq_status & 1 or st & 0b011 != 0b010:
            raise self.fabric.error(f"{ctrl}: no update interrupt or not done "
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
        """The sample through the BMP390's pins, ``spi_master_baro`` (INT paced) and
        ``baro_compensation``: wait until BARO_SAMPLES counts the sample, read BARO_PRESS."""
        self.baro_samples += 1
        count = (self.base_counts["baro"] + self.baro_samples) & 0xFFFFFFFF
        with self._job() as regs:
            self.fabric.feed_baro(int(uncomp_press), int(uncomp_temp))
            wait_count(regs, "BARO_SAMPLES", "count", count, self.fabric.live, limit=100_000)
            press = regs.read_later("BARO_PRESS")
        return bits_to_float(press.value)

    def read_ranger(self, dist: int, strength: int) -> tuple[int, int]:
        """The frame through the TF-Luna's UART pin and ``uart_rx_lidar``: wait until
        LIDAR_FRAMES counts it, read LIDAR_DATA."""
        first = not self.lidar_frames
        self.lidar_frames += 1
        count = (self.base_counts["lidar"] + self.lidar_frames) & 0xFFFFFFFF
        baud = self.fabric.lidar_baud_div
        with self._job() as regs:
            if first:  # the ranger's receiver is enabled with its first frame
                regs.write("LIDAR_CFG", baud_div=baud, enable=1)
            self.fabric.feed_ranger(int(dist), int(strength))
            wait_count(regs, "LIDAR_FRAMES", "count", count, self.fabric.live,
                       limit=200 * baud + 10_000)
            data = regs.read_later("LIDAR_DATA")
        word = data.value
        return word & 0xFFFF, word >> 16

    def read_cov(self):
        p = np.empty((15, 15))
        for i in range(15):
            for j in range(i, 15):
                p[i, j] = p[j, i] = self._p(i, j)
        return p

    def hardware_stats(self) -> dict:
        stats = {"update_interrupts": self.interrupts,
                 "profile_dmas": self.profile.fifo.dmas,
                 "profile_entries_pushed": self.profile.pushes,
                 "baro_samples_through_pins": self.baro_samples,
                 "ranger_frames_through_pins": self.lidar_frames,
                 **self.fabric.stats()}
        if self.fabric.live:
            stats["profile_entries_latched_apart"] = self.profile.fifo.latched_apart
        if "simulated_cycles" in stats:
            stats["cycles_per_imu_sample"] = stats["simulated_cycles"] / max(self.samples, 1)
        return stats

    def close(self):
        self._finalizer()
