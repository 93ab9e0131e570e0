"""Seed 000 ``clk_rst_gen``: the clock and the reset sequence of ``ins_trn_top``.

Seed 000 "Clock and Reset Architecture" draws an MMCM making clk_sys (100 MHz) and clk_dsp
(200 MHz) with synchronised resets, and a reset sequence: wait for the MMCM to lock, then an
8-cycle synchronised reset pulse, then BRAM initialisation and sensor configuration (done by
the blocks themselves once the reset is released).

navgate runs everything in one 100 MHz domain (``sync``): the engines meet the seed's time
budget at 100 MHz (docs/seed000-engines.md), and one domain removes every clock-domain
crossing inside the fabric; the only asynchronous inputs left are the sensor pins, which pass
through synchronisers in the sensor interfaces. ``clk_dsp`` is therefore not generated.

For synthesis the MMCM is an ``MMCME2_BASE`` (7-series clocking resources user guide, UG472)
fed by the Zybo Z7-20's 125 MHz oscillator: VCO = 125 MHz x 8 = 1000 MHz (inside the
-1 speed grade's 600-1200 MHz), CLKOUT0 = 1000 / 10 = 100 MHz, through a BUFG. For simulation
(``simulation=True``) the simulator's clock drives ``sync`` directly and the MMCM is a model
whose LOCKED rises ``lock_cycles`` cycles after power-on.

The reset of ``sync``: high from power-on; released ``reset_cycles`` (8) cycles after LOCKED
has passed a two-flip-flop synchroniser; asserted again, through a synchroniser, while the
external active-low reset (a button or the PS's FCLK_RESET0_N) is low or LOCKED drops.
"""

from __future__ import annotations

from amaranth import ClockDomain, ClockSignal, Elaboratable, Instance, Module, ResetSignal, Signal
from amaranth.lib.cdc import FFSynchronizer

from navgate.gateware.parameters import CheckedParameters

#: the Zybo Z7-20's PL oscillator (pin K17) and the fabric clock
INPUT_CLOCK_HZ = 125e6
SYSTEM_CLOCK_HZ = 100e6
MMCM_PARAMETERS = {"CLKIN1_PERIOD": 8.0, "CLKFBOUT_MULT_F": 8.0, "DIVCLK_DIVIDE": 1,
                   "CLKOUT0_DIVIDE_F": 10.0}


class ClockResetGenerator(CheckedParameters, Elaboratable):
    """Drives the ``sync`` domain's clock and reset (see the module docstring).

    ``clk_in`` is the oscillator pin (synthesis only); ``ext_rst_n`` the active-low external
    reset; ``locked`` the MMCM's lock flag (or its model's).
    """

    LATENCY = 0
    THROUGHPUT = 1

    @classmethod
    def check_parameters(cls, *, simulation, lock_cycles, reset_cycles, define_domain) -> None:
        if reset_cycles < 1 or lock_cycles < 0:
            raise ValueError("reset_cycles must be >= 1 and lock_cycles >= 0")

    def __init__(self, *, simulation: bool = False, lock_cycles: int = 100_000,
                 reset_cycles: int = 8, define_domain: bool = True):
        self.simulation = simulation
        self.lock_cycles = lock_cycles
        self.reset_cycles = reset_cycles
        #: define ``sync`` here (a stand-alone generator); a top level that instantiates the
        #: generator defines ``sync`` itself and passes False
        self.define_domain = define_domain
        self.clk_in = Signal()
        self.ext_rst_n = Signal(init=1)
        self.locked = Signal()

    def elaborate(self, platform):
        m = Module()
        if self.define_domain:
            m.domains.sync = ClockDomain("sync")
        # a domain without reset on the same clock holds the sequencer
        m.domains.por = ClockDomain("por", reset_less=True)
        m.d.comb += ClockSignal("por").eq(ClockSignal("sync"))
        if self.simulation:
            count = Signal(range(self.lock_cycles + 1))
            with m.If(count != self.lock_cycles):
                m.d.por += count.eq(count + 1)
            m.d.comb += self.locked.eq(count == self.lock_cycles)
        else:
            feedback = Signal()
            clk_mmcm = Signal()
            m.submodules.mmcm = Instance(
                "MMCME2_BASE",
                **{f"p_{k}": v for k, v in MMCM_PARAMETERS.items()},
                i_CLKIN1=self.clk_in, i_CLKFBIN=feedback, i_RST=0, i_PWRDWN=0,
                o_CLKFBOUT=feedback, o_CLKOUT0=clk_mmcm, o_LOCKED=self.locked)
            m.submodules.bufg = Instance("BUFG", i_I=clk_mmcm, o_O=ClockSignal("sync"))
        healthy = Signal()
        m.submodules.sync_healthy = FFSynchronizer(self.locked & self.ext_rst_n, healthy,
                                                   o_domain="por", init=0, stages=2)
        hold = Signal(range(self.reset_cycles + 1), init=self.reset_cycles)
        with m.If(~healthy):
            m.d.por += hold.eq(self.reset_cycles)
        with m.Elif(hold != 0):
            m.d.por += hold.eq(hold - 1)
        reset = Signal(init=1)
        m.d.por += reset.eq(hold != 0)
        m.d.comb += ResetSignal("sync").eq(reset)
        return m
