"""Bosch BMP390 barometric pressure sensor: registers, calibration NVM, compensation formulas
(float64 and a float32 bit-true program), raw-value encoder, and a bit-level SPI slave model.

Source: Bosch BMP390 data sheet (BST-BMP390-DS002, as remembered; it could not be re-read in
the development environment, figures marked *(check)* in docs/sensors.md): register map
(section 5), NVM calibration coefficients and their float conversion, and the floating-point
compensation formulas (section 8.4/8.5 "Calculating pressure and temperature"). SPI: modes 0 and
3 (this model implements mode 3, the mode navgate's master uses), 8-bit words, bit 7 of the
first byte = read; a read returns one dummy byte before the data; addresses auto-increment.

The compensation in float32 (:data:`FP32_PROGRAM`, :func:`compensate_fp32`) is a straight-line
program of float32 operations that the ``baro_compensation`` gateware runs on the shared fp32
cores, operation for operation; :func:`compensate_fp32_bound` carries a rigorous first-order
error bound alongside, used by the tests to bound float32 against float64 over the part's whole
range (300-1250 hPa, -40..85 degC).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .spi import SpiSlave, SpiTiming

CHIP_ID = 0x60
REG = {
    "CHIP_ID": 0x00, "REV_ID": 0x01, "ERR_REG": 0x02, "STATUS": 0x03, "DATA_0": 0x04,
    "DATA_3": 0x07, "SENSORTIME_0": 0x0C, "EVENT": 0x10, "INT_STATUS": 0x11,
    "INT_CTRL": 0x19, "IF_CONF": 0x1A, "PWR_CTRL": 0x1B, "OSR": 0x1C, "ODR": 0x1D,
    "CONFIG": 0x1F, "NVM_PAR_T1": 0x31, "CMD": 0x7E,
}
STATUS_CMD_RDY, STATUS_DRDY_PRESS, STATUS_DRDY_TEMP = 0x10, 0x20, 0x40
#: PWR_CTRL: press_en (bit 0), temp_en (bit 1), mode bits 5:4 (0b11 = normal)
PWR_CTRL_NORMAL = 0x33
NVM_ADDR, NVM_LEN = 0x31, 21
#: (name, byte offset in the NVM block, signed, bytes)
NVM_FIELDS = (
    ("T1", 0, False, 2), ("T2", 2, False, 2), ("T3", 4, True, 1), ("P1", 5, True, 2),
    ("P2", 7, True, 2), ("P3", 9, True, 1), ("P4", 10, True, 1), ("P5", 11, False, 2),
    ("P6", 13, False, 2), ("P7", 15, True, 1), ("P8", 16, True, 1), ("P9", 17, True, 2),
    ("P10", 19, True, 1), ("P11", 20, True, 1),
)
#: float coefficient = (NVM integer - OFFSET) * 2**SCALE_EXP  (data sheet section 8.4)
OFFSET = {"P1": 2**14, "P2": 2**14}
SCALE_EXP = {"T1": 8, "T2": -30, "T3": -48, "P1": -20, "P2": -29, "P3": -32, "P4": -37,
             "P5": 3, "P6": -6, "P7": -8, "P8": -15, "P9": -48, "P10": -48, "P11": -65}
PRESSURE_RANGE_PA = (30000.0, 125000.0)
TEMPERATURE_RANGE_C = (-40.0, 85.0)

#: SPI timing limits (data sheet "SPI timing" table, check): f_SPI <= 10 MHz, SCK high/low
#: >= 20 ns, SDI setup/hold >= 20 ns, CSB setup 20 ns, CSB hold 40 ns.
SCLK_MAX_HZ = 10e6
SPI_TIMING = SpiTiming(f_sclk_max=SCLK_MAX_HZ, t_sclk_high_min=20e-9, t_sclk_low_min=20e-9,
                       t_cs_setup_min=20e-9, t_cs_hold_min=40e-9, t_cs_high_min=0.0,
                       t_mosi_setup_min=20e-9, t_mosi_hold_min=20e-9)

#: A plausible NVM image (the coefficients of a part; navgate's default, not from a real unit)
DEFAULT_NVM = {"T1": 27504, "T2": 19001, "T3": -7, "P1": 1024, "P2": -2911, "P3": 23,
               "P4": 0, "P5": 26135, "P6": 29372, "P7": 3, "P8": -10, "P9": 4936, "P10": 7,
               "P11": -60}


def nvm_bytes(par: dict[str, int] = DEFAULT_NVM) -> bytes:
    """The 21-byte NVM block (registers 0x31..0x45, little-endian) of integer coefficients."""
    out = bytearray(NVM_LEN)
    for name, off, signed, size in NVM_FIELDS:
        out[off:off + size] = int(par[name]).to_bytes(size, "little", signed=signed)
    return bytes(out)


def parse_nvm(block: bytes) -> dict[str, int]:
    if len(block) != NVM_LEN:
        raise ValueError(f"BMP390 NVM block has {NVM_LEN} bytes, got {len(block)}")
    return {name: int.from_bytes(block[off:off + size], "little", signed=signed)
            for name, off, signed, size in NVM_FIELDS}


def coefficients(par: dict[str, int]) -> dict[str, float]:
    """Float coefficients (data sheet section 8.4): exact powers-of-two scalings."""
    return {k: (par[k] - OFFSET.get(k, 0)) * 2.0 ** SCALE_EXP[k] for k in SCALE_EXP}


def compensate(uncomp_press, uncomp_temp, par: dict[str, int] = DEFAULT_NVM):
    """float64 data-sheet formulas: raw 24-bit ADC values -> (pressure Pa, temperature degC)."""
    c = coefficients(par)
    up = np.asarray(uncomp_press, float)
    ut = np.asarray(uncomp_temp, float)
    pd1 = ut - c["T1"]
    t = pd1 * c["T2"] + pd1 * pd1 * c["T3"]
    out1 = c["P5"] + c["P6"] * t + c["P7"] * t * t + c["P8"] * t * t * t
    out2 = up * (c["P1"] + c["P2"] * t + c["P3"] * t * t + c["P4"] * t * t * t)
    pd4 = up * up * (c["P9"] + c["P10"] * t) + up * up * up * c["P11"]
    return out1 + out2 + pd4, t


def encode(pressure_pa, temp_c, par: dict[str, int] = DEFAULT_NVM):
    """Inverse of :func:`compensate`: raw (uncomp_press, uncomp_temp) ADC integers (int64) that
    the part would report for ``pressure_pa`` and ``temp_c`` (rounded to the nearest count;
    Newton iterations on the float64 formulas). Values outside 24 bits raise ValueError."""
    c = coefficients(par)
    p = np.asarray(pressure_pa, float)
    t = np.asarray(temp_c, float)
    # temperature: t = c2 d + c3 d^2, d = ut - T1
    d = t / c["T2"]
    for _ in range(6):
        f = c["T2"] * d + c["T3"] * d * d - t
        d = d - f / (c["T2"] + 2 * c["T3"] * d)
    ut = np.rint(d + c["T1"])
    _, t_q = compensate(0.0, ut, par)
    up = (p - c["P5"]) / c["P1"]
    for _ in range(20):
        f, _ = compensate(up, ut, par)
        h = 1.0
        df = (compensate(up + h, ut, par)[0] - compensate(up - h, ut, par)[0]) / (2 * h)
        up = up - (f - p) / df
    up = np.rint(up)
    for name, v in (("pressure", up), ("temperature", ut)):
        if np.any((v < 0) | (v >= 2**24)):
            raise ValueError(f"BMP390 {name} outside the 24-bit ADC range for these inputs")
    return up.astype(np.int64), ut.astype(np.int64)


def data_bytes(uncomp_press, uncomp_temp) -> bytes:
    """DATA_0..DATA_5 (0x04..0x09): pressure XLSB, LSB, MSB, temperature XLSB, LSB, MSB."""
    return int(uncomp_press).to_bytes(3, "little") + int(uncomp_temp).to_bytes(3, "little")


# ---- the float32 program (bit-true face of baro_compensation) -----------------------------
# Registers: inputs "up", "ut" (raw ints), NVM integers "n_T1".."n_P11"; constants "k_*".
# Ops: ("i2f", dst, src) int32 -> float32; ("mul"|"add"|"sub", dst, a, b).


def _program():
    prog = []
    consts = {}
    for name in SCALE_EXP:
        prog.append(("i2f", f"c_{name}", f"n_{name}"))
        if name in OFFSET:
            consts[f"k_off_{name}"] = float(OFFSET[name])
            prog.append(("sub", f"c_{name}", f"c_{name}", f"k_off_{name}"))
        consts[f"k_s_{name}"] = 2.0 ** SCALE_EXP[name]
        prog.append(("mul", f"c_{name}", f"c_{name}", f"k_s_{name}"))
    prog += [
        ("i2f", "fu", "ut"), ("i2f", "fp", "up"),
        ("sub", "pd1", "fu", "c_T1"),
        ("mul", "pd2", "pd1", "c_T2"),
        ("mul", "tmp", "pd1", "pd1"),
        ("mul", "tmp", "tmp", "c_T3"),
        ("add", "t", "pd2", "tmp"),  # t_lin (degC)
        ("mul", "t2", "t", "t"),
        ("mul", "t3", "t2", "t"),
        ("mul", "a1", "c_P6", "t"), ("mul", "a2", "c_P7", "t2"), ("mul", "a3", "c_P8", "t3"),
        ("add", "out1", "c_P5", "a1"), ("add", "out1", "out1", "a2"),
        ("add", "out1", "out1", "a3"),
        ("mul", "a1", "c_P2", "t"), ("mul", "a2", "c_P3", "t2"), ("mul", "a3", "c_P4", "t3"),
        ("add", "s", "c_P1", "a1"), ("add", "s", "s", "a2"), ("add", "s", "s", "a3"),
        ("mul", "out2", "fp", "s"),
        ("mul", "p2", "fp", "fp"),
        ("mul", "a1", "c_P10", "t"), ("add", "a1", "c_P9", "a1"),
        ("mul", "a2", "p2", "a1"),
        ("mul", "p3", "p2", "fp"), ("mul", "a3", "p3", "c_P11"),
        ("add", "pd4", "a2", "a3"),
        ("add", "p", "out1", "out2"), ("add", "p", "p", "pd4"),
    ]
    return tuple(prog), consts


FP32_PROGRAM, FP32_CONSTANTS = _program()
FP32_INPUTS = ("up", "ut") + tuple(f"n_{name}" for name in SCALE_EXP)
FP32_OUTPUTS = ("p", "t")


def run_fp32_program(program, consts, inputs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Interpret a straight-line float32 program (bit-true, :mod:`navgate.numerics.fp32`).

    ``inputs`` maps integer register names to int arrays; constants are float64 values rounded
    to float32. Returns every register (uint32 bit patterns for the float registers)."""
    from navgate.numerics.fp32 import f32_to_bits, fp32_add, fp32_from_int, fp32_mul, fp32_sub

    regs: dict[str, np.ndarray] = {k: np.asarray(v, np.int64) for k, v in inputs.items()}
    for k, v in consts.items():
        regs[k] = f32_to_bits(np.float64(v))
    for op, dst, *src in program:
        if op == "i2f":
            regs[dst] = fp32_from_int(regs[src[0]], 32)
        else:
            f = {"add": fp32_add, "sub": fp32_sub, "mul": fp32_mul}[op]
            regs[dst] = f(regs[src[0]], regs[src[1]])
    return regs


