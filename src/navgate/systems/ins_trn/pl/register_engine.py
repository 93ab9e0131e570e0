"""Seed 000's PL programs on opflow's register machine: the smallest seed-000 engine
(issue 29's one-lane machine reported beside the lane machines).

Reference: issue 29; :mod:`navgate.opflow.regmachine` (compiler, instruction-level model,
machine); the ``plain`` variant of :mod:`navgate.systems.ins_trn.pl.loop_programs` (each part
of the fp32 engine's programs in a step of its own: straight-line segments and loop nests),
as one sequence program (:func:`~navgate.systems.ins_trn.pl.loop_programs.to_sequence`),
bit for bit the fp32 engine's programs. docs/opflow-register-machine.md has the figures.

The register array ``R`` of the sequence form (state, configuration, inputs, passed values)
is the machine's register file; ``P``, ``cP``, ``F``, ``M``, ``E`` and the update vectors are
its data memory. :func:`register_engine` compiles once per process.
"""

from __future__ import annotations

from fractions import Fraction
from functools import lru_cache

from amaranth.hdl import Array, Cat, Const, Module, Mux, Signal
from amaranth.lib import wiring
from amaranth.lib.memory import Memory
from amaranth.lib.wiring import In, Out

from navgate.gateware.fp32._common import leading_zeros
from navgate.opflow.regmachine import RegisterProgram, compile_program
from navgate.systems.ins_trn.pl import loop_programs as L
from navgate.systems.ins_trn.pl.nav_engines import IMU_WORDS

__all__ = ["register_engine", "VARIANT", "RegisterEngineImage", "RegisterEngineCore",
           "register_engine_image", "PL_ENGINES", "pl_engine_image", "ins_engines_compact"]

#: loop_programs' variant the machine runs: every nest in a step of its own (the fused
#: variant's long straight-line segments exist to fill a lane machine's idle slots)
VARIANT = "plain"
#: the chained sums (cov_M, cov_E) interleave this many sums, and each nest runs that many
#: iterations (copies) at once; with more tracks the padding of the sums' tails overflows
#: the table ROM (4 tracks: over 4,096 entries)
TRACKS = 3
#: copies per nest (regmachine.compile_program's ``unroll``): the independent iterations in
#: one block iteration. Every nest's block iterations overlap (software pipelining,
#: ``OVERLAP``), so copies serve what the kernel cannot: an accumulator's recurrence (cov_M
#: and cov_E, one copy per track) and temporaries that live longer than one iteration's
#: issues (cov_kahan's compensated sums, alt_vec); the choice is the fastest within the
#: 1,024-row instruction ROM (docs/opflow-register-machine.md section 8)
UNROLL = {"cov_M": TRACKS, "cov_E": TRACKS, "cov_kahan": 4, "alt_vec": 3}
#: the nests compiled as software pipelines (every nest)
OVERLAP = True


@lru_cache(maxsize=2)
def register_engine(variant: str = VARIANT) -> tuple[RegisterProgram, dict, dict]:
    """(compiled program, register index of array ``R``, loop programs) of seed 000."""
    lps = L.loop_programs(1, variant, TRACKS)
    prog, reg_index = L.to_sequence(lps)
    rom: dict = {}
    for lp in lps.values():
        for array, words in lp.rom.items():
            rom.setdefault(array, {}).update(words)
    return (compile_program(prog, init=rom, unroll=UNROLL, overlap=OVERLAP), reg_index,
            lps)


# ------------------------------------------------------------------ behind ins_trn_top


def int16_to_fp32(m, word):
    """The float32 of the int16 in ``word[0:16]``, as the fp32 programs' ``cvt`` of an IMU
    word: exact (16 bits fit the significand, so no rounding), hence combinational: the
    float32 cores' leading-zero counter and a shift. (``Fp32FromInt`` does the general,
    rounded conversion in four pipeline stages; here a register follows, in
    :class:`RegisterEngineCore`.)"""
    x = word[:16].as_signed()
    sign = x < 0
    mag = Signal(16, name="cvt_mag")
    m.d.comb += mag.eq(Mux(sign, -x, x))
    _, lz = leading_zeros(mag)
    norm = Signal(16, name="cvt_norm")  # the leading one at bit 15
    m.d.comb += norm.eq(mag << lz)
    out = Signal(32, name="cvt_word")
    with m.If(mag != 0):
        m.d.comb += out.eq(Cat(Const(0, 8), norm[:15], (Const(127 + 15, 8) - lz)[:8], sign))
    return out


