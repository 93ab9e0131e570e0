"""Reading IMU logs (CSV) for ``navgate ahrs``.

Two header styles are recognised (case-insensitive, surrounding spaces ignored):

* plain: ``t`` (s), ``gx gy gz`` (rad/s), ``ax ay az`` (m/s^2), optional ``mx my mz`` (any
  consistent unit);
* x-io style (x-io Technologies' NGIMU / x-IMU3 / Fusion CSV exports): ``Time (s)``,
  ``Gyroscope X (deg/s)``, ``Accelerometer X (g)``, ``Magnetometer X (uT)`` and so on. The
  unit in parentheses is converted to SI: time s/ms/us; gyro deg/s, rad/s, dps; accel g,
  m/s^2; magnetometer uT, nT, mT, G/gauss, a.u. (the filters only use its direction).

Bad input never gives a traceback: a missing column, an empty file, an unknown unit, a
binary file, timestamps not in seconds or time that does not strictly increase raise
:class:`LogError` with the row number; rows with a missing or non-numeric value in a used
column are skipped and counted (``ImuLog.skipped_rows``), finite readings beyond any sensor's
range are dropped and counted (``implausible_rows``), a slower or missing magnetometer is
held (``mag_held_rows``). Logs are read in blocks with bounded memory
(:class:`ImuLogReader`). Standard gravity 9.80665 m/s^2 converts g.
"""

from __future__ import annotations

import math
import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

G0 = 9.80665


class LogError(ValueError):
    """An IMU log that cannot be used (message names the file, column or row)."""


@dataclass
class ImuLog:
    t: np.ndarray  #: (N,) s
    gyro: np.ndarray  #: (N, 3) rad/s
    acc: np.ndarray  #: (N, 3) m/s^2
    mag: np.ndarray | None  #: (N, 3) in the log's unit converted to uT where known
    style: str  #: "plain" or "x-io"
    skipped_rows: int
    columns: dict  #: quantity -> header used
    implausible_rows: int = 0  #: finite readings beyond any sensor's range (dropped)
    mag_held_rows: int = 0  #: rows whose magnetometer sample was missing (previous one held)

    def __len__(self) -> int:
        return len(self.t)


_TIME_UNITS = {"s": 1.0, "sec": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6}
_GYRO_UNITS = {"deg/s": math.pi / 180, "dps": math.pi / 180, "°/s": math.pi / 180,
               "rad/s": 1.0}
_ACC_UNITS = {"g": G0, "m/s^2": 1.0, "m/s2": 1.0, "m/s²": 1.0}
_MAG_UNITS = {"ut": 1.0, "µt": 1.0, "nt": 1e-3, "mt": 1e3, "g": 100.0, "gauss": 100.0,
              "a.u.": 1.0, "au": 1.0}

_XIO = re.compile(r"^(time|gyroscope|accelerometer|magnetometer)\s*([xyz])?\s*\((.+)\)$")


def _norm(h: str) -> str:
    return " ".join(h.strip().strip('"').split()).lower()


def _map_columns(header: list[str]):
    """Return ({quantity: (column index, scale)}, style, {quantity: header})."""
    names = [_norm(h) for h in header]
    plain = {"t": "t", "gx": "gx", "gy": "gy", "gz": "gz", "ax": "ax", "ay": "ay",
             "az": "az", "mx": "mx", "my": "my", "mz": "mz"}
    found, used = {}, {}
    if "t" in names or "gx" in names:
        for key in plain:
            if key in names:
                found[key] = (names.index(key), 1.0)
                used[key] = header[names.index(key)].strip()
        return found, "plain", used
    for i, n in enumerate(names):
        m = _XIO.match(n)
        if not m:
            continue
        kind, axis, unit = m.group(1), m.group(2), m.group(3).strip()
        if kind == "time":
            if unit not in _TIME_UNITS:
                raise LogError(f"column {header[i].strip()!r}: unknown time unit {unit!r}")
            found["t"] = (i, _TIME_UNITS[unit])
            used["t"] = header[i].strip()
            continue
        if axis is None:
            continue
        table = {"gyroscope": _GYRO_UNITS, "accelerometer": _ACC_UNITS,
                 "magnetometer": _MAG_UNITS}[kind]
        key_unit = unit if kind != "magnetometer" else unit.lower()
        if key_unit not in table:
            raise LogError(f"column {header[i].strip()!r}: unknown {kind} unit {unit!r} "
                           f"(known: {', '.join(sorted(table))})")
        key = {"gyroscope": "g", "accelerometer": "a", "magnetometer": "m"}[kind] + axis
        found[key] = (i, table[key_unit])
        used[key] = header[i].strip()
    return found, "x-io", used


