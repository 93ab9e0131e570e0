"""Seed 003's attitude solve as an operation program (what the gateware schedules).

Reference: seed 003 sections 3.1.2-3.1.8 (modules INS_acc, INS_mag, INS_gyro, INS_quat,
INS_matx, INS_euler and the fix16 arctangent) and :mod:`navgate.systems.attitude.mahony_fp32`,
whose docstring fixes the operation order. :func:`solve_program` writes that order down as an
:class:`navgate.opflow.ir.Program`, one op per rounded float32 operation (or exact bit
manipulation), so that :mod:`navgate.opflow.phased` can place it on shared arithmetic units
(the unit choices are :mod:`navgate.systems.attitude.datapath`) and :func:`run_program` can
evaluate it with :func:`navgate.opflow.execute.run_bittrue` (:mod:`navgate.numerics.fp32`; the
tests check that evaluation against ``mahony_fp32`` bit for bit, so program and model cannot
drift).

Operation kinds (unit in brackets):

* ``mul``, ``add``, ``sub``, ``div``, ``sqrt`` [the float32 cores];
* the circuit's own kinds (:data:`OWN_KINDS`, evaluated by :data:`EVAL`): ``neg``
  (``fp32_neg``), ``dbl`` (``fp32_add(x, x)``, the exact doubling of INS_matx),
  ``clampneg`` (a negative value -> +0, EULER_P), ``yawsel`` (``a < 0 ? b : a``, the yaw
  wrap) [the one-cycle ``misc`` unit]; ``atan`` (cos, sin) -> radians [the fix16
  arctangent of section 3.1.8]. ``neg`` is opflow's sign flip, but here it runs on the misc
  unit (the circuit has no operand sign flip).

Value names: sensor inputs ``ax ay az mx my mz gx gy gz`` (after the model's axis signs),
state ``q0..q3``, ``c11..c33``, ``exi eyi ezi`` (the integral), parameters ``kp ki dt``,
constants ``ONE HALF D2R R2D F360``. New state values carry ``_n`` (``q0_n``, ``c11_n``,
``exi_n``); the solve's outputs are ``pitch roll yaw`` (degrees, float32); other
temporaries are ``t<n>``.
"""

from __future__ import annotations

import numpy as np

from navgate.numerics.fp32 import (
    fp32_add,
    fp32_compare,
    fp32_div,
    fp32_mul,
    fp32_neg,
    fp32_sqrt,
    fp32_sub,
)
from navgate.opflow.execute import run_bittrue
from navgate.opflow.ir import Builder, Program
from navgate.systems.attitude import mahony_fp32 as bt
from navgate.systems.attitude.atan16 import atan_fp32

__all__ = ["MODULES", "SENSORS", "STATE", "PARAMS", "CONSTANTS", "solve_program",
           "run_program", "module_interface", "UNIT_OF_KIND", "OWN_KINDS", "EVAL"]

#: seed modules in FSM order (acc and mag share the ACC_MAG state)
MODULES = ("acc", "mag", "gyro", "quat", "matx", "euler")
SENSORS = ("ax", "ay", "az", "mx", "my", "mz", "gx", "gy", "gz")
C_NAMES = ("c11", "c12", "c13", "c21", "c22", "c23", "c31", "c32", "c33")
STATE = ("q0", "q1", "q2", "q3") + C_NAMES + ("exi", "eyi", "ezi")
PARAMS = ("kp", "ki", "dt")
CONSTANTS = {"ONE": int(bt.ONE), "HALF": int(bt.HALF), "D2R": int(bt.D2R),
             "R2D": int(bt.R2D), "F360": int(bt.F360)}
OUTPUTS = ("pitch", "roll", "yaw")
UNIT_OF_KIND = {"mul": "mul", "add": "add", "sub": "add", "div": "div", "sqrt": "sqrt",
                "neg": "misc", "dbl": "misc", "clampneg": "misc", "yawsel": "misc",
                "atan": "atan"}


