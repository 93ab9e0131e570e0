"""CORDIC gateware == bit-true model (navgate.numerics.cordic), bit for bit.

Every core gets directed edge cases (axes, quadrant boundaries, diagonals, the zero vector,
full-scale corners, negative full scale) plus 20,000 seeded random vectors, streamed with
random input gaps and output stalls, in Amaranth's simulator and (the same vectors) in
Verilator through cocotb. Cycle counts are exact: LATENCY from the handshake, and the
cycles of a full-rate run follow from LATENCY and THROUGHPUT.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from amaranth.hdl import Fragment

from navgate.gateware.cordic import CordicAtan2, CordicAtan2Iterative, CordicSinCos
from navgate.gateware.verify import simulate, verify
from navgate.numerics.cordic import (
    angle_to_radians,
    cordic_error_bound,
    cordic_rotation,
    cordic_rotation_error_bound,
    cordic_vectoring,
)

N_RANDOM = 20_000


def vectoring_edges(width: int) -> tuple[np.ndarray, np.ndarray]:
    lo, hi = -(1 << (width - 1)), (1 << (width - 1)) - 1
    pts = [
        (0, 0),  # zero vector (model: magnitude 0, angle sum(T))
        (hi, 0), (lo, 0), (0, hi), (0, lo),  # axes, negative full scale
        (1, 0), (-1, 0), (0, 1), (0, -1), (-1, -1), (1, 1), (-1, 1), (1, -1),
        (hi, hi), (lo, lo), (lo, hi), (hi, lo),  # full-scale corners (max magnitude)
        (lo, -1), (lo, 1), (-1, lo), (1, lo), (-1, hi), (lo + 1, lo),  # boundaries
        (-5, 0), (-5, -1), (-5, 1), (0, -5), (0, 5),  # left half-plane x-axis, y axis
        (1000 % hi, -(1000 % hi)), (-(777 % hi), 777 % hi),  # diagonals
    ]
    x, y = zip(*pts, strict=True)
    return np.array(x, dtype=np.int64), np.array(y, dtype=np.int64)


def vectoring_vectors(width: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    ex, ey = vectoring_edges(width)
    lo, hi = -(1 << (width - 1)), 1 << (width - 1)
    x = rng.integers(lo, hi, N_RANDOM)
    y = rng.integers(lo, hi, N_RANDOM)
    # a quarter of the vectors are short (|x|, |y| < 16): truncation dominates there
    short = N_RANDOM // 4
    x[:short] = rng.integers(-16, 16, short)
    y[:short] = rng.integers(-16, 16, short)
    return {"x": np.concatenate([ex, x]), "y": np.concatenate([ey, y])}


def vectoring_model(dut):
    def model(v):
        mag, ang = cordic_vectoring(v["x"], v["y"], dut.width, dut.iterations, dut.angle_bits,
                                    dut.guard_bits, dut.compensate, dut.gain_frac_bits)
        return {"magnitude": mag, "angle": ang}
    return model


def rotation_vectors(angle_bits: int, seed: int) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    half, quarter = 1 << (angle_bits - 1), 1 << (angle_bits - 2)
    edges = [0, 1, -1, quarter, quarter + 1, quarter - 1, -quarter, -quarter - 1,
             -quarter + 1, half - 1, -half, -half + 1, quarter // 2, -quarter // 2,
             3 * quarter // 2, -3 * quarter // 2]
    a = rng.integers(-half, half, N_RANDOM)
    return {"angle": np.concatenate([np.array(edges, dtype=np.int64), a])}


def rotation_model(dut):
    def model(v):
        c, s = cordic_rotation(v["angle"], dut.width, dut.iterations, dut.angle_bits,
                               dut.guard_bits)
        return {"cos": c, "sin": s}
    return model


VECTORING = {
    "atan2": lambda: CordicAtan2(),
    "atan2_compensated": lambda: CordicAtan2(compensate=True),
    "atan2_g0_w12_n10": lambda: CordicAtan2(width=12, iterations=10, guard_bits=0),
    "atan2_iter": lambda: CordicAtan2Iterative(),
    "atan2_iter_comp_w12": lambda: CordicAtan2Iterative(width=12, iterations=11,
                                                        compensate=True, guard_bits=2),
}
# the smaller variants run fewer vectors in the simulator (configuration coverage)
REDUCED = {"atan2_g0_w12_n10": 4000, "atan2_iter_comp_w12": 2000}


@pytest.mark.parametrize("name", list(VECTORING))
def test_vectoring_matches_model_amaranth(name):
    dut = VECTORING[name]()
    vectors = vectoring_vectors(dut.width, seed=11)
    if name in REDUCED:
        vectors = {k: v[: REDUCED[name]] for k, v in vectors.items()}
    result = verify(dut, vectoring_model(dut), vectors, seed=5, valid_prob=0.8, ready_prob=0.7)
    result.assert_ok()
    assert result.n_vectors == len(vectors["x"])
    assert result.latency == dut.LATENCY


@pytest.mark.parametrize("name", ["atan2", "atan2_iter"])
def test_vectoring_matches_model_verilator(name, tmp_path):
    dut = VECTORING[name]()
    vectors = vectoring_vectors(dut.width, seed=11)
    result = verify(dut, vectoring_model(dut), vectors, backend="verilator", seed=5,
                    valid_prob=0.8, ready_prob=0.7, work_dir=tmp_path)
    result.assert_ok()
    assert result.n_vectors == len(vectors["x"]) >= N_RANDOM
    assert result.latency == dut.LATENCY


def test_sincos_matches_model_amaranth():
    dut = CordicSinCos()
    vectors = rotation_vectors(dut.angle_bits, seed=12)
    result = verify(dut, rotation_model(dut), vectors, seed=6, valid_prob=0.8, ready_prob=0.7)
    result.assert_ok()
    assert result.latency == dut.LATENCY == 17


def test_sincos_small_config_matches_model_amaranth():
    dut = CordicSinCos(width=10, iterations=9, angle_bits=12, guard_bits=0)
    vectors = {"angle": rotation_vectors(12, seed=13)["angle"][:4000]}
    verify(dut, rotation_model(dut), vectors, seed=7, valid_prob=0.9, ready_prob=0.5).assert_ok()


def test_sincos_matches_model_verilator(tmp_path):
    dut = CordicSinCos()
    vectors = rotation_vectors(dut.angle_bits, seed=12)
    result = verify(dut, rotation_model(dut), vectors, backend="verilator", seed=6,
                    valid_prob=0.8, ready_prob=0.7, work_dir=tmp_path)
    result.assert_ok()
    assert result.n_vectors >= N_RANDOM


def test_default_atan2_directed_values_are_atan2():
    """Gateware outputs on the axes and corners are the true angles within the model's
    derived worst-case bound (cordic_error_bound, magnitude >= 2**(width-2))."""
    dut = CordicAtan2()
    w = dut.width
    lo, hi = -(1 << (w - 1)), (1 << (w - 1)) - 1
    x = np.array([hi, lo, 0, 0, hi, lo, lo, hi, lo], dtype=np.int64)
    y = np.array([0, 0, hi, lo, hi, lo, hi, lo, -1], dtype=np.int64)
    got, _ = simulate(dut, {"x": x, "y": y})
    bound = cordic_error_bound(w, dut.iterations, dut.angle_bits, dut.guard_bits)
    true = np.arctan2(y.astype(float), x.astype(float))
    err = angle_to_radians(got["angle"], dut.angle_bits) - true
    err = (err + math.pi) % (2 * math.pi) - math.pi  # +180 deg is -32768
    assert np.all(np.abs(err) <= bound)
    assert got["angle"][1] == -(1 << 15)  # (-full scale, 0): exactly 180 deg
    assert got["angle"][2] == 1 << 14 and got["angle"][3] == -(1 << 14)  # +-90 deg exactly


def test_sincos_axes_within_derived_bound():
    """0, +90, 180 and -90 deg (through the quadrant fold) give cos/sin of 0 or +-1.0 within
    the model's derived worst-case bound cordic_rotation_error_bound (output LSBs)."""
    dut = CordicSinCos()
    a = np.array([0, 1 << 14, -(1 << 15), -(1 << 14), (1 << 14) + 1], dtype=np.int64)
    got, _ = simulate(dut, {"angle": a})
    one = 1 << (dut.width - 2)
    bound = cordic_rotation_error_bound(dut.width, dut.iterations, dut.angle_bits,
                                        dut.guard_bits)
    rad = angle_to_radians(a, dut.angle_bits)
    assert np.all(np.abs(got["cos"] - one * np.cos(rad)) <= bound)
    assert np.all(np.abs(got["sin"] - one * np.sin(rad)) <= bound)
    assert got["cos"][2] < -one // 2 and got["sin"][1] > one // 2  # quadrants right


