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


# -- integer words (issue 31: the bit-true models of seeds 001 and 004) -----------------------


@pytest.mark.parametrize("bits, signed, lo, hi", [(16, True, -32768, 32767), (1, False, 0, 1),
                                                  (20, True, -524288, 524287)])
def test_word_range_and_its_ends(bits, signed, lo, hi):
    assert validate.word_range(bits, signed) == (lo, hi)
    assert validate.int_words("w", [lo, hi], bits, signed).tolist() == [lo, hi]
    for v in (lo - 1, hi + 1):
        msg = raises_naming("w", validate.int_words, "w", [0, v], bits, signed)
        assert "index (1,)" in msg and f"{bits}-bit" in msg


@pytest.mark.parametrize("v", [NAN, math.inf, 1.5, -0.25, "x", True, [1, None]])
def test_int_words_refuse_what_a_register_cannot_hold(v):
    raises_naming("ax", validate.int_words, "ax", v, 16)


def test_int_words_accept_integral_floats_as_int64():
    a = validate.int_words("ax", np.array([1.0, -2.0, 32767.0]), 16)
    assert a.dtype == np.int64 and a.tolist() == [1, -2, 32767]
    raises_naming("ax", validate.int_words, "ax", np.zeros((2, 3)), 16, shape=(-1, 7))
    # unsigned 64-bit input beyond int64 is out of range, not wrapped to a negative number
    raises_naming("w", validate.int_words, "w", np.array([2**63], np.uint64), 16)


@pytest.mark.parametrize("v", [2.5, NAN, math.inf, "3", True, None, -1, 16])
def test_integer_in_range(v):
    raises_naming("k_shift", validate.integer, "k_shift", v, 0, 15)


def test_integer_accepts_numpy_and_integral_float():
    assert validate.integer("n", np.int32(7), 0) == 7
    assert validate.integer("n", 7.0, 0, 7) == 7


@pytest.mark.parametrize("v", ["no", "False", 2, -1, 0.5, None])
def test_flag_refuses_truthy_strings_and_numbers(v):
    raises_naming("held_input", validate.flag, "held_input", v)


def test_flag_accepts_bools_and_0_1():
    assert validate.flag("f", np.bool_(True)) is True
    assert validate.flag("f", 0) is False and validate.flag("f", 1) is True