#: screening limits for finite but impossible readings (far beyond any IMU's full scale: the
#: ADIS16500 reads +-2000 deg/s and +-392 m/s^2; high-g parts reach +-200 g = 1961 m/s^2;
#: Earth's field is 25-65 uT and logged magnetometers saturate near 5000 uT)
GYRO_LIMIT_RADPS = 100.0  #: 5730 deg/s
ACC_LIMIT_MPS2 = 2000.0  #: 204 g
MAG_LIMIT = 1.0e5  #: in the log's converted unit (uT where known)
#: gyro magnitudes above this under a rad/s header (2000 deg/s, a MEMS gyro's full scale in
#: rad/s would be 35) in more than 1 % of the first block's rows mean the column is deg/s
DEG_AS_RAD_SUSPECT = 35.0
CHUNK_ROWS = 100_000
MAX_LINE_BYTES = 1 << 16
BLOCK_BYTES = 1 << 22


def nominal_period(t) -> float:
    """Median sample period of the first (up to) 1000 steps: the reference for gap and
    unit checks (the same whether a log is read whole or in chunks)."""
    t = np.asarray(t[:1001], dtype=np.float64)
    return float(np.median(np.diff(t))) if t.size > 1 else math.nan


def _time_unit_error(path, dt: float) -> str | None:
    """A message when the median step says the timestamps are not seconds."""
    if not dt >= 0.5:
        return None
    for unit, factor in (("microseconds", 1e-6), ("milliseconds", 1e-3)):
        rate = 1.0 / (dt * factor)
        if 1.0 <= rate <= 100_000.0:
            return (f"{path}: the median time step is {dt:g} s ({1 / dt:.3g} Hz), not an IMU "
                    f"rate; the timestamps look like {unit} ({rate:.4g} Hz): convert them to "
                    "seconds or use an x-io 'Time (ms)'/'Time (us)' header")
    return (f"{path}: the median time step is {dt:g} s ({1 / dt:.3g} Hz), not an IMU rate; "
            "timestamps must be in seconds")


