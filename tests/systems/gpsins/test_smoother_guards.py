"""The smoother's entry point: ``sweep`` checks its arguments once, before the
backward pass (ValueError naming the argument, never an IndexError half-way or a NaN
solution); ``spd_inverse`` is tested in test_smoother.py."""

from __future__ import annotations

import numpy as np
import pytest

from navgate.systems.gpsins import smoother

N, STEPS, DT = 4, 20, 0.1
P0 = np.eye(N)


def interval(k0, k1, p):
    s = k1 - k0  # as test_smoother.interval_fn: s + 1 covariances, s dynamics matrices
    return np.repeat(p[None], s + 1, axis=0), np.zeros((s, N, N))


def args(**changes):
    a = {"ep_idx": np.array([0, 10, STEPS]), "p_post": np.array([P0] * 3),
         "p_prior": np.array([P0] * 3), "dxs": np.zeros((3, N)), "interval": interval,
         "n_samples": STEPS + 1, "dt": DT}
    a.update(changes)
    return a


@pytest.mark.parametrize("name, change", [
    ("dt", {"dt": 0.0}), ("dt", {"dt": np.nan}),
    ("n_samples", {"n_samples": 0}),
    ("ep_idx", {"ep_idx": np.array([0, 10, 10])}),  # not increasing
    ("ep_idx", {"ep_idx": np.array([0, 10, STEPS + 1])}),  # beyond the samples: IndexError
    ("ep_idx", {"ep_idx": np.array([1, 10, STEPS])}),
    ("ep_idx", {"ep_idx": np.array([0, 10.5, STEPS])}),
    ("p_post", {"p_post": np.array([P0] * 2)}),  # one epoch short
    ("p_post", {"p_post": np.array([P0, P0 * np.nan, P0])}),
    ("p_prior", {"p_prior": np.zeros((3, N, N + 1))}),
    ("dxs", {"dxs": np.full((3, N), np.inf)}),
])
def test_sweep_refuses(name, change):
    with pytest.raises(ValueError) as info:
        smoother.sweep(**args(**change))
    assert str(info.value).startswith(name), str(info.value)


def test_sound_sweep_runs():
    out = smoother.sweep(**args())
    assert len(out) == 1 and out[0].pos_err.shape == (STEPS + 1, 3)
    assert np.all(np.isfinite(out[0].pos_cov))
