"""FixedMul gateware == navgate.numerics.fixed (fixed_mul_full / fixed_mul_trunc), bit for bit.

Directed edge cases (zero, +-1 LSB, +-1.0, full scale, min * min, products just inside and
just outside the range) plus 20,000 seeded random vectors, in Amaranth's simulator with
random gaps/stalls and, with the same vectors, in Verilator through cocotb.
"""

from __future__ import annotations

import numpy as np
import pytest

from navgate.gateware.fixed import FixedMul
from navgate.gateware.verify import simulate, verify
from navgate.numerics.fixed import QFormat, fixed_mul_full, fixed_mul_trunc

N_RANDOM = 20_000


def edges(width: int, frac: int) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
    one = 1 << frac if frac < width - 1 else hi
    root = int(round((hi << frac) ** 0.5))  # root * root ~ the top of the range
    vals = [0, 1, -1, one, -one, hi, lo, root, -root, root + 1, -(root + 1), 2, -2, hi - 1]
    a, b = np.meshgrid(np.array(vals, dtype=np.int64), np.array(vals, dtype=np.int64))
    a, b = a.ravel(), b.ravel()
    keep = (a >= lo) & (a <= hi) & (b >= lo) & (b <= hi)
    return a[keep], b[keep]


def vectors(width: int, frac: int, seed: int, count: int = N_RANDOM) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    ea, eb = edges(width, frac)
    lo, hi = -(1 << (width - 1)), 1 << (width - 1)
    a = rng.integers(lo, hi, count)
    b = rng.integers(lo, hi, count)
    # a third of the vectors with operands near 1.0 (products mostly in range)
    third = count // 3
    span = 1 << min(frac + 1, width - 1)
    a[:third] = rng.integers(-span, span, third)
    b[:third] = rng.integers(-span, span, third)
    return {"a": np.concatenate([ea, a]), "b": np.concatenate([eb, b])}


def model_for(dut: FixedMul):
    fmt = QFormat(dut.width, dut.frac)

    def model(v):
        trunc, over = fixed_mul_trunc(v["a"], v["b"], fmt, mode="wrap")
        sat, over_sat = fixed_mul_trunc(v["a"], v["b"], fmt, mode="saturate")
        assert np.array_equal(over, over_sat)
        return {"full": fixed_mul_full(v["a"], v["b"], fmt), "trunc": trunc, "sat": sat,
                "overflow": over.astype(np.int64)}
    return model


CONFIGS = {"q20_10": (20, 10), "q16_15": (16, 15), "q8_0": (8, 0), "q12_14": (12, 14)}


@pytest.mark.parametrize("name", list(CONFIGS))
def test_fixed_mul_matches_model_amaranth(name):
    width, frac = CONFIGS[name]
    dut = FixedMul(width, frac)
    count = N_RANDOM if name == "q20_10" else 3000
    v = vectors(width, frac, seed=21, count=count)
    result = verify(dut, model_for(dut), v, seed=4, valid_prob=0.8, ready_prob=0.7)
    result.assert_ok()
    assert result.latency == dut.LATENCY == 3


def test_fixed_mul_matches_model_verilator(tmp_path):
    dut = FixedMul()
    v = vectors(20, 10, seed=21)
    result = verify(dut, model_for(dut), v, backend="verilator", seed=4, valid_prob=0.8,
                    ready_prob=0.7, work_dir=tmp_path)
    result.assert_ok()
    assert result.n_vectors >= N_RANDOM


def test_fixed_mul_known_values():
    """Hand-computed Q(20, 10) products: 1.5 * -2.25 = -3.375; min * min overflows."""
    dut = FixedMul()
    a = np.array([1536, -(1 << 19), 3, -3], dtype=np.int64)
    b = np.array([-2304, -(1 << 19), 1, 1], dtype=np.int64)
    got, _ = simulate(dut, {"a": a, "b": b})
    assert got["sat"][0] == -3456 and got["trunc"][0] == -3456 and got["overflow"][0] == 0
    assert got["full"][1] == 1 << 38 and got["overflow"][1] == 1
    assert got["sat"][1] == (1 << 19) - 1  # saturated to max
    assert got["trunc"][1] == 0  # 2**28 wraps to 0 in 20 bits
    assert got["sat"][2] == 0 and got["sat"][3] == -1  # floor: 3/1024 -> 0, -3/1024 -> -1


def test_full_rate_cycle_count():
    dut = FixedMul()
    n = 100
    _, run = simulate(dut, {"a": np.arange(n), "b": np.arange(n)})
    assert run.cycles == n + dut.LATENCY
