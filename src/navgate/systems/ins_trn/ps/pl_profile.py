"""The altitude profile kept in the PL (seed 000 "Altitude Profile Buffer"), as the PS side of
the float32 engines sees it.

Seed 000 keeps the terrain profile in the PL's ``altitude_profile_manager`` (64 entries of
128 bits: float32 h_terrain, pos_n, pos_e, a 24-bit time stamp and a valid bit;
:mod:`navgate.systems.ins_trn.pl.profile_manager`) and the PS takes it by DMA when it
correlates. The reference engine keeps a float64 :class:`navgate.trn.profile.ProfileBuffer`;
the float32 engines (``fp32``, ``rtl``, ``fpga-sim``) keep the profile where the PL keeps it,
in the PL's entry format:

- **timestamp correlator.** When a ranger frame arrives, the PL latches the INS position
  (the state's float32 ``pN``/``pE`` words) and the time (the count of IMU samples
  propagated, k; the time is ``t0 + k dt``, the frame's record time) (PROF_SAMPLE_*).
- **push.** The navigator's profile checks (validity, tilt, spacing, restart after a gap) and
  the terrain height stay on the PS (:class:`ProfileBuffer` ``add``, unchanged); an accepted
  sample goes into the FIFO as its terrain height rounded to float32 with the correlator's
  position and time (:func:`entry_words`; PROF_ENTRY_H, PROF_PUSH).
- **read.** A correlation takes the newest ``min(entries since the last restart, 64)``
  entries from the FIFO (the ``fpga-sim`` engine by DMA into DDR; the ``fp32`` engine from
  its model of the FIFO, :class:`ProfileFifoModel`) and decodes them
  (:func:`decode_entries`: time stamps unwrapped against the current sample count).
- **shift.** The FIFO's entries never change, so a TRN correction cannot move them as the
  float64 buffer does; the PS records every applied correction (position and velocity
  change, time, and how many entries were in the FIFO then) and applies the corrections,
  in order, to each entry they postdate when it reads the profile: an entry stored at t
  moves by ``d - d_v (t_fix - t)`` per correction, the float64 buffer's rule.

The result is one profile for every float32 engine, bit for bit, whether it came through the
co-simulated PL's correlator and DMA or from the model (tests/systems/ins_trn/ps/test_fpga_sim.py).
"""

from __future__ import annotations

from collections import deque

import numpy as np

from navgate.numerics.fp32 import float_to_bits
from navgate.trn.profile import ACCEPTED, ProfileBuffer, ProfileSnapshot

#: the time stamp's range (24 bits of IMU samples: 11.6 h at 400 Hz)
TIME_WRAP = 1 << 24
VALID_BIT = 1 << 24


def entry_words(h_terrain: float, sample: tuple) -> tuple:
    """The four 32-bit words of a valid entry (profile_manager.PROFILE_ENTRY): the float32
    bit pattern of h_terrain (round to nearest) and the correlator's ``sample`` (pos_n and
    pos_e words, IMU sample count k) as ``k | valid << 24``."""
    h = float_to_bits(h_terrain)
    pos_n, pos_e, k = sample
    return h, int(pos_n), int(pos_e), (int(k) % TIME_WRAP) | VALID_BIT


def decode_entries(words, now_samples: int, time_of):
    """(h_terrain, pos_n, pos_e, time_s) float64 arrays from (n, 4) entry words, oldest
    first; each time stamp is the latest sample count at or before ``now_samples`` with its
    24 bits, turned into seconds by ``time_of(k)``."""
    w = np.asarray(words, np.uint64).reshape(-1, 4).astype(np.uint32)
    fl = w[:, :3].view(np.float32).astype(np.float64)
    now = int(now_samples)
    age = (now - (w[:, 3].astype(np.int64) & (TIME_WRAP - 1))) % TIME_WRAP
    t = np.array([time_of(now - int(a)) for a in age], np.float64)
    return fl[:, 0].copy(), fl[:, 1].copy(), fl[:, 2].copy(), t


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
    ``push(words)``, ``read(count) -> (count, 4) words``); ``time_of(k)``: the time (s) of
    IMU sample count k."""

    def __init__(self, fifo, time_of, *, min_spacing_m: float = 30.0, depth: int = 64):
        super().__init__(depth=depth, min_spacing_m=min_spacing_m)
        self.fifo = fifo
        self.time_of = time_of
        self.pushes = 0  #: entries pushed into the FIFO since the start
        self.first = 0  #: push index of the oldest entry of the current profile
        self.shifts: list = []  #: (pushes then, d_n, d_e, d_vn, d_ve, t) per applied fix

    def add(self, *, sample: tuple, **checks) -> str:
        """Offer a ranger sample (``checks``: :meth:`ProfileBuffer.add`'s arguments) with the
        correlator's ``sample`` (pos_n word, pos_e word, IMU sample count)."""
        status = super().add(**checks)
        if status == ACCEPTED:
            i = (self.write_ptr - 1) % self.depth
            self.fifo.push(entry_words(self.h_terrain[i], sample))
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

    def snapshot(self, now_samples: int) -> ProfileSnapshot:
        """The current profile read from the FIFO, corrected by the fixes applied since each
        entry was stored (``now_samples``: the IMU samples propagated so far, for the time
        stamps' wrap)."""
        n = self.count
        h, pn, pe, t = decode_entries(self.fifo.read(n), now_samples, self.time_of)
        index = np.arange(self.pushes - n, self.pushes)
        self.shifts = [s for s in self.shifts if s[0] > self.pushes - n]
        for pushes, dn, de, dvn, dve, t_fix in self.shifts:
            sel = index < pushes
            lag = (t_fix - t[sel]) if t_fix is not None else 0.0
            pn[sel] += dn - dvn * lag
            pe[sel] += de - dve * lag
        return ProfileSnapshot(h, pn, pe, t)