def compensate_fp32(uncomp_press, uncomp_temp, par: dict[str, int] = DEFAULT_NVM):
    """Bit-true float32 compensation: (pressure, temperature) as uint32 float32 patterns."""
    up = np.asarray(uncomp_press, np.int64)
    inputs = {"up": up, "ut": np.asarray(uncomp_temp, np.int64)}
    inputs.update({f"n_{k}": np.full(up.shape, par[k], np.int64) for k in SCALE_EXP})
    regs = run_fp32_program(FP32_PROGRAM, FP32_CONSTANTS, inputs)
    return regs["p"], regs["t"]


def compensate_fp32_bound(uncomp_press, uncomp_temp, par: dict[str, int] = DEFAULT_NVM):
    """float64 values of the program and a rigorous first-order bound on |float32 - exact|.

    Each float32 operation z = x op y carries e_z = (propagated input error) + u |z| with
    u = 2**-24 (round to nearest); the propagated error is e_x + e_y for add/sub and
    |x| e_y + |y| e_x + e_x e_y for mul. Conversions of integers below 2**24 and the power-of-two
    scalings are exact (e = 0). Returns (p, t, bound_p, bound_t), float64 arrays.
    """
    u = 2.0 ** -24
    up = np.asarray(uncomp_press, float)
    val: dict[str, np.ndarray] = {"up": up, "ut": np.asarray(uncomp_temp, float)}
    val.update({f"n_{k}": np.full(up.shape, float(par[k])) for k in SCALE_EXP})
    val.update({k: np.full(up.shape, v) for k, v in FP32_CONSTANTS.items()})
    err = {k: np.zeros(up.shape) for k in val}
    for op, dst, *src in FP32_PROGRAM:
        if op == "i2f":
            val[dst], err[dst] = val[src[0]], np.zeros(up.shape)
            continue
        x, y, ex, ey = val[src[0]], val[src[1]], err[src[0]], err[src[1]]
        if op == "mul":
            z = x * y
            exact_scale = dst.startswith("c_")  # power-of-two scaling of an exact integer
            e = np.abs(x) * ey + np.abs(y) * ex + ex * ey + (0 if exact_scale else u * np.abs(z))
        else:
            z = x + y if op == "add" else x - y
            exact_off = dst.startswith("c_")  # small integer minus 2**14: exact
            e = ex + ey + (0 if exact_off else u * np.abs(z))
        val[dst], err[dst] = z, e
    return val["p"], val["t"], err["p"], err["t"]


