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

import numpy as np


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
    """``/dev/mem`` mapped at ``base`` (default seed 000's 0x4000_0000), ``size`` bytes.

    Every access is one aligned 32-bit load or store: the map is viewed as a NumPy ``uint32``
    array and indexed by word, as ``pynq.MMIO`` does. (``struct.unpack_from`` on the map would
    copy byte by byte, four bus reads of a read-to-clear register, the last three after it
    cleared.) ``words`` replaces the map by any object indexed the same way (``w[i]`` reads
    word ``i``, ``w[i] = v`` writes it): a stand-in for the board, such as
    :class:`navgate.gateware.native_axi.NativeAxiWindow`. ``path`` may name a plain file,
    which a test maps to check the addressing."""

    def __init__(self, base: int = 0x4000_0000, size: int = 0x1000, path: str = "/dev/mem",
                 *, words=None):
        if base % mmap.PAGESIZE and words is None:
            raise ValueError(f"base 0x{base:X} is not page aligned")
        if size <= 0 or size % 4:
            raise ValueError(f"size {size} is not a positive multiple of 4 bytes")
        self.base, self.size = base, size
        self._fd = self._map = None
        if words is None:
            self._fd = os.open(path, os.O_RDWR | os.O_SYNC)
            try:
                self._map = mmap.mmap(self._fd, size, mmap.MAP_SHARED,
                                      mmap.PROT_READ | mmap.PROT_WRITE, offset=base)
            except (OSError, ValueError):
                os.close(self._fd)
                raise
            words = np.frombuffer(self._map, np.uint32)
        self._words = words

    def _index(self, offset: int) -> int:
        if offset % 4 or not 0 <= offset < self.size:
            raise ValueError(f"offset 0x{offset:X} is not a word inside the "
                             f"0x{self.size:X}-byte map")
        return offset >> 2

    def read(self, offset: int) -> int:
        return int(self._words[self._index(offset)])

    def write(self, offset: int, value: int) -> None:
        self._words[self._index(offset)] = int(value) & 0xFFFFFFFF

    def close(self) -> None:
        self._words = None
        if self._map is not None:
            self._map.close()
            os.close(self._fd)
            self._map = self._fd = None


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