class _Builder(Builder):
    """opflow's builder with the solve's shorthands and its explicitly named results."""

    def __init__(self):
        super().__init__("solve", inputs=SENSORS, registers=STATE + PARAMS)

    def M(self, a, b, name=None):
        return self.op("mul", a, b, name=name)

    def A(self, a, b, name=None):
        return self.op("add", a, b, name=name)

    def S(self, a, b, name=None):
        return self.op("sub", a, b, name=name)

    def D(self, a, b, name=None):
        return self.op("div", a, b, name=name)

    def SQ(self, a, name=None):
        return self.op("sqrt", a, name=name)

    def normalise3(self, x, y, z, names):
        M, A = self.M, self.A
        s = A(A(M(x, x), M(y, y)), M(z, z))
        n = self.SQ(s)
        return tuple(self.D(v, n, name=nm) for v, nm in zip((x, y, z), names, strict=True))


def solve_program() -> Program:
    """One solve, in the order of ``mahony_fp32`` (module docstring there): inputs the
    sensors, registers the state and parameters, commits ``<state>_n`` to each state
    register, outputs pitch, roll and yaw."""
    b = _Builder()
    M, A, S, D, SQ = b.M, b.A, b.S, b.D, b.SQ

    b.module = "acc"  # ACC_NOR, ACC_CAL
    ax, ay, az = b.normalise3("ax", "ay", "az", ("an_x", "an_y", "an_z"))
    S(M(ay, "c33"), M(az, "c23"), name="exa")
    S(M(az, "c13"), M(ax, "c33"), name="eya")
    S(M(ax, "c23"), M(ay, "c13"), name="eza")

    b.module = "mag"  # MAG_NOR, MAG_FLU, MAG_CAL
    mx, my, mz = b.normalise3("mx", "my", "mz", ("mn_x", "mn_y", "mn_z"))
    hx = A(A(M("c11", mx), M("c21", my)), M("c31", mz))
    hy = A(A(M("c12", mx), M("c22", my)), M("c32", mz))
    hz = A(A(M("c13", mx), M("c23", my)), M("c33", mz))
    bx = SQ(A(M(hx, hx), M(hy, hy)))
    bz = hz
    wx = A(M("c11", bx), M("c13", bz))
    wy = A(M("c21", bx), M("c23", bz))
    wz = A(M("c31", bx), M("c33", bz))
    S(M(my, wz), M(mz, wy), name="exm")
    S(M(mz, wx), M(mx, wz), name="eym")
    S(M(mx, wy), M(my, wx), name="ezm")

    b.module = "gyro"  # GYRO_KPI, GYRO_RSV
    for ax_ in "xyz":
        e = A(f"e{ax_}a", f"e{ax_}m")
        ik = A(f"e{ax_}i", M(M(e, "ki"), "dt"), name=f"e{ax_}i_n")
        A(A(M(f"g{ax_}", "D2R"), M("kp", e)), ik, name=f"w{ax_}")

    b.module = "quat"  # QUAT_DIF, QUAT_LK, QUAT_NOR
    ht = M("dt", "HALF", name="half_t")
    d0 = b.op("neg", A(A(M("q1", "wx"), M("q2", "wy")), M("q3", "wz")))
    d1 = S(A(M("q0", "wx"), M("q2", "wz")), M("q3", "wy"))
    d2 = A(S(M("q0", "wy"), M("q1", "wz")), M("q3", "wx"))
    d3 = S(A(M("q0", "wz"), M("q1", "wy")), M("q2", "wx"))
    r = [A(qi, M(di, ht)) for qi, di in zip(("q0", "q1", "q2", "q3"), (d0, d1, d2, d3),
                                            strict=True)]
    n = SQ(A(A(A(M(r[0], r[0]), M(r[1], r[1])), M(r[2], r[2])), M(r[3], r[3])))
    for i in range(4):
        D(r[i], n, name=f"q{i}_n")

    b.module = "matx"
    q0, q1, q2, q3 = "q0_n", "q1_n", "q2_n", "q3_n"
    dbl = lambda x, name=None: b.op("dbl", x, name=name)  # noqa: E731
    S("ONE", dbl(A(M(q2, q2), M(q3, q3))), name="c11_n")
    dbl(A(M(q1, q2), M(q0, q3)), name="c12_n")
    dbl(S(M(q1, q3), M(q0, q2)), name="c13_n")
    dbl(S(M(q1, q2), M(q0, q3)), name="c21_n")
    S("ONE", dbl(A(M(q1, q1), M(q3, q3))), name="c22_n")
    dbl(A(M(q2, q3), M(q0, q1)), name="c23_n")
    dbl(A(M(q1, q3), M(q0, q2)), name="c31_n")
    dbl(S(M(q2, q3), M(q0, q1)), name="c32_n")
    S("ONE", dbl(A(M(q1, q1), M(q2, q2))), name="c33_n")

    b.module = "euler"  # EULER_P, EULER_R, EULER_Y
    om = b.op("clampneg", S("ONE", M("c13_n", "c13_n")))
    p_rad = b.op("atan", SQ(om), b.op("neg", "c13_n"))
    M(p_rad, "R2D", name="pitch")
    M(b.op("atan", "c33_n", "c23_n"), "R2D", name="roll")
    yaw = M(b.op("atan", "c11_n", "c12_n"), "R2D")
    b.op("yawsel", yaw, A(yaw, "F360"), name="yaw")
    prog = b.prog
    prog.commit = {k: f"{k}_n" for k in STATE}
    prog.outputs = {k: k for k in OUTPUTS}
    return prog


