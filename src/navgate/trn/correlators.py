"""The terrain correlators the processor side can use, chosen by name.

Every correlator has the interface of :class:`navgate.trn.tercom.TercomCorrelator`: it is built
from ``(dem, tangent, config)`` and ``correlate(profile_snapshot, sigma_max_m)`` returns a result
with ``accepted``, ``reason``, ``time``, ``fix_n``/``fix_e``, ``ins_n``/``ins_e``, ``cov``
(2x2, m^2), ``lag_s`` and ``as_row()``; ``correlate`` also takes an optional ``prior_cov``
(the filter's 2x2 horizontal position covariance), which the point-mass filter uses as its
prior and TERCOM ignores. The navigation loop builds its correlator only through
:func:`make_correlator`, so a new method is one entry in :data:`METHODS`.

:func:`make_monitor` gives the integrity monitor (:mod:`navgate.trn.integrity`) the loop
reports every attempt to; it counts rejections by reason and, on divergence, widens the
correlator's search and asks for a larger filter covariance.
"""

from __future__ import annotations

from navgate.nav.earth import LocalTangent
from navgate.trn.dem import Dem
from navgate.trn.integrity import IntegrityConfig, IntegrityMonitor
from navgate.trn.pmf import PmfConfig, PointMassCorrelator
from navgate.trn.tercom import TercomConfig, TercomCorrelator

#: method name -> one-line description
METHODS: dict[str, str] = {
    "tercom": "batch TERCOM: mean-removed MSD over a search window, sub-grid peak",
    "pmf": "point-mass filter: grid posterior over the position error, honest covariance",
}

#: method name -> seconds between the loop's attempts (FlightConfig.fix_interval_s default):
#: TERCOM matches overlapping 64-sample profiles every 10 s (docs/trn.md); the point-mass
#: filter uses each sample once, so it is asked every 5 s and fixes as soon as 15 fresh
#: samples (7.5 s at 60 m/s) are informative (measured: docs/trn.md)
FIX_INTERVAL_S: dict[str, float] = {"tercom": 10.0, "pmf": 5.0}


def make_correlator(method: str, dem: Dem, tangent: LocalTangent,
                    tercom: TercomConfig | None = None, pmf: PmfConfig | None = None):
    """The correlator called ``method`` (one of :data:`METHODS`); ``ValueError`` otherwise."""
    if method == "tercom":
        return TercomCorrelator(dem, tangent, tercom if tercom is not None else TercomConfig())
    if method == "pmf":
        return PointMassCorrelator(dem, tangent, pmf if pmf is not None else PmfConfig())
    raise ValueError(f"unknown TRN method {method!r}; choose from {', '.join(METHODS)}")


def make_monitor(correlator, config: IntegrityConfig | None = None) -> IntegrityMonitor:
    """The integrity monitor for ``correlator`` (navgate.trn.integrity)."""
    return IntegrityMonitor(correlator, config if config is not None else IntegrityConfig())
