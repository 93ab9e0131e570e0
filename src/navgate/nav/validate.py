"""Argument guards for navgate's public entry points (issue 17; integer words: issue 31).

Each guard raises ``ValueError`` whose message starts with the argument's name, so that a
caller sees which argument is wrong (``q0: quaternion norm is 0, expected 1``) instead of a
ZeroDivisionError or a NaN several steps later. They are called where a value enters a
filter: constructors, ``run_*`` wrappers, measurement updates.

Tolerances: a quaternion is "unit" when | |q| - 1 | <= 1e-6 (far above float64 rounding of a
normalised quaternion, 4 ulp ~ 1e-15, and far below any real attitude error); a covariance
is symmetric when |P - P^T| <= 1e-9 max|P| and positive semi-definite when its smallest
eigenvalue is >= -1e-9 max|P| (rounding of a Joseph-form update stays far inside both).
"""

from __future__ import annotations

import math

import numpy as np

QUAT_NORM_TOL = 1e-6
COV_REL_TOL = 1e-9


def finite_array(name: str, value, shape: tuple | None = None) -> np.ndarray:
    """A float64 array with no NaN/inf (and the given shape, -1 = any length)."""
    a = np.asarray(value, dtype=np.float64)
    if shape is not None and (a.ndim != len(shape) or any(
            s != -1 and s != d for s, d in zip(shape, a.shape, strict=True))):
        want = " x ".join("N" if s == -1 else str(s) for s in shape)
        raise ValueError(f"{name}: expected a {want} array, got shape {a.shape}")
    bad = ~np.isfinite(a)
    if bad.any():
        idx = np.argwhere(bad)[0]
        where = f" at index {tuple(int(i) for i in idx)}" if a.ndim else ""
        raise ValueError(f"{name}: non-finite value{where} ({a[tuple(idx)]})")
    return a


def finite_scalar(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"{name}: must be finite, got {v}")
    return v


def positive(name: str, value) -> float:
    """A finite number > 0 (rates, periods)."""
    v = finite_scalar(name, value)
    if not v > 0:
        raise ValueError(f"{name}: must be positive, got {v:g}")
    return v


def non_negative(name: str, value) -> float:
    """A finite number >= 0 (sigmas, gains)."""
    v = finite_scalar(name, value)
    if v < 0:
        raise ValueError(f"{name}: must be non-negative, got {v:g}")
    return v


def unit_quaternion(name: str, value) -> np.ndarray:
    """A finite 4-vector of norm 1 (to :data:`QUAT_NORM_TOL`)."""
    q = finite_array(name, value, (4,))
    n = float(np.sqrt(q @ q))
    if abs(n - 1.0) > QUAT_NORM_TOL:
        raise ValueError(f"{name}: quaternion norm is {n:.9g}, expected 1 (normalise it)")
    return q


def latitude_rad(name: str, value) -> np.ndarray | float:
    """Latitude(s) in radians within [-pi/2, pi/2]."""
    a = finite_array(name, value)
    if (np.abs(a) > math.pi / 2).any():
        worst = float(np.max(np.abs(a)))
        raise ValueError(f"{name}: latitude {math.degrees(worst):.6g} deg is beyond 90 deg "
                         "(radians expected)")
    return a if a.ndim else float(a)


def covariance(name: str, value, n: int | None = None) -> np.ndarray:
    """A finite, symmetric, positive semi-definite n x n matrix."""
    p = finite_array(name, value)
    if p.ndim != 2 or p.shape[0] != p.shape[1] or (n is not None and p.shape[0] != n):
        want = f"{n} x {n}" if n is not None else "square"
        raise ValueError(f"{name}: expected a {want} covariance, got shape {p.shape}")
    scale = float(np.max(np.abs(p))) if p.size else 0.0
    tol = COV_REL_TOL * max(scale, np.finfo(float).tiny)
    asym = float(np.max(np.abs(p - p.T))) if p.size else 0.0
    if asym > tol:
        raise ValueError(f"{name}: covariance is not symmetric (|P - P^T| = {asym:.3g})")
    if p.shape[0] == 1:
        lam = float(p[0, 0])
    elif p.shape[0] == 2:
        # closed form (a measurement update's R is 1 x 1 or 2 x 2: no LAPACK call per update)
        a, b, c = float(p[0, 0]), 0.5 * float(p[0, 1] + p[1, 0]), float(p[1, 1])
        lam = 0.5 * (a + c) - math.hypot(0.5 * (a - c), b)
    else:
        lam = float(np.linalg.eigvalsh(0.5 * (p + p.T))[0]) if p.size else 0.0
    if lam < -tol:
        raise ValueError(f"{name}: covariance is not positive semi-definite (smallest "
                         f"eigenvalue {lam:.3g})")
    return p


def probability(name: str, value, *, open_low: bool = True, open_high: bool = True) -> float:
    """A probability in (0, 1) (ends included when ``open_low``/``open_high`` are False):
    a chi-square gate at probability 1 is infinite, at 0 it rejects everything."""
    p = finite_scalar(name, value)
    low_ok = p > 0 if open_low else p >= 0
    high_ok = p < 1 if open_high else p <= 1
    if not (low_ok and high_ok):
        lo = "(0" if open_low else "[0"
        hi = "1)" if open_high else "1]"
        raise ValueError(f"{name}: must be a probability in {lo}, {hi}, got {p:g}")
    return p


