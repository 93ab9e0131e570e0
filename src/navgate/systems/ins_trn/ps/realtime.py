"""Real-time mode of the PS's navigator (``navgate fly --realtime [SPEED]``, issue 27 item 4):
the record stream paced to the wall clock, and TRN requests on a worker thread so the IMU loop
never waits on the Pi.

Seed 000's PS runs the INS at the IMU's rate while the Pi correlates: a fix comes back some
time after its request and is applied then, at its own time tag, by the filter's lag
compensation (:meth:`navgate.systems.ins_trn.ps.navigator.Navigator._apply`, the same path as
the simulated ``--trn-latency``, with the age measured instead of set). A fix older than the
navigator's deadline is dropped and counted.

:class:`Realtime` holds the pacing (record time ``t`` is due at wall time
``wall0 + (t - t0) / speed``; the loop sleeps when ahead and records how far behind it is when
late), the one-request worker, and the figures for the summary: fix ages, late counts (late:
back after the next attempt was due) and dropped counts, how far the loop fell behind the wall
clock, and the longest time the loop spent in a call to the Pi's side: asking whether a fix
has come (a look at a future, never a wait for the Pi) and handing a request to the worker
(which wakes the worker thread: with CPython's GIL and a busy CPU the loop can lose a few
milliseconds there to the worker's own packing of the request).

Results depend on thread and wall-clock timing: a real-time run is not deterministic (the
default simulated-time mode is).
"""

from __future__ import annotations

import math
import time
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np


class Realtime:
    """Wall-clock pacing and the TRN worker of one navigation run."""

    def __init__(self, speed: float, t0: float, block_s: float, fix_interval_s: float):
        if not (isinstance(speed, int | float) and math.isfinite(speed) and speed > 0):
            raise ValueError(f"realtime speed must be a positive factor, got {speed!r}")
        self.speed = float(speed)
        self.t0 = float(t0)
        #: one IMU block of records (the IMU samples between two barometer records), in
        #: wall-clock seconds at this speed
        self.block_s = float(block_s) / self.speed
        #: a fix is late when it comes back after the next attempt was due (one request is
        #: in flight at a time, so that attempt waited for it)
        self.fix_interval_s = float(fix_interval_s)
        self.wall0: float | None = None
        self.behind: list[float] = []
        #: the longest the loop spent handing a request to the worker (the worker thread's
        #: wake-up: the GIL and the OS's scheduling) and asking whether a fix has come (a
        #: look at a future, never a wait for the Pi)
        self.submit_max_s = 0.0
        self.poll_max_s = 0.0
        self.ages: list[float] = []
        self.counts = {"requests": 0, "arrived": 0, "late": 0, "dropped_after_deadline": 0,
                       "in_flight_at_end": 0, "worker_errors": 0}
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="trn-request")
        self._wall_end: float | None = None

    # -- pacing -----------------------------------------------------------------------------
    def start(self) -> None:
        # the worker thread starts now, not inside the first request's submit
        self._executor.submit(lambda: None).result()
        self.wall0 = time.perf_counter()

    def pace(self, t: float) -> None:
        """Hold the loop until record time ``t`` is due on the wall clock (record the lag
        when it is already past)."""
        if self.wall0 is None:
            self.start()
        due = self.wall0 + (t - self.t0) / self.speed
        now = time.perf_counter()
        if now < due:
            time.sleep(due - now)
            self.behind.append(0.0)
        else:
            self.behind.append(now - due)

    # -- the worker -------------------------------------------------------------------------
    def submit(self, fn, *args, **kwargs) -> Future:
        start = time.perf_counter()
        future = self._executor.submit(fn, *args, **kwargs)
        self.counts["requests"] += 1
        self.submit_max_s = max(self.submit_max_s, time.perf_counter() - start)
        return future

    def done(self, future: Future) -> bool:
        start = time.perf_counter()
        ready = future.done()
        self.poll_max_s = max(self.poll_max_s, time.perf_counter() - start)
        return ready

    def arrived(self, age_s: float, dropped: bool) -> None:
        self.counts["arrived"] += 1
        self.ages.append(age_s)
        if age_s >= self.fix_interval_s:
            self.counts["late"] += 1
        if dropped:
            self.counts["dropped_after_deadline"] += 1

    def close(self) -> None:
        """Wait for the request in hand (the link's timeouts bound it) and stop the worker."""
        if self._wall_end is None:
            self._wall_end = time.perf_counter()
        self._executor.shutdown(wait=True)

    def summary(self) -> dict:
        behind = np.array(self.behind or [0.0])
        ages = np.array(self.ages) if self.ages else None
        wall = (self._wall_end or time.perf_counter()) - (self.wall0 or time.perf_counter())
        return {
            "speed": self.speed,
            "deterministic": False,
            "wall_s": wall,
            "pacing_behind_max_s": float(behind.max()),
            "pacing_behind_median_s": float(np.median(behind)),
            "pacing_behind_final_s": float(behind[-1]),
            "pi_poll_max_s": self.poll_max_s,
            "pi_submit_max_s": self.submit_max_s,
            "imu_block_wall_s": self.block_s,
            "fix_age_median_s": None if ages is None else float(np.median(ages)),
            "fix_age_max_s": None if ages is None else float(ages.max()),
            **self.counts,
        }


__all__ = ["Realtime"]