@pytest.mark.parametrize("factory", [CordicAtan2, CordicAtan2Iterative, CordicSinCos])
def test_full_rate_cycle_count(factory):
    """With input always valid and output always ready, n results take exactly
    (n - 1) / THROUGHPUT + LATENCY + 1 cycles (the harness counts the last cycle)."""
    dut = factory()
    n = 64
    rng = np.random.default_rng(3)
    if factory is CordicSinCos:
        inputs = {"angle": rng.integers(-(1 << 15), 1 << 15, n)}
    else:
        inputs = {"x": rng.integers(-(1 << 15), 1 << 15, n),
                  "y": rng.integers(-(1 << 15), 1 << 15, n)}
    _, run = simulate(dut, inputs)
    interval = int(1 / dut.THROUGHPUT)
    assert run.cycles == (n - 1) * interval + dut.LATENCY + 1
    assert run.latency == dut.LATENCY


def test_iterative_documented_figures():
    dut = CordicAtan2Iterative(iterations=12)
    Fragment.get(dut, None)  # elaborates
    assert dut.LATENCY == 13
    assert dut.THROUGHPUT == pytest.approx(1 / 12)


@pytest.mark.parametrize("kwargs", [dict(width=1), dict(iterations=0), dict(angle_bits=3),
                                    dict(guard_bits=17)])
def test_bad_parameters_rejected(kwargs):
    with pytest.raises(ValueError):
        CordicAtan2(**kwargs)
