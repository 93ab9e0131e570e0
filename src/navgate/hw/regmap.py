"""Register maps described once in SystemRDL: compile, describe, export, model and drive.

A register map is written in SystemRDL 2.0 (Accellera SystemRDL 2.0 standard, 2018) and compiled
with ``systemrdl-compiler``. From the compiled model this module derives

* :class:`RegisterMap` - a plain description (registers, fields, access, side effects) that the
  gateware register bank (:mod:`navgate.gateware.axi_lite`) is generated from;
* the C header (``peakrdl-cheader``) and the Markdown register documentation
  (``peakrdl-markdown``), :func:`export_c_header` and :func:`export_markdown`;
* :class:`RegisterFileModel` - the bit-true behaviour of the bank as software sees it (byte
  strobes, read-to-clear, write-1 strobes, OKAY/SLVERR), the oracle of the gateware tests;
* :class:`Registers` - the driver: one API over any bus with ``read(offset) -> int`` and
  ``write(offset, value)`` (see :mod:`navgate.hw.bus` for the transports). A bus may offer
  more, and the driver then uses it: ``poll(offset, mask, value, limit)`` (wait for a value in
  the bus's own time, as the co-simulation does in clock cycles), ``read_later(offset)`` and
  ``deferred()`` (queue accesses and send them as one batch; reads answer a
  :class:`Reading` filled in when the batch is sent). On a plain bus (``/dev/mem``, PYNQ)
  :meth:`Registers.wait_until` reads in a bounded loop and every :class:`Reading` is filled in
  at once, so the same driver code runs on the board and in the co-simulation.

Side effects understood (SystemRDL field properties): ``sw`` r/w/rw, ``hw`` r/w/na, ``reset``,
``onread = rclr`` (read to clear; an event in the same cycle as the read stays pending),
``hwset`` (hardware sets bits), ``singlepulse`` (a written 1 is a one-cycle strobe that reads
back 0). Writes to read-only registers are ignored with OKAY; only unmapped offsets answer
SLVERR. User properties ``navgate_extension``, ``navgate_departure`` and
``navgate_float32`` mark registers added to, changed from, and float32 in the source spec.
Arrays are unrolled as ``NAME_0``, ``NAME_1``, ... This module is a shared library: it
knows no particular map (seed 000's is ``navgate/systems/ins_trn/pl/registers.rdl``).
"""

from __future__ import annotations

import contextlib
import math
import numbers
import struct
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

OKAY, SLVERR = 0, 2


class RegisterMapError(ValueError):
    """A register map that cannot be compiled or is outside what the bank generator supports."""


@dataclass(frozen=True)
class FieldSpec:
    name: str
    lsb: int
    width: int
    sw: str  #: "r", "w" or "rw"
    hw: str  #: "r", "w", "rw" or "na"
    reset: int | None
    read_clear: bool = False
    hw_set: bool = False
    single_pulse: bool = False
    desc: str = ""
    extension: bool = False

    @property
    def mask(self) -> int:
        return ((1 << self.width) - 1) << self.lsb

    @property
    def stored(self) -> bool:
        """Held in a register of the bank (software-writable, or set by hardware events)."""
        return (("w" in self.sw and not self.single_pulse) or self.hw_set)

    @property
    def constant(self) -> bool:
        return self.hw == "na" and "w" not in self.sw


@dataclass(frozen=True)
class RegisterSpec:
    name: str
    offset: int
    fields: tuple[FieldSpec, ...]
    title: str = ""
    desc: str = ""
    float32: bool = False
    extension: bool = False
    departure: bool = False  #: a register of the source spec whose layout or meaning changed

    def _mask(self, predicate) -> int:
        return sum(f.mask for f in self.fields if predicate(f))

    @property
    def readable(self) -> bool:
        return any("r" in f.sw for f in self.fields)

    @property
    def writable(self) -> bool:
        return any("w" in f.sw for f in self.fields)

    @property
    def hw_input_mask(self) -> int:
        """Bits the fabric drives continuously (read-only status/state)."""
        return self._mask(lambda f: f.hw == "w" and not f.hw_set and "w" not in f.sw)

    @property
    def hw_set_mask(self) -> int:
        return self._mask(lambda f: f.hw_set)

    @property
    def storage_mask(self) -> int:
        return self._mask(lambda f: f.stored)

    @property
    def sw_write_mask(self) -> int:
        return self._mask(lambda f: "w" in f.sw and not f.single_pulse)

    @property
    def pulse_mask(self) -> int:
        return self._mask(lambda f: f.single_pulse)

    @property
    def read_clear_mask(self) -> int:
        return self._mask(lambda f: f.read_clear)

    @property
    def read_mask(self) -> int:
        return self._mask(lambda f: "r" in f.sw and not f.single_pulse)

    @property
    def reset_value(self) -> int:
        return sum((f.reset or 0) << f.lsb for f in self.fields if f.stored or f.constant)

    @property
    def constant_value(self) -> int:
        return sum((f.reset or 0) << f.lsb for f in self.fields if f.constant)

    @property
    def outputs_to_fabric(self) -> bool:
        return any("r" in f.hw and f.stored for f in self.fields)