class ImuLogReader:
    """Stream an IMU log in blocks of ``chunk_rows`` rows with bounded memory.

    Iterating yields :class:`ImuLog` blocks (SI units, the same checks and counts as
    :func:`read_imu_csv`, which concatenates them). Files are read in binary blocks of
    :data:`BLOCK_BYTES`: a NUL byte (a binary file, ``/dev/zero``) or a line longer than
    :data:`MAX_LINE_BYTES` is a :class:`LogError` at once, never a hang. ``bytes_read`` and
    ``size`` drive a progress bar.

    Screening, per row (counted, never silent): a missing or non-numeric value in t, gyro or
    accel skips the row (``skipped_rows``); a finite gyro/accel value beyond
    :data:`GYRO_LIMIT_RADPS` / :data:`ACC_LIMIT_MPS2` (after unit conversion) drops the row
    (``implausible_rows``); a missing or implausible magnetometer value keeps the row and
    holds the previous magnetometer sample (``mag_held_rows``; before the first one, a zero
    vector, which the filters read as "no magnetometer correction"). ``use_mag=False``
    ignores the magnetometer columns entirely. ``gyro_unit`` ("rad/s" or "deg/s") overrides
    a plain header's rad/s; a plain log whose gyro plainly holds deg/s is a LogError naming
    the unit. Timestamps whose median step is 0.5 s or more are a LogError naming the likely
    unit (ms, us).
    """

    def __init__(self, path: str | Path, *, use_mag: bool = True, gyro_unit: str | None = None,
                 chunk_rows: int | None = None, fileobj=None):
        self.path = Path(path)
        self.chunk_rows = int(CHUNK_ROWS if chunk_rows is None else chunk_rows)
        self.skipped_rows = 0
        self.implausible_rows = 0
        self.mag_held_rows = 0
        self.rows = 0
        self.bytes_read = 0
        self.nominal_dt = math.nan
        self._last_t = -math.inf
        self._last_mag = None
        self._line = 0  # 1-based number of the last line consumed
        path = self.path
        if path.is_dir():
            raise LogError(f"{path}: is a directory, not a CSV file")
        try:
            # ``fileobj``: an already open binary stream for ``path`` (a FIFO the command line
            # opened while waiting for its writer)
            self._fh = fileobj if fileobj is not None else open(path, "rb")  # noqa: SIM115
        except FileNotFoundError:
            raise LogError(f"{path}: no such file") from None
        except OSError as error:
            raise LogError(f"{path}: cannot read ({error.strerror})") from None
        try:
            self.size = os.fstat(self._fh.fileno()).st_size
        except OSError:  # pragma: no cover
            self.size = 0
        self._pending = b""
        self._lines: list[str] = []
        self._eof = False
        self._first = True
        header_line = None
        while header_line is None:
            line = self._next_line()
            if line is None:
                raise LogError(f"{path}: empty file")
            if line.strip():
                header_line = line
        self.delim = "," if "," in header_line else None
        header = header_line.split(self.delim) if self.delim else header_line.split()
        cols, self.style, used = _map_columns(header)
        if gyro_unit is not None:
            if gyro_unit not in _GYRO_UNITS:
                raise LogError(f"unknown gyro unit {gyro_unit!r} (known: rad/s, deg/s)")
            for k in ("gx", "gy", "gz"):
                if k in cols:
                    cols[k] = (cols[k][0], _GYRO_UNITS[gyro_unit])
        self._gyro_unit_given = gyro_unit is not None or self.style == "x-io"
        required = ["t", "gx", "gy", "gz", "ax", "ay", "az"]
        missing = [k for k in required if k not in cols]
        if missing:
            raise LogError(f"{path}: missing column(s) {', '.join(missing)} (need t, gx gy gz, "
                           "ax ay az or x-io 'Time (s)', 'Gyroscope X (deg/s)', "
                           "'Accelerometer X (g)' headers)")
        mag_keys = ["mx", "my", "mz"]
        has_mag = [k in cols for k in mag_keys]
        if use_mag and any(has_mag) and not all(has_mag):
            raise LogError(f"{path}: magnetometer columns incomplete (need all of mx, my, mz)")
        self.has_mag = use_mag and all(has_mag)
        self.keys = required + (mag_keys if self.has_mag else [])
        self.idx = [cols[k][0] for k in self.keys]
        self.scale = np.array([cols[k][1] for k in self.keys])
        self.width = len(header)
        self.columns = {k: v for k, v in used.items() if k in self.keys}

    # -- bytes to lines ---------------------------------------------------------------------
    def _fill(self) -> None:
        """Read one block; complete lines go to ``_lines``, the tail stays in ``_pending``."""
        block = self._fh.read(BLOCK_BYTES)
        if not block:
            self._eof = True
            return
        self.bytes_read += len(block)
        if b"\0" in block:
            raise LogError(f"{self.path}: binary data (NUL bytes) near byte {self.bytes_read}; "
                           "not a CSV text file")
        if self._first:
            self._first = False
            if block.startswith(b"\xef\xbb\xbf"):
                block = block[3:]
        pending = self._pending + block
        cut = pending.rfind(b"\n")
        if cut >= 0:
            text = pending[:cut].decode("utf-8", errors="replace")
            lines = text.split("\n")
            if max(map(len, lines)) > MAX_LINE_BYTES:
                raise LogError(f"{self.path}: a line near line {self._line + 1} is longer than "
                               f"{MAX_LINE_BYTES} bytes; not a CSV log")
            self._lines.extend(x[:-1] if x.endswith("\r") else x for x in lines)
            pending = pending[cut + 1:]
        if len(pending) > MAX_LINE_BYTES:
            raise LogError(f"{self.path}: line {self._line + len(self._lines) + 1} is longer "
                           f"than {MAX_LINE_BYTES} bytes; not a CSV log")
        self._pending = pending

    def _next_lines(self, n: int) -> list[str]:
        """Up to n lines (the last line of the file may lack its newline)."""
        out: list[str] = []
        while len(out) < n:
            if self._lines:
                k = n - len(out)
                out += self._lines[:k]
                del self._lines[:k]
                continue
            if self._eof:
                if self._pending:
                    tail = self._pending.decode("utf-8", errors="replace")
                    out.append(tail[:-1] if tail.endswith("\r") else tail)
                    self._pending = b""
                break
            self._fill()
        self._line += len(out)
        return out

    def _next_line(self) -> str | None:
        lines = self._next_lines(1)
        return lines[0] if lines else None

    # -- lines to numbers -------------------------------------------------------------------
    def _parse(self, body: list[str]) -> np.ndarray:
        data = None
        if body and all(line.strip() for line in body):
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    data = np.loadtxt(body, delimiter=self.delim, usecols=self.idx,
                                      comments=None, ndmin=2, dtype=np.float64)
                if data.shape != (len(body), len(self.keys)):
                    data = None
            except (ValueError, IndexError):
                data = None
        if data is not None:
            return data
        data = np.full((len(body), len(self.keys)), np.nan)
        delim, width, idx = self.delim, self.width, self.idx
        for r, line in enumerate(body):
            if not line.strip():
                continue
            cells = line.split(delim) if delim else line.split()
            if len(cells) < width:
                cells = cells + [""] * (width - len(cells))
            for j, c in enumerate(idx):
                try:
                    data[r, j] = float(cells[c])
                except (ValueError, IndexError):
                    pass
        return data

    def __iter__(self):
        try:
            while True:
                first_line = self._line + 1
                body = self._next_lines(self.chunk_rows)
                if not body:
                    return
                block = self._block(self._parse(body), first_line)
                if block is not None:
                    yield block
        finally:
            self._fh.close()

    def _block(self, data: np.ndarray, first_line: int) -> ImuLog | None:
        imu = data[:, :7]
        good = np.all(np.isfinite(imu), axis=1)
        self.skipped_rows += int(np.count_nonzero(~good))
        lines = np.flatnonzero(good) + first_line
        data = data[good] * self.scale
        if self.rows == 0 and data.shape[0] > 1 and not self._gyro_unit_given:
            fast = np.max(np.abs(data[:, 1:4]), axis=1) > DEG_AS_RAD_SUSPECT
            if np.count_nonzero(fast) > 0.01 * data.shape[0]:
                peak = float(np.max(np.abs(data[:, 1:4])))
                raise LogError(f"{self.path}: gyro values up to {peak:.4g} under a rad/s header "
                               f"({np.count_nonzero(fast)} rows above {DEG_AS_RAD_SUSPECT:g}) "
                               "look like deg/s; pass --gyro-unit deg/s (or rad/s if they "
                               "really are)")
        ok = ((np.max(np.abs(data[:, 1:4]), axis=1) <= GYRO_LIMIT_RADPS)
              & (np.max(np.abs(data[:, 4:7]), axis=1) <= ACC_LIMIT_MPS2))
        self.implausible_rows += int(np.count_nonzero(~ok))
        data, lines = data[ok], lines[ok]
        if data.shape[0] == 0:
            return None
        t = data[:, 0]
        steps = np.diff(np.concatenate([[self._last_t], t]))
        bad = np.flatnonzero(steps <= 0)
        if bad.size:
            k = int(bad[0])
            prev = self._last_t if k == 0 else t[k - 1]
            raise LogError(f"{self.path}: time does not increase at line {int(lines[k])} "
                           f"({prev:.6g} s then {t[k]:.6g} s)")
        if self.rows == 0:
            self.nominal_dt = nominal_period(t)
            message = _time_unit_error(self.path, self.nominal_dt)
            if message:
                raise LogError(message)
        self._last_t = float(t[-1])
        self.rows += data.shape[0]
        mag = None
        if self.has_mag:
            mag = np.array(data[:, 7:10])
            have = np.all(np.isfinite(mag), axis=1) & (np.max(np.abs(np.nan_to_num(mag)),
                                                               axis=1) <= MAG_LIMIT)
            self.mag_held_rows += int(np.count_nonzero(~have))
            if not have.all():
                # hold the last good sample: index of the latest good row at or before each row
                src = np.where(have, np.arange(mag.shape[0]), -1)
                np.maximum.accumulate(src, out=src)
                held = mag[np.maximum(src, 0)]
                before = src < 0
                held[before] = self._last_mag if self._last_mag is not None else 0.0
                mag = held
            self._last_mag = mag[-1].copy() if (self._last_mag is not None or have.any()) \
                else None
        return ImuLog(t=np.ascontiguousarray(t), gyro=np.ascontiguousarray(data[:, 1:4]),
                      acc=np.ascontiguousarray(data[:, 4:7]),
                      mag=None if mag is None else np.ascontiguousarray(mag), style=self.style,
                      skipped_rows=self.skipped_rows, columns=self.columns,
                      implausible_rows=self.implausible_rows, mag_held_rows=self.mag_held_rows)


