"""Seed 000's float32 op programs on opflow's executors: the compiled calibration against
nav.calibration's float32 face, the engine's programs compiled against bit-true, series bounds,
and the updates against the float64 reference from the same state."""

import math

import numpy as np
import pytest

from navgate.nav.calibration import (
    ImuCalibration,
    apply_calibration_fp32,
    calibration_to_fp32,
)
from navgate.numerics import fp32 as F
from navgate.numerics.fp32 import float_to_bits, floats_to_bits
from navgate.opflow import ir
from navgate.opflow.execute import (
    Machine,
    execute,
    run_bittrue,
)
from navgate.systems.ins_trn.pl import fp32_program as fp


def test_calibration_program_is_bit_identical_to_apply_calibration_fp32():
    rng = np.random.default_rng(5)
    cal = ImuCalibration.from_parts(
        gyro_bias=rng.normal(0, 1e-3, 3), gyro_scale=1 + rng.normal(0, 1e-3, 3),
        gyro_misalignment=np.where(np.eye(3) > 0, 0, rng.normal(0, 1e-3, (3, 3))),
        accel_bias=rng.normal(0, 0.05, 3), accel_scale=1 + rng.normal(0, 1e-3, 3),
        accel_misalignment=np.where(np.eye(3) > 0, 0, rng.normal(0, 1e-3, (3, 3))))
    c32 = calibration_to_fp32(cal)
    n = 400
    gw = rng.integers(-32768, 32768, (n, 3))
    aw = rng.integers(-32768, 32768, (n, 3))
    gw[:4] = [[-32768, 32767, 0], [1, -1, 0], [32767, 32767, 32767], [-32768, -32768, -32768]]
    want_g, want_a = apply_calibration_fp32(c32, gw, aw)
    prog = fp.calibration_program()
    state = {}
    for s, lsb, bias, mat in (("g", c32.gyro_lsb, c32.gyro_bias, c32.gyro_matrix),
                              ("a", c32.accel_lsb, c32.accel_bias, c32.accel_matrix)):
        state[f"cal_{s}_lsb"] = lsb
        for j in range(3):
            state[f"cal_{s}_b{j}"] = bias[j]
            for i in range(3):
                state[f"cal_{s}_m{i}{j}"] = mat[i, j]
    inputs = {f"wg{i}": gw[:, i].astype(float) for i in range(3)}
    inputs |= {f"wa{i}": aw[:, i].astype(float) for i in range(3)}
    _, out, _ = run_bittrue(prog, state, inputs, n)
    for i in range(3):
        assert np.array_equal(out[f"g{i}"], want_g[:, i])
        assert np.array_equal(out[f"a{i}"], want_a[:, i])
    # and the compiled machine, sample by sample
    m = Machine({"cal": prog})
    for k, v in state.items():
        m.regs[m.index[k]] = float(np.uint32(v).view(np.float32))
    c = m.compiled["cal"]
    for k in range(0, n, 7):
        for i in range(3):
            m.regs[m.index[f"wg{i}"]] = float(gw[k, i])
            m.regs[m.index[f"wa{i}"]] = float(aw[k, i])
        execute(m.regs, c.ops)
        got = floats_to_bits([m.regs[c.outputs[f"{s}{i}"]] for s in "ga" for i in range(3)])
        assert np.array_equal(got, np.concatenate([want_g[k], want_a[k]]))


