"""The ``board`` engine: the PS of a Zybo Z7-20 flying the real ``ins_trn_top`` on the Zynq's PL.

Reference: seed 000 "System Architecture" (the PS configures and monitors the PL over
AXI4-Lite, the PL interrupts it, the profile goes to DDR by DMA) and the block design that
:mod:`navgate.systems.ins_trn.pl.vivado` writes: the register bank at ``0x4000_0000`` on
M_AXI_GP0, the profile DMA into DDR through S_AXI_HP0, ``irq`` on IRQ_F2P[0]. The engine is
:class:`navgate.systems.ins_trn.ps.pl_registers.RegisterEngine`, the very class ``fpga-sim``
flies the Verilated top with; only its :class:`BoardFabric` differs:

- **the bus** (``--board-bus``): ``devmem`` (default: ``/dev/mem`` mapped at ``--board-base``
  by :class:`navgate.hw.bus.DevMemBus`; needs root and nothing else, so it works on any Zynq
  Linux, PetaLinux or PYNQ) or ``pynq`` (:class:`navgate.hw.bus.PynqBus`, ``pynq.MMIO``; pynq
  is imported only then);
- **the profile DMA**: into a buffer the PL's HP0 port can reach. With ``devmem``, physical
  DDR at ``--board-dma`` (default ``0x3FF0_0000``, the last MiB of the Zybo's 1 GiB, which
  Linux must be kept off: ``mem=1023M`` on the kernel command line or a ``reserved-memory``
  node), mapped uncached through ``/dev/mem``; with ``pynq``, a ``pynq.allocate`` buffer
  (contiguous memory, invalidated before it is read);
- **the interrupt** (``--board-irq``): ``poll`` (default: IRQ_STATUS read until a bit is set,
  bounded; it needs no kernel set-up) or a UIO device ``/dev/uioN`` (IRQ_F2P[0] bound to
  ``generic-uio`` in the device tree: write 1 to unmask, wait with a timeout, then read
  IRQ_STATUS to clear);
- **the sensors**: on the board, the real ADIS16500, BMP390 and TF-Luna on the Pmods; the PS
  pushes nothing and waits, as in the simulation, until the fabric counts the samples. The
  flight's simulated truth then says nothing about the navigation (the board measures the
  bench, not the simulated route): a check of the whole chain on the hardware.

Before the first access (:func:`open_board`), each of these is one line and exit 2 from the
CLI, never a traceback or a hang: no ``/dev/mem`` or no permission, no pynq, a base address
outside the PS's GP ports or not page aligned, a PL the kernel's FPGA manager does not
report as ``operating`` (a read on GP0 with no bitstream can stall the bus), and a bank whose
ID register does not read ``NAVG``. The ID is read in a forked child first, so a bus error
(SIGBUS) or a stalled read ends the child, not the PS. Every wait is bounded (reads or
seconds).

The stand-in (``--board-bus verilator``): the Verilated ``ins_trn_top`` with the sensor
emulators on its pins (``fpga-sim``'s :class:`InsTrnSimTop`), behind the native AXI server and
seen through :class:`navgate.gateware.native_axi.NativeAxiWindow` as the word window that
:class:`DevMemBus` takes in place of its ``/dev/mem`` map. The board's code path (DevMemBus
addressing, access-by-access register traffic, polled interrupt, DMA buffer read through a
second DevMemBus) then runs end to end on a machine without a board, with the flight's
sensor words pushed into the emulators (what the real sensors measure on the board). It
equals ``fpga-sim`` and so ``fp32`` bit for bit (tests/systems/ins_trn/ps/test_board_engine.py).
It was not run on a board.
"""

from __future__ import annotations

import faulthandler
import mmap
import os
import select
import signal
import struct
from dataclasses import dataclass

import numpy as np

