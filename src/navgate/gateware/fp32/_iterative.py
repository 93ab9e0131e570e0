"""Control shared by the iterative (area-saving) float32 digit-recurrence cores.

:class:`~navgate.gateware.fp32.div_iter.Fp32DivIter` and
:class:`~navgate.gateware.fp32.sqrt_iter.Fp32SqrtIter` compute what the pipelined
``Fp32Div`` / ``Fp32Sqrt`` compute (the same radix-2 restoring recurrences, Ercegovac & Lang,
"Digital Arithmetic", 2004, ch. 5 and 6), but with one recurrence step in hardware that is
reused over ``WORK_CYCLES`` clock cycles by a counter, instead of 25 unrolled stages.

Timing of one operation with ``o.ready`` held 1, in the counting of the verification
harness (the input is accepted in cycle 0, i.e. by clock edge ``E0`` at the end of that
cycle; a result "valid in cycle L" was registered by edge ``E(L-1)``):

* ``E0`` loads the unpacked operands, the special-case class and the exponent;
* ``E1 .. E{WORK_CYCLES}`` are the work edges (``count = 0 .. WORK_CYCLES - 1``): the
  divider's pre-normalisation, then the recurrence steps;
* in cycle ``WORK_CYCLES + 1`` (``count = WORK_CYCLES``, the *finish* cycle) the tail rounds
  (sticky bit, round-to-nearest-even, range check: :func:`~._common.round_pack`) and
  selects the special result (:func:`~._common.select_special`); edge
  ``E{WORK_CYCLES + 1}`` loads the output register, valid from cycle ``WORK_CYCLES + 2``.

So ``LATENCY = WORK_CYCLES + 2``. ``i.ready = ~busy | finish``: the finish cycle also
accepts the next input (its operands load at the same edge as the previous result), hence
``INTERVAL = WORK_CYCLES + 1 = LATENCY - 1`` cycles between two accepted inputs, exactly,
while inputs wait and ``o.ready`` is held 1 (never fewer), and
``THROUGHPUT = 1 / INTERVAL``. With ``o.ready`` low the core holds in the finish cycle
until the output register is free (a valid output is never dropped or changed) and keeps
``i.ready`` low meanwhile.

``steps_per_cycle = 2`` chains two recurrence steps per cycle (two subtractors; the
quotient or root is then computed to 26 bits, the extra bit joining the sticky bit), which
about halves ``WORK_CYCLES``; the class attributes describe the default, one step per
cycle, and an instance with two steps carries its own ``WORK_CYCLES``, ``LATENCY``,
``INTERVAL`` and ``THROUGHPUT``.

Data registers are reset-less (they are always loaded before use); ``busy`` and the output
valid bit reset to 0.
"""

import math
from fractions import Fraction

from amaranth.hdl import Module, Signal

from navgate.gateware.parameters import CheckedParameters

from ._common import StreamOp, round_pack, select_special

__all__ = ["IterativeRecurrence"]


class IterativeRecurrence(CheckedParameters, StreamOp):
    """Base class: the counter, handshake and rounding tail of an iterative core.

    Subclasses set ``WORK_CYCLES`` (for one step per cycle) and ``SETUP_CYCLES`` (work
    cycles that are not recurrence steps) and implement :meth:`datapath`, which builds the
    operand registers, loads them when ``accept`` is high and advances the recurrence by
    ``self.steps_per_cycle`` steps when ``work`` is high (``count`` is the work cycle
    index), and returns
    ``(sign, exp, mant, rnd, sticky, kind)`` for the finish cycle: the 24-bit significand
    with its leading one, the signed biased exponent, the round bit, the sticky bit and the
    special-case bits (nan, inf, zero) of :func:`~._common.select_special`.
    """

    RESULT_BITS = 25  # hidden bit, 23 fraction bits, round bit
    STEPS_PER_CYCLE = (1, 2)
    WORK_CYCLES: int
    SETUP_CYCLES: int

    def __init_subclass__(cls, **kwargs):
        # The timing constants are spelled out in each subclass (for readers); keep them
        # consistent with the control implemented here.
        super().__init_subclass__(**kwargs)
        if not (cls.WORK_CYCLES == cls.SETUP_CYCLES + cls.RESULT_BITS
                and cls.LATENCY == cls.WORK_CYCLES + 2 and cls.INTERVAL == cls.WORK_CYCLES + 1
                and cls.THROUGHPUT == Fraction(1, cls.INTERVAL)):
            raise TypeError(f"{cls.__name__}: LATENCY/INTERVAL/THROUGHPUT disagree with "
                            f"WORK_CYCLES = {cls.WORK_CYCLES}")

    @classmethod
    def check_parameters(cls, steps_per_cycle):
        if type(steps_per_cycle) is not int or steps_per_cycle not in cls.STEPS_PER_CYCLE:
            raise ValueError(f"steps_per_cycle must be 1 or 2, got {steps_per_cycle!r}")

    def __init__(self, steps_per_cycle: int = 1):
        self.steps_per_cycle = steps_per_cycle
        #: result bits computed (25 rounded up to a multiple of steps_per_cycle)
        self.bits = steps_per_cycle * math.ceil(self.RESULT_BITS / steps_per_cycle)
        if steps_per_cycle != 1:
            self.WORK_CYCLES = self.SETUP_CYCLES + self.bits // steps_per_cycle
            self.LATENCY = self.WORK_CYCLES + 2
            self.INTERVAL = self.WORK_CYCLES + 1
            self.THROUGHPUT = Fraction(1, self.INTERVAL)
        super().__init__()

    def split_result(self, digits, remainder):
        """``(mant, rnd, sticky)`` from the ``self.bits`` result digits (leading one at the
        top) and the final remainder: bits below the round bit join the sticky bit."""
        extra = self.bits - self.RESULT_BITS
        sticky = remainder != 0
        if extra:
            sticky = sticky | (digits[0:extra] != 0)
        return digits[extra + 1:extra + 25], digits[extra], sticky

    def datapath(self, m: Module, accept, work, count):
        raise NotImplementedError

    def elaborate(self, platform):
        m = Module()
        n = self.WORK_CYCLES
        count = Signal(range(n + 1), name="count", reset_less=True)
        busy = Signal(name="busy")
        out = Signal(32, name="out", reset_less=True)
        out_valid = Signal(name="out_valid")

        last = count == n
        finish = Signal(name="finish")
        accept = Signal(name="accept")
        work = Signal(name="work")
        m.d.comb += [
            finish.eq(busy & last & (~out_valid | self.o.ready)),
            self.i.ready.eq(~busy | finish),
            accept.eq(self.i.valid & self.i.ready),
            work.eq(busy & ~last),
            self.o.valid.eq(out_valid),
            self.o.payload.r.eq(out),
        ]

        sign, exp, mant, rnd, sticky, kind = self.datapath(m, accept, work, count)
        rounded = round_pack(m, sign, exp, mant, rnd, sticky)
        result = select_special(m, kind, sign, rounded)

        with m.If(self.o.ready):
            m.d.sync += out_valid.eq(0)
        with m.If(finish):
            m.d.sync += [out.eq(result), out_valid.eq(1), busy.eq(0)]
        with m.Elif(work):
            m.d.sync += count.eq(count + 1)
        with m.If(accept):
            m.d.sync += [count.eq(0), busy.eq(1)]
        return m
