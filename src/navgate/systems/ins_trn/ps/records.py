"""The sensor record stream of seed 000 and its log file format (``navgate fly --record``).

The navigator (:mod:`navgate.systems.ins_trn.ps.navigator`) consumes timestamped records in
stream order:

======== ================================================ ====================================
kind     fields                                           source (seed 000 "Sensor Interfaces")
======== ================================================ ====================================
``I``    gx gy gz ax ay az: the six 16-bit output words    ADIS16500 burst read (one per IMU
         of one IMU burst (int16; floats for the ideal    sample; stamped at the *end* of the
         sensors of ``--ideal-sensors``)                  sample interval)
``B``    altitude (m, ISA), status (0 valid, 1 invalid)   BMP390 sample
``R``    slant range (m), status (0 ok, 1 dropout,        AGL ranger frame
         2 out of range)
``T``    truth latitude, longitude (rad), height (m)      optional; at the log rate, for scoring
======== ================================================ ====================================

Records with equal time are kept in file order (an IMU sample that ends at t, then the
barometer and ranger samples taken at t).

Log file (UTF-8 text, one record a line)::

    navgate-records 1
    H <JSON header: flight configuration, start time, IMU calibration, initial estimate>
    I,<t>,<gx>,<gy>,<gz>,<ax>,<ay>,<az>
    B,<t>,<altitude_m>,<status>
    R,<t>,<slant_range_m>,<status>
    T,<t>,<lat_rad>,<lon_rad>,<h_m>
    ...

Numbers are written with Python's ``repr`` (the shortest string that reads back to the same
float64), so a log replays bit for bit. Reading (:func:`read_log`) checks every record:
truncated or unparsable lines, an unknown kind, non-finite numbers where a value is required
(the time; IMU words; a valid barometer altitude or ranger range), int16 words out of range
are *bad records*: counted by reason, skipped, reported. Time order is resynchronised: of the
remaining records the longest run that never goes back in time is kept, so one wrong stamp
(far ahead or behind) costs one record, not the rest of the log ("time out of order").
``records_read`` and ``used_fraction`` say how much of the log a stream holds. Lines are read
in bounded pieces (:data:`MAX_RECORD_CHARS`, :data:`MAX_HEADER_CHARS`). Only a log with no
valid IMU record, or an unreadable header, is an error (:class:`LogError`);
:func:`check_header` checks that the header describes a usable navigator.
"""

from __future__ import annotations

import bisect
import json
import math
from dataclasses import asdict, dataclass, field

import numpy as np

IMU, BARO, RANGER, TRUTH = 0, 1, 2, 3
KIND_CODES = {"I": IMU, "B": BARO, "R": RANGER, "T": TRUTH}
MAGIC = "navgate-records 1"


class LogError(ValueError):
    """The log cannot be used at all (unreadable, no header, no valid IMU record)."""


@dataclass
class RecordStream:
    """Records in stream order, columnar: ``kind[i]``, ``t[i]`` and ``index[i]`` into the
    per-kind table of that kind."""

    kind: np.ndarray  #: (M,) uint8
    t: np.ndarray  #: (M,) float64 s
    index: np.ndarray  #: (M,) int64
    gyro_words: np.ndarray  #: (N, 3)
    accel_words: np.ndarray  #: (N, 3)
    baro_altitude: np.ndarray  #: (B,)
    baro_status: np.ndarray  #: (B,) 0 valid
    ranger_range: np.ndarray  #: (R,)
    ranger_status: np.ndarray  #: (R,) 0 ok
    truth: np.ndarray  #: (T, 3) lat, lon, h
    header: dict = field(default_factory=dict)
    bad_records: dict = field(default_factory=dict)  #: reason -> count (from a log)
    records_read: int = 0  #: records in the log (used and bad; 0 when not from a log)

    @property
    def used_fraction(self) -> float:
        """The fraction of the log's records this stream holds (1.0 when not from a log)."""
        return len(self) / self.records_read if self.records_read else 1.0

    def __len__(self):
        return self.kind.size

    @property
    def n_imu(self) -> int:
        return self.gyro_words.shape[0]


