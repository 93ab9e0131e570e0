"""Seed 000's PL computations as float32 operation programs (the bit-true face of the PL).

Reference: seed 000 "INS Mechanization", "Covariance Propagation" (sparse Phi, 120 stored
elements of P), "Kalman Update Engine" (innovation, S, 2x2 inverse by the direct formula,
K, state and covariance update); the pattern is seed 004's frame program
(:func:`navgate.systems.kf2x2.model.frame_program`): one list of operations that is executed by
the bit-true model, scheduled onto shared units for the gateware, and counted for cycle
estimates. docs/seed000-navigator.md is the full description.

Representation
--------------
A :class:`Program` is a list of :class:`Op` in SSA form: every op writes a *new* temporary
``dst = kind(*srcs)``; its operands are named registers of four classes:

* **state** (:data:`STATE_REGS`): persistent registers: navigation state (``pN pE h vN vE vD
  q0..q3``: position float32 NED metres about the reference point the PS set, height, NED
  velocity, quaternion C_b^n), the Kahan compensation words of the position
  (``cN cE cD``: the position is ``pN - cN`` etc.), of velocity and quaternion (``cvN cvE
  cvD cq0..3``), the position scale factors ``kN kE``
  of the last step, the bias estimates (``ba0..2 bg0..2``), the 120-element upper
  triangle of P (``P{i}_{j}``, i <= j), and configuration words the PS writes
  (calibration, dt, noise, reference point: :data:`CONFIG_REGS`);
* **input**: the per-call inputs (IMU words, measurement, R, lag, gate);
* **const**: float32 literals (``c:<hex bits>``), a ROM in the gateware;
* **temp**: SSA values.

At the end of a program, ``commit`` copies temporaries into state registers (all reads of a
state register in the program see its value at program start, so the gateware may overwrite
state in any order once the last read is done). ``outputs`` names temporaries the sequencer
reads (the gate flags, NIS).

Operations (the cores of :mod:`navgate.gateware.fp32`, :mod:`navgate.numerics.fp32`
semantics: round to nearest even, subnormals flushed on input and output): ``add sub mul div
sqrt``; ``neg`` (sign flip, wiring); ``cvt`` (an input number to float32: exact for int16
words); ``le``/``lt`` (compare, result 1.0 or 0.0).

Numerical choices (derivations in docs/seed000-navigator.md): the rotation-vector
quaternion by its Taylor series in |theta|^2 (terms to |theta|^4; truncation below
|theta|^6 / 46080, < 1.2e-11 for |theta| <= 0.0873 rad = 2000 deg/s over 2.5 ms); the
navigation-frame rotation (|theta| < 1e-6) to first order; quaternion normalisation by the
first-order correction q <- q (3 - |q|^2) / 2 (residual 3/4 eps^2 for |q|^2 = 1 + eps);
sin/cos of latitude from the reference point's by the angle-sum formula with the series of
the offset (|dlat| <= 0.02 rad: truncation < 7e-9).
"""

from __future__ import annotations

from dataclasses import dataclass

from navgate.nav.earth import E2, GAMMA_E, M_RATIO, OMEGA_IE, SOMIGLIANA_K, A, F
from navgate.nav.eskf import N_STATES
from navgate.opflow.ir import UNIT, Builder, Program

NAV_REGS = ("pN", "pE", "h", "vN", "vE", "vD", "q0", "q1", "q2", "q3")
P_REGS = tuple(f"P{i}_{j}" for i in range(N_STATES) for j in range(i, N_STATES))
CP_REGS = tuple("c" + p for p in P_REGS)  #: Kahan compensation words of P
CAL_REGS = tuple(f"cal_{s}_{p}" for s in ("g", "a")
                 for p in ("lsb", "b0", "b1", "b2", "m00", "m01", "m02", "m10", "m11", "m12",
                           "m20", "m21", "m22"))
CONFIG_REGS = CAL_REGS + (
    "dt", "half_dt", "q_vel", "q_att", "q_ba", "q_bg", "eps_a", "eps_g", "e2_a", "e2_g",
    "sin_lat0", "cos_lat0", "inv_mlat", "m_lat", "m_lon")
STATE_REGS = NAV_REGS + ("cN", "cE", "cD", "cvN", "cvE", "cvD", "cq0", "cq1", "cq2", "cq3",
                         "kN", "kE", "ba0", "ba1", "ba2", "bg0", "bg1", "bg2") \
    + P_REGS + CP_REGS + CONFIG_REGS