@dataclass(frozen=True)
class RegisterMap:
    """A compiled register map: 32-bit registers at word-aligned byte offsets."""

    name: str
    registers: tuple[RegisterSpec, ...]
    source: Path | None = None
    desc: str = ""

    @cached_property
    def by_name(self) -> dict[str, RegisterSpec]:
        return {r.name: r for r in self.registers}

    @cached_property
    def by_offset(self) -> dict[int, RegisterSpec]:
        return {r.offset: r for r in self.registers}

    @property
    def address_width(self) -> int:
        """Byte-address bits the bank decodes (enough for the highest offset)."""
        top = max(r.offset for r in self.registers) + 4
        return max(4, math.ceil(math.log2(top)))

    def __getitem__(self, name: str) -> RegisterSpec:
        try:
            return self.by_name[name]
        except KeyError:
            raise KeyError(f"no register {name!r} in {self.name}") from None


def _compile(path: Path):
    from systemrdl import RDLCompileError, RDLCompiler

    compiler = RDLCompiler()
    try:
        compiler.compile_file(str(path))
        return compiler.elaborate()
    except RDLCompileError as error:
        raise RegisterMapError(f"{path}: SystemRDL compilation failed: {error}") from None


def _prop(node, name, default=None):
    try:
        value = node.get_property(name)
    except LookupError:
        return default
    return default if value is None else value


def load_rdl(path: str | Path) -> RegisterMap:
    """Compile a SystemRDL file into a :class:`RegisterMap` (32-bit registers only)."""
    from systemrdl.node import RegNode
    from systemrdl.rdltypes import AccessType, OnReadType

    path = Path(path)
    root = _compile(path)
    top = root.top
    sw_names = {AccessType.r: "r", AccessType.w: "w", AccessType.rw: "rw",
                AccessType.w1: "w", AccessType.rw1: "rw", AccessType.na: "na"}
    registers = []
    for node in top.descendants(unroll=True):
        if not isinstance(node, RegNode):
            continue
        if node.get_property("regwidth") != 32:
            raise RegisterMapError(f"{node.get_path()}: only 32-bit registers are supported")
        name = node.inst_name
        if node.is_array:
            name = f"{name}_{node.current_idx[0]}"
        fields = []
        for f in node.fields():
            sw = sw_names[f.get_property("sw")]
            hw = sw_names[f.get_property("hw")]
            fields.append(FieldSpec(
                name=f.inst_name, lsb=f.lsb, width=f.width, sw=sw, hw=hw,
                reset=f.get_property("reset"),
                read_clear=f.get_property("onread") == OnReadType.rclr,
                hw_set=bool(f.get_property("hwset")),
                single_pulse=bool(f.get_property("singlepulse")),
                desc=(f.get_property("desc") or "").strip(),
                extension=bool(_prop(f, "navgate_extension", False)),
            ))
        registers.append(RegisterSpec(
            name=name, offset=node.absolute_address - top.absolute_address,
            fields=tuple(fields), title=(node.get_property("name") or name),
            desc=(node.get_property("desc") or "").strip(),
            float32=bool(_prop(node, "navgate_float32", False)),
            extension=bool(_prop(node, "navgate_extension", False)),
            departure=bool(_prop(node, "navgate_departure", False)),
        ))
    offsets = [r.offset for r in registers]
    if len(set(offsets)) != len(offsets) or any(o % 4 for o in offsets):
        raise RegisterMapError(f"{path}: registers must sit at distinct word-aligned offsets")
    registers.sort(key=lambda r: r.offset)
    return RegisterMap(top.inst_name, tuple(registers), path,
                       (top.get_property("desc") or "").strip())


def export_c_header(rdl_path: str | Path, out_path: str | Path) -> Path:
    """The C header of the map (``peakrdl-cheader``): register structs and offsets."""
    from peakrdl_cheader.exporter import CHeaderExporter

    out_path = Path(out_path)
    CHeaderExporter().export(_compile(Path(rdl_path)).top, str(out_path))
    return out_path


def export_markdown(rdl_path: str | Path, out_path: str | Path) -> Path:
    """The register documentation as Markdown (``peakrdl-markdown``)."""
    from peakrdl_markdown import MarkdownExporter

    out_path = Path(out_path)
    MarkdownExporter().export(_compile(Path(rdl_path)).top, str(out_path), rename=None)
    return out_path


# ---------------------------------------------------------------------- behaviour model