def read_imu_csv(path: str | Path, *, use_mag: bool = True, gyro_unit: str | None = None,
                 chunk_rows: int | None = None, fileobj=None) -> ImuLog:
    """Read a whole IMU log (see :class:`ImuLogReader` for formats, checks and counts)."""
    reader = ImuLogReader(path, use_mag=use_mag, gyro_unit=gyro_unit, chunk_rows=chunk_rows,
                          fileobj=fileobj)
    blocks = list(reader)
    if reader.rows == 0 and reader.skipped_rows == 0 and reader.implausible_rows == 0:
        raise LogError(f"{reader.path}: no data rows after the header")
    if reader.rows < 2:
        raise LogError(f"{reader.path}: fewer than two usable data rows "
                       f"({reader.skipped_rows} skipped, {reader.implausible_rows} implausible)")

    def cat(name):
        return np.ascontiguousarray(np.concatenate([getattr(b, name) for b in blocks]))

    return ImuLog(t=cat("t"), gyro=cat("gyro"), acc=cat("acc"),
                  mag=cat("mag") if reader.has_mag else None, style=reader.style,
                  skipped_rows=reader.skipped_rows, columns=reader.columns,
                  implausible_rows=reader.implausible_rows,
                  mag_held_rows=reader.mag_held_rows)


def write_attitude_csv(path: str | Path, t, q, roll_deg, pitch_deg, yaw_deg) -> None:
    """Columns ``t qw qx qy qz roll_deg pitch_deg yaw_deg`` (comma separated)."""
    out = np.column_stack([t, q, roll_deg, pitch_deg, yaw_deg])
    np.savetxt(path, out, delimiter=",", header="t,qw,qx,qy,qz,roll_deg,pitch_deg,yaw_deg",
               comments="", fmt=["%.6f"] + ["%.9f"] * 4 + ["%.5f"] * 3)