def p_reg(i: int, j: int) -> str:
    """The stored element of P at (i, j) (upper triangle)."""
    return f"P{min(i, j)}_{max(i, j)}"


# ------------------------------------------------------------------ calibration


def emit_calibration(b: Builder, words_g, words_a):
    """Seed 000 ``imu_calibration`` in exactly the order of
    :func:`navgate.nav.calibration.apply_calibration_fp32`; returns (gyro[3], accel[3])."""
    b.module = "imu_calibration"
    out = []
    for s, words in (("g", words_g), ("a", words_a)):
        x = [b.sub(b.mul(b.cvt(w), f"cal_{s}_lsb"), f"cal_{s}_b{j}") for j, w in enumerate(words)]
        out.append([b.add(b.add(b.mul(f"cal_{s}_m{i}0", x[0]), b.mul(f"cal_{s}_m{i}1", x[1])),
                          b.mul(f"cal_{s}_m{i}2", x[2])) for i in range(3)])
    return out[0], out[1]


def calibration_program() -> Program:
    ins = ("wg0", "wg1", "wg2", "wa0", "wa1", "wa2")
    b = Builder("imu_calibration", ins, registers=STATE_REGS)
    g, a = emit_calibration(b, ins[:3], ins[3:])
    b.prog.outputs = {"g0": g[0], "g1": g[1], "g2": g[2], "a0": a[0], "a1": a[1], "a2": a[2]}
    return b.prog


# ------------------------------------------------------------------ mechanization


def _dcm(b: Builder, q):
    q0, q1, q2, q3 = q
    sq = {i: b.mul(q[i], q[i]) for i in range(4)}

    def twice(x):
        return b.add(x, x)

    c = [[None] * 3 for _ in range(3)]
    c[0][0] = b.sub(b.sub(b.add(sq[0], sq[1]), sq[2]), sq[3])
    c[1][1] = b.sub(b.add(b.sub(sq[0], sq[1]), sq[2]), sq[3])
    c[2][2] = b.add(b.sub(b.sub(sq[0], sq[1]), sq[2]), sq[3])
    p12, p03 = b.mul(q1, q2), b.mul(q0, q3)
    p13, p02 = b.mul(q1, q3), b.mul(q0, q2)
    p23, p01 = b.mul(q2, q3), b.mul(q0, q1)
    c[0][1] = twice(b.sub(p12, p03))
    c[1][0] = twice(b.add(p12, p03))
    c[0][2] = twice(b.add(p13, p02))
    c[2][0] = twice(b.sub(p13, p02))
    c[1][2] = twice(b.sub(p23, p01))
    c[2][1] = twice(b.add(p23, p01))
    return c


def _rotvec_quat(b: Builder, x, y, z):
    """Quaternion of the rotation vector (x, y, z): series in a2 = |theta|^2."""
    a2 = b.add(b.add(b.mul(x, x), b.mul(y, y)), b.mul(z, z))
    w = b.add(1.0, b.mul(a2, b.add(-1.0 / 8.0, b.mul(a2, 1.0 / 384.0))))
    s = b.add(0.5, b.mul(a2, b.add(-1.0 / 48.0, b.mul(a2, 1.0 / 3840.0))))
    return w, b.mul(s, x), b.mul(s, y), b.mul(s, z)


def _qmul(b: Builder, a, c):
    a0, a1, a2, a3 = a
    b0, b1, b2, b3 = c
    m = b.mul
    return (b.sum([(1, m(a0, b0)), (-1, m(a1, b1)), (-1, m(a2, b2)), (-1, m(a3, b3))]),
            b.sum([(1, m(a0, b1)), (1, m(a1, b0)), (1, m(a2, b3)), (-1, m(a3, b2))]),
            b.sum([(1, m(a0, b2)), (-1, m(a1, b3)), (1, m(a2, b0)), (1, m(a3, b1))]),
            b.sum([(1, m(a0, b3)), (1, m(a1, b2)), (-1, m(a2, b1)), (1, m(a3, b0))]))


def _normalise(b: Builder, q):
    n2 = b.add(b.add(b.add(b.mul(q[0], q[0]), b.mul(q[1], q[1])), b.mul(q[2], q[2])),
               b.mul(q[3], q[3]))
    k = b.sub(1.5, b.mul(0.5, n2))
    return tuple(b.mul(qi, k) for qi in q)


