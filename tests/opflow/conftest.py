"""Shared data of the loop-nest tests: a sparse pattern and random or special-value memories."""

from types import SimpleNamespace

import numpy as np
import pytest

#: float32 values that exercise the units' special cases: signed zeros, infinities, NaN,
#: the largest finite, the smallest normal and a subnormal (flushed), products that overflow
#: or underflow
SPECIAL = np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 3.4028235e38, -3.4028235e38,
                    1.1754944e-38, -1.1754944e-38, 1e-40, 1.0, -1.0, 1e20, 1e-20, 65504.0,
                    2.0**-64], np.float64)


def memories(nest, rng, special=False):
    """Every array of ``nest``: random float32 over ten decades, or drawn from SPECIAL;
    subnormals flushed (memory words are flushed on the way in, as run_nest does)."""
    out = {}
    for name, words in nest.arrays.items():
        v = rng.standard_normal(words) * np.exp(rng.uniform(-5, 5, words))
        if special:
            v = rng.choice(SPECIAL, words)
        v = v.astype(np.float32).astype(np.float64)
        v[np.abs(v) < 2.0**-126] *= 0.0
        out[name] = v
    return out


@pytest.fixture
def loop_data():
    return SimpleNamespace(rows=[0, 0, 2, 2, 2, 3, 5, 5], cols=[1, 4, 0, 2, 3, 4, 0, 5],
                           memories=memories)