#: registers on the adapter's start: a start follows the host writes before it, which take
#: two stages (the translated address and the data; then the IMU word's conversion)
START_DELAY = 2


class RegisterEngineImage:
    """The register machine seen as the banked engine image (``engine_image("ins_engines")``)
    by the sequencer, the stream wrapper and the PS: the same programs, register addresses
    and output addresses (so the register map and the PS are unchanged), the register
    machine's cycles, and :meth:`machine` the adapter core (:class:`RegisterEngineCore`)."""

    def __init__(self):
        from navgate.systems.ins_trn.pl.nav_engines import engine_image

        self.banked = engine_image("ins_engines")
        self.rp, self.reg_index, _ = register_engine()
        self.programs = self.banked.programs
        self.layout = self.banked.layout
        self.fields = self.banked.fields
        missing = [k for k in self.programs if k not in self.rp.entries]
        if missing:
            raise ValueError(f"register machine lacks entries {missing}")

    def cycles(self, key: str) -> int:
        """Cycles from the start to ``done`` minus one (the banked machine's convention):
        the adapter's start, registered twice (after the two stages of a host write), then
        the register machine's entry."""
        return self.rp.cycles(key) + START_DELAY - 1

    def output_addr(self, key: str) -> dict:
        return self.banked.output_addr(key)

    def machine(self, init: dict | None = None):
        if init:
            raise ValueError("the register engine has no initial register contents")
        return RegisterEngineCore(self)

    def new_address(self, name: str) -> int | None:
        """The register machine host address of a register or output name (None: not held
        by the register machine, e.g. the banked engine's gate-to-apply registers)."""
        rp = self.rp
        if name in self.reg_index:
            return rp.host_address(L.REG_ARRAY, self.reg_index[name])
        if name in L.STATE_WORDS:
            return rp.host_address(*L.STATE_WORDS[name])
        if name.startswith("dx") and name[2:].isdigit():
            return rp.host_address("DX", int(name[2:]))
        return None

    def translation(self) -> tuple[list, dict]:
        """(ROM: banked address -> valid << 12 | imu << 11 | register machine host address,
        shared: banked address -> {program key: word}) for the output addresses that hold
        different names after different programs (the banked scheduler reuses an output
        address across programs: the dx words of the two applies, a gate's flag and another
        program's output). The banked engine's such a word holds what the last program
        writing it wrote; the core follows: the word of the last program run that has the
        address among its outputs (the ROM's word before any has run)."""
        aw = self.fields.aw
        rom = [0] * (1 << aw)

        def word(name):
            a = self.new_address(name)
            if a is None:
                return 0
            return 1 << 12 | int(name in IMU_WORDS) << 11 | a

        for name, a in self.layout.fixed.items():
            if not name.startswith("c:"):
                rom[a] = word(name)
        written: dict = {}
        for key in self.programs:
            for name, a in self.output_addr(key).items():
                written.setdefault(a, {})[key] = word(name)
        shared = {}
        for a, words in written.items():
            distinct = set(words.values())
            if rom[a] == 0 and len(distinct) == 1:
                rom[a] = distinct.pop()
            elif distinct != {rom[a]}:
                shared[a] = words
        return rom, shared