@dataclass
class FrameTerms:
    s: str
    c: str
    rn: str
    re: str
    inv_rn_h: str
    inv_re_h: str
    wie_n: str
    wie_d: str
    wen_n: str
    wen_e: str
    wen_d: str
    g: str
    kn: str
    ke: str


def _frame_terms(b: Builder) -> FrameTerms:
    """Radii, Earth and transport rates, gravity and position scale factors at the start of
    the interval (nav.strapdown._frame_terms), latitude from the reference point's."""
    b.module = "ins_mechanization"
    d = b.mul("pN", "inv_mlat")
    d2 = b.mul(d, d)
    cd = b.sub(1.0, b.mul(0.5, d2))
    sd = b.sub(d, b.mul(b.mul(d, d2), 1.0 / 6.0))
    s = b.add(b.mul("sin_lat0", cd), b.mul("cos_lat0", sd))
    c = b.sub(b.mul("cos_lat0", cd), b.mul("sin_lat0", sd))
    s2 = b.mul(s, s)
    dd = b.sub(1.0, b.mul(E2, s2))
    sqrt_d = b.sqrt(dd)
    re = b.div(A, sqrt_d)
    rn = b.div(b.mul(re, 1.0 - E2), dd)
    inv_re_h = b.div(1.0, b.add(re, "h"))
    inv_rn_h = b.div(1.0, b.add(rn, "h"))
    inv_c = b.div(1.0, c)
    wie_n = b.mul(OMEGA_IE, c)
    wie_d = b.neg(b.mul(OMEGA_IE, s))
    wen_n = b.mul("vE", inv_re_h)
    wen_e = b.neg(b.mul("vN", inv_rn_h))
    wen_d = b.neg(b.mul(wen_n, b.mul(s, inv_c)))
    g0 = b.mul(b.mul(GAMMA_E / A, b.add(1.0, b.mul(SOMIGLIANA_K, s2))), re)
    c1 = b.sub(2.0 / A * (1.0 + F + M_RATIO), b.mul(2.0 / A * 2.0 * F, s2))
    bracket = b.add(b.sub(1.0, b.mul(c1, "h")), b.mul(b.mul("h", "h"), 3.0 / (A * A)))
    g = b.mul(g0, bracket)
    kn = b.mul("m_lat", inv_rn_h)
    ke = b.mul(b.mul("m_lon", inv_re_h), inv_c)
    return FrameTerms(s, c, rn, re, inv_rn_h, inv_re_h, wie_n, wie_d, wen_n, wen_e, wen_d, g,
                      kn, ke)


def _attitude_increment(b: Builder, q, theta, n):
    """q <- normalise(n (x) q (x) dq(theta)) in increment form with Kahan compensation.

    dq(theta) = [1 + wm1, s theta] (series); the new quaternion is q + D with
    D = q (wm1 + km1) + q (x) [0, s theta] + [0, n] (x) q, km1 = (1 - |q|^2) / 2 the
    first-order normalisation of the current q; the second-order cross terms
    (|n| |theta| < 1e-10 per sample) are dropped. D is formed in full relative precision and
    added to q with a compensation word per component (``cq0..3``)."""
    m = b.mul
    x, y, z = theta
    a2 = b.add(b.add(m(x, x), m(y, y)), m(z, z))
    wm1 = m(a2, b.add(-1.0 / 8.0, m(a2, 1.0 / 384.0)))
    s = b.add(0.5, m(a2, b.add(-1.0 / 48.0, m(a2, 1.0 / 3840.0))))
    v1, v2, v3 = m(s, x), m(s, y), m(s, z)
    q0, q1, q2, q3 = q
    n2 = b.add(b.add(b.add(m(q0, q0), m(q1, q1)), m(q2, q2)), m(q3, q3))
    km1 = b.sub(0.5, m(0.5, n2))
    sc = b.add(wm1, km1)
    nx, ny, nz = n
    d = (b.sum([(1, m(q0, sc)), (-1, m(q1, v1)), (-1, m(q2, v2)), (-1, m(q3, v3)),
                (-1, m(nx, q1)), (-1, m(ny, q2)), (-1, m(nz, q3))]),
         b.sum([(1, m(q1, sc)), (1, m(q0, v1)), (1, m(q2, v3)), (-1, m(q3, v2)),
                (1, m(nx, q0)), (1, m(ny, q3)), (-1, m(nz, q2))]),
         b.sum([(1, m(q2, sc)), (1, m(q0, v2)), (-1, m(q1, v3)), (1, m(q3, v1)),
                (-1, m(nx, q3)), (1, m(ny, q0)), (1, m(nz, q1))]),
         b.sum([(1, m(q3, sc)), (1, m(q0, v3)), (1, m(q1, v2)), (-1, m(q2, v1)),
                (1, m(nx, q2)), (-1, m(ny, q1)), (1, m(nz, q0))]))
    out = []
    for i in range(4):
        qi, ci = _kahan(b, q[i], f"cq{i}", d[i])
        b.prog.commit[f"cq{i}"] = ci
        out.append(qi)
    return tuple(out)


