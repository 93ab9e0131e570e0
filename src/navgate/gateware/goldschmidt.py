"""Goldschmidt divider and reciprocal gateware (pipelined, one result per cycle).

Implements :func:`navgate.numerics.goldschmidt.goldschmidt_divide` and
:func:`~navgate.numerics.goldschmidt.goldschmidt_reciprocal` bit for bit; the datapath is
the one that module's docstring states (sign/magnitude, normalisation to [0.5, 1), seed
from a ROM or a linear approximation, ``iterations`` multiply steps with truncating
products, rounded denormalisation, sign, saturation). The seed ROM contents come from
``goldschmidt_seed_table``, so model and gateware share one table. References: Goldschmidt
1964; Oberman and Flynn 1997; seed 004 (``goldschmidt_struct.v``: "only multipliers and
subtractors", Q(N=20, FRAC=10)).

Pipeline (every stage one register, common enable, see
:class:`navgate.gateware.fixed.StreamPipeline`):

====== =================================================================================
stage  work
====== =================================================================================
1      |n|, |d|, leading-one detection, normalising shifts, exponent difference, flags
2      seed x0 (ROM of 2**seed_bits words, or C1 - (C2 D >> F))
3      N0 = (num x0) >> F, D0 = (D x0) >> F (the reciprocal's num = 1.0: N0 = x0, no
       multiply)
4..    one stage per iteration: G = 2 - D, N = (N G) >> F, D = (D G) >> F (the last
       iteration's D product is never used and is not built)
k+4    denormalising shift, rounding (nearest: ((N >> (s-1)) + 1) >> 1, which equals the
       model's (N + 2**(s-1)) >> s)
k+5    saturation, sign, zero/divide-by-zero overrides, flags
====== =================================================================================

``LATENCY = iterations + 5``, ``THROUGHPUT = 1``. With ``split_iterations=True`` each
iteration takes two stages (``G = 2 - D`` registered first, so that the multiply stage is
register -> multiplier -> register): ``LATENCY = 2 * iterations + 5``, the same cells (the
extra registers fold into the DSP input registers on xc7) and a higher clock (ECP5 proxy for
the default divider: 59.5 -> 72.8 MHz, then limited by the seed multiply).

Multipliers: (F+2) x (F+2) bits unsigned,
``2 * iterations + 1`` of them for the divider and ``2 * iterations`` for the reciprocal
(``+ 1`` with the linear seed); with the defaults (F = 20) each maps to two DSP48E1.

Payloads: divider ``{n, d}`` (signed ``width``), reciprocal ``{d}``; both produce
``{q, divide_by_zero, overflow}`` with ``q`` signed ``width`` in the same Q format.
"""

from __future__ import annotations

from amaranth import Array, Const, Module, Mux, Signal, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.gateware.fixed import StreamPipeline
from navgate.gateware.parameters import CheckedParameters
from navgate.numerics.goldschmidt import goldschmidt_seed_table

__all__ = ["GoldschmidtDivider", "GoldschmidtReciprocal"]


def leading_one(m: Module, value, name: str) -> tuple[Signal, Signal]:
    """Position ``p`` of the highest set bit of ``value`` (0 when ``value`` is 0) and the
    leading-zero count ``len(value) - 1 - p``."""
    w = len(value)
    pos = Signal(range(max(2, w)), name=name)
    zeros = Signal(range(max(2, w)), name=f"{name}_lz")
    for k in range(w):
        with m.If(value[k]):
            m.d.comb += [pos.eq(k), zeros.eq(w - 1 - k)]
    return pos, zeros


