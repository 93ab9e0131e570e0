"""Goldschmidt divider/reciprocal gateware == navgate.numerics.goldschmidt, bit for bit.

Directed cases (division by zero with every numerator sign, 0/0, 0/x, +-1, +-full scale,
powers of two, quotients just inside and outside the range) plus 20,000 seeded random
vectors per core (a quarter with a small divisor, so that overflow and saturation are
exercised), in Amaranth's simulator with random gaps/stalls and in Verilator via cocotb.
"""

from __future__ import annotations

import numpy as np
import pytest

from navgate.gateware.goldschmidt import GoldschmidtDivider, GoldschmidtReciprocal
from navgate.gateware.verify import simulate, verify
from navgate.numerics.goldschmidt import goldschmidt_divide, goldschmidt_reciprocal

N_RANDOM = 20_000


def special_values(width: int) -> list[int]:
    lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
    pows = [1 << k for k in range(width - 1)]
    return sorted({0, 1, -1, 2, -2, 3, -3, hi, lo, hi - 1, lo + 1, *pows, *(-p for p in pows)})


def division_vectors(width: int, seed: int, count: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    s = np.array(special_values(width), dtype=np.int64)
    en, ed = (g.ravel() for g in np.meshgrid(s, s))
    lo, hi = -(1 << (width - 1)), 1 << (width - 1)
    n = rng.integers(lo, hi, count)
    d = rng.integers(lo, hi, count)
    small = count // 4
    d[:small] = rng.integers(-64, 65, small)
    return {"n": np.concatenate([en, n]), "d": np.concatenate([ed, d])}


def _params(dut) -> dict:
    return dict(width=dut.width, frac=dut.frac, iterations=dut.iterations,
                seed_bits=dut.seed_bits, internal_frac=dut.internal_frac, seed=dut.seed,
                rounding=dut.rounding)


def divide_model(dut):
    def model(v):
        q, flags = goldschmidt_divide(v["n"], v["d"], **_params(dut))
        return {"q": q, "divide_by_zero": flags["divide_by_zero"].astype(np.int64),
                "overflow": flags["overflow"].astype(np.int64)}
    return model


def reciprocal_model(dut):
    def model(v):
        q, flags = goldschmidt_reciprocal(v["d"], **_params(dut))
        return {"q": q, "divide_by_zero": flags["divide_by_zero"].astype(np.int64),
                "overflow": flags["overflow"].astype(np.int64)}
    return model


CONFIGS = {
    "default": {},
    "truncate": dict(rounding="truncate"),
    "linear_seed": dict(seed="linear", iterations=2),
    "split": dict(split_iterations=True),
    "q16_0_it4": dict(width=16, frac=0, iterations=4, seed_bits=2),
    "q16_0_F18": dict(width=16, frac=0, iterations=4, seed_bits=2, internal_frac=18),
    "q12_12_it0": dict(width=12, frac=12, iterations=0),
    "q8_3_seed0": dict(width=8, frac=3, iterations=1, seed_bits=0),
}


@pytest.mark.parametrize("name", list(CONFIGS))
def test_divider_matches_model_amaranth(name):
    dut = GoldschmidtDivider(**CONFIGS[name])
    count = N_RANDOM if name == "default" else 2000
    v = division_vectors(dut.width, seed=31, count=count)
    result = verify(dut, divide_model(dut), v, seed=8, valid_prob=0.8, ready_prob=0.7)
    result.assert_ok()
    stages_per_iteration = 2 if dut.split_iterations else 1
    assert result.latency == dut.LATENCY == stages_per_iteration * dut.iterations + 5


@pytest.mark.parametrize("name", list(CONFIGS))
def test_reciprocal_matches_model_amaranth(name):
    dut = GoldschmidtReciprocal(**CONFIGS[name])
    count = N_RANDOM if name == "default" else 2000
    v = division_vectors(dut.width, seed=32, count=count)
    result = verify(dut, reciprocal_model(dut), {"d": v["d"]}, seed=9, valid_prob=0.8,
                    ready_prob=0.7)
    result.assert_ok()
    assert result.latency == dut.LATENCY


def test_divider_matches_model_verilator(tmp_path):
    dut = GoldschmidtDivider()
    v = division_vectors(dut.width, seed=31, count=N_RANDOM)
    result = verify(dut, divide_model(dut), v, backend="verilator", seed=8, valid_prob=0.8,
                    ready_prob=0.7, work_dir=tmp_path)
    result.assert_ok()
    assert result.n_vectors >= N_RANDOM


def test_reciprocal_matches_model_verilator(tmp_path):
    dut = GoldschmidtReciprocal()
    v = division_vectors(dut.width, seed=32, count=N_RANDOM)
    result = verify(dut, reciprocal_model(dut), {"d": v["d"]}, backend="verilator", seed=9,
                    valid_prob=0.8, ready_prob=0.7, work_dir=tmp_path)
    result.assert_ok()
    assert result.n_vectors >= N_RANDOM


def test_divider_known_values():
    """Q(20, 10): 3 / 1.5 = 2 exactly; 1 / 0 saturates with the flag; -1 / 0 -> min;
    0 / 0 -> 0; full scale / 2**-10 overflows."""
    dut = GoldschmidtDivider()
    one = 1 << 10
    n = np.array([3 * one, one, -one, 0, (1 << 19) - 1], dtype=np.int64)
    d = np.array([3 * one // 2, 0, 0, 0, 1], dtype=np.int64)
    got, _ = simulate(dut, {"n": n, "d": d})
    assert got["q"].tolist() == [2 * one, (1 << 19) - 1, -(1 << 19), 0, (1 << 19) - 1]
    assert got["divide_by_zero"].tolist() == [0, 1, 1, 1, 0]
    assert got["overflow"].tolist() == [0, 0, 0, 0, 1]


def test_full_rate_cycle_count():
    dut = GoldschmidtDivider()
    n = 100
    rng = np.random.default_rng(2)
    _, run = simulate(dut, {"n": rng.integers(-1000, 1000, n), "d": rng.integers(1, 1000, n)})
    assert run.cycles == n + dut.LATENCY