def _kahan(b: Builder, p, comp, inc):
    """p + inc with the compensation word ``comp`` (Kahan summation); returns (p', comp')."""
    y = b.sub(inc, comp)
    t = b.add(p, y)
    comp_new = b.sub(b.sub(t, p), y)
    return t, comp_new


def emit_mechanization(b: Builder, gyro, accel, compensated: bool = True):
    """One strapdown step (nav.strapdown.mechanize_step in float32); returns the values the
    covariance propagation needs and fills the commit map."""
    ft = _frame_terms(b)
    b.module = "ins_mechanization"
    w = [b.sub(gyro[i], f"bg{i}") for i in range(3)]
    f = [b.sub(accel[i], f"ba{i}") for i in range(3)]
    q = ("q0", "q1", "q2", "q3")
    c_old = _dcm(b, q)
    ix = b.add(ft.wie_n, ft.wen_n)
    iy = ft.wen_e
    iz = b.add(ft.wie_d, ft.wen_d)
    # navigation-frame rotation of -(w_ie + w_en) dt, first order: [1, -w dt / 2]
    nx, ny, nz = (b.neg(b.mul(v, "half_dt")) for v in (ix, iy, iz))
    m = b.mul
    if compensated:
        q = _attitude_increment(b, q, [m(w[i], "dt") for i in range(3)], (nx, ny, nz))
    else:
        dqb = _rotvec_quat(b, b.mul(w[0], "dt"), b.mul(w[1], "dt"), b.mul(w[2], "dt"))
        q = _qmul(b, q, dqb)
        q = (b.sum([(1, q[0]), (-1, m(nx, q[1])), (-1, m(ny, q[2])), (-1, m(nz, q[3]))]),
             b.sum([(1, q[1]), (1, m(nx, q[0])), (1, m(ny, q[3])), (-1, m(nz, q[2]))]),
             b.sum([(1, q[2]), (-1, m(nx, q[3])), (1, m(ny, q[0])), (1, m(nz, q[1]))]),
             b.sum([(1, q[3]), (1, m(nx, q[2])), (-1, m(ny, q[1])), (1, m(nz, q[0]))]))
        q = _normalise(b, q)
    c_new = _dcm(b, q)
    f_n = []
    for i in range(3):
        s = b.add(b.add(m(b.add(c_old[i][0], c_new[i][0]), f[0]),
                        m(b.add(c_old[i][1], c_new[i][1]), f[1])),
                  m(b.add(c_old[i][2], c_new[i][2]), f[2]))
        f_n.append(m(s, 0.5))
    wx = b.add(b.add(ft.wie_n, ft.wie_n), ft.wen_n)
    wy = ft.wen_e
    wz = b.add(b.add(ft.wie_d, ft.wie_d), ft.wen_d)
    cor_n = b.sub(m(wy, "vD"), m(wz, "vE"))
    cor_e = b.sub(m(wz, "vN"), m(wx, "vD"))
    cor_d = b.sub(m(wx, "vE"), m(wy, "vN"))
    dv = (m(b.sub(f_n[0], cor_n), "dt"), m(b.sub(f_n[1], cor_e), "dt"),
          m(b.sub(b.add(f_n[2], ft.g), cor_d), "dt"))
    if compensated:
        (vn, cvn), (ve, cve), (vd, cvd) = (_kahan(b, v, f"c{v}", d)
                                           for v, d in zip(("vN", "vE", "vD"), dv, strict=True))
        b.prog.commit.update({"cvN": cvn, "cvE": cve, "cvD": cvd})
    else:
        vn, ve, vd = (b.add(v, d) for v, d in zip(("vN", "vE", "vD"), dv, strict=True))
    inc_n = m(m(b.add("vN", vn), "half_dt"), ft.kn)
    inc_e = m(m(b.add("vE", ve), "half_dt"), ft.ke)
    inc_h = b.neg(m(b.add("vD", vd), "half_dt"))
    if compensated:
        pn, cn = _kahan(b, "pN", "cN", inc_n)
        pe, ce = _kahan(b, "pE", "cE", inc_e)
        h, cd = _kahan(b, "h", "cD", inc_h)
        b.prog.commit.update({"cN": cn, "cE": ce, "cD": cd})
    else:
        pn, pe, h = b.add("pN", inc_n), b.add("pE", inc_e), b.add("h", inc_h)
    b.prog.commit.update({"pN": pn, "pE": pe, "h": h, "vN": vn, "vE": ve, "vD": vd,
                          "q0": q[0], "q1": q[1], "q2": q[2], "q3": q[3],
                          "kN": ft.kn, "kE": ft.ke})
    return ft, c_old, f_n, (wx, wy, wz), (ix, iy, iz)