from navgate.hw.bus import DevMemBus, PynqBus
from navgate.hw.regmap import Reading, Registers, RegisterTimeout
from navgate.systems.ins_trn.pl.registers import BASE_ADDRESS, ID_VALUE, register_map
from navgate.systems.ins_trn.ps.pl_interface import EngineSetup
from navgate.systems.ins_trn.ps.pl_registers import (
    DMA_ENTRIES,
    LIDAR_BIT_CYCLES,
    Fabric,
    PlRegisterError,
    RegisterEngine,
)

__all__ = ["BoardEngine", "BoardError", "BoardSettings", "Board", "open_board",
           "BUSES", "DMA_ADDRESS", "FPGA_STATE"]

#: the ways to the bank: the board's two, and the stand-in for checks without a board
BUSES = ("devmem", "pynq", "verilator")
#: the profile DMA's default buffer: the last MiB of the Zybo Z7-20's 1 GiB DDR
DMA_ADDRESS = 0x3FF0_0000
#: where Linux's FPGA manager says whether the PL is configured ("operating")
FPGA_STATE = "/sys/class/fpga_manager/fpga0/state"
#: the Zynq-7000's PS -> PL general-purpose AXI windows (M_AXI_GP0 and GP1)
GP_WINDOWS = ((0x4000_0000, 0x8000_0000), (0x8000_0000, 0xC000_0000))
#: the register bank's span (the map's 11 address bits)
BANK_BYTES = 0x800
#: LIDAR_CFG.baud_div for the real TF-Luna: 115200 baud from the 100 MHz clock
TFLUNA_BAUD_DIV = 868
#: seconds the forked ID probe may take before the bus is called stalled
PROBE_SECONDS = 2.0
#: seconds a UIO interrupt may take
UIO_SECONDS = 1.0
#: fabric cycles the stand-in runs per PS bus access: 2.5 us at 100 MHz, an estimate (not
#: measured) of one register access from Python on the Zybo's 667 MHz Cortex-A9
STANDIN_ACCESS_CYCLES = 250


class BoardError(PlRegisterError):
    """The board cannot be used, or its fabric answered unexpectedly (one line)."""


@dataclass(frozen=True)
class BoardSettings:
    """How to reach the fabric (the ``--board-*`` options; module docstring)."""

    bus: str = "devmem"
    base: int = BASE_ADDRESS
    dma: int = DMA_ADDRESS
    irq: str = "poll"
    mem: str = "/dev/mem"
    fpga_state: str = FPGA_STATE

    def check(self) -> None:
        if self.bus not in BUSES:
            raise BoardError(f"--board-bus {self.bus!r}: choose from {', '.join(BUSES)}")
        if self.base % mmap.PAGESIZE:
            raise BoardError(f"--board-base 0x{self.base:X} is not page aligned "
                             f"({mmap.PAGESIZE} bytes)")
        if self.bus != "verilator" and self.mem == "/dev/mem" and not any(
                lo <= self.base and self.base + BANK_BYTES <= hi for lo, hi in GP_WINDOWS):
            raise BoardError(f"--board-base 0x{self.base:08X} is outside the Zynq's GP "
                             f"ports (0x40000000-0xBFFFFFFF); the block design puts the "
                             f"bank at 0x{BASE_ADDRESS:08X}")
        if self.dma % 16 or not 0 <= self.dma <= 0xFFFF_FFFF - 16 * DMA_ENTRIES:
            raise BoardError(f"--board-dma 0x{self.dma:X} is not a 16-byte aligned 32-bit "
                             "address")
        if self.irq != "poll" and not os.path.isabs(self.irq):
            raise BoardError(f"--board-irq {self.irq!r}: give poll or a UIO device's path "
                             "(/dev/uioN)")


def _fpga_configured(path: str) -> None:
    """The FPGA manager's word on the PL, where the kernel has one (else nothing to check)."""
    try:
        with open(path) as f:
            state = f.read().strip()
    except FileNotFoundError:
        return
    except OSError as error:
        raise BoardError(f"cannot read {path}: {error.strerror}") from None
    if state != "operating":
        raise BoardError(f"the PL is not configured ({path} says {state!r}): load the "
                         "bitstream first (PYNQ: Overlay('ins_trn_top.bit'); PetaLinux: "
                         "fpgautil -b ins_trn_top.bit)")