def strobe_mask(wstrb: int) -> int:
    """32-bit mask of the bytes selected by a 4-bit AXI write strobe."""
    return sum(0xFF << (8 * i) for i in range(4) if wstrb >> i & 1)


class RegisterFileModel:
    """What a bus master sees of a bank generated from ``regmap`` (bit-true oracle).

    ``hw_inputs`` holds the values the fabric drives (by register name); :meth:`hw_set` marks
    hardware events on ``hwset`` fields; :attr:`pulses` collects the write-1 strobes
    (register name -> list of pulsed bit masks).
    """

    def __init__(self, regmap: RegisterMap):
        self.regmap = regmap
        self.stored = {r.name: r.reset_value & r.storage_mask for r in regmap.registers}
        self.hw_inputs = {r.name: 0 for r in regmap.registers if r.hw_input_mask}
        self.pulses: dict[str, list[int]] = {}

    def hw_set(self, name: str, bits: int) -> None:
        reg = self.regmap[name]
        self.stored[name] |= bits & reg.hw_set_mask

    def write(self, offset: int, data: int, wstrb: int = 0xF) -> int:
        reg = self.regmap.by_offset.get(offset & ~3)
        if reg is None:
            return SLVERR
        bytes_ = strobe_mask(wstrb)
        keep = reg.sw_write_mask & bytes_
        self.stored[reg.name] = (self.stored[reg.name] & ~keep) | (data & keep)
        pulse = data & reg.pulse_mask & bytes_
        if pulse:
            self.pulses.setdefault(reg.name, []).append(pulse)
        return OKAY

    def peek(self, name: str) -> int:
        """The value a read would return, without side effects."""
        reg = self.regmap[name]
        value = reg.constant_value
        value |= self.stored[name] & reg.storage_mask
        value |= self.hw_inputs.get(name, 0) & reg.hw_input_mask
        return value & reg.read_mask

    def read(self, offset: int) -> tuple[int, int]:
        reg = self.regmap.by_offset.get(offset & ~3)
        if reg is None:
            return 0, SLVERR
        value = self.peek(reg.name)
        self.stored[reg.name] &= ~reg.read_clear_mask
        return value, OKAY


# ---------------------------------------------------------------------- driver


def f32_bits(value: float) -> int:
    return struct.unpack("<I", struct.pack("<f", value))[0]


def bits_f32(bits: int) -> float:
    return struct.unpack("<f", struct.pack("<I", bits & 0xFFFFFFFF))[0]


#: the largest finite float32 (values beyond round to inf)
F32_MAX = float(np.finfo(np.float32).max)