# ------------------------------------------------------------------ covariance propagation


def emit_phi(b: Builder, ft: FrameTerms, c_old, f_n, wxyz, ixyz):
    """The non-zero, non-unit entries of Phi = I + F dt (nav.eskf._build_phi) as a dict
    (i, j) -> register; unit entries are listed in the set ``ones``."""
    b.module = "phi_q_generation"
    m = b.mul
    phi = {}
    ones = {(i, i) for i in range(9)}
    for i in range(3):
        phi[i, 3 + i] = "dt"
    wx, wy, wz = (m(v, "dt") for v in wxyz)
    phi[3, 4], phi[3, 5] = wz, b.neg(wy)
    phi[4, 3], phi[4, 5] = b.neg(wz), wx
    phi[5, 3], phi[5, 4] = wy, b.neg(wx)
    r0 = b.add(b.sqrt(m(ft.rn, ft.re)), "h")
    phi[5, 2] = b.div(m(2.0 * 9.80665, "dt"), r0)
    fx, fy, fz = (m(v, "dt") for v in f_n)
    phi[3, 7], phi[3, 8] = fz, b.neg(fy)
    phi[4, 6], phi[4, 8] = b.neg(fz), fx
    phi[5, 6], phi[5, 7] = fy, b.neg(fx)
    ix, iy, iz = (m(v, "dt") for v in ixyz)
    phi[6, 7], phi[6, 8] = iz, b.neg(iy)
    phi[7, 6], phi[7, 8] = b.neg(iz), ix
    phi[8, 6], phi[8, 7] = iy, b.neg(ix)
    for i in range(3):
        for j in range(3):
            e = b.neg(m(c_old[i][j], "dt"))
            phi[3 + i, 9 + j] = e
            phi[6 + i, 12 + j] = e
        # bias decay exp(-dt/tau) = 1 - eps: held as eps (see emit_covariance)
        phi[9 + i, 9 + i] = "eps_a"
        phi[12 + i, 12 + i] = "eps_g"
    return phi, ones


def emit_covariance(b: Builder, phi: dict, ones: set):
    """P <- Phi P Phi' + Q on the 120 stored elements, skipping Phi's zero and unit entries.

    A = Phi P (all 225 entries, row i: sum over Phi's row pattern in ascending column order);
    P'_ij = sum_k A_ik Phi_jk for j >= i (ascending k), plus Q on the diagonal.
    """
    b.module = "covariance_propagator"
    n = N_STATES
    rows = {i: sorted([k for (r, k) in list(phi) + list(ones) if r == i]) for i in range(n)}

    def term(i, k, x):
        return x if (i, k) in ones else b.mul(phi[i, k], x)

    a = {}
    for i in range(n):
        for j in range(n):
            if i >= 9:  # bias rows: (1 - eps) P = P - eps P (eps keeps full precision)
                if i == j:
                    continue  # the diagonal bias entries are done in one step below
                a[i, j] = b.sub(p_reg(i, j), b.mul(phi[i, i], p_reg(i, j)))
            else:
                a[i, j] = b.sum([(1, term(i, k, p_reg(k, j))) for k in rows[i]])
    q = {i: "q_vel" for i in (3, 4, 5)} | {i: "q_att" for i in (6, 7, 8)}
    for i in range(n):
        for j in range(i, n):
            if i == j and i >= 9:
                # (1 - eps)^2 P + q = P + (q - e2 P), e2 = 1 - (1 - eps)^2: the increment is
                # formed before it meets P, so the stationary variance stays put
                qq, e2 = ("q_ba", "e2_a") if i < 12 else ("q_bg", "e2_g")
                v = b.add(p_reg(i, i), b.sub(qq, b.mul(e2, p_reg(i, i))))
            elif j >= 9:
                v = b.sub(a[i, j], b.mul(a[i, j], phi[j, j]))
            else:
                v = b.sum([(1, a[i, k] if (j, k) in ones else b.mul(a[i, k], phi[j, k]))
                           for k in rows[j]])
                if i == j and i in q:
                    v = b.add(v, q[i])
            b.prog.commit[p_reg(i, j)] = v


