"""Seed 004's 2x2 adaptive fixed-point Kalman filter: frame program, bit-true model, float64
reference and the series-RLC scenario.

Reference: seed 004 (``shared/seeds/004_434634b8563392b1.txt``): a 2x2 Kalman filter in
signed Q(N, FRAC) fixed point (default N=20, FRAC=10) whose frame is computed by eight
modules (prior state, prior covariance, estimated output, Kalman gain, posterior state,
posterior covariance, Q update, R update) in 34 clock cycles. docs/seed004-kf2x2.md is the
full specification; this module is the numerical half of it.

Model (all matrices 2x2, all vectors 2x1, as the seed says)::

    x(k) = A x(k-1) + B u(k) + w,     z(k) = H x(k) + v
    prior:      xp = A x + B u,        Pp = A P A^T + Q
    output:     zh = H xp,             e = z - zh            (innovation)
    gain:       T = Pp H^T,  S = H T + R,  K = T adj(S) / det(S)
    posterior:  dx = K e,  x+ = xp + dx,  P+ = Pp - K T^T    (= Pp - K H Pp)
    adaptation (subsystem_eq1), see below.

One description, two faces (docs/DESIGN.md): :func:`frame_program` returns the frame as a
list of :class:`Op` (one arithmetic operation each, with its operands and the module it
belongs to). :func:`run_frame` interprets that list with the bit-true operators below;
:mod:`navgate.systems.kf2x2.top` schedules the *same* list onto shared arithmetic units. The
float64 reference :func:`float_frame` is written independently with NumPy matrices.

Bit-true operators (Q(N, FRAC) raw integers, :mod:`navgate.numerics.fixed`):

* ``mul(a, b)``: the exact product shifted right by FRAC (floor), saturated to N bits
  (``fixed_mul_trunc(..., mode="saturate")``);
* ``add``/``sub``: exact sum/difference saturated to N bits;
* ``abs``: ``fixed_abs`` (saturating, ``|min| -> max``);
* ``recip``: :func:`navgate.numerics.goldschmidt.goldschmidt_reciprocal` (N, FRAC,
  ``div_iterations``, ``div_seed_bits``, F = N, table seed, rounded);
* an operand written ``("shr", name, s)`` is ``name >> s`` (arithmetic, floor; wiring only).

Every saturation sets the frame's ``overflow`` flag (sticky over the frame); the divider
reports ``div_zero`` (det(S) = 0) and ``div_overflow``. Saturate-and-flag is the overflow
behaviour (the seed's truncated adder drops the carry, i.e. wraps; we do not, see the docs).

Covariances are symmetric and stored as three words (00, 01, 11). Adaptive noise
covariances (the seed names ``subsystem_eq1`` without equations; the scheme is a
fading-memory covariance matching estimator, Sage and Husa 1969 / Myers and Tapley 1976
for R, Mohamed and Schwarz 1999 / Akhlaghi et al. 2017 for Q, weights 2**-shift):

* R (diagonal, one ``subsystem_eq1`` per measurement): ``R_ii <- (R_ii - R_ii >> r_shift)
  + |ep_i^2 - gp_ii| >> r_shift``, ep the previous frame's innovation and gp the previous
  frame's diagonal of H Pp H^T; R_01 is kept. The absolute value (the seed's ``fxp_abs``)
  keeps R non-negative (the "improved Sage-Husa" form).
* Q: ``Q_ij <- (Q_ij - Q_ij >> q_shift) + (dq_i dq_j) >> q_shift`` with dq the previous
  frame's correction K e = x+ - xp.

The previous frame's quantities are used because the seed's Q and R slots (C10-C12,
C12-C14) lie before this frame's K (C24) and H Pp H^T (C14) exist; with a memory of
2**shift = 32 frames the one-frame lag is immaterial (docs/seed004-kf2x2.md).
Both are computed every frame and committed at the end of the frame only when the frame's
``adapt_q`` / ``adapt_r`` input is set (otherwise Q and R stay as they are).

Guards (issue 31, :mod:`navgate.nav.validate`), by the kind of value:

* Parameters (:class:`KfParams`) are integers in the gateware's ranges; 20.5, "3" or a bool
  is a ``ValueError`` naming the field.
* Raw words given to :func:`run_frame` / :func:`run_frames` (state and frame inputs) are
  integers that fit Q(N, FRAC): NaN, 1.5 (once silently truncated to 1) or 2^30 is a
  ``ValueError`` naming the word and the frame; a missing word is named the same way.
* Overflow *inside* a frame is the filter's documented behaviour: saturated, and counted in
  the ``overflow`` flag of the frame (the CLI's ``overflow_frames``), never refused.
* Real values converted to Q(N, FRAC): the model's constants (A, B, H) and the initial state
  (:func:`init_state`: x, P, Q, R) are configuration: a value the format cannot hold is a
  ``ValueError`` naming it (silently saturating P = 1e9 would start a different filter).
  Measurements and inputs (z, u in :func:`quantize_frames`) are data from a sensor: out of
  range they saturate as an ADC does, counted per word and per frame
  (:class:`QuantizedFrames`), so one spike does not stop a run. Non-finite values are a
  ``ValueError`` in both cases.
* Covariances (P, Q, R of :func:`init_state` and :func:`float_frame`) are symmetric positive
  semi-definite; S = H Pp H^T + R must be invertible in the float64 reference (a singular S is
  a ``ValueError`` naming R; the bit-true model flags it as ``div_zero``).
* Scenario parameters (:func:`rlc_scenario`) are finite and physical: L, C and dt positive,
  R and the noise levels non-negative, the noise step inside the run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from navgate.nav import validate
from navgate.numerics.goldschmidt import goldschmidt_normalised, goldschmidt_reciprocal

__all__ = [
    "KfParams",
    "Op",
    "MODULES",
    "FRAME_INPUTS",
    "STATE_NAMES",
    "frame_program",
    "run_frame",
    "run_frames",
    "float_frame",
    "run_frames_float",
    "RlcScenario",
    "rlc_scenario",
    "quantize_frames",
]

#: the seed's eight modules, in the seed table's order
MODULES = ("prior_state", "prior_cov", "est_output", "kalman_gain", "post_state",
           "post_cov", "q_update", "r_update")

#: per-frame inputs (held by the caller during a frame)
FRAME_INPUTS = ("A00", "A01", "A10", "A11", "B00", "B01", "B10", "B11",
                "H00", "H01", "H10", "H11", "u0", "u1", "z0", "z1")

#: filter state, carried from frame to frame (dq: the previous correction K e)
STATE_NAMES = ("x0", "x1", "P00", "P01", "P11", "Q00", "Q01", "Q11", "R00", "R01", "R11",
               "dq0", "dq1", "ep0", "ep1", "gp00", "gp11")

#: state register <- value of the frame program committed at the end of a frame
COMMIT = {"x0": "xn0", "x1": "xn1", "P00": "pn00", "P01": "pn01", "P11": "pn11",
          "Q00": "qn00", "Q01": "qn01", "Q11": "qn11", "R00": "rn00", "R11": "rn11",
          "dq0": "dx0", "dq1": "dx1", "ep0": "e0", "ep1": "e1", "gp00": "g00", "gp11": "g11"}


@dataclass(frozen=True)
class KfParams:
    """Word length and algorithm constants (the gateware's constructor parameters)."""

    n: int = 20
    frac: int = 10
    q_shift: int = 5
    r_shift: int = 5
    div_iterations: int = 1
    div_seed_bits: int = 8

    def __post_init__(self):
        for name in ("n", "frac", "q_shift", "r_shift", "div_iterations", "div_seed_bits"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise ValueError(f"{name}: expected an integer, got {value!r}")
            object.__setattr__(self, name, int(value))
        if not 8 <= self.n <= 32:
            raise ValueError(f"n must be in [8, 32], got {self.n}")
        if not 1 <= self.frac <= self.n - 2:
            raise ValueError(f"frac must be in [1, n-2], got {self.frac}")
        for name in ("q_shift", "r_shift"):
            if not 0 <= getattr(self, name) < self.n:
                raise ValueError(f"{name} must be in [0, n)")
        if not 1 <= self.div_iterations <= 4:
            raise ValueError("div_iterations must be in [1, 4]")
        if not 0 <= self.div_seed_bits <= 8:
            raise ValueError("div_seed_bits must be in [0, 8]")
        if self.div_seed_bits > self.n - 1:  # Goldschmidt seed table: seed_bits <= F - 1, F = n
            raise ValueError(f"n must be in [{self.div_seed_bits + 1}, 32] with the "
                             f"{self.div_seed_bits}-bit divider seed table, got {self.n}")

    @property
    def min_int(self) -> int:
        return -(1 << (self.n - 1))

    @property
    def max_int(self) -> int:
        return (1 << (self.n - 1)) - 1

    @property
    def scale(self) -> float:
        return float(1 << self.frac)


@dataclass(frozen=True)
class Op:
    """One operation of the frame program: ``name = kind(*srcs)`` in ``module``."""

    name: str
    kind: str  # "mul", "add", "sub", "absdiff", "recip"
    srcs: tuple
    module: str
    deps: tuple = field(default=())

    def __post_init__(self):
        names = tuple(s if isinstance(s, str) else s[1] for s in self.srcs)
        object.__setattr__(self, "deps", names)


def frame_program(params: KfParams = KfParams()) -> list[Op]:
    """The frame as a list of operations (association order fixed: it is the bit-true spec)."""
    ops: list[Op] = []

    def op(module, name, kind, *srcs):
        ops.append(Op(name, kind, tuple(srcs), module))
        return name

    def dot2(module, name, a0, b0, a1, b1):
        """name = a0 b0 + a1 b1 (two truncated products, one saturating add)."""
        p = op(module, f"{name}_p0", "mul", a0, b0)
        q = op(module, f"{name}_p1", "mul", a1, b1)
        return op(module, name, "add", p, q)

    # prior state: xp_i = (A_i0 x0 + A_i1 x1) + (B_i0 u0 + B_i1 u1)
    for i in (0, 1):
        ax = dot2("prior_state", f"ax{i}", f"A{i}0", "x0", f"A{i}1", "x1")
        bu = dot2("prior_state", f"bu{i}", f"B{i}0", "u0", f"B{i}1", "u1")
        op("prior_state", f"xp{i}", "add", ax, bu)
    # prior covariance: AP (P symmetric, P10 = P01), then (AP) A^T + Q, three entries
    pm = {(0, 0): "P00", (0, 1): "P01", (1, 0): "P01", (1, 1): "P11"}
    for i in (0, 1):
        for j in (0, 1):
            dot2("prior_cov", f"ap{i}{j}", f"A{i}0", pm[0, j], f"A{i}1", pm[1, j])
    for i, j in ((0, 0), (0, 1), (1, 1)):
        m = dot2("prior_cov", f"apa{i}{j}", f"ap{i}0", f"A{j}0", f"ap{i}1", f"A{j}1")
        op("prior_cov", f"pp{i}{j}", "add", m, f"Q{i}{j}")
    # estimated output and innovation
    for i in (0, 1):
        dot2("est_output", f"zh{i}", f"H{i}0", "xp0", f"H{i}1", "xp1")
        op("est_output", f"e{i}", "sub", f"z{i}", f"zh{i}")
    # Kalman gain: T = Pp H^T, G = H T (symmetric), S = G + R, det, 1/det, K = T adj(S)/det
    ppm = {(0, 0): "pp00", (0, 1): "pp01", (1, 0): "pp01", (1, 1): "pp11"}
    kg = "kalman_gain"
    for j in (0, 1):  # column 0 first: G00 needs only column 0
        for i in (0, 1):
            dot2(kg, f"t{i}{j}", ppm[i, 0], f"H{j}0", ppm[i, 1], f"H{j}1")
    for i, j in ((0, 0), (0, 1), (1, 1)):
        dot2(kg, f"g{i}{j}", f"H{i}0", f"t0{j}", f"H{i}1", f"t1{j}")
        op(kg, f"s{i}{j}", "add", f"g{i}{j}", f"R{i}{j}")
    d0 = op(kg, "det_p0", "mul", "s00", "s11")
    d1 = op(kg, "det_p1", "mul", "s01", "s01")
    op(kg, "det", "sub", d0, d1)
    op(kg, "inv", "recip", "det")
    # M = T adj(S), adj(S) = [[s11, -s01], [-s01, s00]], computed while the divider runs
    for i in (0, 1):
        a = op(kg, f"mk{i}0_p0", "mul", f"t{i}0", "s11")
        b = op(kg, f"mk{i}0_p1", "mul", f"t{i}1", "s01")
        op(kg, f"mk{i}0", "sub", a, b)
        a = op(kg, f"mk{i}1_p0", "mul", f"t{i}1", "s00")
        b = op(kg, f"mk{i}1_p1", "mul", f"t{i}0", "s01")
        op(kg, f"mk{i}1", "sub", a, b)
    for i in (0, 1):
        for j in (0, 1):
            op(kg, f"k{i}{j}", "mul", f"mk{i}{j}", "inv")
    # posterior state
    for i in (0, 1):
        dot2("post_state", f"dx{i}", f"k{i}0", "e0", f"k{i}1", "e1")
        op("post_state", f"xn{i}", "add", f"xp{i}", f"dx{i}")
    # posterior covariance: Pp - K T^T, three entries
    for i, j in ((0, 0), (0, 1), (1, 1)):
        dot2("post_cov", f"w{i}{j}", f"k{i}0", f"t{j}0", f"k{i}1", f"t{j}1")
        op("post_cov", f"pn{i}{j}", "sub", f"pp{i}{j}", f"w{i}{j}")
    # Q update from the previous frame's correction dq:  Q+ = (Q - Q>>s) + (dq dq^T)>>s
    for i, j in ((0, 0), (0, 1), (1, 1)):
        p = op("q_update", f"qq{i}{j}", "mul", f"dq{i}", f"dq{j}")
        f = op("q_update", f"qf{i}{j}", "sub", f"Q{i}{j}", ("shr", f"Q{i}{j}", params.q_shift))
        op("q_update", f"qn{i}{j}", "add", f, ("shr", p, params.q_shift))
    # R update, subsystem_eq1 for R00 and R11, from the previous frame's innovation ep and
    # (H Pp H^T) diagonal gp:  R+ = (R - R>>s) + |ep^2 - gp| >> s
    for i in (0, 1):
        sq = op("r_update", f"re{i}", "mul", f"ep{i}", f"ep{i}")
        a = op("r_update", f"ra{i}", "absdiff", sq, f"gp{i}{i}")
        f = op("r_update", f"rf{i}", "sub", f"R{i}{i}", ("shr", f"R{i}{i}", params.r_shift))
        op("r_update", f"rn{i}{i}", "add", f, ("shr", a, params.r_shift))
    return ops


# ----------------------------------------------------------------------------- bit-true


def reciprocal(d: int, params: KfParams) -> tuple[int, dict]:
    """1/d as the gateware's Goldschmidt divider computes it (F = N internal fraction bits).

    For N <= 20 this is :func:`~navgate.numerics.goldschmidt.goldschmidt_reciprocal`
    itself. Its int64 model stops at N = 20 (it needs F + 2N + 1 <= 62), so for wider words
    the same datapath runs as: normalisation and the final rounding/saturation
    (``_finish`` of that module, round half up on the magnitude) in Python integers around
    :func:`~navgate.numerics.goldschmidt.goldschmidt_normalised` (int64 up to F = 29, Python
    integers beyond, so N runs up to 32 without overflow).
    The tests check that both paths agree wherever both exist.
    """
    n, frac = params.n, params.frac
    if n <= 20:
        q, flags = goldschmidt_reciprocal(d, n, frac, iterations=params.div_iterations,
                                          seed_bits=params.div_seed_bits)
        return int(q), {k: bool(v) for k, v in flags.items()}
    return _reciprocal_wide(d, params)


def _reciprocal_wide(d: int, params: KfParams) -> tuple[int, dict]:
    n, frac, F = params.n, params.frac, params.n
    if d == 0:
        return params.max_int, {"divide_by_zero": True, "overflow": False}
    neg = d < 0
    a = abs(d)
    p = a.bit_length() - 1
    D = a << (F - 1 - p)
    N = int(goldschmidt_normalised(1 << F, D, F, params.div_iterations,
                                   params.div_seed_bits))
    shift = 2 * frac - p - 1 - F
    q = N << shift if shift >= 0 else (N + (1 << (-shift - 1))) >> (-shift)
    limit = (1 << (n - 1)) if neg else params.max_int
    over = q > limit
    q = min(q, limit)
    return (-q if neg else q), {"divide_by_zero": False, "overflow": over}


def _sat(v: int, p: KfParams) -> tuple[int, bool]:
    if v > p.max_int:
        return p.max_int, True
    if v < p.min_int:
        return p.min_int, True
    return v, False


def _raw_word(name: str, v, p: KfParams) -> int:
    """A raw Q(N, FRAC) word: an integer (integral float accepted) in [min_int, max_int]."""
    if type(v) is int and p.min_int <= v <= p.max_int:  # the common case, fast
        return v
    try:
        return validate.integer(name, v, p.min_int, p.max_int)
    except ValueError as error:
        raise ValueError(f"{error} (a raw Q({p.n}, {p.frac}) word)") from None


def run_frame(params: KfParams, state: dict, inputs: dict, adapt_q: bool = True,
              adapt_r: bool = True, program: list[Op] | None = None):
    """One frame of the bit-true model.

    ``state`` (:data:`STATE_NAMES`) and ``inputs`` (:data:`FRAME_INPUTS`) hold raw Q(N, FRAC)
    integers. Returns ``(new_state, values, flags)``: ``values`` every named value of the
    program (the gateware's registers), ``flags`` = ``overflow``, ``div_zero``,
    ``div_overflow``.
    """
    prog = frame_program(params) if program is None else program
    env: dict[str, int] = {}
    for what, names, words in (("state", STATE_NAMES, state), ("inputs", FRAME_INPUTS, inputs)):
        for name in names:
            try:
                v = words[name]
            except (KeyError, TypeError, IndexError):
                raise ValueError(f"{what}: missing word {name!r}") from None
            env[name] = _raw_word(f"{what}[{name!r}]", v, params)
    overflow = False
    div_zero = div_over = False

    def val(src):
        if isinstance(src, str):
            return env[src]
        kind, name, s = src
        assert kind == "shr"
        return env[name] >> s

    for o in prog:
        a = [val(s) for s in o.srcs]
        if o.kind == "mul":
            r, f = _sat((a[0] * a[1]) >> params.frac, params)
        elif o.kind == "add":
            r, f = _sat(a[0] + a[1], params)
        elif o.kind == "sub":
            r, f = _sat(a[0] - a[1], params)
        elif o.kind == "absdiff":
            r, f = _sat(abs(a[0] - a[1]), params)
        elif o.kind == "recip":
            q, flags = reciprocal(a[0], params)
            r, f = int(q), False
            div_zero = div_zero or flags["divide_by_zero"]
            div_over = div_over or flags["overflow"]
        else:
            raise ValueError(f"unknown op kind {o.kind!r}")
        overflow = overflow or f
        env[o.name] = r
    new = {k: env[k] for k in STATE_NAMES}
    for reg, src in COMMIT.items():
        if reg.startswith("Q") and not adapt_q:
            continue
        if reg.startswith("R") and not adapt_r:
            continue
        if src in env:  # (a partial program, as in unit tests, commits what it has)
            new[reg] = env[src]
    values = {o.name: env[o.name] for o in prog}
    return new, values, {"overflow": overflow, "div_zero": div_zero, "div_overflow": div_over}


def run_frames(params: KfParams, init_state: dict, frames: list[dict],
               adapt_q: bool = True, adapt_r: bool = True):
    """Run the bit-true model over ``frames`` (dicts of :data:`FRAME_INPUTS`); returns a dict
    of int64 arrays: every state word after each frame, the gains ``k..`` and the flags."""
    prog = frame_program(params)
    adapt_q = validate.flag("adapt_q", adapt_q)
    adapt_r = validate.flag("adapt_r", adapt_r)
    state = check_state(params, init_state)
    rows = []
    for index, fr in enumerate(frames):
        try:
            state, values, flags = run_frame(params, state, fr, adapt_q, adapt_r, prog)
        except ValueError as error:
            raise ValueError(f"frames[{index}]: {error}") from None
        row = dict(state)
        row.update({k: values[k] for k in ("k00", "k01", "k10", "k11", "inv", "det")})
        row.update({k: int(v) for k, v in flags.items()})
        rows.append(row)
    return {k: np.array([r[k] for r in rows], dtype=np.int64) for k in rows[0]} if rows else {}


def _missing(what: str, name: str):
    raise ValueError(f"{what}: missing word {name!r}")


def check_state(params: KfParams, state: dict, what: str = "init_state") -> dict:
    """The state words (:data:`STATE_NAMES`) as ints, each a raw Q(N, FRAC) word."""
    return {k: _raw_word(f"{what}[{k!r}]", state[k], params) if k in state
            else _missing(what, k) for k in STATE_NAMES}


def check_frames(params: KfParams, frames) -> list[dict]:
    """The frames' input words (:data:`FRAME_INPUTS`) as ints, each a raw Q(N, FRAC) word;
    a bad one is a ValueError naming the frame and the word."""
    out = []
    for index, fr in enumerate(frames):
        out.append({k: _raw_word(f"frames[{index}]: inputs[{k!r}]", fr[k], params)
                    if k in fr else _missing(f"frames[{index}]: inputs", k)
                    for k in FRAME_INPUTS})
    return out


# ----------------------------------------------------------------------------- float64


def float_frame(params: KfParams, state: dict, A, B, H, u, z, adapt_q=True, adapt_r=True):
    """One frame of the float64 reference (matrix form, same adaptive scheme, real-valued
    weights 2**-shift). ``state``: dict with x (2,), P, Q, R (2, 2), dq (2,)."""
    A, B, H = (validate.finite_array(n, m, (2, 2)) for n, m in (("A", A), ("B", B), ("H", H)))
    u = validate.finite_array("u", u, (2,))
    z = validate.finite_array("z", z, (2,))
    for key in ("x", "P", "Q", "R", "dq"):
        if key not in state:
            raise ValueError(f"state: missing {key!r}")
    x = validate.finite_array("state['x']", state["x"], (2,))
    dq = validate.finite_array("state['dq']", state["dq"], (2,))
    P, Q, R = (validate.covariance(f"state[{k!r}]", state[k], 2) for k in ("P", "Q", "R"))
    ep = validate.finite_array("state['ep']", state.get("ep", np.zeros(2)), (2,))
    gp = validate.finite_array("state['gp']", state.get("gp", np.zeros(2)), (2,))
    xp = A @ x + B @ u
    Pp = A @ P @ A.T + Q
    e = z - H @ xp
    T = Pp @ H.T
    G = H @ T
    S = G + R
    det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
    if not abs(det) > 1e-12 * max(float(np.abs(S).max()) ** 2, np.finfo(float).tiny):
        raise ValueError(f"state['R']: the innovation covariance H Pp H^T + R is singular "
                         f"(det {det:.3g}); R must make it invertible")
    K = T @ np.linalg.inv(S)
    dx = K @ e
    xn = xp + dx
    Pn = Pp - K @ T.T
    Qn, Rn = Q.copy(), R.copy()
    if adapt_q:
        Qn = Q + (np.outer(dq, dq) - Q) * 2.0**-params.q_shift
    if adapt_r:
        for i in (0, 1):
            Rn[i, i] = R[i, i] + (abs(ep[i] ** 2 - gp[i]) - R[i, i]) * 2.0**-params.r_shift
    return {"x": xn, "P": Pn, "Q": Qn, "R": Rn, "dq": dx, "K": K, "ep": e,
            "gp": np.diag(G).copy()}


def run_frames_float(params: KfParams, init: dict, scenario: RlcScenario,
                     adapt_q=True, adapt_r=True):
    """float64 filter over a scenario; returns x (frames, 2), R diag, Q, K."""
    st = {k: np.array(v, dtype=float) for k, v in init.items()}
    xs, rs, ks = [], [], []
    for k in range(scenario.frames):
        st = float_frame(params, st, scenario.A, scenario.B, scenario.H, scenario.u[k],
                         scenario.z[k], adapt_q, adapt_r)
        xs.append(st["x"])
        rs.append(np.diag(st["R"]))
        ks.append(st["K"])
    return {"x": np.array(xs), "R": np.array(rs), "K": np.array(ks)}


# ----------------------------------------------------------------------------- scenario


@dataclass
class RlcScenario:
    """Discretised series RLC circuit (states: capacitor voltage [V], inductor current [A])."""

    A: np.ndarray
    B: np.ndarray
    H: np.ndarray
    u: np.ndarray  # (frames, 2): source voltage, 0
    x: np.ndarray  # (frames, 2) truth after each frame
    z: np.ndarray  # (frames, 2) noisy measurements
    sigma_v: np.ndarray  # (frames, 2) measurement noise std actually used
    q_true: np.ndarray  # (2, 2) process noise covariance
    x0: np.ndarray
    dt: float

    @property
    def frames(self) -> int:
        return len(self.u)


def _expm(M: np.ndarray) -> np.ndarray:
    """Matrix exponential by scaling and squaring of a Taylor series (2x2, well scaled)."""
    s = max(0, int(np.ceil(np.log2(max(np.abs(M).sum(), 1e-300)))) + 4)
    X = M / 2.0**s
    E = np.eye(len(M))
    term = np.eye(len(M))
    for k in range(1, 20):
        term = term @ X / k
        E = E + term
    for _ in range(s):
        E = E @ E
    return E


def rlc_scenario(frames: int = 4000, seed: int = 0, r_ohm: float = 1.0, l_h: float = 1e-3,
                 c_f: float = 1e-3, dt: float = 1e-4, amplitude: float = 4.0,
                 source_hz: float = 25.0, sigma_meas: tuple = (0.4, 0.4),
                 step_frame: int | None = None, step_factor: float = 1.0,
                 sigma_process: float = 0.01) -> RlcScenario:
    """Series RLC driven by a square-wave source, both states measured.

    Continuous model: dv/dt = i / C, di/dt = (u - R i - v) / L, discretised exactly
    (zero-order hold on u, matrix exponential of the augmented system). Process noise:
    white, std ``sigma_process`` per step on each state. Measurement noise std
    ``sigma_meas``, multiplied by ``step_factor`` from frame ``step_frame`` on (the
    measurement-noise step that the adaptive R must follow). Defaults: omega0 =
    1/sqrt(LC) = 1000 rad/s, damping 0.5, sqrt(L/C) = 1 ohm, so volts and amperes have the
    same scale.
    """
    frames = validate.positive_int("frames", frames)
    seed = validate.integer("seed", seed, 0)
    r_ohm = validate.non_negative("r_ohm", r_ohm)
    l_h = validate.positive("l_h", l_h)
    c_f = validate.positive("c_f", c_f)
    dt = validate.positive("dt", dt)
    amplitude = validate.finite_scalar("amplitude", amplitude)
    source_hz = validate.non_negative("source_hz", source_hz)
    sigma_meas = validate.finite_array("sigma_meas", sigma_meas, (2,))
    if (sigma_meas < 0).any():
        raise ValueError(f"sigma_meas: must be non-negative, got {sigma_meas.tolist()}")
    if step_frame is not None:
        step_frame = validate.integer("step_frame", step_frame, 0, frames)
    step_factor = validate.non_negative("step_factor", step_factor)
    sigma_process = validate.non_negative("sigma_process", sigma_process)
    # the exact discretisation exponentiates A_c dt: beyond |A_c dt| ~ 700 it overflows float64
    stiff = dt * max(1.0 / c_f, 1.0 / l_h, r_ohm / l_h)
    if stiff > 100.0:
        raise ValueError(f"dt: {dt:g} s is {stiff:.3g} time constants of the circuit (at most "
                         "100: the discrete model would over- or underflow)")
    rng = np.random.default_rng(seed)
    Ac = np.array([[0.0, 1.0 / c_f], [-1.0 / l_h, -r_ohm / l_h]])
    Bc = np.array([[0.0], [1.0 / l_h]])
    aug = np.zeros((3, 3))
    aug[:2, :2] = Ac * dt
    aug[:2, 2:] = Bc * dt
    E = _expm(aug)
    A = E[:2, :2]
    B = np.zeros((2, 2))
    B[:, 0] = E[:2, 2]
    H = np.eye(2)
    t = np.arange(frames) * dt
    src = amplitude * np.where(np.sin(2 * np.pi * source_hz * t) >= 0, 1.0, -1.0)
    u = np.stack([src, np.zeros(frames)], axis=1)
    sig = np.tile(np.asarray(sigma_meas, dtype=float), (frames, 1))
    if step_frame is not None:
        sig[step_frame:] *= step_factor
    x = np.zeros(2)
    xs, zs = [], []
    for k in range(frames):
        x = A @ x + B @ u[k] + rng.normal(0.0, sigma_process, 2)
        xs.append(x)
        zs.append(H @ x + rng.normal(0.0, 1.0, 2) * sig[k])
    return RlcScenario(A=A, B=B, H=H, u=u, x=np.array(xs), z=np.array(zs), sigma_v=sig,
                       q_true=np.eye(2) * sigma_process**2, x0=np.zeros(2), dt=dt)


class QuantizedFrames(list):
    """The frames of :func:`quantize_frames` (a list of dicts of raw words) and what the
    conversion saturated: ``saturated`` words, ``saturated_frames`` (their frame indices)."""

    saturated: int = 0
    saturated_frames: tuple = ()


def _to_raw(name: str, v: float, params: KfParams) -> int:
    """A real value as a raw Q(N, FRAC) word (round half up); out of range is a ValueError."""
    v = validate.finite_scalar(name, v)
    r = math.floor(v * params.scale + 0.5)
    if not params.min_int <= r <= params.max_int:
        raise ValueError(f"{name}: {v:g} does not fit Q({params.n}, {params.frac}) "
                         f"[{params.min_int / params.scale:g}, {params.max_int / params.scale:g}]")
    return r


def quantize_frames(params: KfParams, scenario: RlcScenario) -> QuantizedFrames:
    """Frame inputs as raw Q(N, FRAC) integers (round to nearest).

    A, B, H (the model) must fit the format (a ``ValueError`` naming the entry otherwise);
    the source u and the measurements z saturate like an ADC, counted in the result's
    ``saturated`` and ``saturated_frames``. Non-finite values are a ``ValueError``."""
    const = {}
    for name, M in (("A", scenario.A), ("B", scenario.B), ("H", scenario.H)):
        M = validate.finite_array(f"scenario.{name}", M, (2, 2))
        for i in (0, 1):
            for j in (0, 1):
                const[f"{name}{i}{j}"] = _to_raw(f"scenario.{name}[{i}, {j}]", M[i, j], params)
    u = validate.finite_array("scenario.u", scenario.u, (-1, 2))
    z = validate.finite_array("scenario.z", scenario.z, (-1, 2))
    if len(u) != len(z):
        raise ValueError(f"scenario.z: {len(z)} frames, scenario.u has {len(u)}")
    raw = np.floor(np.column_stack([u, z]) * params.scale + 0.5)
    clipped = np.clip(raw, params.min_int, params.max_int)
    hit = clipped != raw
    words = clipped.astype(np.int64).tolist()
    out = QuantizedFrames()
    for k in range(len(u)):
        fr = dict(const)
        fr.update(zip(("u0", "u1", "z0", "z1"), words[k], strict=True))
        out.append(fr)
    out.saturated = int(hit.sum())
    out.saturated_frames = tuple(int(k) for k in np.flatnonzero(hit.any(axis=1)))
    return out


def init_state(params: KfParams, x=(0.0, 0.0), P=(1.0, 0.0, 1.0), Q=(0.01, 0.0, 0.01),
               R=(0.25, 0.0, 0.25)) -> dict:
    """Raw initial state from real values (P, Q, R as (00, 01, 11)).

    Every value must fit Q(N, FRAC) (a ``ValueError`` naming it, never a silent saturation)
    and P, Q, R must be symmetric positive semi-definite."""
    x = validate.finite_array("x", x, (2,))
    st = {"x0": _to_raw("x[0]", x[0], params), "x1": _to_raw("x[1]", x[1], params),
          "dq0": 0, "dq1": 0, "ep0": 0, "ep1": 0, "gp00": 0, "gp11": 0}
    for name, vals in (("P", P), ("Q", Q), ("R", R)):
        a, b, c = validate.finite_array(name, vals, (3,))
        validate.covariance(f"{name} (00, 01, 11)", [[a, b], [b, c]], 2)
        for key, v in zip(("00", "01", "11"), (a, b, c), strict=True):
            st[name + key] = _to_raw(f"{name}{key}", v, params)
    return st


__all__ += ["init_state", "COMMIT", "reciprocal", "QuantizedFrames", "check_state",
            "check_frames"]