class _GoldschmidtBase(CheckedParameters, wiring.Component):
    _reciprocal = False

    @classmethod
    def check_parameters(cls, width, frac, iterations, seed_bits, internal_frac, seed, rounding,
                         split_iterations):
        # the ranges the bit-true model accepts (navgate.numerics.goldschmidt)
        if not 2 <= width <= 30:
            raise ValueError(f"width must be in [2, 30], got {width}")
        if not 0 <= frac <= width:
            raise ValueError(f"frac must be in [0, width], got {frac}")
        F = width if internal_frac is None else int(internal_frac)
        if F < width:
            raise ValueError("internal_frac must be >= width (exact normalisation)")
        if 2 * F + 4 > 62 or F + 2 * width + 1 > 62:
            raise ValueError("internal_frac too large for the bit-true model (2F+4 <= 62)")
        if seed not in ("table", "linear"):
            raise ValueError(f"seed must be 'table' or 'linear', got {seed!r}")
        if seed == "table" and not 0 <= seed_bits <= min(16, F - 1):
            raise ValueError(f"seed_bits must be in [0, min(16, F-1)], got {seed_bits}")
        if rounding not in ("nearest", "truncate"):
            raise ValueError(f"rounding must be 'nearest' or 'truncate', got {rounding!r}")
        if iterations < 0:
            raise ValueError("iterations must be >= 0")

    def __init__(self, width: int, frac: int, iterations: int, seed_bits: int,
                 internal_frac: int | None, seed: str, rounding: str,
                 split_iterations: bool):
        F = width if internal_frac is None else int(internal_frac)
        self.width = width
        self.frac = frac
        self.iterations = iterations
        self.seed_bits = seed_bits
        self.internal_frac = F
        self.seed = seed
        self.rounding = rounding
        self.split_iterations = bool(split_iterations)
        self.LATENCY = (2 if self.split_iterations else 1) * iterations + 5
        self.THROUGHPUT = 1
        inputs = {"d": signed(width)} if self._reciprocal else {
            "n": signed(width), "d": signed(width)}
        super().__init__({
            "i": In(stream.Signature(data.StructLayout(inputs))),
            "o": Out(stream.Signature(data.StructLayout({
                "q": signed(width), "divide_by_zero": unsigned(1), "overflow": unsigned(1)}))),
        })

    def elaborate(self, platform):
        m = Module()
        w, F, frac, k = self.width, self.internal_frac, self.frac, self.iterations
        pipe = StreamPipeline(m, self.i, self.o, self.LATENCY)
        reg = pipe.reg
        # exponent difference range: |shift| <= F - frac + w (both operations)
        shift_shape = signed(max(F + w + 2, 2 * w + 2).bit_length() + 1)
        depth = self.LATENCY

        # flags and shift travel down the pipe beside the data
        neg = [reg(unsigned(1), f"neg_{s}") for s in range(depth)]
        dzero = [reg(unsigned(1), f"dzero_{s}") for s in range(depth)]
        nzero = [reg(unsigned(1), f"nzero_{s}") for s in range(depth)]
        shift = [reg(shift_shape, f"shift_{s}") for s in range(depth)]

        # ---- stage 1: sign/magnitude, normalisation ---------------------------------
        d = self.i.payload.d
        d_zero = d == 0
        a = Mux(d_zero, 1, Mux(d[-1], -d, d))[:w]  # |min_int| = 2**(w-1) fits in w bits
        pd, lzd = leading_one(m, a, "pd")
        Dn = reg(unsigned(F), "D_norm")
        # D = a << (F - 1 - p), as (a << (w - 1 - p)) << (F - w)
        d_norm = (a << lzd)[:w] << (F - w)
        if self._reciprocal:
            s1 = [neg[0].eq(d[-1]), dzero[0].eq(d_zero), nzero[0].eq(0),
                  shift[0].eq(2 * frac - pd - 1 - F), Dn.eq(d_norm)]
            Nn = None
        else:
            n = self.i.payload.n
            n_zero = n == 0
            b = Mux(n_zero, 1, Mux(n[-1], -n, n))[:w]
            pn, lzn = leading_one(m, b, "pn")
            Nn = reg(unsigned(F + 1), "N_norm")
            s1 = [neg[0].eq(n[-1] ^ d[-1]), dzero[0].eq(d_zero), nzero[0].eq(n_zero),
                  shift[0].eq(pn - pd + frac - F), Dn.eq(d_norm),
                  Nn.eq((b << lzn)[:w] << (F - w))]

        # ---- stage 2: seed ------------------------------------------------------------
        x0 = reg(unsigned(F + 2), "x0")
        D1 = reg(unsigned(F), "D_s2")
        if self.seed == "table":
            rom = Array(Const(int(v), unsigned(F + 1))
                        for v in goldschmidt_seed_table(self.seed_bits, F))
            index = Dn[F - 1 - self.seed_bits: F - 1] if self.seed_bits else 0
            seed_value = rom[index]
        else:
            c1 = round(48 / 17 * 2**F)
            c2 = round(32 / 17 * 2**F)
            seed_value = Const(c1, unsigned(c1.bit_length())) - (
                (Const(c2, unsigned(c2.bit_length())) * Dn) >> F)
        s2 = [x0.eq(seed_value), D1.eq(Dn)]
        N1 = None
        if Nn is not None:
            N1 = reg(unsigned(F + 1), "N_s2")
            s2.append(N1.eq(Nn))

        # ---- stage 3: seed multiply ---------------------------------------------------
        rw = F + 2  # N, D, G < 2**(F+2)
        Ns = [reg(unsigned(rw), f"N_{j}") for j in range(k + 1)]
        Ds = [reg(unsigned(rw), f"D_{j}") for j in range(k)]  # last D unused
        spi = 2 if self.split_iterations else 1  # stages per iteration
        s3 = [Ns[0].eq(x0 if N1 is None else (N1 * x0) >> F)]
        if k:
            s3.append(Ds[0].eq((D1 * x0) >> F))

        # ---- stages 4 .. k+3: iterations ----------------------------------------------
        two = 2 << F
        s_iter = []
        for j in range(k):
            G = (Const(two, unsigned(F + 2)) - Ds[j])[:rw]
            N_in, D_in = Ns[j], Ds[j]
            if self.split_iterations:
                # G = 2 - D gets its own stage: the multiply stage is then reg -> mul -> reg
                Gq = reg(unsigned(rw), f"G_{j}")
                N_in = reg(unsigned(rw), f"N_{j}_a")
                D_in = reg(unsigned(rw), f"D_{j}_a")
                s_iter += [Gq.eq(G), N_in.eq(Ns[j]), D_in.eq(Ds[j])]
                G = Gq
            s_iter.append(Ns[j + 1].eq((N_in * G) >> F))
            if j + 1 < k:
                s_iter.append(Ds[j + 1].eq((D_in * G) >> F))

        # ---- stage k+4: denormalising shift and rounding --------------------------------
        mag = Ns[k]
        sh = shift[spi * k + 2]
        q_low = reg(unsigned(w), "q_low")
        big = reg(unsigned(1), "q_big")
        left_amt = Signal(range(w + 1))
        right_amt = Signal(range(max(2, F + w + 3)))  # s = -shift >= 1 when used
        m.d.comb += [left_amt.eq(Mux(sh[-1], 0, sh)), right_amt.eq(Mux(sh[-1], -sh, 0))]
        left = mag << left_amt
        if self.rounding == "nearest":
            right_m1 = Signal(range(max(2, F + w + 3)))
            m.d.comb += right_m1.eq(Mux(sh[-1], -sh - 1, 0))
            right = ((mag >> right_m1) + 1) >> 1
        else:
            right = mag >> right_amt
        shifted = Mux(sh[-1], right, left)
        s_shift = [q_low.eq(shifted[:w]), big.eq(shifted[w:].any())]

        # ---- stage k+5: saturate, sign, overrides ------------------------------------------
        last = depth - 1
        ngt = neg[last - 1]
        limit = Mux(ngt, 1 << (w - 1), (1 << (w - 1)) - 1)
        over = big | (q_low > limit)
        q_mag = Mux(over, limit, q_low)
        value = Mux(ngt, -q_mag, q_mag)
        dz, nz = dzero[last - 1], nzero[last - 1]
        out = reg(self.o.payload.shape(), "out_q")
        if self._reciprocal:
            final = [out.q.eq(Mux(dz, (1 << (w - 1)) - 1, value)),
                     out.overflow.eq(over & ~dz)]
        else:
            sat = Mux(ngt, -(1 << (w - 1)), (1 << (w - 1)) - 1)
            final = [out.q.eq(Mux(dz, Mux(nz, 0, sat), Mux(nz, 0, value))),
                     out.overflow.eq(over & ~nz & ~dz)]
        final.append(out.divide_by_zero.eq(dz))

        with m.If(pipe.en):
            m.d.sync += s1 + s2 + s3 + s_iter + s_shift + final
            for s in range(1, depth):
                m.d.sync += [neg[s].eq(neg[s - 1]), dzero[s].eq(dzero[s - 1]),
                             nzero[s].eq(nzero[s - 1]), shift[s].eq(shift[s - 1])]
        m.d.comb += self.o.payload.eq(out)
        return m


class GoldschmidtDivider(_GoldschmidtBase):
    """Goldschmidt fixed-point divider q = n / d in signed Q(width, frac) (seed 004)."""

    def __init__(self, width: int = 20, frac: int = 10, iterations: int = 3,
                 seed_bits: int = 4, internal_frac: int | None = None, seed: str = "table",
                 rounding: str = "nearest", split_iterations: bool = False):
        super().__init__(width, frac, iterations, seed_bits, internal_frac, seed, rounding,
                         split_iterations)


class GoldschmidtReciprocal(_GoldschmidtBase):
    """Goldschmidt fixed-point reciprocal q = 1 / d in signed Q(width, frac) (seed 004)."""

    _reciprocal = True

    def __init__(self, width: int = 20, frac: int = 10, iterations: int = 3,
                 seed_bits: int = 4, internal_frac: int | None = None, seed: str = "table",
                 rounding: str = "nearest", split_iterations: bool = False):
        super().__init__(width, frac, iterations, seed_bits, internal_frac, seed, rounding,
                         split_iterations)
