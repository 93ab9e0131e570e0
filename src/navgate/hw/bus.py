"""Bus transports for :class:`navgate.hw.regmap.Registers`: one API, several ways to the bank.

A bus is any object with ``read(offset) -> int`` and ``write(offset, value)`` (32-bit words at
byte offsets from the bank's base). Transports here:

* :class:`MemoryBus` - a :class:`~navgate.hw.regmap.RegisterFileModel` in Python (unit tests of
  software that uses the driver);
* :class:`DevMemBus` - ``/dev/mem`` mapped with ``mmap`` on a Zynq running Linux (root needed);
* :class:`PynqBus` - ``pynq.MMIO`` on a PYNQ image (``pynq`` is imported only when used).

The co-simulation transports live with the simulators: a cocotb AXI4-Lite master on the
Verilated bank (:mod:`navgate.gateware.axi_lite_cocotb`, inside the simulator) and
:class:`navgate.gateware.native_axi.NativeAxiBus` (batched commands to a native Verilator
process running the whole top).
"""

from __future__ import annotations

import mmap
import os
import struct


class MemoryBus:
    """Reads and writes a :class:`~navgate.hw.regmap.RegisterFileModel`; SLVERR raises."""

    def __init__(self, model):
        self.model = model

    def read(self, offset: int) -> int:
        value, resp = self.model.read(offset)
        if resp:
            raise OSError(f"SLVERR reading offset 0x{offset:03X}")
        return value

    def write(self, offset: int, value: int) -> None:
        if self.model.write(offset, value):
            raise OSError(f"SLVERR writing offset 0x{offset:03X}")


class DevMemBus:
    """``/dev/mem`` mapped at ``base`` (default seed 000's 0x4000_0000), ``size`` bytes."""

    def __init__(self, base: int = 0x4000_0000, size: int = 0x1000, path: str = "/dev/mem"):
        page = mmap.PAGESIZE
        if base % page:
            raise ValueError(f"base 0x{base:X} is not page aligned")
        self._fd = os.open(path, os.O_RDWR | os.O_SYNC)
        try:
            self._map = mmap.mmap(self._fd, size, mmap.MAP_SHARED,
                                  mmap.PROT_READ | mmap.PROT_WRITE, offset=base)
        except OSError:
            os.close(self._fd)
            raise

    def read(self, offset: int) -> int:
        return struct.unpack_from("<I", self._map, offset)[0]

    def write(self, offset: int, value: int) -> None:
        struct.pack_into("<I", self._map, offset, value & 0xFFFFFFFF)

    def close(self) -> None:
        self._map.close()
        os.close(self._fd)


class PynqBus:
    """``pynq.MMIO`` at ``base`` (imported lazily: no PYNQ needed to install navgate)."""

    def __init__(self, base: int = 0x4000_0000, size: int = 0x1000):
        try:
            from pynq import MMIO
        except ImportError as error:
            raise RuntimeError("PynqBus needs the pynq package on a PYNQ board image") \
                from error
        self._mmio = MMIO(base, size)

    def read(self, offset: int) -> int:
        return int(self._mmio.read(offset))

    def write(self, offset: int, value: int) -> None:
        self._mmio.write(offset, int(value) & 0xFFFFFFFF)
