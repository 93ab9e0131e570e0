"""The altitude profile kept in the PL (seed 000 "Altitude Profile Buffer"), as the PS side of
the float32 engines sees it.

Seed 000 keeps the terrain profile in the PL's ``altitude_profile_manager`` (64 entries of
128 bits: float32 h_terrain, pos_n, pos_e, a 24-bit millisecond time stamp and a valid bit;
:mod:`navgate.systems.ins_trn.profile_manager`) and the PS takes it by DMA when it
correlates. The reference engine keeps a float64 :class:`navgate.trn.profile.ProfileBuffer`;
the float32 engines (``fp32``, ``rtl``, ``fpga-sim``) keep the profile where the PL keeps it,
in the PL's entry format:

- **push.** The navigator's profile checks (validity, tilt, spacing, restart after a gap) and
  the terrain height stay on the PS (:class:`ProfileBuffer` ``add``, unchanged); an accepted
  sample goes into the PL FIFO as its four words (:func:`entry_words`: the float64 values
  rounded to float32, the time to whole milliseconds).
- **read.** A correlation takes the newest ``min(entries since the last restart, 64)``
  entries from the FIFO (the ``fpga-sim`` engine by DMA into DDR; the ``fp32`` engine from
  its model of the FIFO, :class:`ProfileFifoModel`) and decodes them
  (:func:`decode_entries`: time stamps unwrapped against the correlation time).
- **shift.** The PL FIFO's entries never change, so a TRN correction cannot move them as the
  float64 buffer does; the PS records every applied correction (position and velocity
  change, time, and how many entries were in the FIFO then) and applies the corrections,
  in order, to each entry they postdate when it reads the profile: an entry stored at t
  moves by ``d - d_v (t_fix - t)`` per correction, the float64 buffer's rule.

The result is one profile for every float32 engine, bit for bit, whether it came through the
co-simulated PL's DMA or from the model (tests/systems/ins_trn/test_fpga_sim.py).
"""

from __future__ import annotations

from collections import deque

import numpy as np

from navgate.trn.profile import ACCEPTED, ProfileBuffer, ProfileSnapshot

#: the time stamp's range (24-bit milliseconds; it wraps after 4.66 h)
TIME_WRAP_MS = 1 << 24
VALID_BIT = 1 << 24


def entry_words(h_terrain: float, pos_n: float, pos_e: float, time_s: float) -> tuple:
    """The four 32-bit words of a valid entry (profile_manager.PROFILE_ENTRY): the float32
    bit patterns of h_terrain, pos_n, pos_e (round to nearest) and ``time_ms | valid << 24``."""
    f = np.array([h_terrain, pos_n, pos_e], np.float64).astype(np.float32).view(np.uint32)
    time_ms = int(round(float(time_s) * 1000.0)) % TIME_WRAP_MS
    return int(f[0]), int(f[1]), int(f[2]), time_ms | VALID_BIT


def decode_entries(words, now_s: float):
    """(h_terrain, pos_n, pos_e, time_s) float64 arrays from (n, 4) entry words, oldest
    first; each time stamp is the latest time at or before ``now_s`` with its 24-bit
    millisecond value."""
    w = np.asarray(words, np.uint64).reshape(-1, 4).astype(np.uint32)
    fl = w[:, :3].view(np.float32).astype(np.float64)
    now_ms = int(round(float(now_s) * 1000.0))
    age_ms = (now_ms - (w[:, 3].astype(np.int64) & (TIME_WRAP_MS - 1))) % TIME_WRAP_MS
    return fl[:, 0].copy(), fl[:, 1].copy(), fl[:, 2].copy(), (now_ms - age_ms) / 1000.0


class ProfileFifoModel:
    """The PL FIFO's contents as the DMA returns them (the ``fp32`` engine's model)."""

    def __init__(self, depth: int):
        self.entries: deque = deque(maxlen=depth)

    def push(self, words) -> None:
        self.entries.append(tuple(int(x) for x in words))

    def read(self, count: int) -> np.ndarray:
        """The newest ``count`` entries, oldest first, as an (count, 4) uint32 array."""
        rows = list(self.entries)[len(self.entries) - count:] if count else []
        return np.array(rows, np.uint32).reshape(-1, 4)


class PlProfileBuffer(ProfileBuffer):
    """The profile checks of :class:`ProfileBuffer` with the entries in a PL FIFO (``fifo``:
    ``push(words)``, ``read(count) -> (count, 4) words``)."""

    def __init__(self, fifo, *, min_spacing_m: float = 30.0, depth: int = 64):
        super().__init__(depth=depth, min_spacing_m=min_spacing_m)
        self.fifo = fifo
        self.pushes = 0  #: entries pushed into the FIFO since the start
        self.first = 0  #: push index of the oldest entry of the current profile
        self.shifts: list = []  #: (pushes then, d_n, d_e, d_vn, d_ve, t) per applied fix

    def add(self, **sample) -> str:
        status = super().add(**sample)
        if status == ACCEPTED:
            i = (self.write_ptr - 1) % self.depth
            self.fifo.push(entry_words(self.h_terrain[i], self.pos_n[i], self.pos_e[i],
                                       self.time[i]))
            self.pushes += 1
        return status

    def clear(self):
        super().clear()
        self.first = self.pushes  # the FIFO's older entries belong to another profile

    def shift(self, d_north, d_east, d_vnorth=0.0, d_veast=0.0, now=None):
        super().shift(d_north, d_east, d_vnorth, d_veast, now=now)  # the spacing reference
        self.shifts.append((self.pushes, float(d_north), float(d_east), float(d_vnorth),
                            float(d_veast), now))

    @property
    def count(self) -> int:
        return min(self.pushes - self.first, self.depth)

    def snapshot(self, now: float | None = None) -> ProfileSnapshot:
        """The current profile read from the FIFO, corrected by the fixes applied since each
        entry was stored (``now``: the correlation time, for the time stamps' wrap; default
        the newest entry's time)."""
        n = self.count
        if now is None:
            now = self._last_time if self._last_time is not None else 0.0
        h, pn, pe, t = decode_entries(self.fifo.read(n), now)
        index = np.arange(self.pushes - n, self.pushes)
        self.shifts = [s for s in self.shifts if s[0] > self.pushes - n]
        for pushes, dn, de, dvn, dve, t_fix in self.shifts:
            sel = index < pushes
            lag = (t_fix - t[sel]) if t_fix is not None else 0.0
            pn[sel] += dn - dvn * lag
            pe[sel] += de - dve * lag
        return ProfileSnapshot(h, pn, pe, t)

