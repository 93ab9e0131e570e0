"""TRN integrity monitoring: innovation statistics over a window, divergence detection and
reinitialisation of the search (the monitoring layer of MBARI-style TRN and of SITAN's
bank-of-filters "divergence / reset" logic; Bar-Shalom, Li & Kirubarajan 2001, sec. 5.4 for
the windowed NIS test).

The monitor sits between a correlator (:mod:`navgate.trn.correlators`) and the navigation
filter. The loop asks the correlator for a fix, offers it to the filter (chi-square gate),
then reports the outcome with :meth:`IntegrityMonitor.review`, which counts every
rejection by reason and watches three symptoms:

- windowed NIS: the sum of the normalised innovations of the last ``window`` fixes that
  reached the filter (applied or gated) exceeds the chi-square(2 window) quantile at
  ``probability``: the fixes and the filter disagree more than their covariances allow;
- ``max_consecutive_gated`` fixes in a row rejected by the filter's gate;
- ``max_consecutive_inconsistent`` profiles in a row that no shift in the search window
  explains ("profile inconsistent with DEM"): the true position is outside the window.

Any of them declares divergence. The response is a reinitialisation of the search: the
correlator's window is widened (``correlator.reinitialise``) and the loop is asked to grow
the filter's horizontal position covariance by ``inflate`` (the scatter of the recent
innovations, or the square of the window sigma), so that correct fixes pass the gate again.
The window statistics then restart. Flat terrain and ambiguity are detected by the
correlators themselves (their rejection reasons are counted here too).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

GATED = "rejected by chi-square gate"
DIVERGENCE = "divergence: search reinitialised"
INCONSISTENT = "profile inconsistent with DEM"


@dataclass(frozen=True)
class IntegrityConfig:
    window: int = 6
    probability: float = 0.999
    max_consecutive_gated: int = 3
    max_consecutive_inconsistent: int = 3
    widen: float = 3.0

    def __post_init__(self):
        from navgate.nav import validate

        validate.positive_int("window", self.window)
        validate.probability("probability", self.probability)
        validate.positive_int("max_consecutive_gated", self.max_consecutive_gated)
        validate.positive_int("max_consecutive_inconsistent", self.max_consecutive_inconsistent)
        if not validate.finite_scalar("widen", self.widen) >= 1.0:
            raise ValueError(f"widen: a reinitialisation widens the search (>= 1), got "
                             f"{self.widen:g}")


@dataclass
class Review:
    event: str = ""  #: "" or DIVERGENCE
    inflate: np.ndarray | None = None  #: 2x2 (m^2) to add to the filter's position covariance


class IntegrityMonitor:
    def __init__(self, correlator, config: IntegrityConfig = IntegrityConfig()):
        from navgate.nav.eskf import chi2_gate  # chi2.ppf, cached, without scipy.stats

        if not isinstance(config, IntegrityConfig):
            raise ValueError(f"config: expected an IntegrityConfig, got {type(config).__name__}")
        self.correlator = correlator
        self.config = config
        self.threshold = chi2_gate(config.probability, 2 * config.window)
        self.counts: dict[str, int] = {}
        self.events: dict[str, int] = {}
        self._nis: list[float] = []
        self._innov: list[np.ndarray] = []
        self._gated = 0
        self._inconsistent = 0

    def _count(self, reason):
        self.counts[reason] = self.counts.get(reason, 0) + 1

    def review(self, result, update=None, innovation=None, sigma_max_m: float = 0.0) -> Review:
        """Count the outcome of one attempt; declare divergence when the symptoms say so.

        ``update`` is the filter's UpdateResult (None when the correlator gave no fix),
        ``innovation`` the 2-vector offered to the filter.
        """
        from navgate.nav import validate

        cfg = self.config
        validate.non_negative("sigma_max_m", sigma_max_m)
        if update is not None and result.accepted:
            validate.finite_array("innovation", innovation, (2,))
            # an applied update's NIS is >= 0 (NaN or negative: S was not positive definite);
            # a refused one (the fp32 engine's "innovation covariance not positive") may carry
            # any value and is counted as gated below
            if update.accepted and not float(update.nis) >= 0:
                raise ValueError(f"update.nis: an applied update's normalised innovation "
                                 f"squared is >= 0, got {update.nis}")
        if not result.accepted:
            self._count(result.reason)
            if result.reason == INCONSISTENT:
                self._inconsistent += 1
                if self._inconsistent >= cfg.max_consecutive_inconsistent:
                    return self._diverged(np.eye(2) * (2.0 * sigma_max_m) ** 2)
            return Review()
        self._inconsistent = 0
        if update is None:
            return Review()
        self._nis.append(float(update.nis))
        self._innov.append(np.asarray(innovation, float))
        self._nis = self._nis[-cfg.window:]
        self._innov = self._innov[-cfg.window:]
        if update.accepted:
            self._count("applied")
            self._gated = 0
        else:
            self._count(GATED)
            self._gated += 1
        windowed = len(self._nis) == cfg.window and sum(self._nis) > self.threshold
        if windowed or self._gated >= cfg.max_consecutive_gated:
            scatter = np.mean([np.outer(y, y) for y in self._innov], axis=0)
            return self._diverged(scatter)
        return Review()

    def _diverged(self, inflate):
        self.events[DIVERGENCE] = self.events.get(DIVERGENCE, 0) + 1
        self._nis.clear()
        self._innov.clear()
        self._gated = 0
        self._inconsistent = 0
        if hasattr(self.correlator, "reinitialise"):
            self.correlator.reinitialise(self.config.widen)
        inflate = 0.5 * (inflate + inflate.T)
        return Review(DIVERGENCE, inflate)
