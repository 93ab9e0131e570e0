"""Bad input to seed 004's public entry points (issue 31): the parameters (fixed-point
format), the bit-true filter (raw words), the conversion of real values to Q(N, FRAC), the
float64 reference and the RLC scenario. One test per class of bad input: non-integer or
out-of-range raw words, missing words, values the Q format cannot hold (refused for the
model and the initial state, saturated and counted for measurements), non-finite values,
wrong shapes, covariances that are not positive semi-definite, a singular innovation
covariance, and unphysical scenario parameters."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navgate.systems.kf2x2 import model as kf

NAN = float("nan")
P = kf.KfParams()  # Q(20, 10): raw words in [-524288, 524287], values in [-512, 512)


def raises_naming(name, fn, *args, **kwargs):
    with pytest.raises(ValueError) as info:
        fn(*args, **kwargs)
    assert str(info.value).startswith(name), str(info.value)
    return str(info.value)


@pytest.fixture(scope="module")
def frames():
    return kf.quantize_frames(P, kf.rlc_scenario(frames=3))


@pytest.mark.parametrize("field, value", [("n", 20.5), ("frac", "3"), ("q_shift", True),
                                          ("div_iterations", 1.0), ("n", None)])
def test_params_are_integers(field, value):
    """n = 20.5 was accepted (and failed later at 1 << 19.5); frac = "3" was a TypeError."""
    raises_naming(field, kf.KfParams, **{field: value})


@pytest.mark.parametrize("value", [NAN, 1.5, -0.25, "7", None])
def test_raw_words_must_be_integers(value, frames):
    """P00 = 1.5 was truncated to 1 silently; NaN was "cannot convert float NaN"."""
    st = kf.init_state(P)
    raises_naming("state['P00']", kf.run_frame, P, {**st, "P00": value}, frames[0])
    raises_naming("inputs['z1']", kf.run_frame, P, st, {**frames[0], "z1": value})


@pytest.mark.parametrize("value", [P.max_int + 1, P.min_int - 1, 2**30])
def test_raw_words_must_fit_the_format(value, frames):
    st = kf.init_state(P)
    msg = raises_naming("state['x0']", kf.run_frame, P, {**st, "x0": value}, frames[0])
    assert "[-524288, 524287]" in msg and "Q(20, 10)" in msg
    # run_frames names the frame too
    bad = [frames[0], {**frames[1], "u0": value}]
    msg = raises_naming("frames[1]", kf.run_frames, P, st, bad)
    assert "inputs['u0']" in msg


def test_missing_words_are_named(frames):
    """A missing input was a bare KeyError: 'z0'."""
    st = kf.init_state(P)
    raises_naming("inputs: missing word 'z0'", kf.run_frame, P, st,
                  {k: v for k, v in frames[0].items() if k != "z0"})
    raises_naming("init_state: missing word 'gp11'", kf.run_frames, P,
                  {k: v for k, v in st.items() if k != "gp11"}, frames)
    raises_naming("adapt_q", kf.run_frames, P, st, frames, adapt_q="no")


def test_integral_floats_and_numpy_words_run_as_ints(frames):
    st = kf.init_state(P)
    as_int = kf.run_frames(P, st, frames)
    as_float = kf.run_frames(P, {k: float(v) for k, v in st.items()},
                             [{k: np.int32(v) for k, v in fr.items()} for fr in frames])
    assert all(np.array_equal(as_int[k], as_float[k]) for k in as_int)


@pytest.mark.parametrize("kwargs, name", [
    ({"P": (1e9, 0.0, 1.0)}, "P00"),       # once saturated silently to 511.999
    ({"R": (0.25, 0.0, -600.0)}, "R (00, 01, 11)"),  # not PSD (checked before the range)
    ({"x": (0.0, 512.0)}, "x[1]"),         # 512 = 2^9 is one LSB beyond Q(20, 10)
    ({"P": (NAN, 0.0, 1.0)}, "P"),
    ({"Q": (1.0, 5.0, 1.0)}, "Q (00, 01, 11)"),  # indefinite: eigenvalues 6 and -4
    ({"x": (0.0, 0.0, 0.0)}, "x"),         # wrong shape
    ({"P": (1.0, 1.0)}, "P"),
])
def test_initial_state_refuses_what_q_cannot_hold(kwargs, name):
    raises_naming(name, kf.init_state, P, **kwargs)


def test_initial_state_at_the_format_ends():
    top = P.max_int / P.scale  # 511.999..., the largest value Q(20, 10) holds
    st = kf.init_state(P, x=(top, -512.0), P=(top, 0.0, top))
    assert (st["x0"], st["x1"], st["P00"]) == (P.max_int, P.min_int, P.max_int)


def test_measurements_saturate_counted_and_flagged():
    """u and z beyond the format clip like an ADC, counted per word and per frame; the model
    constants A, B, H must fit (a ValueError naming the entry)."""
    sc = kf.rlc_scenario(frames=20, sigma_meas=(0.1, 0.1))
    sc.z[3] = [600.0, -700.0]  # two words beyond +-512
    sc.z[7, 1] = 1e12
    sc.u[7, 0] = -1e6
    q = kf.quantize_frames(P, sc)
    assert isinstance(q, list) and len(q) == 20
    assert q.saturated == 4 and q.saturated_frames == (3, 7)
    assert (q[3]["z0"], q[3]["z1"], q[7]["u0"]) == (P.max_int, P.min_int, P.min_int)
    assert kf.quantize_frames(P, kf.rlc_scenario(frames=20)).saturated == 0
    sc.A = sc.A * 1000.0
    raises_naming("scenario.A[0, 0]", kf.quantize_frames, P, sc)
    sc = kf.rlc_scenario(frames=5)
    sc.z[2, 0] = NAN
    raises_naming("scenario.z", kf.quantize_frames, P, sc)


def _state(**over):
    st = {"x": np.zeros(2), "P": np.eye(2), "Q": 0.01 * np.eye(2), "R": np.eye(2),
          "dq": np.zeros(2)}
    st.update(over)
    return st


@pytest.mark.parametrize("args, name", [
    ({"A": np.full((2, 2), NAN)}, "A"),          # NaN once propagated silently to x
    ({"B": np.eye(3)}, "B"),                      # a matmul shape error
    ({"z": [0.0, math.inf]}, "z"),
    ({"u": [0.0]}, "u"),
    ({"state": _state(P=-np.eye(2))}, "state['P']"),  # once gave P+ = 0 without a word
    ({"state": _state(R=np.array([[1.0, 2.0], [0.0, 1.0]]))}, "state['R']"),
    ({"state": _state(x=[NAN, 0.0])}, "state['x']"),
    ({"state": {"x": np.zeros(2)}}, "state: missing"),
    ({"state": _state(P=np.zeros((2, 2)), Q=np.zeros((2, 2)), R=np.zeros((2, 2)))},
     "state['R']: the innovation covariance"),   # LinAlgError: Singular matrix
])
def test_float_reference_guards(args, name):
    call = {"state": _state(), "A": np.eye(2), "B": np.eye(2), "H": np.eye(2),
            "u": [0.0, 0.0], "z": [0.0, 0.0], **args}
    raises_naming(name, kf.float_frame, P, call.pop("state"), **call)


@pytest.mark.parametrize("kwargs, name", [
    ({"frames": -5}, "frames"), ({"frames": 0}, "frames"),
    ({"l_h": 0.0}, "l_h"),               # ZeroDivisionError
    ({"c_f": -1e-3}, "c_f"),
    ({"dt": -1.0}, "dt"),                # overflow in matmul (RuntimeWarning only)
    ({"dt": 1.0}, "dt"),                 # 1000 time constants: exp over/underflows
    ({"r_ohm": -1.0}, "r_ohm"),
    ({"amplitude": NAN}, "amplitude"),   # NaN measurements, silently
    ({"sigma_meas": (-1.0, 0.4)}, "sigma_meas"),  # accepted: noise of std -1
    ({"sigma_meas": (0.4,)}, "sigma_meas"),
    ({"step_frame": 10**9}, "step_frame"),       # a step that never comes, silently
    ({"step_factor": -2.0}, "step_factor"),
    ({"sigma_process": math.inf}, "sigma_process"),
    ({"seed": -1}, "seed"),
])
def test_scenario_parameters(kwargs, name):
    raises_naming(name, kf.rlc_scenario, **{"frames": 10, **kwargs})


def test_scenario_defaults_still_run():
    sc = kf.rlc_scenario(frames=10, step_frame=10, step_factor=0.0)
    assert sc.frames == 10 and np.isfinite(sc.z).all()


def test_gateware_entry_points_check_before_building(frames):
    """The divider unit takes the filter's parameter checks (iterations = 0 was accepted, n =
    20.5 a TypeError from Amaranth), and verify_frames refuses a bad raw word before it
    elaborates or simulates anything."""
    from navgate.systems.kf2x2.rtl_sim import verify_frames
    from navgate.systems.kf2x2.top import Kf2x2
    from navgate.systems.kf2x2.units import GoldschmidtSerial

    raises_naming("div_iterations", GoldschmidtSerial, iterations=0)
    raises_naming("n", GoldschmidtSerial, n=20.5)
    raises_naming("n", Kf2x2, n=20.5)
    st = kf.init_state(P)
    raises_naming("init['x0']", verify_frames, P, {**st, "x0": 1.5}, frames)
    raises_naming("frames[2]: inputs['z0']", verify_frames, P, st,
                  [*frames[:2], {**frames[2], "z0": P.max_int + 1}])
