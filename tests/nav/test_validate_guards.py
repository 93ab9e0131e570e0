"""The range guards of navgate.nav.validate: probabilities, integer windows, ranges, the
navigation latitude (pole margin) and height range, and the closed-form 2 x 2 covariance
test (measurement updates call it once per fix, without LAPACK)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navgate.nav import validate

NAN = float("nan")


def raises_naming(name, fn, *args, **kwargs):
    with pytest.raises(ValueError) as info:
        fn(*args, **kwargs)
    assert str(info.value).startswith(name), str(info.value)
    return str(info.value)


@pytest.mark.parametrize("p", [0.0, 1.0, -0.5, 1.5, NAN, "x"])
def test_probability_open_interval(p):
    raises_naming("probability", validate.probability, "probability", p)


def test_probability_closed_ends_when_asked():
    assert validate.probability("f", 0.0, open_low=False) == 0.0
    assert validate.probability("f", 1.0, open_high=False) == 1.0
    raises_naming("f", validate.probability, "f", 1.0 + 1e-12, open_high=False)


@pytest.mark.parametrize("v", [0, -3, 2.5, NAN, math.inf, "six", None])
def test_positive_int(v):
    raises_naming("window", validate.positive_int, "window", v)


def test_positive_int_accepts_integral_floats_and_minimum():
    assert validate.positive_int("window", 6.0) == 6
    raises_naming("depth", validate.positive_int, "depth", 1, minimum=2)


def test_nav_latitude_margin():
    edge = math.radians(90.0 - validate.POLE_MARGIN_DEG)
    assert validate.nav_latitude("lat", edge) == edge
    raises_naming("lat", validate.nav_latitude, "lat", math.nextafter(edge, 2.0))
    raises_naming("lat", validate.nav_latitude, "lat", -math.pi / 2)


def test_height_range():
    lo, hi = validate.HEIGHT_RANGE_M
    assert validate.height_m("h", lo) == lo and validate.height_m("h", hi) == hi
    raises_naming("h", validate.height_m, "h", -7e6)
    raises_naming("h", validate.height_m, "h", NAN)


@pytest.mark.parametrize("seed", range(5))
def test_two_by_two_closed_form_agrees_with_eigvalsh(seed):
    """The closed-form smallest eigenvalue decides as LAPACK does, on matrices either side of
    the PSD boundary: A A' (PSD) shifted by -/+ 1e-6 of its scale."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(2, 2))
    p = a @ a.T
    lam = np.linalg.eigvalsh(p)[0]
    scale = np.abs(p).max()
    validate.covariance("R", p - (lam - 1e-6 * scale) * np.eye(2) + 1e-6 * scale * np.eye(2))
    raises_naming("R", validate.covariance, "R", p - (lam + 1e-6 * scale) * np.eye(2))


@pytest.mark.parametrize("name, args", [("lat0", (math.pi / 2, 0.0)),
                                        ("lat0", (-math.pi / 2, 0.0)),
                                        ("h0", (0.8, 0.1, -7e6))])
def test_local_tangent_refuses_a_pole_and_absurd_heights(name, args):
    from navgate.nav.earth import LocalTangent

    # at a pole m_per_rad_lon is 0: to_geodetic would divide by it
    raises_naming(name, LocalTangent, *args)