def positive_int(name: str, value, minimum: int = 1) -> int:
    """An integer >= ``minimum`` (window lengths, sample counts); 2.0 is accepted, 2.5 not."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected an integer, got {value!r}") from None
    if not math.isfinite(v) or v != int(v):
        raise ValueError(f"{name}: expected an integer, got {value!r}")
    if int(v) < minimum:
        raise ValueError(f"{name}: must be at least {minimum}, got {int(v)}")
    return int(v)


def in_range(name: str, value, low: float, high: float, unit: str = "") -> float:
    """A finite number in [low, high]."""
    v = finite_scalar(name, value)
    if not low <= v <= high:
        raise ValueError(f"{name}: {v:g}{unit} is outside [{low:g}, {high:g}]{unit}")
    return v


#: The NED mechanization is singular at the poles (longitude rate v_E / ((R_E + h) cos lat),
#: transport rate v_E tan(lat) / (R_E + h)): a navigation latitude must stay this far from
#: them. At 89.9 deg, 300 m/s east turns the frame at 0.027 rad/s, 7e-5 rad per 400 Hz step,
#: still a small-angle step; at the pole itself the terms divide by zero.
POLE_MARGIN_DEG = 0.1

#: Heights a navigation state may hold (m above the WGS84 ellipsoid): from below the deepest
#: ocean trench (-11 km, with margin) to the top of the atmosphere (the normal-gravity series
#: of navgate.nav.earth is a second-order expansion in h / a meant for flight, not orbit).
HEIGHT_RANGE_M = (-20_000.0, 100_000.0)


def nav_latitude(name: str, value) -> float:
    """A latitude (rad) a local-level NED mechanization can use: |lat| <= 90 - 0.1 deg."""
    lat = latitude_rad(name, value)
    limit = math.radians(90.0 - POLE_MARGIN_DEG)
    if np.any(np.abs(lat) > limit):
        raise ValueError(f"{name}: latitude {math.degrees(float(np.max(np.abs(lat)))):.6g} deg "
                         f"is within {POLE_MARGIN_DEG} deg of a pole, where the NED "
                         "mechanization is singular")
    return lat


def height_m(name: str, value) -> float:
    """A height above the ellipsoid (m) in :data:`HEIGHT_RANGE_M`."""
    return in_range(name, value, *HEIGHT_RANGE_M, unit=" m")


# -- integer (fixed-point) words: the bit-true models of seeds 001 and 004 ---------------------


def word_range(bits: int, signed: bool = True) -> tuple[int, int]:
    """The values a ``bits``-bit register holds: [-2^(bits-1), 2^(bits-1) - 1] signed,
    [0, 2^bits - 1] unsigned."""
    return (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)


def integer(name: str, value, low: int | None = None, high: int | None = None) -> int:
    """An integer in [low, high] (either end open when None). A float is accepted only when it
    is integral (2.0, not 2.5); a bool, a string, NaN or inf is a ValueError naming ``name``."""
    if isinstance(value, (bool, np.bool_)) or isinstance(value, (str, bytes)):
        raise ValueError(f"{name}: expected an integer, got {value!r}")
    if isinstance(value, (int, np.integer)):
        v = int(value)
    else:
        try:
            f = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"{name}: expected an integer, got {value!r}") from None
        if not math.isfinite(f) or f != int(f):
            raise ValueError(f"{name}: expected an integer, got {value!r}")
        v = int(f)
    if (low is not None and v < low) or (high is not None and v > high):
        lo = "-inf" if low is None else str(low)
        hi = "inf" if high is None else str(high)
        raise ValueError(f"{name}: {v} is outside [{lo}, {hi}]")
    return v


def int_words(name: str, value, bits: int, signed: bool = True,
              shape: tuple | None = None) -> np.ndarray:
    """Raw ``bits``-bit register words as an int64 array: every value an integer (integral
    floats accepted) inside the word's range (:func:`word_range`). NaN, inf, a fraction or a
    value the register cannot hold is a ValueError naming ``name`` and the first bad index;
    ``shape`` as in :func:`finite_array`."""
    lo, hi = word_range(bits, signed)
    a = np.asarray(value)
    if a.dtype == np.bool_ or not (np.issubdtype(a.dtype, np.integer)
                                   or np.issubdtype(a.dtype, np.floating)):
        raise ValueError(f"{name}: expected integer words, got {a.dtype} values")
    if shape is not None and (a.ndim != len(shape) or any(
            s != -1 and s != d for s, d in zip(shape, a.shape, strict=True))):
        want = " x ".join("N" if s == -1 else str(s) for s in shape)
        raise ValueError(f"{name}: expected a {want} array, got shape {a.shape}")
    if np.issubdtype(a.dtype, np.floating):
        f = a.astype(np.float64)
        bad = ~np.isfinite(f) | (f != np.floor(np.where(np.isfinite(f), f, 0.0)))
        if bad.any():
            idx = tuple(int(i) for i in np.argwhere(bad)[0])
            where = f" at index {idx}" if a.ndim else ""
            raise ValueError(f"{name}: expected integer words, got {f[idx].item()!r}{where}")
        out_of = (f < lo) | (f > hi)
    elif a.dtype == np.uint64:
        out_of = a > np.uint64(hi) if hi >= 0 else np.ones(a.shape, bool)
    else:
        out_of = (a < lo) | (a > hi)
    if np.any(out_of):
        idx = tuple(int(i) for i in np.argwhere(out_of)[0])
        where = f" at index {idx}" if a.ndim else ""
        raise ValueError(f"{name}: {a[idx].item()!r}{where} does not fit a {bits}-bit "
                         f"{'signed' if signed else 'unsigned'} word [{lo}, {hi}]")
    return a.astype(np.int64)


def flag(name: str, value) -> bool:
    """A yes/no parameter: a bool (or the integers 0 and 1), never a string such as "no"."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)) and int(value) in (0, 1):
        return bool(value)
    raise ValueError(f"{name}: expected True or False, got {value!r}")
