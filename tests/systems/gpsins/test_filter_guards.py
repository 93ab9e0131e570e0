"""The GPS/INS filter's guard: a GPS update refuses a covariance that is not one (a
negative-definite P, an indefinite P whose innovation covariance is not positive definite),
for the 9-state filter and the augmented filter's 15 states (one update serves both), with a
ValueError naming P, and leaves P as it was."""

from __future__ import annotations

import numpy as np
import pytest

from navgate.systems.gpsins import filter as gf

X = np.array([0.6, -1.4, 300.0, 50.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
FIX = np.array([0.6 + 1e-6, -1.4, 305.0])
SIGMA = np.array([3.0, 3.0, 5.0])


def covariances(n):
    neg = -np.eye(n)  # negative definite
    indef = np.eye(n)
    # positive diagonal, indefinite: the north/east position block [[1, 2], [2, 1]]
    indef[0, 0], indef[1, 1] = 1e-12, 1e-12
    indef[0, 1] = indef[1, 0] = 1e-11
    nan = np.eye(n)
    nan[4, 4] = np.nan
    return {"negative definite": neg, "indefinite": indef, "nan variance": nan}


@pytest.mark.parametrize("update, n", [(gf.gps_update, gf.NX), (gf.gps_update, 15)],
                         ids=["filter", "augmented (15 states)"])
@pytest.mark.parametrize("case", ["negative definite", "indefinite", "nan variance"])
def test_gps_update_refuses_a_non_covariance(update, n, case):
    p = covariances(n)[case]
    p0 = p.copy()
    with pytest.raises(ValueError) as info:
        update(p, X.copy(), FIX, SIGMA)
    assert str(info.value).startswith("P"), str(info.value)
    np.testing.assert_array_equal(p, p0)


def test_indefinite_case_passes_the_diagonal_test():
    """The indefinite P has a positive diagonal: only the S test (Sylvester) catches it."""
    p = covariances(gf.NX)["indefinite"]
    assert (np.diag(p) > 0).all() and np.linalg.eigvalsh(p)[0] < 0


def test_sound_update_unchanged():
    p = np.eye(gf.NX) * 1e-10
    p[2, 2] = 100.0
    dx, z, s = gf.gps_update(p, X.copy(), FIX, SIGMA)
    assert np.all(np.linalg.eigvalsh(s) > 0)
    assert z[2] == pytest.approx(-5.0)