def emit_covariance_increment(b: Builder, phi: dict, ones: set):
    """P <- P + E, E = G P + (G P)' + (G P) G' + Q with G = Phi - I (the same products as
    Phi P Phi' + Q, formed as an increment so that the small per-sample changes keep their
    full relative precision), added to each of the 120 stored elements with a Kahan
    compensation word ``cP{i}_{j}`` (the covariance is P - cP)."""
    b.module = "covariance_propagator"
    n = N_STATES
    g_rows = {i: sorted(k for (r, k) in phi if r == i) for i in range(n)}

    def g_entry(i, k, x):
        """G_ik * x: the bias rows' G_ii = -eps."""
        if i >= 9:
            return b.neg(b.mul(phi[i, i], x))
        return b.mul(phi[i, k], x)

    mm = {}
    for i in range(n):
        for j in range(n):
            if i >= 9 and i == j:
                continue
            mm[i, j] = b.sum([(1, g_entry(i, k, p_reg(k, j))) for k in g_rows[i]])
    q = {i: "q_vel" for i in (3, 4, 5)} | {i: "q_att" for i in (6, 7, 8)}
    for i in range(n):
        for j in range(i, n):
            if i == j and i >= 9:
                qq, e2 = ("q_ba", "e2_a") if i < 12 else ("q_bg", "e2_g")
                e = b.sub(qq, b.mul(e2, p_reg(i, i)))
            else:
                terms = [(1, mm[i, j]), (1, mm[j, i])]
                if j >= 9:
                    terms.append((-1, b.mul(mm[i, j], phi[j, j])))
                else:
                    terms += [(1, b.mul(mm[i, k], phi[j, k])) for k in g_rows[j]]
                if i == j and i in q:
                    terms.append((1, q[i]))
                e = b.sum(terms)
            pij, cij = _kahan(b, p_reg(i, j), "c" + p_reg(i, j), e)
            b.prog.commit[p_reg(i, j)] = pij
            b.prog.commit["c" + p_reg(i, j)] = cij


def propagate_program(compensated: bool = True) -> Program:
    """One IMU sample: calibration, mechanization, Phi/Q, covariance propagation."""
    ins = ("wg0", "wg1", "wg2", "wa0", "wa1", "wa2")
    b = Builder("propagate", ins, registers=STATE_REGS)
    g, a = emit_calibration(b, ins[:3], ins[3:])
    ft, c_old, f_n, wxyz, ixyz = emit_mechanization(b, g, a, compensated)
    phi, ones = emit_phi(b, ft, c_old, f_n, wxyz, ixyz)
    if compensated:
        emit_covariance_increment(b, phi, ones)
    else:
        emit_covariance(b, phi, ones)
    return b.prog


# ------------------------------------------------------------------ Kalman update engine


#: the module of the ops that zero P's compensation words in an update
RESET_MODULE = "compensation_reset"