def module_interface(program: Program, module: str) -> tuple[list[str], list[str]]:
    """External inputs (read, not produced in the module) and outputs (produced in it and
    read elsewhere or final) of one module, in program order."""
    mine = [o for o in program.ops if o.module == module]
    produced = {o.dst for o in mine}
    ins: list[str] = []
    for o in mine:
        for a in o.srcs:
            if a not in produced and a not in CONSTANTS and a not in ins:
                ins.append(a)
    used_elsewhere = {a for o in program.ops if o.module != module for a in o.srcs}
    outs = [o.dst for o in mine if o.dst in used_elsewhere or o.dst.endswith("_n")
            or o.dst in OUTPUTS]
    return ins, outs


# ------------------------------------------------------------------------------ evaluation

def _clampneg(x):
    neg = fp32_compare(x, np.uint32(0))["lt"]
    return np.where(neg, np.uint32(0), x).astype(np.uint32)


def _yawsel(a, b):
    return np.where(fp32_compare(a, np.uint32(0))["lt"], b, a).astype(np.uint32)


#: every kind of the program -> its bit-true function (uint32 bit patterns)
EVAL = {
    "mul": fp32_mul, "add": fp32_add, "sub": fp32_sub, "div": fp32_div, "sqrt": fp32_sqrt,
    "neg": fp32_neg, "dbl": lambda x: fp32_add(x, x), "clampneg": _clampneg,
    "yawsel": _yawsel, "atan": lambda c, s: atan_fp32(c, s)[0],
}


#: the kinds opflow's float32 IR does not have (the circuit's misc and atan units)
OWN_KINDS = ("neg", "dbl", "clampneg", "yawsel", "atan")


def run_program(program: Program, values: dict) -> dict:
    """Evaluate ``program`` on float32 bit patterns (arrays of one length, or scalars);
    ``values`` holds the inputs it reads (constants are added). Returns every value by name,
    as arrays of the common length."""
    env = {k: np.asarray(v, dtype=np.uint32) for k, v in values.items()}
    for k, v in CONSTANTS.items():
        env.setdefault(k, np.uint32(v))
    lanes = max((a.size for a in env.values()), default=1)
    _, _, regs = run_bittrue(program, {}, env, lanes=lanes,
                             kinds={k: EVAL[k] for k in OWN_KINDS})
    return regs