# ------------------------------------------------------------------ stream from a simulated flight


def stream_from_sensors(data, truth_every: int | None, header: dict) -> RecordStream:
    """The record stream of a simulated flight (:class:`navgate.sim.flight.SensorData`).

    IMU sample k (0-based) covers [t_k, t_k+1] and is stamped ``t0 + (k + 1) dt``; a
    barometer or ranger sample at IMU boundary k is stamped ``t0 + k dt`` and follows the IMU
    sample that ends there. ``truth_every``: add a truth record every that many IMU samples
    (row r at boundary ``min(r * truth_every, N)``, the scorer's sampling).
    """
    truth = data.truth
    n = data.imu.gyro_words.shape[0]
    t0 = float(truth.t[0])
    dt = 1.0 / float(header["imu_rate_hz"])
    # sort key: (boundary, order) with IMU sample k at boundary k+1 first
    keys = [np.arange(1, n + 1) * 4 + 0]
    kinds = [np.full(n, IMU, np.uint8)]
    idx = [np.arange(n)]
    times = [t0 + np.arange(1, n + 1) * dt]
    bi = np.asarray(data.baro_index, np.int64)
    keys.append(bi * 4 + 1)
    kinds.append(np.full(bi.size, BARO, np.uint8))
    idx.append(np.arange(bi.size))
    times.append(np.array([t0 + int(k) * dt for k in bi]))
    ri = np.asarray(data.ranger_index, np.int64)
    keys.append(ri * 4 + 2)
    kinds.append(np.full(ri.size, RANGER, np.uint8))
    idx.append(np.arange(ri.size))
    times.append(np.array([t0 + int(k) * dt for k in ri]))
    truth_rows = np.empty((0, 3))
    if truth_every:
        rows = np.minimum(np.arange(n // truth_every + 1) * truth_every, len(truth) - 1)
        truth_rows = np.column_stack([truth.lat[rows], truth.lon[rows], truth.h[rows]])
        keys.append(rows * 4 + 3)
        kinds.append(np.full(rows.size, TRUTH, np.uint8))
        idx.append(np.arange(rows.size))
        times.append(np.array([t0 + int(k) * dt for k in rows]))
    key = np.concatenate(keys)
    order = np.argsort(key, kind="stable")
    baro_status = np.where(np.asarray(data.baro.valid, bool)
                           & np.isfinite(data.baro.altitude), 0, 1).astype(np.int8)
    return RecordStream(
        np.concatenate(kinds)[order], np.concatenate(times)[order],
        np.concatenate(idx)[order].astype(np.int64),
        np.asarray(data.imu.gyro_words), np.asarray(data.imu.accel_words),
        np.asarray(data.baro.altitude, float), baro_status,
        np.asarray(data.ranger.slant_range, float),
        np.asarray(data.ranger.status, np.int8), truth_rows, dict(header or {}))


# ------------------------------------------------------------------ header


def make_header(cfg, data, init, calibration, reference, trn=None) -> dict:
    """JSON-ready header: what the navigator needs besides the records. ``config`` is the
    scenario (:class:`navgate.sim.flight.FlightConfig`), ``trn`` the navigator's TRN settings
    (:class:`~navgate.systems.ins_trn.ps.trn_settings.TrnSettings`, default when None); a log
    written before that split has the TRN keys inside ``config``
    (:func:`~navgate.systems.ins_trn.ps.trn_settings.from_header` reads both)."""
    from navgate.systems.ins_trn.ps.trn_settings import TrnSettings, header_entry

    def arr(x):
        return np.asarray(x, float).tolist()

    return {
        "config": asdict(cfg),
        "trn": header_entry(TrnSettings() if trn is None else trn),
        "ideal": bool(data.ideal),
        "imu_rate_hz": float(cfg.imu_rate_hz),
        "t0": float(data.truth.t[0]),
        "n_imu": int(data.imu.gyro_words.shape[0]),
        "calibration": {"gyro_bias": arr(calibration.gyro_bias),
                        "gyro_matrix": arr(calibration.gyro_matrix),
                        "accel_bias": arr(calibration.accel_bias),
                        "accel_matrix": arr(calibration.accel_matrix),
                        "gyro_lsb": float(calibration.gyro_lsb),
                        "accel_lsb": float(calibration.accel_lsb)},
        "initial": {"nav": arr(init.nav), "p0": arr(init.p0), "bias_a": arr(init.bias_a),
                    "bias_g": arr(init.bias_g)},
        "reference": {"lat_rad": reference.lat0, "lon_rad": reference.lon0,
                      "h_m": reference.h0},
    }


def _array(value, shape, name):
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise LogError(f"header {name} is not an array of numbers") from None
    if a.shape != shape:
        raise LogError(f"header {name} has shape {a.shape}, expected {shape}")
    if not np.all(np.isfinite(a)):
        raise LogError(f"header {name} holds non-finite values")
    return a


def _number(value, name, lo=-math.inf, hi=math.inf, lo_open=False):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise LogError(f"header {name} is not a number")
    v = float(value)
    if not math.isfinite(v) or v > hi or v < lo or (lo_open and v == lo):
        raise LogError(f"header {name} = {v:g} is outside [{lo:g}, {hi:g}]")
    return v


def check_header(header: dict) -> None:
    """Raise :class:`LogError` (one line naming the field) unless the header describes a
    usable navigator: calibration vectors (3,) and matrices (3, 3), positive LSBs, an initial
    state of 10 finite values with a latitude inside (-90, 90) deg, a height within
    [-1 km, 100 km] and a unit quaternion, a symmetric positive definite 15 x 15 P0, finite
    biases, a reference point on the Earth and a positive IMU rate."""
    try:
        cal, ini, ref = header["calibration"], header["initial"], header["reference"]
        for part, name in ((cal, "calibration"), (ini, "initial"), (ref, "reference")):
            if not isinstance(part, dict):
                raise LogError(f"header {name} is not an object")
        for key in ("gyro_bias", "accel_bias"):
            _array(cal[key], (3,), f"calibration.{key}")
        for key in ("gyro_matrix", "accel_matrix"):
            _array(cal[key], (3, 3), f"calibration.{key}")
        for key in ("gyro_lsb", "accel_lsb"):
            _number(cal[key], f"calibration.{key}", 0.0, lo_open=True)
        nav = _array(ini["nav"], (10,), "initial.nav")
        half_pi = math.pi / 2
        _number(nav[0], "initial.nav latitude (rad)", -half_pi, half_pi)
        if abs(nav[0]) >= half_pi:
            raise LogError("header initial.nav latitude is at a pole")
        _number(nav[1], "initial.nav longitude (rad)", -2 * math.pi, 2 * math.pi)
        _number(nav[2], "initial.nav height (m)", -1000.0, 100_000.0)
        if abs(float(np.linalg.norm(nav[6:10])) - 1.0) > 1e-6:
            raise LogError("header initial.nav quaternion is not a unit quaternion")
        p0 = _array(ini["p0"], (15, 15), "initial.p0")
        if not np.allclose(p0, p0.T, rtol=1e-9, atol=0.0):
            raise LogError("header initial.p0 is not symmetric")
        try:
            np.linalg.cholesky(p0)
        except np.linalg.LinAlgError:
            raise LogError("header initial.p0 is not positive definite") from None
        for key in ("bias_a", "bias_g"):
            _array(ini[key], (3,), f"initial.{key}")
        lat = _number(ref["lat_rad"], "reference.lat_rad", -half_pi, half_pi)
        if abs(lat) >= half_pi:
            raise LogError("header reference.lat_rad is at a pole")
        _number(ref["lon_rad"], "reference.lon_rad", -2 * math.pi, 2 * math.pi)
        _number(ref["h_m"], "reference.h_m", -1000.0, 100_000.0)
        _number(header["t0"], "t0")
        if "imu_rate_hz" in header:
            _number(header["imu_rate_hz"], "imu_rate_hz", 0.0, 1e6, lo_open=True)
    except KeyError as error:
        raise LogError(f"header lacks {error}") from None
    except TypeError as error:
        raise LogError(f"header has a field of the wrong type ({error})") from None


# ------------------------------------------------------------------ writing and reading


def write_log(stream: RecordStream, path) -> None:
    """Write ``stream`` in the log format of the module docstring."""
    gw, aw = stream.gyro_words, stream.accel_words
    int_words = np.issubdtype(gw.dtype, np.integer)
    with open(path, "w", encoding="utf-8", newline="\n") as fh:
        fh.write(MAGIC + "\n")
        fh.write("H " + json.dumps(stream.header, separators=(",", ":")) + "\n")
        lines = []
        kinds, ts, idxs = stream.kind.tolist(), stream.t.tolist(), stream.index.tolist()
        gwl, awl = gw.tolist(), aw.tolist()
        for k, t, i in zip(kinds, ts, idxs, strict=True):
            if k == IMU:
                g, a = gwl[i], awl[i]
                if int_words:
                    lines.append(f"I,{t!r},{g[0]},{g[1]},{g[2]},{a[0]},{a[1]},{a[2]}")
                else:
                    lines.append("I," + ",".join(repr(float(v)) for v in (t, *g, *a)))
            elif k == BARO:
                lines.append(f"B,{t!r},{float(stream.baro_altitude[i])!r},"
                             f"{int(stream.baro_status[i])}")
            elif k == RANGER:
                lines.append(f"R,{t!r},{float(stream.ranger_range[i])!r},"
                             f"{int(stream.ranger_status[i])}")
            else:
                la, lo, h = stream.truth[i]
                lines.append(f"T,{t!r},{float(la)!r},{float(lo)!r},{float(h)!r}")
            if len(lines) >= 65536:
                fh.write("\n".join(lines) + "\n")
                lines = []
        if lines:
            fh.write("\n".join(lines) + "\n")


_FIELDS = {"I": 8, "B": 4, "R": 4, "T": 5}
#: the longest header line and record line read: a longer line (a binary file, a file of
#: zeros) is an error or a bad record, never a line read without end
MAX_HEADER_CHARS = 1 << 22
MAX_RECORD_CHARS = 1 << 10


def _lines(fh):
    """The file's lines, each at most MAX_RECORD_CHARS long; a longer line is yielded as
    None (an over-long record) and skipped to its end in bounded pieces."""
    while True:
        line = fh.readline(MAX_RECORD_CHARS)
        if not line:
            return
        if len(line) >= MAX_RECORD_CHARS and not line.endswith("\n"):
            while line and not line.endswith("\n"):
                line = fh.readline(MAX_RECORD_CHARS)
            yield None
            continue
        yield line


def _in_time_order(times: list) -> list:
    """Indices of the longest subsequence of ``times`` that never goes backwards (patience
    sorting, O(n log n)); ties keep file order."""
    tails: list = []  # tails[k]: smallest last time of a kept run of length k + 1
    tail_at: list = []
    previous = [-1] * len(times)
    for i, t in enumerate(times):
        k = bisect.bisect_right(tails, t)
        if k == len(tails):
            tails.append(t)
            tail_at.append(i)
        else:
            tails[k] = t
            tail_at[k] = i
        previous[i] = tail_at[k - 1] if k else -1
    keep = []
    i = tail_at[-1] if tail_at else -1
    while i >= 0:
        keep.append(i)
        i = previous[i]
    return keep[::-1]


def read_log(path) -> RecordStream:
    """Read a log; bad records are counted in ``bad_records`` and skipped (see module doc)."""
    try:
        fh = open(path, encoding="utf-8", errors="replace")
    except OSError as error:
        raise LogError(f"cannot read {path}: {error.strerror}") from None
    bad: dict = {}

    def reject(reason):
        bad[reason] = bad.get(reason, 0) + 1

    recs: list = []  # (kind, t, values) of every record that passed its own checks
    read = 0
    float_words = False
    with fh:
        first = fh.readline(64).strip()
        if first != MAGIC:
            raise LogError(f"{path} is not a navgate record log (first line {first[:40]!r})")
        hline = fh.readline(MAX_HEADER_CHARS)
        if not hline.startswith("H "):
            raise LogError(f"{path}: missing header line")
        if len(hline) >= MAX_HEADER_CHARS and not hline.endswith("\n"):
            raise LogError(f"{path}: header line longer than {MAX_HEADER_CHARS} characters")
        try:
            header = json.loads(hline[2:])
        except json.JSONDecodeError as error:
            raise LogError(f"{path}: unreadable header ({error.msg})") from None
        except RecursionError:
            raise LogError(f"{path}: unreadable header (nested too deeply)") from None
        if not isinstance(header, dict):
            raise LogError(f"{path}: unreadable header (not a JSON object)")
        float_words = bool(header.get("ideal", False))
        for line in _lines(fh):
            if line is None:
                read += 1
                reject("over-long record")
                continue
            parts = line.rstrip("\n").split(",")
            kind = parts[0]
            if kind not in _FIELDS:
                if line.strip():
                    read += 1
                    reject("unknown record kind")
                continue
            read += 1
            if len(parts) != _FIELDS[kind]:
                reject("truncated record")
                continue
            try:
                vals = [float(p) for p in parts[1:]]
            except ValueError:
                reject("unparsable number")
                continue
            t = vals[0]
            if not math.isfinite(t):
                reject("non-finite time")
                continue
            if kind == "I":
                w = vals[1:]
                if not all(math.isfinite(v) for v in w):
                    reject("non-finite IMU word")
                    continue
                if not float_words and not all(v == int(v) and -32768 <= v <= 32767
                                               for v in w):
                    reject("IMU word outside int16")
                    continue
            elif kind == "B":
                alt, st = vals[1], vals[2]
                if st not in (0.0, 1.0) or (st == 0.0 and not math.isfinite(alt)):
                    reject("bad barometer sample")
                    continue
            elif kind == "R":
                rng, st = vals[1], vals[2]
                if st not in (0.0, 1.0, 2.0) or (st == 0.0 and not math.isfinite(rng)):
                    reject("bad ranger frame")
                    continue
            elif not all(math.isfinite(v) for v in vals[1:]):
                reject("non-finite truth")
                continue
            recs.append((kind, t, vals))
    # resynchronise on time: keep the longest run of records in time order; a record whose
    # stamp jumps ahead or falls back is dropped alone, not everything after it
    keep = _in_time_order([r[1] for r in recs])
    if len(keep) < len(recs):
        bad["time out of order"] = len(recs) - len(keep)
    kinds, ts, idxs = [], [], []
    gyro, accel, balt, bst, rr, rst, truth = [], [], [], [], [], [], []
    for i in keep:
        kind, t, vals = recs[i]
        if kind == "I":
            kinds.append(IMU)
            idxs.append(len(gyro))
            gyro.append(vals[1:4])
            accel.append(vals[4:])
        elif kind == "B":
            kinds.append(BARO)
            idxs.append(len(balt))
            balt.append(vals[1] if vals[2] == 0.0 else math.nan)
            bst.append(int(vals[2]))
        elif kind == "R":
            kinds.append(RANGER)
            idxs.append(len(rr))
            rr.append(vals[1] if vals[2] == 0.0 else math.nan)
            rst.append(int(vals[2]))
        else:
            kinds.append(TRUTH)
            idxs.append(len(truth))
            truth.append(vals[1:])
        ts.append(t)
    if not gyro:
        raise LogError(f"{path}: no valid IMU record"
                       + (f" ({sum(bad.values())} bad records)" if bad else ""))
    wdtype = float if float_words else np.int16
    return RecordStream(
        np.array(kinds, np.uint8), np.array(ts, float), np.array(idxs, np.int64),
        np.array(gyro, float).astype(wdtype), np.array(accel, float).astype(wdtype),
        np.array(balt, float), np.array(bst, np.int8), np.array(rr, float),
        np.array(rst, np.int8), np.array(truth, float).reshape(-1, 3), header, bad, read)
