"""Seed 000 nav_output_formatter: float64 reference, bit-true model and gateware agree.

* reference (float64) against the seed's DCM and navgate.nav.rotations, directed gimbal-lock
  and wrap cases;
* bit-true model against the reference within the derived bounds (euler_error_bound per
  angle, rotation_error_bound for the rotation) over 20,000 seeded random unit quaternions
  and directed cases (identity, +-90 deg pitch, yaw +-180 deg, non-unit, zero, NaN, inf);
* gateware == bit-true model bit for bit: directed cases plus random vectors, 600 in
  Amaranth's simulator (2,000 under -m slow) and 2,000 in Verilator (20,000 under -m slow),
  exact LATENCY.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from navgate.gateware.verify import verify
from navgate.nav.rotations import euler_to_dcm_array, quat_to_euler
from navgate.numerics.fp32 import QNAN, bits_to_f32, f32_to_bits
from navgate.systems.ins_trn.pl import output_formatter as F

ANGLES = ("roll", "pitch", "yaw")


def euler_quat(roll, pitch, yaw):
    """Hamilton scalar-first quaternion of C_b^n = Rz(yaw) Ry(pitch) Rx(roll) (float64)."""
    a, b, c = yaw / 2, pitch / 2, roll / 2
    ca, sa, cb, sb, cc, sc = (np.cos(a), np.sin(a), np.cos(b), np.sin(b), np.cos(c),
                              np.sin(c))
    return np.stack([ca * cb * cc + sa * sb * sc, ca * cb * sc - sa * sb * cc,
                     ca * sb * cc + sa * cb * sc, sa * cb * cc - ca * sb * sc], axis=-1)


def words_from(q, rng=None):
    """Input words (uint32) for quaternions ``q`` (N, 4); other state words random."""
    q = np.atleast_2d(np.asarray(q, dtype=np.float64))
    n = len(q)
    rng = rng or np.random.default_rng(0)
    w = {}
    for name in F.IN_FIELDS:
        w[name] = f32_to_bits((rng.normal(size=n) * 1000).astype(np.float32))
    for i in range(4):
        w[f"q{i}"] = f32_to_bits(q[:, i].astype(np.float32))
    return w


def values(words):
    return {k: bits_to_f32(v).astype(np.float64) for k, v in words.items()}


def wrapped(a, b):
    d = np.asarray(a, float) - np.asarray(b, float)
    return np.abs((d + np.pi) % (2 * np.pi) - np.pi)


def rotation_angle(roll, pitch, yaw, q):
    """Angle (rad) between C(roll, pitch, yaw) and the rotation of q/|q|."""
    c1 = euler_to_dcm_array(roll, pitch, yaw)
    ref = F.reference_euler(q)
    c2 = euler_to_dcm_array(ref[0], ref[1], ref[2])
    tr = np.einsum("nij,nij->n", c1, c2)  # trace(C1' C2)
    return np.arccos(np.clip((tr - 1) / 2, -1, 1))


# --- reference ---------------------------------------------------------------------------
def test_reference_matches_rotations_module_and_round_trips():
    rng = np.random.default_rng(10)
    roll = rng.uniform(-np.pi, np.pi, 500)
    pitch = rng.uniform(-1.5, 1.5, 500)
    yaw = rng.uniform(-np.pi, np.pi, 500)
    q = euler_quat(roll, pitch, yaw)
    r, p, y, _ = F.reference_euler(q)
    assert np.max(wrapped(r, roll)) < 1e-12
    assert np.max(np.abs(p - pitch)) < 1e-12
    assert np.max(wrapped(y, yaw)) < 1e-12
    for k in range(0, 500, 50):  # the project's rotation module agrees
        assert np.allclose(quat_to_euler(q[k]), (r[k], p[k], y[k]), atol=1e-12)
    # scale and sign of q do not matter
    r2, p2, y2, _ = F.reference_euler(-2.5 * q)
    assert np.max(wrapped(r2, r)) < 1e-12 and np.max(wrapped(y2, y)) < 1e-12


@pytest.mark.parametrize("sign", [1, -1])
def test_reference_gimbal_lock_branch(sign):
    roll, yaw = 0.3, 0.5
    q = euler_quat(np.array([roll]), np.array([sign * np.pi / 2]), np.array([yaw]))
    r, p, y, cos_p = F.reference_euler(q)
    assert cos_p[0] < F.REF_GIMBAL_COS
    assert r[0] == 0.0
    assert abs(p[0] - sign * np.pi / 2) < 1e-7  # asin clamp: no NaN at |c31| >= 1
    # +90: only yaw - roll is defined, -90: yaw + roll
    assert wrapped(y[0], yaw - sign * roll) < 1e-12
    # the rotation is the same
    assert rotation_angle(r, p, y, q)[0] < 1e-7


# --- bit-true model against the reference ---------------------------------------------
def random_unit(n, seed):
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1)[:, None], rng


def check_against_reference(words):
    bt = F.formatter_bittrue(words)
    v = values(words)
    ref = F.reference_format(v)
    q = np.stack([v[f"q{i}"] for i in range(4)], axis=1)
    mp = np.hypot(q[:, 0] - q[:, 2], q[:, 3] + q[:, 1])
    mm = np.hypot(q[:, 0] + q[:, 2], q[:, 3] - q[:, 1])
    got = {a: bits_to_f32(bt[a]).astype(np.float64) for a in ANGLES}
    worst = {a: 0.0 for a in ANGLES}
    for j in range(len(q)):
        ry, pb = F.euler_error_bound(mp[j], mm[j], ref["norm"][j])
        for a, bnd in (("roll", ry), ("pitch", pb), ("yaw", ry)):
            err = wrapped(got[a][j], ref[a][j])
            assert err <= bnd, (j, a, err, bnd, q[j])
            worst[a] = max(worst[a], err / bnd)
    rot = rotation_angle(got["roll"], got["pitch"], got["yaw"], q)
    assert np.max(rot) <= F.rotation_error_bound()
    return bt, ref, worst, rot


def test_bittrue_random_unit_quaternions_within_bound():
    q, rng = random_unit(20_000, 11)
    words = words_from(q, rng)
    bt, ref, worst, rot = check_against_reference(words)
    assert np.all(bt["flags"] == 0) and np.all(ref["flags"] == 0)
    # the bound is tight enough to catch a one-bit-per-step mistake: well under 1e-5 rad
    assert F.euler_error_bound(1.0, 1.0)[0] < 4e-6
    assert F.euler_error_bound(1.0, 1.0)[1] < 5e-6
    assert F.rotation_error_bound() < 2e-5
    # and it is not vacuous: the errors use a fair part of it
    assert max(worst.values()) > 0.05
    # the state words pass through; POS_D = REF_ALT - h is one float32 rounding
    for name, src in F.PASS_THROUGH.items():
        assert np.array_equal(bt[name], words[src])
    exact = ref["pos_d"]
    got = bits_to_f32(bt["pos_d"]).astype(np.float64)
    ulp = np.spacing(np.abs(exact).astype(np.float32)).astype(np.float64)
    assert np.all(np.abs(got - exact) <= 0.5 * ulp)


def test_bittrue_near_gimbal_lock_and_wrap():
    rng = np.random.default_rng(12)
    n = 2000
    roll = rng.uniform(-np.pi, np.pi, n)
    yaw = rng.uniform(-np.pi, np.pi, n)
    sign = np.where(rng.random(n) < 0.5, 1.0, -1.0)
    pitch = sign * (np.pi / 2 - 10.0 ** rng.uniform(-9, -1, n))
    q = euler_quat(roll, pitch, yaw)
    _, _, _, rot = check_against_reference(words_from(q, rng))
    # yaw at +-180 deg: the wrap is taken modulo 2 pi, both sides
    yaw = np.array([np.pi, -np.pi, np.pi - 1e-6, -np.pi + 1e-6, np.pi - 3e-7])
    q = euler_quat(np.zeros(5), np.zeros(5), yaw)
    bt, _, _, _ = check_against_reference(words_from(q))
    got = bits_to_f32(bt["yaw"]).astype(np.float64)
    assert np.all(np.abs(np.abs(got) - np.pi) < 2e-6)
    assert np.all(np.abs(got) <= F.PI_F32)


def test_bittrue_directed_cases():
    cases = {
        "identity": [1, 0, 0, 0],
        "minus_identity": [-1, 0, 0, 0],
        "pitch_up": euler_quat(0.3, np.pi / 2, 0.5),
        "pitch_down": euler_quat(0.3, -np.pi / 2, 0.5),
        "yaw_180": [0, 0, 0, 1],
        "roll_180": [0, 1, 0, 0],
        "non_unit_1.01": np.array(euler_quat(0.1, 0.2, 0.3)) * 1.01,
        "non_unit_0.6": np.array(euler_quat(0.1, 0.2, 0.3)) * 0.6,
        "too_long_1.6": np.array(euler_quat(0.1, 0.2, 0.3)) * 1.6,
        "too_short_0.4": np.array(euler_quat(0.1, 0.2, 0.3)) * 0.4,
        "zero": [0, 0, 0, 0],
        "component_2": [2.0, 0, 0, 0],
    }
    q = np.array([np.asarray(v, float).ravel() for v in cases.values()])
    words = words_from(q)
    bt = F.formatter_bittrue(words)
    f = dict(zip(cases, bt["flags"], strict=True))
    ang = {a: dict(zip(cases, bits_to_f32(bt[a]).astype(np.float64), strict=True))
           for a in ANGLES}
    b_ry, b_p = F.euler_error_bound(1.0, 1.0)
    for name in ("identity", "minus_identity"):
        assert f[name] == 0
        assert all(abs(ang[a][name]) <= b_ry for a in ANGLES)
    for name, sgn in (("pitch_up", 1), ("pitch_down", -1)):
        assert f[name] == F.FLAG_GIMBAL  # exact lock: the explicit rule
        assert ang["roll"][name] == 0.0
        assert abs(ang["pitch"][name] - sgn * np.pi / 2) <= 1e-6
        assert wrapped(ang["yaw"][name], 0.5 - sgn * 0.3) <= 2e-6
    assert wrapped(ang["yaw"]["yaw_180"], np.pi) <= b_ry
    assert wrapped(ang["roll"]["roll_180"], np.pi) <= b_ry
    for name in ("non_unit_1.01", "non_unit_0.6"):  # angles of q/|q|, flagged
        assert f[name] == F.FLAG_NON_UNIT
        for a, want in zip(ANGLES, (0.1, 0.2, 0.3), strict=True):
            assert abs(ang[a][name] - want) <= 2 * b_ry
    for name in ("too_long_1.6", "too_short_0.4", "zero", "component_2"):
        assert f[name] == F.FLAG_INVALID, name
        assert all(bt[a][list(cases).index(name)] == QNAN for a in ANGLES)


def test_bittrue_nan_inf_never_silent():
    rng = np.random.default_rng(13)
    n = 3000
    q, _ = random_unit(n, 14)
    words = words_from(q, rng)
    # sprinkle specials over every input word
    specials = np.array([0x7FC00000, 0x7F800000, 0xFF800000, 0x7F7FFFFF, 0x00000001,
                         0x80000000, 0x40000000, 0xC0000000], dtype=np.uint32)
    for name in F.IN_FIELDS:
        hit = rng.random(n) < 0.04
        words[name] = np.where(hit, rng.choice(specials, n), words[name]).astype(np.uint32)
    bt = F.formatter_bittrue(words)
    nan_any = np.zeros(n, dtype=bool)
    for name in F.OUT_WORDS:
        nan_any |= (bt[name] & 0x7F800000) == 0x7F800000
    assert nan_any.sum() > 100
    assert np.all(bt["flags"][nan_any] != 0)
    # a NaN quaternion word always invalidates the angles
    qnan = np.zeros(n, dtype=bool)
    for name in ("q0", "q1", "q2", "q3"):
        qnan |= (words[name] & 0x7FFFFFFF) >= 0x7F800000
    assert np.all(bt["flags"][qnan] & F.FLAG_INVALID)
    assert np.all(bt["roll"][qnan] == QNAN)


def test_flags_agree_with_reference_away_from_thresholds():
    rng = np.random.default_rng(15)
    n = 4000
    q, _ = random_unit(n, 16)
    scale = rng.choice([1.0, 1.0 + 1e-3, 1.0 - 1e-3, 1.0 + 1e-5, 0.3, 1.7, 0.8, 1.3], n)
    words = words_from(q * scale[:, None], rng)
    bt = F.formatter_bittrue(words)
    ref = F.reference_format(values(words))
    n_ = ref["norm"]
    clear = ((np.abs(n_ - 0.5) > 1e-5) & (np.abs(n_ - 1.5) > 1e-5)
             & (np.abs(np.abs(n_ - 1) - F.UNIT_TOL) > 1e-5))
    assert clear.sum() > 0.9 * n
    mask = F.FLAG_INVALID | F.FLAG_NON_UNIT
    assert np.array_equal(bt["flags"][clear] & mask, ref["flags"][clear] & mask)
    assert set(np.unique(bt["flags"] & mask)) == {0, F.FLAG_INVALID, F.FLAG_NON_UNIT}


def test_cordic_magnitude_is_zero_only_for_the_zero_pair():
    """The gimbal rule keys on m == 0; that must mean the pair was (0, 0) (the vectoring's x
    register never decreases), for the smallest pairs and random ones."""
    from navgate.numerics.cordic import cordic_vectoring

    r = np.arange(-6, 7)
    x, y = (a.ravel() for a in np.meshgrid(r, r))
    rng = np.random.default_rng(17)
    x = np.concatenate([x, rng.integers(-(1 << 23), 1 << 23, 5000)])
    y = np.concatenate([y, rng.integers(-(1 << 23), 1 << 23, 5000)])
    mag, _ = cordic_vectoring(x, y, F.WIDTH, F.ITERATIONS, F.ANGLE_BITS, F.GUARD)
    assert np.array_equal(mag == 0, (x == 0) & (y == 0))
    assert np.all(mag[(x != 0) | (y != 0)] >= np.maximum(np.abs(x), np.abs(y))[(x != 0) | (y != 0)])


def test_on_the_fp32_engine_states_of_a_flight():
    """Real state words: a 60 s INS/TRN flight with the float32 engine, the state recorded
    after every propagate call. The Kahan compensation words change no float32 readout by
    more than one ulp (the reason they are not inputs), the formatter raises no flag, and its
    angles are within the bound of the reference on the same words."""
    from navgate.systems.ins_trn.ps import flight
    from navgate.systems.ins_trn.ps.fp32_engine import Fp32Engine
    from navgate.systems.ins_trn.ps.navigator import Navigator, engine_setup
    from navgate.trn.dem import Dem

    comp = ("cN", "cE", "cD", "cvN", "cvE", "cvD", "cq0", "cq1", "cq2", "cq3")
    rec = []

    class Recording(Fp32Engine):
        def propagate(self, gyro_words, accel_words):
            super().propagate(gyro_words, accel_words)
            rec.append([self.m.get(n) for n in F.STATE_WORDS + comp])

    dem = Dem.default()
    cfg = flight.FlightConfig(duration_s=60.0, seed=1)
    data = flight.simulate_sensors(flight.plan_route(dem, cfg), dem, cfg)
    stream = flight.flight_stream(data, dem, cfg, flight.initial_estimate(data, cfg))
    eng = Recording(engine_setup(stream.header, cfg))
    Navigator(eng, cfg, t0=stream.header["t0"], dem=dem, use_trn=True).run(stream)
    r = np.array(rec)
    assert len(r) >= 1000
    x = r[:, :10].astype(np.float32)
    compensated = (r[:, :10] - r[:, 10:]).astype(np.float32)  # one rounding of x - c
    ulps = np.abs(compensated.view(np.int32).astype(np.int64) - x.view(np.int32))
    assert ulps.max() <= 1 and np.mean(ulps == 0) > 0.999
    words = {name: f32_to_bits(x[:, i]) for i, name in enumerate(F.STATE_WORDS)}
    words["ref_alt"] = np.zeros(len(r), dtype=np.uint32)
    bt, ref, _, _ = check_against_reference(words)
    assert np.all(bt["flags"] == 0)
    assert np.array_equal(bits_to_f32(bt["pos_d"]), -x[:, 2])


# --- gateware ----------------------------------------------------------------------------
def gateware_vectors(n, seed):
    """Directed cases, then random: unit quaternions, near
    gimbal lock, non-unit, out of range, and special words anywhere."""
    rng = np.random.default_rng(seed)
    directed = np.array([[1, 0, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 1], [0, 1, 0, 0],
                         [0, 0, 1, 0], [0, 0, 0, 0], [2, 0, 0, 0], [-2, 0, 0, 0],
                         [1.9999999, 0, 0, 0], [0.5, 0.5, 0.5, 0.5], [0.5, -0.5, 0.5, -0.5]]
                        + [euler_quat(0.3, s * np.pi / 2, 0.5) for s in (1, -1)]
                        + [euler_quat(0, 0, y) for y in (np.pi, -np.pi, np.pi - 1e-6)]
                        + [np.array(euler_quat(0.1, 0.2, 0.3)) * s
                           for s in (1.01, 0.6, 1.6, 0.4, 1.5, 0.5)], dtype=float)
    m = n - len(directed)
    q, _ = random_unit(m, seed + 1)
    k = m // 4
    pitch = np.where(rng.random(k) < 0.5, 1, -1) * (np.pi / 2 - 10.0 ** rng.uniform(-8, -1, k))
    q[:k] = euler_quat(rng.uniform(-3, 3, k), pitch, rng.uniform(-3, 3, k))
    q[k:2 * k] *= rng.uniform(0.3, 1.7, k)[:, None]
    q = np.concatenate([directed, q])
    words = words_from(q, rng)
    specials = np.array([0x7FC00000, 0x7F800000, 0xFF800000, 0x00000001, 0x80000000],
                        dtype=np.uint32)
    sl = slice(len(directed) + 2 * k, len(directed) + 2 * k + k // 4)
    # P's diagonal words: variances over many decades, some negative (the square root's
    # NaN), then special words among them as among the state words
    for name in F.COV_FIELDS:
        var = 10.0 ** rng.uniform(-12, 6, len(q)) * np.where(rng.random(len(q)) < 0.03, -1, 1)
        words[name] = np.float32(var).view(np.uint32)
    for name in F.IN_FIELDS + F.COV_FIELDS:
        hit = rng.random(sl.stop - sl.start) < 0.05
        seg = words[name][sl]
        words[name][sl] = np.where(hit, rng.choice(specials, len(seg)), seg)
    return {k_: v.astype(np.uint64) for k_, v in words.items()}


def model(v):
    o = F.formatter_bittrue({k: np.asarray(v[k]).astype(np.uint32) for k in F.IN_FIELDS})
    o.update(F.sigma_bittrue({k: np.asarray(v[k]).astype(np.uint32) for k in F.COV_FIELDS}))
    return {k: o[k] for k in F.OUT_WORDS + F.SIGMA_WORDS + ("flags",)}


def test_sigma_model_directed():
    """COV_POS/VEL/ATT: sqrt((a + b) + c) in float32: exact squares give exact roots, a
    negative sum the canonical NaN, +inf stays +inf, subnormal words flush to zero."""
    def words(vals):
        return {f"diag{k}": np.float32([v]).view(np.uint32) for k, v in vals.items()}

    base = {0: 9.0, 1: 16.0, 3: 1.0, 4: 4.0, 5: 4.0, 6: 0.25, 7: 0.0, 8: 0.0}
    got = F.sigma_bittrue(words(base))
    assert [float(np.uint32(got[w][0]).view(np.float32)) for w in F.SIGMA_WORDS] == \
        [5.0, 3.0, 0.5]
    got = F.sigma_bittrue(words({**base, 0: -30.0, 3: np.inf, 6: 1e-40, 7: 1e-40, 8: 1e-40}))
    assert int(got["sigma_pos"][0]) == 0x7FC00000
    assert int(got["sigma_vel"][0]) == 0x7F800000
    assert int(got["sigma_att"][0]) == 0


def test_gateware_latency_and_cycles_exact():
    vec = gateware_vectors(30, 20)
    res = verify(F.NavOutputFormatter(), model, vec, seed=1)
    res.assert_ok()
    assert res.latency == F.NavOutputFormatter.LATENCY == 106
    # one vector every LATENCY cycles at full rate (accept in the cycle the output leaves)
    assert res.cycles == 30 * F.NavOutputFormatter.LATENCY + 1


@pytest.mark.parametrize("n", [600, pytest.param(2000, marks=pytest.mark.slow)])
def test_gateware_matches_model_amaranth(n):
    vec = gateware_vectors(n, 21)
    bt = model(vec)
    assert np.count_nonzero(bt["flags"] & F.FLAG_GIMBAL) >= 2
    assert np.count_nonzero(bt["flags"] & F.FLAG_INVALID) > 20
    assert np.count_nonzero(bt["flags"] & F.FLAG_NON_UNIT) > 20
    assert all(np.count_nonzero(bt[w] == 0x7FC00000) > 5 for w in F.SIGMA_WORDS)
    res = verify(F.NavOutputFormatter(), model, vec, seed=2, valid_prob=0.7, ready_prob=0.6)
    res.assert_ok()
    assert res.n_vectors == n


@pytest.mark.parametrize("n", [2000, pytest.param(20_000, marks=pytest.mark.slow)])
def test_gateware_matches_model_verilator(n, tmp_path):
    vec = gateware_vectors(n, 22 + n)
    res = verify(F.NavOutputFormatter(), model, vec, backend="verilator", seed=3,
                 valid_prob=0.7, ready_prob=0.6, work_dir=tmp_path)
    res.assert_ok()
    assert res.n_vectors == n


def test_block_is_registered():
    from navgate.systems import BLOCKS

    assert BLOCKS["nav_output_formatter"][0] == \
        "navgate.systems.ins_trn.pl.output_formatter:NavOutputFormatter"
    assert math.isclose(float(F.NavOutputFormatter.THROUGHPUT), 1 / 106)


def test_angle_conversion_as_integer_equals_the_model():
    """The gateware converts binary angles as integers and multiplies by pi * 2^-31
    (PI_BITS_INT): equal, word for word, to the model's fixed-point conversion times pi,
    over random angles and the extremes."""
    from navgate.numerics.fp32 import fp32_from_fixed, fp32_from_int, fp32_mul

    rng = np.random.default_rng(8)
    a = np.concatenate([rng.integers(-2**31, 2**31, 500_000),
                        rng.integers(-2**12, 2**12, 20_000),
                        [0, 1, -1, 2**31 - 1, -2**31, 2**30, -2**30, 2**29]]).astype(np.int64)
    fixed = fp32_from_fixed(a, F.ANGLE_BITS - 1, F.ANGLE_BITS)
    as_int = fp32_from_int(a, F.ANGLE_BITS)
    for model_const, hw_const in ((F.PI_BITS, F.PI_BITS_INT), (F.TWO_PI_BITS, F.TWO_PI_BITS_INT)):
        want = fp32_mul(fixed, np.uint32(model_const))
        got = fp32_mul(as_int, np.uint32(hw_const))
        assert np.array_equal(want, got)