def _engine_state(rng):
    """A plausible register state: attitude, velocity, position, P (SPD), config."""
    s = {}
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    vals = {"pN": rng.uniform(-9e3, 9e3), "pE": rng.uniform(-9e3, 9e3),
            "h": rng.uniform(500, 2000), "vN": rng.normal(0, 50), "vE": rng.normal(0, 50),
            "vD": rng.normal(0, 3), "q0": q[0], "q1": q[1], "q2": q[2], "q3": q[3],
            "cN": 1e-4, "cE": -2e-4, "cD": 3e-5, "kN": 1.0001, "kE": 0.9998,
            "dt": 1 / 400, "half_dt": 0.5 / 400, "q_vel": 1e-8, "q_att": 1e-12,
            "q_ba": 1e-14, "q_bg": 1e-18, "eps_a": 7e-7, "eps_g": 7e-7, "e2_a": 1.4e-6,
            "e2_g": 1.4e-6, "sin_lat0": math.sin(0.64), "cos_lat0": math.cos(0.64),
            "inv_mlat": 1 / 6.36e6, "m_lat": 6.36e6, "m_lon": 5.1e6}
    for i in range(3):
        vals[f"ba{i}"] = rng.normal(0, 0.01)
        vals[f"bg{i}"] = rng.normal(0, 1e-4)
    a = rng.normal(size=(15, 15)) * np.r_[[5] * 3, [0.1] * 3, [1e-3] * 3, [0.01] * 3,
                                          [1e-4] * 3][:, None]
    p = a @ a.T + np.diag(np.r_[[1.0] * 3, [1e-2] * 3, [1e-6] * 3, [1e-4] * 3, [1e-8] * 3])
    for i in range(15):
        for j in range(i, 15):
            vals[fp.p_reg(i, j)] = p[i, j]
    for sns in "ga":
        vals[f"cal_{sns}_lsb"] = 1e-4 if sns == "g" else 0.0122
        for j in range(3):
            vals[f"cal_{sns}_b{j}"] = rng.normal(0, 1e-3)
            for i in range(3):
                vals[f"cal_{sns}_m{i}{j}"] = (1.0 if i == j else 0.0) + rng.normal(0, 1e-3)
    for k in fp.STATE_REGS:
        s[k] = F.flush_subnormal(F.f32_to_bits(np.float64(vals.get(k, 0.0))))
    return s


@pytest.mark.parametrize("key", ["propagate", "alt_apply", "trn_gate", "trn_apply"])
def test_engine_programs_compiled_equal_bittrue(key):
    from navgate.systems.ins_trn.pl.fp32_program import programs

    progs = programs()
    prog = progs[key]
    rng = np.random.default_rng(11)
    lanes = 6
    states = [_engine_state(rng) for _ in range(lanes)]
    state = {k: np.array([s[k] for s in states], np.uint32) for k in fp.STATE_REGS}
    if key == "propagate":
        inputs = {n: rng.integers(-3000, 3000, lanes).astype(float) for n in prog.inputs}
    else:
        vals = {"h_meas": 1200.0, "r": 0.09, "y0": 12.5, "y1": -7.25, "r00": 100.0,
                "r01": 10.0, "r11": 80.0, "lag": 3.0, "gate": 9.2}
        inputs = {n: np.full(lanes, F.f32_to_bits(np.float64(vals[n])), np.uint32)
                  for n in prog.inputs}
    new_state, outputs, _ = run_bittrue(prog, state, inputs, lanes)
    m = Machine(progs)
    c = m.compiled[key]
    for lane in range(lanes):
        for k in fp.STATE_REGS:
            m.regs[m.index[k]] = float(np.uint32(state[k][lane]).view(np.float32))
        for n in prog.inputs:
            v = inputs[n][lane]
            m.regs[m.index[n]] = float(v) if key == "propagate" else float(
                np.uint32(v).view(np.float32))
        execute(m.regs, c.ops)
        for name, idx in c.outputs.items():
            assert float_to_bits(m.regs[idx]) == int(outputs[name][lane]), name
        from navgate.opflow.execute import commit

        commit(m.regs, c.table)
        for k in fp.STATE_REGS:
            assert float_to_bits(m.regs[m.index[k]]) == int(new_state[k][lane]), (lane, k)


