"""The terrain correlators the processor side can use, chosen by name.

Every correlator has the interface of :class:`navgate.trn.tercom.TercomCorrelator`: it is built
from ``(dem, tangent, config)`` and ``correlate(profile_snapshot, sigma_max_m)`` returns a result
with ``accepted``, ``reason``, ``time``, ``fix_n``/``fix_e``, ``ins_n``/``ins_e``, ``cov``
(2x2, m^2), ``lag_s`` and ``as_row()``. The navigation loop builds its correlator only through
:func:`make_correlator`, so a new method is one entry in :data:`METHODS`.
"""

from __future__ import annotations

from navgate.nav.earth import LocalTangent
from navgate.trn.dem import Dem
from navgate.trn.tercom import TercomConfig, TercomCorrelator

#: method name -> one-line description
METHODS: dict[str, str] = {
    "tercom": "batch TERCOM: mean-removed MSD over a search window, sub-grid peak",
}


def make_correlator(method: str, dem: Dem, tangent: LocalTangent,
                    tercom: TercomConfig | None = None):
    """The correlator called ``method`` (one of :data:`METHODS`); ``ValueError`` otherwise."""
    if method == "tercom":
        return TercomCorrelator(dem, tangent, tercom if tercom is not None else TercomConfig())
    raise ValueError(f"unknown TRN method {method!r}; choose from {', '.join(METHODS)}")
