"""Reading IMU logs (CSV) for ``navgate ahrs``.

Two header styles are recognised (case-insensitive, surrounding spaces ignored):

* plain: ``t`` (s), ``gx gy gz`` (rad/s), ``ax ay az`` (m/s^2), optional ``mx my mz`` (any
  consistent unit);
* x-io style (x-io Technologies' NGIMU / x-IMU3 / Fusion CSV exports): ``Time (s)``,
  ``Gyroscope X (deg/s)``, ``Accelerometer X (g)``, ``Magnetometer X (uT)`` and so on. The
  unit in parentheses is converted to SI: time s/ms/us; gyro deg/s, rad/s, dps; accel g,
  m/s^2; magnetometer uT, nT, mT, G/gauss, a.u. (the filters only use its direction).

Bad input never gives a traceback: a missing column, an empty file, an unknown unit or time
that does not strictly increase raise :class:`LogError` with the row number; rows with a
missing or non-numeric value in a used column are skipped and counted
(``ImuLog.skipped_rows``). Standard gravity 9.80665 m/s^2 converts g.
"""

from __future__ import annotations

import math
import re
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


def read_imu_csv(path: str | Path) -> ImuLog:
    """Read an IMU log; see the module docstring for formats and error handling."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig", errors="replace")
    except FileNotFoundError:
        raise LogError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise LogError(f"{path}: is a directory, not a CSV file") from None
    except OSError as error:
        raise LogError(f"{path}: cannot read ({error.strerror})") from None
    lines = text.splitlines()
    while lines and not lines[0].strip():
        lines.pop(0)
    if not lines:
        raise LogError(f"{path}: empty file")
    delim = "," if "," in lines[0] else None
    header = lines[0].split(delim) if delim else lines[0].split()
    cols, style, used = _map_columns(header)
    required = ["t", "gx", "gy", "gz", "ax", "ay", "az"]
    missing = [k for k in required if k not in cols]
    if missing:
        raise LogError(f"{path}: missing column(s) {', '.join(missing)} (need t, gx gy gz, "
                       "ax ay az or x-io 'Time (s)', 'Gyroscope X (deg/s)', "
                       "'Accelerometer X (g)' headers)")
    mag_keys = ["mx", "my", "mz"]
    has_mag = [k in cols for k in mag_keys]
    if any(has_mag) and not all(has_mag):
        raise LogError(f"{path}: magnetometer columns incomplete (need all of mx, my, mz)")
    keys = required + (mag_keys if all(has_mag) else [])
    idx = [cols[k][0] for k in keys]
    scale = np.array([cols[k][1] for k in keys])
    body = lines[1:]
    if not body:
        raise LogError(f"{path}: no data rows after the header")
    data = np.full((len(body), len(keys)), np.nan)
    width = len(header)
    for r, line in enumerate(body):
        if not line.strip():
            continue
        cells = line.split(delim) if delim else line.split()
        if len(cells) < width:
            cells = cells + [""] * (width - len(cells))
        for j, c in enumerate(idx):
            try:
                data[r, j] = float(cells[c])
            except ValueError:
                pass
    good = np.all(np.isfinite(data), axis=1)
    skipped = int(np.count_nonzero(~good))
    rows = np.flatnonzero(good)
    if rows.size < 2:
        raise LogError(f"{path}: fewer than two usable data rows ({skipped} skipped)")
    data = data[good] * scale
    t = data[:, 0]
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        k = int(bad[0])
        # +2: 1-based line numbers and the header line
        raise LogError(f"{path}: time does not increase at line {int(rows[k + 1]) + 2} "
                       f"({t[k]:.6g} s then {t[k + 1]:.6g} s)")
    return ImuLog(
        t=t, gyro=np.ascontiguousarray(data[:, 1:4]), acc=np.ascontiguousarray(data[:, 4:7]),
        mag=np.ascontiguousarray(data[:, 7:10]) if len(keys) == 10 else None, style=style,
        skipped_rows=skipped, columns=used)


def write_attitude_csv(path: str | Path, t, q, roll_deg, pitch_deg, yaw_deg) -> None:
    """Columns ``t qw qx qy qz roll_deg pitch_deg yaw_deg`` (comma separated)."""
    out = np.column_stack([t, q, roll_deg, pitch_deg, yaw_deg])
    np.savetxt(path, out, delimiter=",", header="t,qw,qx,qy,qz,roll_deg,pitch_deg,yaw_deg",
               comments="", fmt=["%.6f"] + ["%.9f"] * 4 + ["%.5f"] * 3)