def test_rotation_vector_series_meets_its_bound():
    """The float32 series quaternion against the exact one up to 2000 deg/s at 400 Hz: error
    within the truncation bound plus float32 rounding (a few ulps of 1)."""
    theta_max = math.radians(2000.0) / 400.0
    b_cos, b_sin = fp.rotvec_series_bound(theta_max)
    assert b_cos < 1.2e-11 and b_sin < 2e-12
    b = ir.Builder("rv", ("x", "y", "z"))
    w, qx, qy, qz = fp._rotvec_quat(b, "x", "y", "z")
    b.prog.outputs = {"w": w, "qx": qx, "qy": qy, "qz": qz}
    m = Machine({"rv": b.prog})
    rng = np.random.default_rng(3)
    worst = 0.0
    for _ in range(300):
        v = rng.normal(size=3)
        v *= rng.uniform(0, theta_max) / np.linalg.norm(v)
        out = m.run("rv", x=v[0], y=v[1], z=v[2])
        vv = np.array([m.get("x"), m.get("y"), m.get("z")])  # the float32 inputs
        a = np.linalg.norm(vv)
        exact = np.r_[math.cos(a / 2), (math.sin(a / 2) / a if a else 0.5) * vv]
        got = np.array([out["w"], out["qx"], out["qy"], out["qz"]])
        worst = max(worst, np.max(np.abs(got - exact)))
    # six rounded operations of magnitude <= 1: at most 6 * 2^-24 (+ the truncation bound)
    assert worst <= 6 * 2.0**-24 + b_cos


def test_latitude_series_bound():
    assert fp.latitude_series_bound(0.02) < 2.0**-24
    d = 0.02
    assert abs(math.cos(d) - (1 - d * d / 2)) <= fp.latitude_series_bound(d)
    assert abs(math.sin(d) - (d - d**3 / 6)) <= fp.latitude_series_bound(d)


def test_covariance_propagation_multiply_budget():
    counts = fp.propagate_program().counts_by_module()
    assert counts["covariance_propagator"]["mul"] + counts["phi_q_generation"]["mul"] <= 1500
    total = fp.propagate_program().counts()
    assert total["div"] == 6 and total["sqrt"] == 2


def test_schedule_bounds_on_a_small_program():
    """a*b + c then sqrt: critical path mul + add + sqrt; resource bound from unit counts."""
    b = ir.Builder("x", ("a", "b", "c"))
    t = b.add(b.mul("a", "b"), "c")
    b.sqrt(b.neg(t))
    for _ in range(5):
        b.mul("a", "c")
    lat = {"add": 8, "mul": 5, "div": 30, "sqrt": 29, "cmp": 2, "cvt": 4}
    got = fp.schedule_bounds(b.prog, lat, {"add": 1, "mul": 2, "div": 1, "sqrt": 1})
    assert got["critical_path"] == 5 + 8 + 29
    assert got["ops_per_unit"] == {"mul": 6, "add": 1, "sqrt": 1}
    assert got["resource"] == 3 and got["bound"] == 42


@pytest.mark.parametrize("key", ["alt_apply", "trn_apply"])
def test_updates_zero_the_compensation_words(key):
    """An update's new P is the whole covariance: every cP word is +0 after it (from non-zero
    words), and the new P is computed from the stored P (the same bits whatever cP was)."""
    from navgate.systems.ins_trn.pl.fp32_program import CP_REGS, P_REGS, programs

    prog = programs()[key]
    rng = np.random.default_rng(5)
    base = _engine_state(rng)
    vals = {"h_meas": 1200.0, "r": 0.09, "y0": 12.5, "y1": -7.25, "r00": 100.0,
            "r01": 10.0, "r11": 80.0, "lag": 3.0, "gate": 9.2}
    inputs = {n: np.uint32(F.f32_to_bits(np.float64(vals[n]))) for n in prog.inputs}
    got = []
    for scale in (0.0, 1.0, -1.0):
        state = dict(base)
        for p, c in zip(P_REGS, CP_REGS, strict=True):
            # a compensation word below half an ulp of its element, of either sign
            v = float(np.uint32(base[p]).view(np.float32)) * 2.0**-26 * scale
            state[c] = F.flush_subnormal(F.f32_to_bits(np.float64(v)))
        new, _, _ = run_bittrue(prog, state, inputs)
        assert all(int(new[c][0]) == 0 for c in CP_REGS)
        got.append([int(new[p][0]) for p in P_REGS])
    assert got[0] == got[1] == got[2]
    assert got[0] != [int(base[p]) for p in P_REGS]  # the update changed P