def _joseph(b: Builder, cols, k, s):
    """P <- P - C K' + K W' with W = K S - C on the upper triangle, C = P H' (15 x m) and S
    (m x m, symmetric, as dict (r, c) -> reg): the Joseph form P - K C' - C K' + K S K' for
    these H, written with 2m products an element instead of 3m (S K' - C' = W'; issue 29,
    docs/seed000-engines.md, "The shorter Joseph form"). The update reads the stored P (not
    P - cP) and zeroes each compensation word cP: the covariance after an update is the new
    P alone (docs/seed000-engines.md, "Compensation words")."""
    m_dim = len(cols)
    n = N_STATES
    w = {}
    for j in range(n):
        for r in range(m_dim):
            sk = b.sum([(1, b.mul(s[min(r, c), max(r, c)], k[c][j])) for c in range(m_dim)])
            w[j, r] = b.sub(sk, cols[r][j])
    for i in range(n):
        for j in range(i, n):
            terms = [(1, p_reg(i, j))]
            terms += [(-1, b.mul(cols[r][i], k[r][j])) for r in range(m_dim)]
            terms += [(1, b.mul(k[r][i], w[j, r])) for r in range(m_dim)]
            b.prog.commit[p_reg(i, j)] = b.sum(terms)
            # the new P is the whole covariance: its compensation word restarts at zero
            # (cP - cP = +0 for every finite cP; a NaN or infinite word stays NaN)
            module, b.module = b.module, RESET_MODULE
            b.prog.commit["c" + p_reg(i, j)] = b.sub("c" + p_reg(i, j), "c" + p_reg(i, j))
            b.module = module


def emit_correction(b: Builder, dx):
    """Closed-loop feedback of dx (eskf.ErrorStateFilter.apply_correction in float32)."""
    b.module = "state_correction"
    m = b.mul
    commit = b.prog.commit
    commit["pN"] = b.sub("pN", m(dx[0], "kN"))
    commit["pE"] = b.sub("pE", m(dx[1], "kE"))
    commit["h"] = b.add("h", dx[2])
    for i, v in enumerate(("vN", "vE", "vD")):
        commit[v] = b.sub(v, dx[3 + i])
    dq = _rotvec_quat(b, b.neg(dx[6]), b.neg(dx[7]), b.neg(dx[8]))
    q = _qmul(b, dq, ("q0", "q1", "q2", "q3"))
    q = _normalise(b, q)
    for i in range(4):
        commit[f"q{i}"] = q[i]
    for i in range(3):
        commit[f"ba{i}"] = b.sub(f"ba{i}", dx[9 + i])
        commit[f"bg{i}"] = b.sub(f"bg{i}", dx[12 + i])


def altitude_gate_program() -> Program:
    """1-D update, first half: innovation, S, NIS and the gate (sequencer reads ``accept``)."""
    b = Builder("kalman_update_engine", ("h_meas", "r", "gate"), registers=STATE_REGS)
    y = b.add(b.sub("h_meas", "h"), "cD")
    s = b.add(p_reg(2, 2), "r")
    inv = b.div(1.0, s)
    nis = b.mul(b.mul(y, y), inv)
    b.prog.outputs = {"nis": nis, "accept": b.le(nis, "gate"), "positive": b.lt(0.0, s)}
    return b.prog


def altitude_apply_program() -> Program:
    """1-D update, second half (run when accepted): K, Joseph covariance update, feedback."""
    b = Builder("kalman_update_engine", ("h_meas", "r"), registers=STATE_REGS)
    y = b.add(b.sub("h_meas", "h"), "cD")
    s = b.add(p_reg(2, 2), "r")
    inv = b.div(1.0, s)
    col = [p_reg(i, 2) for i in range(N_STATES)]
    k = [b.mul(ci, inv) for ci in col]
    _joseph(b, [col], [k], {(0, 0): s})
    b.module = "kalman_update_engine"
    dx = [b.mul(ki, y) for ki in k]
    emit_correction(b, dx)
    b.prog.outputs = {f"dx{i}": dx[i] for i in range(N_STATES)}
    return b.prog


def _trn_common(b: Builder):
    """C = P H' for H = [I2, -lag I2 (velocity), 0], S = H C + R, det, S^-1, NIS."""
    n = N_STATES
    cols = [[b.sub(p_reg(i, 0), b.mul("lag", p_reg(i, 3))) for i in range(n)],
            [b.sub(p_reg(i, 1), b.mul("lag", p_reg(i, 4))) for i in range(n)]]
    s00 = b.add(b.sub(cols[0][0], b.mul("lag", cols[0][3])), "r00")
    s01 = b.add(b.sub(cols[1][0], b.mul("lag", cols[1][3])), "r01")
    s11 = b.add(b.sub(cols[1][1], b.mul("lag", cols[1][4])), "r11")
    det = b.sub(b.mul(s00, s11), b.mul(s01, s01))
    inv = b.div(1.0, det)
    i00, i01, i11 = b.mul(s11, inv), b.neg(b.mul(s01, inv)), b.mul(s00, inv)
    y0, y1 = "y0", "y1"
    nis = b.add(b.add(b.mul(b.mul(y0, y0), i00), b.mul(b.mul(b.add(y0, y0), y1), i01)),
                b.mul(b.mul(y1, y1), i11))
    return cols, {(0, 0): s00, (0, 1): s01, (1, 1): s11}, det, (i00, i01, i11), nis


