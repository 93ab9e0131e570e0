"""One float32 adder, multiplier and int -> float32 converter shared by two blocks of
``ins_trn_top``.

The output formatter (``nav_output_formatter``: REF_ALT - h, the quaternion conversions, the
sigmas' sums, the angles times pi) and the barometer compensation (``baro_compensation``: the
BMP390 formulas in float32) each need an adder and a multiplier for about a hundred cycles
per sample, at 400 Hz and 25 Hz. Built with ``shared_units=True``, each block has ports to
the units instead of its own (:func:`unit_members`, :func:`unit_port`, and
:func:`forward_units` through a block that contains the user); the top
(:func:`share_units`) gives the units to one block at a time, for a whole vector: a block
that has work waits until the other is idle (at most its ~500 or ~106 cycles). Results do not
change, only when they appear. This saves one ``Fp32Add``, one ``Fp32Mul`` (and its two
DSP48E1) and one integer -> float32 converter (docs/seed000-top.md, Resources).
"""

from __future__ import annotations

from functools import partial
from types import SimpleNamespace

from amaranth import Mux, Signal
from amaranth.hdl import signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware.fp32 import Fp32Add, Fp32FromInt, Fp32Mul

__all__ = ["SHARED_CORES", "unit_members", "unit_port", "forward_units", "share_units",
           "arbitrate"]

#: the shared units: port name -> (core, input layout, output layout) (the formatter
#: converts its angles as integers, output_formatter.PI_BITS_INT)
SHARED_CORES = {
    "add": (Fp32Add, Fp32Add.IN_LAYOUT, Fp32Add.OUT_LAYOUT),
    "mul": (Fp32Mul, Fp32Mul.IN_LAYOUT, Fp32Mul.OUT_LAYOUT),
    "cvt": (partial(Fp32FromInt, 32), data.StructLayout({"x": signed(32)}),
            data.StructLayout({"r": unsigned(32)})),
}


def unit_members(prefix: str = "") -> dict:
    """Signature members of a block that drives the shared units: ``<prefix>add_i`` (the
    adder's input stream, driven by the block), ``<prefix>add_o`` (its output), the same for
    ``mul`` and ``cvt``."""
    members = {}
    for name, (_core, in_layout, out_layout) in SHARED_CORES.items():
        members[f"{prefix}{name}_i"] = Out(stream.Signature(in_layout))
        members[f"{prefix}{name}_o"] = In(stream.Signature(out_layout))
    return members


def unit_port(component, name: str, prefix: str = ""):
    """An object with ``i`` and ``o`` like the core's own, made of the block's ports."""
    return SimpleNamespace(i=getattr(component, f"{prefix}{name}_i"),
                           o=getattr(component, f"{prefix}{name}_o"))


def forward_units(m, inner, outer, prefix: str = ""):
    """Connect the unit ports of ``inner`` (a submodule built with shared units) to the same
    ports of ``outer`` (the component that contains it), named ``<prefix>add_i`` ... there."""
    for name in SHARED_CORES:
        wiring.connect(m, getattr(inner, f"{name}_i"),
                       wiring.flipped(getattr(outer, f"{prefix}{name}_i")))
        wiring.connect(m, wiring.flipped(getattr(outer, f"{prefix}{name}_o")),
                       getattr(inner, f"{name}_o"))


def share_units(m, first: dict, second: dict, second_owns):
    """Instantiate the shared units in ``m`` and connect them to the blocks ``first`` and
    ``second`` (each a dict unit name -> an object with ``i``/``o``, from :func:`unit_port`).
    ``second_owns`` (a signal) routes the inputs from ``second``, else from ``first``. The
    results' ``valid`` goes to the owner only: ownership may change only while both blocks
    are idle with no operation in flight (the arbitration's rule), so every result belongs to
    the block that owns the units when it appears."""
    for name, (core, in_layout, out_layout) in SHARED_CORES.items():
        unit = core()
        if (unit.i.payload.shape(), unit.o.payload.shape()) != (in_layout, out_layout):
            raise TypeError(f"shared unit {name}: the core's layouts are not SHARED_CORES'")
        m.submodules[f"shared_{name}"] = unit
        a, b = first[name], second[name]
        m.d.comb += [
            unit.i.valid.eq(Mux(second_owns, b.i.valid, a.i.valid)),
            unit.i.payload.eq(Mux(second_owns, b.i.payload.as_value(), a.i.payload.as_value())),
            a.i.ready.eq(unit.i.ready & ~second_owns), b.i.ready.eq(unit.i.ready & second_owns),
            unit.o.ready.eq(1),
        ]
        m.d.comb += [a.o.valid.eq(unit.o.valid & ~second_owns),
                     b.o.valid.eq(unit.o.valid & second_owns)]
        for port in (a, b):
            m.d.comb += port.o.payload.eq(unit.o.payload)


def arbitrate(m, first_ready, first_request, second_busy):
    """The rule by which ``first`` (the formatter: ``first_request`` = a vector waiting,
    ``first_ready`` = idle) and ``second`` (the compensation: ``second_busy``) take turns.
    Returns (``first_valid``, ``second_grant``): the first block's input valid, and the grant
    that lets the second take an input. A grant lasts while the second is busy, so a vector
    it has started is never interrupted; the first block starts only while the second is
    idle; when both want to start in the same cycle, the first wins."""
    first_valid, second_grant = Signal(), Signal()
    m.d.comb += [first_valid.eq(first_request & ~second_busy),
                 second_grant.eq(second_busy | (first_ready & ~first_request))]
    return first_valid, second_grant