def _probe_id(bus_factory, base: int) -> int:
    """The ID register read in a forked child: a bus error (SIGBUS) or a read that stalls
    ends the child, not this process."""
    offset = register_map()["ID"].offset
    rfd, wfd = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: one read, its value on the pipe
        code = 1
        try:
            faulthandler.disable()  # a bus error ends the child quietly; the parent says it
            os.close(rfd)
            bus = bus_factory()
            os.write(wfd, struct.pack("<I", bus.read(offset)))
            code = 0
        finally:
            os._exit(code)
    os.close(wfd)
    try:
        ready, _, _ = select.select([rfd], [], [], PROBE_SECONDS)
        data = os.read(rfd, 4) if ready else b""
    finally:
        os.close(rfd)
    if len(data) == 4:
        os.waitpid(pid, 0)
        return struct.unpack("<I", data)[0]
    if not ready:
        os.kill(pid, signal.SIGKILL)
    _, status = os.waitpid(pid, 0)
    where = f"0x{base + offset:08X}"
    if os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGBUS:
        raise BoardError(f"reading the ID register at {where} raised a bus error: nothing "
                         "answers at --board-base (or the bitstream is not loaded)")
    if not ready:
        raise BoardError(f"reading the ID register at {where} did not return in "
                         f"{PROBE_SECONDS:g} s: the bus stalls (is the bitstream loaded?)")
    raise BoardError(f"reading the ID register at {where} failed in the probe process "
                     f"(status {status})")