# ---- bit-level device model --------------------------------------------------------------

FAULTS = ("stuck_low", "stuck_high", "missing")


@dataclass
class BaroStream:
    """What the model serves: raw ADC values per sample, the part's NVM, per-sample faults."""

    uncomp_press: np.ndarray
    uncomp_temp: np.ndarray
    par: dict[str, int] = field(default_factory=lambda: dict(DEFAULT_NVM))
    faults: dict[int, str] = field(default_factory=dict)

    def __post_init__(self):
        for k, f in self.faults.items():
            if f not in FAULTS:
                raise ValueError(f"unknown BMP390 fault {f!r} at sample {k}")

    @classmethod
    def from_physical(cls, pressure_pa, temp_c, par=None, faults=None):
        par = dict(DEFAULT_NVM if par is None else par)
        up, ut = encode(pressure_pa, temp_c, par)
        return cls(up, ut, par, dict(faults or {}))


class Bmp390Model(SpiSlave):
    """BMP390 SPI slave (mode 3, 8-bit) serving :class:`BaroStream` samples.

    A read transfer that covers all six data registers (0x04..0x09), and does not reach into the
    NVM (a start-up read), delivers the current sample and advances the stream when CS_N rises;
    STATUS reports drdy for both sensors while the part is in normal mode with both enabled
    (PWR_CTRL = 0x33), the data registers read the reset
    value 0x800000 otherwise. Faults per sample (applied to the transfer that reads it):
    ``stuck_low``/``stuck_high``/``missing`` (MISO held for the whole transfer). A fault at
    index -1 applies to the first start-up read (one reaching the NVM at 0x31..0x45).
    """

    WORD_BITS = 8
    timing = SPI_TIMING

    def __init__(self, stream: BaroStream, timing: SpiTiming | None = None):
        super().__init__(timing)
        self.stream = stream
        self.sample = 0
        self.served: list[int] = []
        self.regs = bytearray(128)
        self.regs[REG["CHIP_ID"]] = CHIP_ID
        self.regs[REG["REV_ID"]] = 0x01
        self.regs[NVM_ADDR:NVM_ADDR + NVM_LEN] = nvm_bytes(stream.par)
        self.nvm_reads = 0
        self.nvm_attempts = 0
        self.writes: list[tuple[int, int]] = []
        self._load_sample()

    def _normal(self):
        return self.regs[REG["PWR_CTRL"]] & 0x33 == PWR_CTRL_NORMAL

    def _load_sample(self):
        k = min(self.sample, len(self.stream.uncomp_press) - 1)
        if self._normal():
            self.regs[4:10] = data_bytes(self.stream.uncomp_press[k], self.stream.uncomp_temp[k])
            self.regs[REG["STATUS"]] = STATUS_CMD_RDY | STATUS_DRDY_PRESS | STATUS_DRDY_TEMP
        else:
            self.regs[4:10] = bytes([0, 0, 0x80, 0, 0, 0x80])
            self.regs[REG["STATUS"]] = STATUS_CMD_RDY

    def begin(self):
        self._read = None
        self._addr = None
        self._waddr = None
        self._first = None

    def next_word(self, index):
        if index == 0 or self._read is None:
            return 0xFF
        if index == 1:
            return 0x00  # the dummy byte of an SPI read
        addr = (self._addr + index - 2) & 0x7F
        return self.regs[addr]

    def word(self, index, value):
        if index == 0:
            self._first = value & 0x7F
            if value & 0x80:
                self._read = True
                self._addr = value & 0x7F
                if self.nvm_reads == 0:
                    # a start-up read (no NVM read completed yet): fault -1 hits the first one
                    fault = self.stream.faults.get(-1) if self.nvm_attempts == 0 else None
                    self.nvm_attempts += 1
                else:
                    fault = self.stream.faults.get(self.sample)
                self._stuck = {"stuck_low": 0, "stuck_high": 1, "missing": 1}.get(fault)
            else:
                self._waddr = value & 0x7F
            return
        if self._read is None:  # write: address, data, address, data ...
            if self._waddr is None:
                self._waddr = value & 0x7F
            else:
                self._write(self._waddr, value)
                self._waddr = None

    def _covers_data(self, nbytes):
        return self._addr is not None and self._addr <= 4 and self._addr + nbytes - 1 >= 9

    def _write(self, addr, value):
        self.writes.append((addr, value))
        if addr in (REG["PWR_CTRL"], REG["OSR"], REG["ODR"], REG["CONFIG"], REG["INT_CTRL"],
                    REG["IF_CONF"]):
            self.regs[addr] = value
            self._load_sample()
        elif addr == REG["CMD"] and value == 0xB6:
            self.regs[REG["PWR_CTRL"]] = 0
            self._load_sample()

    def end(self, bits):
        if self._read:
            nbytes = bits // 8 - 2
            if self._addr <= NVM_ADDR and self._addr + nbytes >= NVM_ADDR + NVM_LEN:
                self.nvm_reads += 1
            reaches_nvm = self._addr + nbytes - 1 >= NVM_ADDR
            if self._covers_data(nbytes) and self._normal() and not reaches_nvm:
                self.served.append(self.sample)
                self.sample += 1
                self._load_sample()
        self._stuck = None
