"""Seed 000's navigator configuration for terrain-referenced navigation (the PS side's own).

Reference: seed 000 "Data Flow" (the PS runs the TRN correlation and writes fixes) and
docs/trn.md (the two methods, their configurations and fix intervals). These settings belong to
the navigator, not to the scenario: :class:`navgate.sim.flight.FlightConfig` says what is flown
and sensed; :class:`TrnSettings` says how seed 000's PS turns ranger profiles into fixes:

- ``method``: a name of :data:`navgate.trn.correlators.METHODS` (``pmf`` or ``tercom``);
- ``pmf`` / ``tercom``: the correlators' configurations (only the method's own is used);
- ``fix_interval_s``: seconds between TRN attempts; ``None`` means the method's own
  (:data:`navgate.trn.correlators.FIX_INTERVAL_S`), resolved at construction
  (``dataclasses.replace`` keeps the resolved value);
- ``lag_compensation``: carry a fix's measurement lag forward through the error state.

A sensor log's header keeps these under ``"trn"`` beside the scenario's ``"config"``
(:func:`header_entry`); logs written before the split carry them inside ``"config"``
(``trn_method``, ``pmf``, ``tercom``, ``fix_interval_s``, ``lag_compensation``), which
:func:`from_header` maps.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

from navgate.trn.correlators import FIX_INTERVAL_S, METHODS
from navgate.trn.pmf import PmfConfig
from navgate.trn.tercom import TercomConfig

#: the keys of a pre-split log header's "config" that are TRN settings, and their field names
LEGACY_KEYS = {"trn_method": "method", "pmf": "pmf", "tercom": "tercom",
               "fix_interval_s": "fix_interval_s", "lag_compensation": "lag_compensation"}


@dataclass(frozen=True)
class TrnSettings:
    """How the navigator's TRN runs: method, correlator configurations, fix schedule, lag."""

    method: str = "pmf"
    fix_interval_s: float | None = None
    lag_compensation: bool = True
    pmf: PmfConfig = field(default_factory=PmfConfig)
    tercom: TercomConfig = field(default_factory=TercomConfig)

    def __post_init__(self):
        if not isinstance(self.method, str) or self.method not in METHODS:
            raise ValueError(f"unknown TRN method {self.method!r}; choose from "
                             f"{', '.join(METHODS)}")
        if self.fix_interval_s is None:
            object.__setattr__(self, "fix_interval_s", FIX_INTERVAL_S[self.method])
        if (isinstance(self.fix_interval_s, bool)
                or not isinstance(self.fix_interval_s, int | float)
                or not (math.isfinite(self.fix_interval_s) and self.fix_interval_s > 0)):
            raise ValueError(f"invalid fix_interval_s: {self.fix_interval_s!r} (a finite "
                             "number of seconds > 0)")
        if not isinstance(self.lag_compensation, bool):
            raise ValueError(f"invalid lag_compensation: {self.lag_compensation!r} "
                             "(true or false)")
        if not isinstance(self.pmf, PmfConfig):
            raise ValueError(f"invalid pmf: {type(self.pmf).__name__}, not a PmfConfig")
        if not isinstance(self.tercom, TercomConfig):
            raise ValueError(f"invalid tercom: {type(self.tercom).__name__}, not a "
                             "TercomConfig")

    @property
    def correlator_config(self):
        """The configuration of the chosen method's correlator."""
        return self.pmf if self.method == "pmf" else self.tercom

    def to_dict(self) -> dict:
        """JSON-ready: the layout :meth:`from_dict` reads."""
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> TrnSettings:
        """From :meth:`to_dict`'s layout (unknown keys are an error naming them)."""
        if not isinstance(d, dict):
            raise ValueError(f"TRN settings must be a mapping, got {type(d).__name__}")
        unknown = sorted(set(d) - {"method", "fix_interval_s", "lag_compensation", "pmf",
                                   "tercom"})
        if unknown:
            raise ValueError(f"unknown TRN setting(s): {', '.join(unknown)}")
        kw = dict(d)
        for name, cls_ in (("pmf", PmfConfig), ("tercom", TercomConfig)):
            if name in kw:
                if not isinstance(kw[name], dict):
                    raise ValueError(f"invalid {name}: a mapping of its settings expected")
                try:
                    kw[name] = cls_(**kw[name])
                except TypeError as error:  # an unknown field
                    raise ValueError(f"invalid {name}: {error}") from None
        return cls(**kw)


def header_entry(settings: TrnSettings) -> dict:
    """The ``"trn"`` entry of a sensor log's header."""
    return settings.to_dict()


def from_header(header: dict) -> TrnSettings:
    """The TRN settings a log was recorded with: its ``"trn"`` entry, or (a log written before
    the scenario/navigator split) the TRN keys of its ``"config"``; defaults where absent."""
    if "trn" in header:
        return TrnSettings.from_dict(header["trn"])
    conf = header.get("config", {})
    if not isinstance(conf, dict):
        raise ValueError("config must be a mapping")
    return TrnSettings.from_dict({LEGACY_KEYS[k]: v for k, v in conf.items()
                                  if k in LEGACY_KEYS})


__all__ = ["LEGACY_KEYS", "TrnSettings", "from_header", "header_entry"]