TRN_INPUTS = ("y0", "y1", "r00", "r01", "r11", "lag", "gate")


def trn_gate_program() -> Program:
    b = Builder("kalman_update_engine", TRN_INPUTS, registers=STATE_REGS)
    _, _, det, _, nis = _trn_common(b)
    b.prog.outputs = {"nis": nis, "accept": b.le(nis, "gate"), "positive": b.lt(0.0, det)}
    return b.prog


def trn_apply_program() -> Program:
    b = Builder("kalman_update_engine", TRN_INPUTS, registers=STATE_REGS)
    cols, s, _, (i00, i01, i11), _ = _trn_common(b)
    n = N_STATES
    k0 = [b.add(b.mul(cols[0][i], i00), b.mul(cols[1][i], i01)) for i in range(n)]
    k1 = [b.add(b.mul(cols[0][i], i01), b.mul(cols[1][i], i11)) for i in range(n)]
    _joseph(b, cols, [k0, k1], s)
    b.module = "kalman_update_engine"
    dx = [b.add(b.mul(k0[i], "y0"), b.mul(k1[i], "y1")) for i in range(n)]
    emit_correction(b, dx)
    b.prog.outputs = {f"dx{i}": dx[i] for i in range(N_STATES)}
    return b.prog


# ------------------------------------------------------------------ cycle estimates


def schedule_bounds(prog: Program, latency: dict, units: dict) -> dict:
    """Lower bounds on one program's cycles on pipelined units (one issue per unit per
    cycle): the dependency bound (critical path; state, input and constant operands ready at
    cycle 0, ``neg`` free) and the resource bound (ops on a unit kind / units of that kind).

    ``latency``: kind of unit (``UNIT`` values: add, mul, div, sqrt, cmp, cvt) -> cycles from
    issue to a usable result; ``units``: unit kind -> count. Any schedule needs at least
    ``max`` of the two; the list scheduler of the gateware issue reports the achieved count.
    """
    ready: dict = {}
    for op in prog.ops:
        start = max((ready.get(s, 0) for s in op.srcs), default=0)
        unit = UNIT[op.kind]
        ready[op.dst] = start + (0 if unit == "wire" else latency[unit])
    path = max(ready.values(), default=0)
    per_unit: dict = {}
    for op in prog.ops:
        unit = UNIT[op.kind]
        if unit != "wire":
            per_unit[unit] = per_unit.get(unit, 0) + 1
    resource = max((-(-n // units[u]) for u, n in per_unit.items()), default=0)
    return {"critical_path": path, "resource": resource, "bound": max(path, resource),
            "ops_per_unit": per_unit}


# ------------------------------------------------------------------ error bounds


def rotvec_series_bound(theta_max: float) -> tuple[float, float]:
    """Truncation bounds of the rotation-vector series at |theta| <= theta_max:
    (|cos(a/2) - w|, |sin(a/2)/a - s|) <= (a^6/46080, a^6/322560) (alternating series with
    decreasing terms: the error is below the first omitted term)."""
    a6 = theta_max**6
    return a6 / 46080.0, a6 / 322560.0


def latitude_series_bound(dlat_max: float) -> float:
    """Truncation of cos(d) ~ 1 - d^2/2 and sin(d) ~ d - d^3/6: <= d^4/24 (+ d^5/120)."""
    return dlat_max**4 / 24.0 + dlat_max**5 / 120.0


_PROGRAMS = {}


def programs(compensated: bool = True) -> dict:
    """The engine's programs (built once per process)."""
    key = bool(compensated)
    if key not in _PROGRAMS:
        _PROGRAMS[key] = {
            "propagate": propagate_program(compensated),
            "alt_gate": altitude_gate_program(),
            "alt_apply": altitude_apply_program(),
            "trn_gate": trn_gate_program(),
            "trn_apply": trn_apply_program(),
        }
    return _PROGRAMS[key]