class RegisterEngineCore(wiring.Component):
    """The banked machine's ports (``start``/``prog``/``busy``/``done``, ``host_we``,
    ``host_waddr``, ``host_wdata``, ``host_raddr``, ``host_rdata`` with one cycle of read
    latency) on the register machine: banked addresses translated by a ROM, IMU words
    converted from int16 to float32 on the way in, host writes in two register stages and
    ``start`` registered :data:`START_DELAY` times (so a start follows the writes before
    it). A host read in the two cycles after a host write is not supported (the write takes
    the machine's one host address); no caller makes one."""

    def __init__(self, image: RegisterEngineImage):
        self.image = image
        aw = image.fields.aw
        self.keys = list(image.programs)
        #: an IMU sample: the start cycle to ``done`` (one sample per run)
        self.LATENCY = image.cycles("propagate") + 1
        self.THROUGHPUT = Fraction(1, self.LATENCY)
        super().__init__({"start": In(1), "prog": In(range(max(2, len(self.keys)))),
                          "busy": Out(1), "done": Out(1),
                          "host_we": In(1), "host_waddr": In(aw), "host_wdata": In(32),
                          "host_raddr": In(aw), "host_rdata": Out(32)})

    def elaborate(self, platform):
        from navgate.opflow.regmachine import RegisterMachine

        m = Module()
        img = self.image
        m.submodules.rm = rm = RegisterMachine(img.rp)
        rom, shared = img.translation()
        translate = Memory(shape=13, depth=len(rom), init=rom)
        m.submodules.translate = translate
        # reads: combinational ROM (the register machine's read is the one cycle); writes:
        # the ROM word registered with the data
        rd = translate.read_port(domain="comb")
        wr = translate.read_port(domain="comb")
        # per shared output address: whose word it holds (0: the ROM's; k + 1: the k-th
        # program's of its list), set when a program that writes it starts (a start while
        # busy is outside the handshake and starts nothing)
        holder = {a: Signal(range(len(words) + 1), name=f"holder_{a}")
                  for a, words in shared.items()}
        for a, words in shared.items():
            for k, key in enumerate(words):
                with m.If(self.start & ~self.busy & (self.prog == self.keys.index(key))):
                    m.d.sync += holder[a].eq(k + 1)

        def mapped(port, addr):
            m.d.comb += port.addr.eq(addr)
            w = Signal(13, name=f"map_{port.addr.name}")
            m.d.comb += w.eq(port.data)
            for a, words in shared.items():
                for k, word in enumerate(words.values()):
                    with m.If((addr == a) & (holder[a] == k + 1)):
                        m.d.comb += w.eq(word)
            return w

        rword = mapped(rd, self.host_raddr)
        wword = mapped(wr, self.host_waddr)
        # host writes in two stages: the translated address and the data registered, then
        # the IMU word's int16 -> float32 conversion registered (the sequencer's write
        # multiplexer and the conversion in one cycle made the top's longest path, 5.3 ns;
        # the conversion alone into the data memory's write port 4.3 ns)
        w_pending, w_imu = Signal(), Signal()
        w_addr = Signal(11)
        w_data = Signal(32)
        m.d.sync += [w_pending.eq(self.host_we & wword[12]), w_addr.eq(wword[:11]),
                     w_imu.eq(wword[11]), w_data.eq(self.host_wdata)]
        cvt = int16_to_fp32(m, w_data)
        w2_pending = Signal()
        w2_addr = Signal(11)
        w2_word = Signal(32)
        m.d.sync += [w2_pending.eq(w_pending), w2_addr.eq(w_addr),
                     w2_word.eq(Mux(w_imu, cvt, w_data))]
        m.d.comb += [rm.host_we.eq(w2_pending), rm.host_wdata.eq(w2_word),
                     rm.host_addr.eq(Mux(w2_pending, w2_addr, rword[:11]))]
        # a name the register machine does not hold reads as 0
        r_valid = Signal()
        m.d.sync += r_valid.eq(rword[12])
        m.d.comb += self.host_rdata.eq(Mux(r_valid, rm.host_rdata, 0))
        entry_of = Array([Const(rm.entry_index(k), len(rm.entry)) for k in self.keys])
        start_d = Signal(START_DELAY)
        entry_d = [Signal(len(rm.entry), name=f"entry_d{k}") for k in range(START_DELAY)]
        m.d.sync += [start_d.eq(Cat(self.start, start_d[:-1])),
                     entry_d[0].eq(entry_of[self.prog])]
        m.d.sync += [entry_d[k].eq(entry_d[k - 1]) for k in range(1, START_DELAY)]
        m.d.comb += [rm.start.eq(start_d[-1]), rm.entry.eq(entry_d[-1]),
                     self.done.eq(rm.done), self.busy.eq(rm.busy | start_d.any())]
        return m


@lru_cache(maxsize=1)
def register_engine_image() -> RegisterEngineImage:
    return RegisterEngineImage()


#: the PL engines ``ins_trn_top`` can carry: the banked scheduled datapath
#: (:mod:`navgate.systems.ins_trn.pl.nav_engines`, the default) or the register machine
PL_ENGINES = ("banked", "register")


def pl_engine_image(kind: str = "banked"):
    """The engine image of ``kind`` (:data:`PL_ENGINES`): what the sequencer, the stream
    wrapper and the PS read (programs, register and output addresses, cycles, machine)."""
    if kind == "banked":
        from navgate.systems.ins_trn.pl.nav_engines import engine_image

        return engine_image("ins_engines")
    if kind == "register":
        return register_engine_image()
    raise ValueError(f"unknown PL engine {kind!r}; choose from {', '.join(PL_ENGINES)}")


def ins_engines_compact():
    """``navgate build ins_engines_compact``: the register machine of seed 000 behind the
    banked engine's ports (the adapter core), the engine ``ins_trn_top_compact`` carries."""
    return RegisterEngineCore(register_engine_image())
