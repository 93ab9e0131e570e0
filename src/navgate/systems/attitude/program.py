"""Seed 003's attitude solve as an operation program (what the gateware schedules).

Reference: seed 003 sections 3.1.2-3.1.8 (modules INS_acc, INS_mag, INS_gyro, INS_quat,
INS_matx, INS_euler and the fix16 arctangent) and :mod:`navgate.systems.attitude.mahony_fp32`,
whose docstring fixes the operation order. :func:`solve_program` writes that order down as a
list of :class:`Op`, one per rounded float32 operation (or exact bit manipulation), so that a
scheduler can place it on shared arithmetic units (:mod:`navgate.systems.attitude.schedule`)
and :func:`run_program` can evaluate it with :mod:`navgate.numerics.fp32` (the tests check
that evaluation against ``mahony_fp32`` bit for bit, so program and model cannot drift).

Operation kinds (unit in brackets):

* ``mul``, ``add``, ``sub``, ``div``, ``sqrt`` [the float32 cores];
* ``neg`` (``fp32_neg``), ``dbl`` (``fp32_add(x, x)``, the exact doubling of INS_matx),
  ``clampneg`` (a negative value -> +0, EULER_P), ``yawsel`` (``a < 0 ? b : a``, the yaw
  wrap) [the one-cycle ``misc`` unit];
* ``atan`` (cos, sin) -> radians [the fix16 arctangent of section 3.1.8].

Value names: sensor inputs ``ax ay az mx my mz gx gy gz`` (after the model's axis signs),
state ``q0..q3``, ``c11..c33``, ``exi eyi ezi`` (the integral), parameters ``kp ki dt``,
constants ``ONE HALF D2R R2D F360``. New state values carry ``_n`` (``q0_n``, ``c11_n``,
``exi_n``); the solve's outputs are ``pitch roll yaw`` (degrees, float32).
"""

from __future__ import annotations

from dataclasses import dataclass

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
from navgate.systems.attitude import mahony_fp32 as bt
from navgate.systems.attitude.atan16 import atan_fp32

__all__ = ["Op", "MODULES", "SENSORS", "STATE", "PARAMS", "CONSTANTS", "solve_program",
           "run_program", "module_interface"]

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


@dataclass(frozen=True)
class Op:
    name: str
    kind: str
    args: tuple[str, ...]
    module: str

    @property
    def unit(self) -> str:
        return UNIT_OF_KIND[self.kind]


class _Builder:
    def __init__(self):
        self.ops: list[Op] = []
        self.module = ""
        self._n = 0

    def op(self, kind, *args, name=None):
        if name is None:
            self._n += 1
            name = f"{self.module}_{kind}{self._n}"
        self.ops.append(Op(name, kind, tuple(args), self.module))
        return name

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


def solve_program() -> list[Op]:
    """One solve, in the order of ``mahony_fp32`` (module docstring there)."""
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
    return b.ops


def module_interface(program: list[Op], module: str) -> tuple[list[str], list[str]]:
    """External inputs (read, not produced in the module) and outputs (produced in it and
    read elsewhere or final) of one module, in program order."""
    mine = [o for o in program if o.module == module]
    produced = {o.name for o in mine}
    ins: list[str] = []
    for o in mine:
        for a in o.args:
            if a not in produced and a not in CONSTANTS and a not in ins:
                ins.append(a)
    used_elsewhere = {a for o in program if o.module != module for a in o.args}
    outs = [o.name for o in mine if o.name in used_elsewhere or o.name.endswith("_n")
            or o.name in OUTPUTS]
    return ins, outs


# ------------------------------------------------------------------------------ evaluation

def _clampneg(x):
    neg = fp32_compare(x, np.uint32(0))["lt"]
    return np.where(neg, np.uint32(0), x).astype(np.uint32)


def _yawsel(a, b):
    return np.where(fp32_compare(a, np.uint32(0))["lt"], b, a).astype(np.uint32)


EVAL = {
    "mul": fp32_mul, "add": fp32_add, "sub": fp32_sub, "div": fp32_div, "sqrt": fp32_sqrt,
    "neg": fp32_neg, "dbl": lambda x: fp32_add(x, x), "clampneg": _clampneg,
    "yawsel": _yawsel, "atan": lambda c, s: atan_fp32(c, s)[0],
}


def run_program(program: list[Op], values: dict) -> dict:
    """Evaluate ``program`` on float32 bit patterns (arrays or scalars); ``values`` holds the
    inputs it reads (constants are added). Returns every value by name."""
    env = {k: np.asarray(v, dtype=np.uint32) for k, v in values.items()}
    for k, v in CONSTANTS.items():
        env.setdefault(k, np.uint32(v))
    for o in program:
        env[o.name] = np.asarray(EVAL[o.kind](*(env[a] for a in o.args)), dtype=np.uint32)
    return env
