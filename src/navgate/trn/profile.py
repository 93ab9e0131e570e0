"""Altitude profile buffer (seed 000 "Altitude Profile Buffer", module altitude_profile_manager).

Terrain elevation samples for TRN correlation: ``h_terrain = h_baro - h_agl`` with the
seed's validity checks, kept in a 64-entry circular buffer whose entries are
``(h_terrain, pos_n, pos_e, time, valid)`` (seed: 32-bit h, pos_n, pos_e, 24-bit time,
1-bit valid; this float64 model keeps the fields, not the packing).

Validity checks (seed 000 lists: baro valid, lidar valid (in range, good SNR), "altitude
change > threshold (moving)"):

- the barometric altitude is finite;
- the ranger returned a measurement (in range, no dropout);
- the beam is near nadir: |roll| and |pitch| at most ``max_tilt`` (the AGL is the slant
  range times cos(roll) cos(pitch), exact over locally flat terrain only, so steep banks
  are skipped);
- the vehicle has moved at least ``min_spacing_m`` horizontally since the last stored
  sample. The seed's "moving" check is read as along-track spacing, which is what makes
  successive entries independent terrain samples.

A gap longer than ``max_gap_s`` between accepted samples (a steep turn, dropouts, a DEM
void) restarts the profile: older samples would stretch the profile over a time in which
the INS error is no longer a near-constant offset.

Each rejection reason is counted. ``pos_n``/``pos_e`` are INS positions (metres, in the TRN
map frame); when the filter corrects the INS position, :meth:`ProfileBuffer.shift` moves the
stored positions by the same correction so that the profile track stays self-consistent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

PROFILE_DEPTH = 64

ACCEPTED = "accepted"
REJECT_BARO = "baro invalid"
REJECT_RANGER = "ranger invalid"
REJECT_TILT = "tilt too large"
REJECT_NOT_MOVING = "not moved far enough"
RESTARTED = "profile restarted after a gap"


@dataclass
class ProfileSnapshot:
    """The buffer's valid entries, oldest first."""

    h_terrain: np.ndarray
    pos_n: np.ndarray
    pos_e: np.ndarray
    time: np.ndarray

    def __len__(self):
        return self.h_terrain.size

    @property
    def track_length_m(self) -> float:
        if len(self) < 2:
            return 0.0
        return float(np.sum(np.hypot(np.diff(self.pos_n), np.diff(self.pos_e))))


@dataclass
class ProfileBuffer:
    depth: int = PROFILE_DEPTH
    min_spacing_m: float = 30.0
    max_tilt_rad: float = math.radians(20.0)
    max_gap_s: float = 5.0
    counts: dict = field(default_factory=dict)

    def __post_init__(self):
        from navgate.nav import validate

        self.depth = validate.positive_int("depth", self.depth, minimum=2)
        validate.non_negative("min_spacing_m", self.min_spacing_m)
        validate.in_range("max_tilt_rad", self.max_tilt_rad, 0.0, math.pi / 2, " rad")
        validate.positive("max_gap_s", self.max_gap_s)
        self.h_terrain = np.zeros(self.depth)
        self.pos_n = np.zeros(self.depth)
        self.pos_e = np.zeros(self.depth)
        self.time = np.zeros(self.depth)
        self.valid = np.zeros(self.depth, dtype=bool)
        self.write_ptr = 0
        self._last = None
        self._last_time = None

    def _count(self, reason):
        self.counts[reason] = self.counts.get(reason, 0) + 1
        return reason

    def add(self, *, time, h_baro, slant_range, range_valid, roll, pitch, pos_n, pos_e) -> str:
        """Offer one sample; returns ACCEPTED or the rejection reason.

        Sensor defects are counted rejections, never stored: a non-finite barometric
        height, ``range_valid`` False, a non-finite or negative range (no ranger measures
        one; a damaged log can hold one, and a replay must go on). What the navigation side
        supplies must be sound, anything else is a ValueError naming the argument: a finite
        ``time`` not before the previous accepted sample's, finite ``roll``/``pitch``/
        ``pos_n``/``pos_e``."""
        from navgate.nav import validate

        time = validate.finite_scalar("time", time)
        if self._last_time is not None and time < self._last_time:
            raise ValueError(f"time: {time:.9g} s is before the previous sample's "
                             f"{self._last_time:.9g} s (time goes backwards)")
        for name, value in (("roll", roll), ("pitch", pitch), ("pos_n", pos_n),
                            ("pos_e", pos_e)):
            validate.finite_scalar(name, value)
        if not math.isfinite(h_baro):
            return self._count(REJECT_BARO)
        if not range_valid or not (math.isfinite(slant_range) and slant_range >= 0):
            return self._count(REJECT_RANGER)
        if abs(roll) > self.max_tilt_rad or abs(pitch) > self.max_tilt_rad:
            return self._count(REJECT_TILT)
        if self._last is not None and math.hypot(pos_n - self._last[0],
                                                 pos_e - self._last[1]) < self.min_spacing_m:
            return self._count(REJECT_NOT_MOVING)
        if self._last_time is not None and time - self._last_time > self.max_gap_s:
            # a gap (turn, dropouts, void): the old samples belong to another profile
            self.clear()
            self._count(RESTARTED)
        h_agl = slant_range * math.cos(roll) * math.cos(pitch)
        i = self.write_ptr
        self.h_terrain[i] = h_baro - h_agl
        self.pos_n[i] = pos_n
        self.pos_e[i] = pos_e
        self.time[i] = time
        self.valid[i] = True
        self.write_ptr = (i + 1) % self.depth
        self._last = (pos_n, pos_e)
        self._last_time = time
        return self._count(ACCEPTED)

    def shift(self, d_north, d_east, d_vnorth=0.0, d_veast=0.0, now=None):
        """Apply an INS correction to the stored positions.

        The INS position now moved by (d_north, d_east) and its velocity by
        (d_vnorth, d_veast); a position stored dt seconds ago moves by d - dt * d_v (the
        same first-order error model as the filter's lagged TRN measurement).
        """
        from navgate.nav import validate

        for name, value in (("d_north", d_north), ("d_east", d_east), ("d_vnorth", d_vnorth),
                            ("d_veast", d_veast)):
            validate.finite_scalar(name, value)
        if now is not None:
            validate.finite_scalar("now", now)
        valid = self.valid
        lag = (now - self.time[valid]) if now is not None else 0.0
        self.pos_n[valid] += d_north - d_vnorth * lag
        self.pos_e[valid] += d_east - d_veast * lag
        if self._last is not None:
            self._last = (self._last[0] + d_north, self._last[1] + d_east)

    def clear(self):
        self.valid[:] = False
        self._last = None
        self._last_time = None

    @property
    def count(self) -> int:
        return int(np.count_nonzero(self.valid))

    def snapshot(self) -> ProfileSnapshot:
        order = (np.arange(self.depth) + self.write_ptr) % self.depth
        order = order[self.valid[order]]
        return ProfileSnapshot(self.h_terrain[order].copy(), self.pos_n[order].copy(),
                               self.pos_e[order].copy(), self.time[order].copy())
