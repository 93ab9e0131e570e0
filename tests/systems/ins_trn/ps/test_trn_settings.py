"""The navigator's TRN settings: defaults, validation naming the field, the log header's
layouts (the new "trn" entry and the old one inside "config")."""

from __future__ import annotations

import json
import math

import pytest

from navgate.sim.flight import FlightConfig
from navgate.systems.ins_trn.ps.trn_settings import (
    LEGACY_KEYS,
    TrnSettings,
    from_header,
    header_entry,
)
from navgate.trn.correlators import FIX_INTERVAL_S
from navgate.trn.pmf import PmfConfig
from navgate.trn.tercom import TercomConfig


def test_fix_interval_follows_the_method_unless_given():
    assert TrnSettings().method == "pmf"
    assert TrnSettings().fix_interval_s == FIX_INTERVAL_S["pmf"] == 5.0
    assert TrnSettings(method="tercom").fix_interval_s == FIX_INTERVAL_S["tercom"] == 10.0
    assert TrnSettings(method="tercom", fix_interval_s=3.0).fix_interval_s == 3.0
    assert TrnSettings().lag_compensation is True
    assert TrnSettings().correlator_config == PmfConfig()
    assert TrnSettings(method="tercom").correlator_config == TercomConfig()


@pytest.mark.parametrize("field, value", [
    ("method", "magic"), ("method", None),
    ("fix_interval_s", 0.0), ("fix_interval_s", -1.0), ("fix_interval_s", math.nan),
    ("fix_interval_s", math.inf), ("fix_interval_s", "5"), ("fix_interval_s", True),
    ("lag_compensation", 1), ("lag_compensation", "yes"),
    ("pmf", {}), ("tercom", PmfConfig()),
])
def test_bad_settings_are_value_errors_naming_the_field(field, value):
    with pytest.raises(ValueError) as info:
        TrnSettings(**{field: value})
    name = "TRN method" if field == "method" else field
    assert name in str(info.value)


def test_dict_round_trip_through_json():
    s = TrnSettings(method="tercom", fix_interval_s=7.5, lag_compensation=False,
                    tercom=TercomConfig(max_half_width_m=1500))
    back = TrnSettings.from_dict(json.loads(json.dumps(header_entry(s))))
    assert back == s and back.tercom.max_half_width_m == 1500


@pytest.mark.parametrize("d, needle", [
    ({"magic": 1}, "unknown TRN setting(s): magic"),
    ({"pmf": [1, 2]}, "invalid pmf"),
    ({"tercom": {"no_such_field": 1}}, "invalid tercom"),
    ([1, 2], "must be a mapping"),
])
def test_bad_dicts_are_value_errors(d, needle):
    with pytest.raises(ValueError) as info:
        TrnSettings.from_dict(d)
    assert needle in str(info.value)


def test_old_and_new_header_layouts_give_the_same_settings():
    """A log written before the split keeps the TRN keys in its flight configuration under
    their old names; from_header maps them to the settings the new layout records."""
    s = TrnSettings(method="tercom", fix_interval_s=3.0, lag_compensation=False,
                    pmf=PmfConfig(range_sigma_m=2.0))
    new = {"config": {"duration_s": 600.0}, "trn": header_entry(s)}
    entry = header_entry(s)
    old_config = {"duration_s": 600.0, "trn_method": entry["method"],
                  "fix_interval_s": entry["fix_interval_s"],
                  "lag_compensation": entry["lag_compensation"], "pmf": entry["pmf"],
                  "tercom": entry["tercom"]}
    assert set(old_config) - {"duration_s"} == set(LEGACY_KEYS)
    assert from_header(new) == from_header({"config": old_config}) == s
    # an old log without the keys (or with only some) gets the defaults for the rest
    assert from_header({"config": {"duration_s": 600.0}}) == TrnSettings()
    assert from_header({"config": {"trn_method": "tercom"}}).fix_interval_s == 10.0


def test_the_scenario_config_refuses_the_navigators_settings():
    for key in LEGACY_KEYS:
        with pytest.raises(TypeError):
            FlightConfig(**{key: None})


def test_the_navigator_refuses_settings_of_another_type():
    """A method name where the settings belong is a clear error, before any engine work."""
    from navgate.systems.ins_trn.ps.navigator import Navigator

    with pytest.raises(ValueError, match="trn must be TrnSettings, got str"):
        Navigator(None, None, t0=0.0, trn="tercom")