def _register_int(name: str, value) -> int:
    """An integer register or field value: bool/int/np.integer, or a float with an integer
    value (2.0); 1.5, NaN, 1e300 or a string is a ValueError naming the register."""
    if isinstance(value, (bool, int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        if math.isfinite(value) and float(value).is_integer():
            return int(value)
        raise ValueError(f"{name}: expected an integer register value, got {value!r}")
    raise ValueError(f"{name}: expected an integer register value, got {value!r}")


class RegisterTimeout(TimeoutError):
    """:meth:`Registers.wait_until` ran out of reads before the register took the value."""


class Reading:
    """A register value that may not have been read yet: filled in at once on a plain bus,
    or when a deferring bus (``deferred()``) sends its batch. :attr:`value` before then is a
    RuntimeError."""

    __slots__ = ("_value",)

    def __init__(self, value: int | None = None):
        self._value = value

    def set(self, value: int) -> None:
        self._value = int(value)

    @property
    def ready(self) -> bool:
        return self._value is not None

    @property
    def value(self) -> int:
        if self._value is None:
            raise RuntimeError("the read has not been sent yet (it is queued in a deferred "
                               "batch: leave the block, or read something, first)")
        return self._value

    def __repr__(self) -> str:
        return f"Reading({self._value!r})"


class Registers:
    """Driver for a register map over a bus (``read(offset)``, ``write(offset, value)``).

    The same code drives the co-simulated bank (cocotb AXI-Lite master) and the real board
    (:class:`navgate.hw.bus.DevMemBus`, :class:`navgate.hw.bus.PynqBus`)::

        regs = Registers(load_rdl(path), bus)
        regs.write("IMU_CFG", enable=1, spi_div=9)
        regs.write_f32("TRN_POS_N", 1234.5)
        north = regs.read_f32("POS_N")
        regs.wait_until("ENG_STATUS", busy=0, limit=100_000)

    With a bus that batches (:class:`navgate.gateware.native_axi.NativeAxiBus`), accesses
    inside ``with regs.deferred():`` go out as one round trip; :meth:`read_later` and
    :meth:`wait_until` then answer :class:`Reading` objects filled in when it is sent. On
    any other bus ``deferred()`` does nothing and every access happens when it is made.
    """

    def __init__(self, regmap: RegisterMap, bus):
        self.regmap = regmap
        self.bus = bus

    def offset(self, name: str) -> int:
        return self.regmap[name].offset

    def read(self, name: str) -> int:
        return int(self.bus.read(self.offset(name))) & 0xFFFFFFFF

    def read_fields(self, name: str) -> dict[str, int]:
        return self.decode(name, self.read(name))

    def decode(self, name: str, value: int) -> dict[str, int]:
        """The fields of ``value`` as register ``name`` lays them out."""
        return {f.name: (value >> f.lsb) & ((1 << f.width) - 1)
                for f in self.regmap[name].fields}

    def read_later(self, name: str) -> Reading:
        """Read ``name``: at once on a plain bus, queued in the batch on a deferring bus."""
        later = getattr(self.bus, "read_later", None)
        if later is None:
            return Reading(self.read(name))
        return later(self.offset(name))

    def deferred(self):
        """A context in which a batching bus queues the accesses and sends them as one
        batch (on leaving it, or with the first plain :meth:`read`); elsewhere a no-op."""
        deferred = getattr(self.bus, "deferred", None)
        return deferred() if deferred is not None else contextlib.nullcontext(self)

    def field_mask(self, name: str, **fields: int) -> tuple[int, int]:
        """(mask, value) selecting the named fields at the given values."""
        known = {f.name: f for f in self.regmap[name].fields}
        mask = value = 0
        for field_name, field_value in fields.items():
            f = known.get(field_name)
            if f is None:
                raise KeyError(f"register {name} has no field {field_name!r}")
            field_value = _register_int(f"{name}.{field_name}", field_value)
            if not 0 <= field_value < (1 << f.width):
                raise ValueError(f"{name}.{field_name} = {field_value} does not fit "
                                 f"{f.width} bits")
            mask |= f.mask
            value |= field_value << f.lsb
        return mask, value

    def wait_until(self, name: str, mask: int | None = None, value: int | None = None, *,
                   limit: int = 10_000, **fields: int) -> Reading:
        """Wait until ``(register & mask) == value`` (or the named fields hold the given
        values); the final register value. A bus with ``poll(offset, mask, value, limit)``
        waits in its own time (the co-simulation: at most ``limit`` clock cycles, queued in
        the batch under :meth:`deferred`); on any other bus the register is read at most
        ``limit`` times, then :class:`RegisterTimeout`."""
        if fields:
            if mask is not None or value is not None:
                raise TypeError("give either mask and value or fields, not both")
            mask, value = self.field_mask(name, **fields)
        elif mask is None or value is None:
            raise TypeError("wait_until needs mask and value, or fields")
        if not (0 <= mask <= 0xFFFFFFFF and 0 <= value <= 0xFFFFFFFF) or value & ~mask:
            raise ValueError(f"{name}: value {value:#x} outside mask {mask:#x}")
        limit = int(limit)
        if limit < 1:
            raise ValueError(f"{name}: wait limit {limit} (at least 1)")
        offset = self.offset(name)
        poll = getattr(self.bus, "poll", None)
        if poll is not None:
            got = poll(offset, mask, value, limit)
            return got if isinstance(got, Reading) else Reading(int(got))
        for _ in range(limit):
            got = self.read(name)
            if got & mask == value:
                return Reading(got)
        raise RegisterTimeout(f"{name} & {mask:#x} != {value:#x} after {limit} reads "
                              f"(last {got:#x})")

    def write(self, name: str, value: int | None = None, **fields: int) -> None:
        """Write a whole value, or named fields (the others from their reset values)."""
        reg = self.regmap[name]
        if value is None:
            mask, field_bits = self.field_mask(name, **fields)
            value = (reg.reset_value & reg.sw_write_mask & ~mask) | field_bits
        elif fields:
            raise TypeError("give either a value or fields, not both")
        else:
            value = _register_int(name, value)
        if not 0 <= value <= 0xFFFFFFFF:
            raise ValueError(f"{name}: {value} is not a 32-bit value")
        self.bus.write(reg.offset, value)

    def read_f32(self, name: str) -> float:
        return bits_f32(self.read(name))

    def write_f32(self, name: str, value: float) -> None:
        """Write ``value`` rounded to float32. NaN, inf and finite values beyond float32's
        range (which would round to inf) are refused: a register the PL computes with must
        not start from a non-finite word."""
        if not isinstance(value, numbers.Real):
            raise ValueError(f"{name}: expected a number, got {value!r}")
        v = float(value)
        if not math.isfinite(v):
            raise ValueError(f"{name}: refusing to write the non-finite value {v} into a "
                             "float32 register")
        if abs(v) > F32_MAX:
            raise ValueError(f"{name}: {v:g} is beyond float32's range (+-{F32_MAX:.7g})")
        self.write(name, f32_bits(v))