class _DevMemDma:
    """The DMA buffer in physical DDR, mapped through ``/dev/mem`` (uncached: no flush)."""

    def __init__(self, settings: BoardSettings, words=None):
        page = mmap.PAGESIZE
        start = settings.dma - settings.dma % page
        self.skip = settings.dma - start
        size = -(-(self.skip + 16 * DMA_ENTRIES) // page) * page
        self.address = settings.dma
        self.bus = DevMemBus(start, size, settings.mem, words=words)

    def words(self, count: int) -> list[int]:
        return [self.bus.read(self.skip + 4 * k) for k in range(count)]

    def close(self) -> None:
        self.bus.close()


class _PynqDma:
    """A ``pynq.allocate`` buffer (physically contiguous; invalidated before it is read)."""

    def __init__(self):
        import pynq

        self.buffer = pynq.allocate(shape=(4 * DMA_ENTRIES,), dtype=np.uint32)
        self.address = int(self.buffer.physical_address)

    def words(self, count: int) -> list[int]:
        self.buffer.invalidate()
        return [int(w) for w in self.buffer[:count]]

    def close(self) -> None:
        self.buffer.freebuffer()


class _UioInterrupt:
    """IRQ_F2P[0] through a UIO device: unmask (write 1), wait with a timeout, acknowledge."""

    def __init__(self, path: str):
        try:
            self.fd = os.open(path, os.O_RDWR)
        except OSError as error:
            raise BoardError(f"--board-irq {path}: {error.strerror}") from None
        self.path = path

    def wait(self) -> None:
        os.write(self.fd, struct.pack("<I", 1))
        ready, _, _ = select.select([self.fd], [], [], UIO_SECONDS)
        if not ready:
            raise BoardError(f"no interrupt on {self.path} within {UIO_SECONDS:g} s")
        os.read(self.fd, 4)

    def close(self) -> None:
        os.close(self.fd)


class _Repeating:
    """A word window seen repeated through a larger address range (index modulo its size)."""

    def __init__(self, window):
        self.window = window

    def __getitem__(self, index):
        return self.window[index % len(self.window)]

    def __setitem__(self, index, value):
        self.window[index % len(self.window)] = value


class _Standin:
    """The stand-in's fabric and sensors: ``fpga-sim``'s co-simulation top in Verilator, its
    AXI space as a physical map (the bank at ``BASE_ADDRESS``, the DMA's 1 KiB "DDR" wherever
    the DMA address points, modulo its size; elsewhere nothing: reads 0)."""

    def __init__(self):
        from navgate.gateware.native_axi import NativeAxiWindow
        from navgate.systems.ins_trn.ps import fpga_sim

        self.fpga_sim = fpga_sim
        self.sim = fpga_sim.start_sim()
        self.window = NativeAxiWindow

    def words(self, base: int, size: int, dma: bool = False):
        if dma:  # the DMA's memory decodes the low address bits: it repeats through DDR
            ddr = self.window(self.sim, self.fpga_sim.DMA_WINDOW, self.fpga_sim.DMA_WORDS,
                              access_cycles=STANDIN_ACCESS_CYCLES)
            return _Repeating(ddr)
        if base == BASE_ADDRESS:
            return self.window(self.sim, 0, BANK_BYTES // 4,
                               access_cycles=STANDIN_ACCESS_CYCLES)
        return np.zeros(size // 4, np.uint32)

    def feed_imu(self, w) -> None:
        self.sim.push("imu_feed", self.fpga_sim.imu_fields(w))

    def feed_baro(self, up: int, ut: int) -> None:
        self.sim.push("baro_feed", {"up": up, "ut": ut})

    def feed_ranger(self, dist: int, strength: int) -> None:
        self.sim.push("lidar_feed", {"dist": dist, "strength": strength,
                                     "temp": self.fpga_sim.LIDAR_TEMP_WORD})

    def close(self) -> None:
        self.sim.close()


class Board:
    """An opened board (or its stand-in): the driver, the DMA buffer, the interrupt and the
    sensors; open it with :func:`open_board`, close it after the flights."""

    def __init__(self, settings: BoardSettings):
        settings.check()
        self.settings = settings
        self.standin = self.irq = self.dma = self.bus = None
        try:
            self._open(settings)
        except BaseException:
            self.close()
            raise

    def _open(self, s: BoardSettings) -> None:
        if s.bus == "verilator":
            self.standin = _Standin()
            self.bus = DevMemBus(s.base, 0x1000, words=self.standin.words(s.base, 0x1000))
            self._check_id(self.bus.read(register_map()["ID"].offset))
            self.dma = _DevMemDma(s, words=self.standin.words(s.dma, 0, dma=True))
            self.lidar_baud_div = LIDAR_BIT_CYCLES  # the emulator's bit time
        else:
            if s.bus == "pynq":
                try:
                    import pynq  # noqa: F401
                except ImportError:
                    raise BoardError("--board-bus pynq needs the pynq package, which a PYNQ "
                                     "board image brings (not installed here); or use "
                                     "--board-bus devmem") from None
                factory = lambda: PynqBus(s.base, 0x1000)  # noqa: E731
            else:
                try:
                    os.close(os.open(s.mem, os.O_RDWR | os.O_SYNC))
                except FileNotFoundError:
                    raise BoardError(f"no {s.mem} on this machine: --engine board runs on "
                                     "the Zynq's PS (Linux), as root") from None
                except PermissionError:
                    raise BoardError(f"no permission to open {s.mem}: run as root (or give "
                                     "--board-bus pynq on a PYNQ image)") from None
                except OSError as error:
                    raise BoardError(f"cannot open {s.mem}: {error.strerror}") from None
                factory = lambda: DevMemBus(s.base, 0x1000, s.mem)  # noqa: E731
            _fpga_configured(s.fpga_state)
            self._check_id(_probe_id(factory, s.base))
            try:
                self.bus = factory()
            except (OSError, ValueError) as error:
                raise BoardError(f"cannot map the register bank at 0x{s.base:08X}: "
                                 f"{getattr(error, 'strerror', None) or error}") from None
            try:
                self.dma = _PynqDma() if s.bus == "pynq" else _DevMemDma(s)
            except (OSError, ValueError) as error:
                raise BoardError(f"cannot map the profile DMA's buffer at --board-dma "
                                 f"0x{s.dma:08X}: {getattr(error, 'strerror', None) or error} "
                                 "(keep Linux off it: mem=1023M)") from None
            self.lidar_baud_div = TFLUNA_BAUD_DIV
        if s.irq != "poll":
            self.irq = _UioInterrupt(s.irq)
        self.regs = Registers(register_map(), self.bus)

    def _check_id(self, found: int) -> None:
        if found != ID_VALUE:
            raise BoardError(f"no ins_trn register bank at --board-base "
                             f"0x{self.settings.base:08X}: ID reads 0x{found:08X}, the "
                             f"register map says 0x{ID_VALUE:08X} ('NAVG')")

    def close(self) -> None:
        for part in (self.irq, self.dma, self.bus, self.standin):
            if part is not None:
                part.close()
        self.standin = self.irq = self.dma = self.bus = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def open_board(settings: BoardSettings | None = None) -> Board:
    """Open and check the board (module docstring); :class:`BoardError` in one line."""
    return Board(settings or BoardSettings())


class BoardFabric(Fabric):
    """The board for :class:`RegisterEngine`: access by access, the interrupt polled or
    through UIO, the DMA buffer in DDR, the sensors on the pins (or the stand-in's)."""

    error = BoardError

    def __init__(self, board: Board, owned: bool = False):
        super().__init__(board.regs)
        self.board, self.owned = board, owned
        self.dma_address = board.dma.address
        self.lidar_baud_div = board.lidar_baud_div
        self.live = board.standin is None  # the stand-in's emulators stop at each sample
        self.polls = 0  #: IRQ_STATUS reads while waiting for an interrupt

    def feed_imu(self, w) -> None:
        if self.board.standin is not None:
            self.board.standin.feed_imu(w)

    def feed_baro(self, uncomp_press: int, uncomp_temp: int) -> None:
        if self.board.standin is not None:
            self.board.standin.feed_baro(uncomp_press, uncomp_temp)

    def feed_ranger(self, dist: int, strength: int) -> None:
        if self.board.standin is not None:
            self.board.standin.feed_ranger(dist, strength)

    def wait_interrupt(self, limit: int) -> Reading:
        if self.board.irq is not None:
            self.board.irq.wait()
            return Reading(self.regs.read("IRQ_STATUS"))
        for _ in range(int(limit)):
            self.polls += 1
            status = self.regs.read("IRQ_STATUS")
            if status:
                return Reading(status)
        raise RegisterTimeout(f"no interrupt: IRQ_STATUS read 0 {limit} times")

    def dma_words(self, count: int) -> list[Reading]:
        return [Reading(w) for w in self.board.dma.words(count)]

    def stats(self) -> dict:
        out = {"board_bus": self.board.settings.bus, "interrupt_polls": self.polls}
        if self.board.standin is not None:
            sim = self.board.standin.sim
            out.update(simulated_cycles=sim.cycles, bus_batches=sim.batches,
                       bus_commands=sim.commands)
        return out

    def close(self) -> None:
        if self.owned:
            self.board.close()


class BoardEngine(RegisterEngine):
    """The PS flying the real ``ins_trn_top`` (module docstring): ``board`` an opened
    :class:`Board` (kept open; the engines of one flight share it), else one is opened with
    ``settings`` and closed with the engine."""

    name = "board"

    def __init__(self, setup: EngineSetup, *, check_pd: bool = False, board: Board | None = None,
                 settings: BoardSettings | None = None):
        if check_pd:
            raise ValueError("check_pd needs the whole of P after every sample, which the "
                             "board engine does not read back (use the fp32 engine)")
        owned = board is None
        if owned:
            board = open_board(settings)
        super().__init__(setup, BoardFabric(board, owned))
