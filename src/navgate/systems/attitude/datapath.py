"""Seed 003's attitude circuit on opflow's phased datapath: its unit choices, FSM phases and
register banks.

References: seed 003 section 3.1.1 (figure 3-2: the top FSM runs ACC_MAG, GYRO, QUAT, MATX,
EULER, END, each state waiting for its modules' ``*_finish``), the scheduler
:mod:`navgate.opflow.phased` (the rules the hardware follows) and the datapath
:mod:`navgate.opflow.phased_machine` (units, banks, control ROM from the schedule). What this
module chooses:

* units, one of each kind: :class:`~navgate.gateware.fp32.Fp32Mul`,
  :class:`~navgate.gateware.fp32.Fp32Add` (add or subtract: the ``sub`` control field),
  :class:`~navgate.gateware.fp32.Fp32Div` and :class:`~navgate.gateware.fp32.Fp32Sqrt` (both
  with two recurrence steps per stage, latencies 18 and 17),
  :class:`~navgate.systems.attitude.units.MiscUnit` (``neg dbl clampneg yawsel``: the ``mop``
  control field) and :class:`~navgate.systems.attitude.units.AtanUnit` (iterative CORDIC,
  one issue every ``AtanUnit.II`` cycles; its saturation flag is the ``atan_sat`` output);
  only the kinds the program uses are built;
* phases: the seed's FSM order, ACC_MAG (acc and mag side by side, sharing units), GYRO,
  QUAT, MATX, EULER;
* two register banks of distributed RAM, at most 32 words each.
"""

from __future__ import annotations

from navgate.gateware.fp32 import Fp32Add, Fp32Div, Fp32Mul, Fp32Sqrt
from navgate.opflow.phased import PhasedUnits, Schedule, build_schedule
from navgate.opflow.phased_machine import Control, PhasedDatapath
from navgate.systems.attitude.program import CONSTANTS, UNIT_OF_KIND
from navgate.systems.attitude.units import MISC_OPS, AtanUnit, MiscUnit

__all__ = ["STEPS_PER_STAGE", "PHASES", "BANKS", "BANK_DEPTH", "PORTS", "unit_latencies",
           "units", "make_schedule", "make_datapath"]

STEPS_PER_STAGE = 2  #: recurrence steps per pipeline stage of the divider and square root
#: operand ports of each unit (the datapath's unit order)
PORTS = {"mul": ("a", "b"), "add": ("a", "b"), "div": ("a", "b"), "sqrt": ("a",),
         "misc": ("a", "b"), "atan": ("a", "b")}
PHASES = (("acc", "mag"), ("gyro",), ("quat",), ("matx",), ("euler",))
BANKS = 2
BANK_DEPTH = 32
#: the control fields that select an op on a shared unit
CONTROLS = (Control("sub", 1, "add", "sub", {"sub": 1}),
            Control("mop", 2, "misc", "op", MISC_OPS))
#: the arctangent's saturated-input flag
FLAGS = {"atan_sat": ("atan", "saturated")}


def _make_unit(kind: str):
    if kind == "mul":
        return Fp32Mul()
    if kind == "add":
        return Fp32Add()
    if kind == "div":
        return Fp32Div(steps_per_stage=STEPS_PER_STAGE)
    if kind == "sqrt":
        return Fp32Sqrt(steps_per_stage=STEPS_PER_STAGE)
    if kind == "misc":
        return MiscUnit()
    if kind == "atan":
        return AtanUnit()
    raise ValueError(kind)


def unit_latencies() -> dict:
    """Latency of every unit kind as :func:`_make_unit` builds it (the schedule is made with
    these), read from the classes without building a unit."""
    fixed = {"mul": Fp32Mul, "add": Fp32Add, "misc": MiscUnit, "atan": AtanUnit}
    stepped = {"div": Fp32Div, "sqrt": Fp32Sqrt}
    out = {}
    for k in PORTS:
        if k in stepped:
            out[k] = stepped[k].latency_for(STEPS_PER_STAGE)
        else:
            out[k] = fixed[k].LATENCY
    return out


def units() -> PhasedUnits:
    """The circuit's units for opflow's phased scheduler."""
    return PhasedUnits(UNIT_OF_KIND, unit_latencies(), PORTS, {"atan": AtanUnit.II})


def make_schedule(program, sources, sinks, **kw) -> Schedule:
    """Schedule ``program`` (a list of ops) on the circuit's units, phases and banks."""
    kw = {"phases": PHASES, "banks": BANKS, "bank_depth": BANK_DEPTH, **kw}
    return build_schedule(program, sources, sinks, units(), constants=CONSTANTS, **kw)


def make_datapath(schedule: Schedule) -> PhasedDatapath:
    """The datapath that runs ``schedule``: ports ``start``, ``busy``, ``last``, ``phase``,
    ``atan_sat``, ``src_<name>``, ``we_<reg>``/``wd_<reg>``
    (:mod:`navgate.opflow.phased_machine`)."""
    return PhasedDatapath(schedule, _make_unit, CONTROLS, FLAGS)
