"""Seed 000's navigation sequencer: the control between the sensors, the register bank and the
PL engines of ``ins_trn_top``.

Reference: seed 000 "Data Flow" (an IMU sample runs calibration, mechanization and covariance
propagation; the PS's TRN fix runs the Kalman update engine) and "Memory Architecture" (one
state memory the engines share). The engines are the banked float32 machine of
:mod:`navgate.systems.ins_trn.pl.nav_engines` (``ins_engines``: programs ``propagate``,
``alt_gate``/``alt_apply``, ``trn_gate``/``trn_apply``); this block owns its host port and its
start/done handshake and runs one *job* at a time:

=========== ===================================================================================
job         steps
=========== ===================================================================================
``imu``     write the six raw IMU words (int16 sign-extended; the ``propagate`` program
            calibrates them) -> run ``propagate`` -> read back the shadow words
``alt``     write ``h_meas``, ``r``, ``gate`` (ALT_MEAS, ALT_VAR, ALT_GATE) -> run ``alt_gate``
            -> read ``positive``, ``accept``, ``nis`` -> when both flags are 1.0, run
            ``alt_apply`` -> read back
``trn``     write ``y0 y1 r00 r01 r11 lag gate`` (TRN_POS_N/E as the innovation, TRN_COV_NN/NE/
            EE, TRN_LAG, TRN_GATE) -> run ``trn_gate`` -> flags -> ``trn_apply`` -> read back
``write``   ENG_WDATA to register ENG_ADDR (the PS's engine register window)
``read``    register ENG_ADDR to ENG_RDATA
``cal``     CAL_APPLY: the 26 calibration registers (biases, matrices, LSBs; seed "IMU
            Calibration Parameters") into the engines' calibration words
=========== ===================================================================================

The decision between the gate and the apply half is the fp32 engine's
(:meth:`navgate.systems.ins_trn.ps.fp32_engine.Fp32Engine._update`): apply only when ``positive``
and ``accept`` are both exactly 1.0 (``0x3F800000``); the inputs are not rewritten between the
halves (they are unchanged), so the result is the fp32 engine's bit for bit.

Priorities when several requests wait: window commands, CAL_APPLY, the TRN update, then the altitude
update, then an IMU sample (which waits in the sensor interface's FIFO). Requests are latched
(a strobe while a job runs is kept, one per kind). The *shadow* words (the navigation state,
the biases and the 15 variances of P as stored) are read back after every job that changes
them and feed the output registers (through the output formatter) in the same order.

Timing (cycles of ``sync``, exact, :func:`job_cycles`): an IMU sample takes 1 + 6 + 1 +
(638 + 1) + 32 + 1 = 680 cycles from its handshake to ``update``; an altitude update 337
(67 when rejected), a TRN update 469 (158), CAL_APPLY 29.
"""

from __future__ import annotations

from amaranth import Array, Const, Module, Signal
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from navgate.systems.ins_trn.pl.fp32_program import CAL_REGS, N_STATES, p_reg

__all__ = ["NavSequencer", "SHADOW_WORDS", "RAW_IMU_LAYOUT", "ONE", "job_cycles"]

#: float32 1.0: the compare results of the gate programs
ONE = 0x3F800000
#: the raw IMU words the propagate program reads, in the sensor layout's field order
IMU_FIELDS = ("gx", "gy", "gz", "ax", "ay", "az")
IMU_REGS = ("wg0", "wg1", "wg2", "wa0", "wa1", "wa2")
RAW_IMU_LAYOUT = data.StructLayout({f: 32 for f in IMU_FIELDS})
#: the words read back after a job: state, biases, the diagonal of P (stored words)
SHADOW_WORDS = (("pN", "pE", "h", "vN", "vE", "vD", "q0", "q1", "q2", "q3")
                + tuple(f"ba{i}" for i in range(3)) + tuple(f"bg{i}" for i in range(3))
                + tuple(p_reg(i, i) for i in range(N_STATES)))
ALT_INPUTS = ("h_meas", "r", "gate")
TRN_INPUTS = ("y0", "y1", "r00", "r01", "r11", "lag", "gate")
GATE_OUTPUTS = ("positive", "accept", "nis")
JOBS = ("imu", "alt", "trn", "write", "read", "cal")
#: the calibration registers CAL_APPLY copies into the engines (fp32_program.CAL_REGS order)
CAL_INPUTS = CAL_REGS


def job_cycles(image, job: str, applied: bool = True) -> int:
    """Cycles from the IMU sample's handshake, or from the cycle after an update's start strobe
    (the strobe is latched for one cycle), to the one in which ``update`` is high: the request
    cycle, one write per input, the start cycle, the program
    (``cycles + 1`` to ``done``), for an update the three gate reads plus one and the decision,
    then (imu, or an applied update) the apply start and program, the read-back of the shadow
    words (one cycle more than words) and the finishing cycle. A window command ("write",
    "read") returns to IDLE after 3 or 4 cycles and raises no ``update``."""
    n_shadow = len(SHADOW_WORDS)
    if job in ("write", "read"):
        return 3 if job == "write" else 4
    if job == "cal":
        return 2 + len(CAL_INPUTS) + 1
    if job == "imu":
        return 1 + len(IMU_REGS) + 1 + image.cycles("propagate") + 1 + n_shadow + 1 + 1
    ins = ALT_INPUTS if job == "alt" else TRN_INPUTS
    n = 1 + 1 + len(ins) + 1 + image.cycles(f"{job}_gate") + 1 + len(GATE_OUTPUTS) + 1 + 1
    if applied:
        n += 1 + image.cycles(f"{job}_apply") + 1 + n_shadow + 1 + 1
    return n


class NavSequencer(wiring.Component):
    """Runs the engine jobs (module docstring). Ports: ``imu`` (raw words), the register
    bank's fields (``*_start`` strobes, inputs, window), the status and shadow outputs, and
    ``update`` (one-cycle pulse at the end of every imu/alt/trn job)."""

    THROUGHPUT = None  # set from the image (one IMU sample per imu job)

    def __init__(self, image, register_words: dict[str, int] | None = None):
        self.image = image
        #: inputs read from a register file instead of a port each: input name (``alt_r``,
        #: ``trn_y0``, ``cal_g_lsb`` ...) -> word address; the sequencer puts the word on
        #: ``reg_word`` in the cycle it writes the input into the engines and takes
        #: ``reg_data`` (combinational) as the data, so one register-file read port replaces
        #: a multiplexer of up to 36 inputs
        self.register_words = dict(register_words or {})
        self.keys = list(image.programs)
        aw = image.fields.aw
        self.addr = image.layout.fixed
        self.LATENCY = job_cycles(image, "imu")
        self.THROUGHPUT = 1 / self.LATENCY
        members = {
            "imu": In(stream.Signature(RAW_IMU_LAYOUT)),
            "enable": In(1),
            # engine register window
            "eng_addr": In(aw), "eng_wdata": In(32), "eng_write": In(1), "eng_read": In(1),
            "eng_rdata": Out(32), "busy": Out(1), "propagations": Out(24),
            # updates
            "alt_start": In(1), "trn_start": In(1), "cal_apply": In(1),
            "alt_status": Out(3), "trn_status": Out(3), "alt_nis": Out(32), "trn_nis": Out(32),
            "shadow": Out(data.ArrayLayout(32, len(SHADOW_WORDS))),
            "shadow_valid": Out(1),  #: one-cycle pulse: the shadow words are new
            "update": Out(1),
        }
        inputs = ([f"alt_{n}" for n in ALT_INPUTS] + [f"trn_{n}" for n in TRN_INPUTS]
                  + list(CAL_INPUTS))
        unknown = set(self.register_words) - set(inputs)
        if unknown:
            raise ValueError(f"not sequencer inputs: {', '.join(sorted(unknown))}")
        for n in inputs:
            if n not in self.register_words:
                members[n] = In(32)
        if self.register_words:
            members["reg_word"] = Out(max(self.register_words.values()).bit_length())
            members["reg_data"] = In(32)
        super().__init__(members)

    def elaborate(self, platform):
        m = Module()
        img = self.image
        m.submodules.core = core = img.machine()
        a = self.addr
        prog_no = {k: self.keys.index(k) for k in self.keys}

        # latched requests
        req = {j: Signal(name=f"req_{j}") for j in ("alt", "trn", "write", "read", "cal")}
        for j, strobe in (("alt", self.alt_start), ("trn", self.trn_start),
                          ("cal", self.cal_apply),
                          ("write", self.eng_write), ("read", self.eng_read)):
            with m.If(strobe):
                m.d.sync += req[j].eq(1)

        job = Signal(range(len(JOBS)))
        step = Signal(range(64))
        positive = Signal(32)
        accept = Signal(32)
        nis = Signal(32)
        applying = Signal()
        imu_words = Signal(RAW_IMU_LAYOUT)
        alt_status = Signal(3)  # busy, done, rejected
        trn_status = Signal(3)
        propagations = Signal(24)
        m.d.comb += [self.alt_status.eq(alt_status), self.trn_status.eq(trn_status),
                     self.propagations.eq(propagations)]
        # a start strobe shows busy at once (not done), so that a status poll right after the
        # start never sees the previous update's done
        with m.If(self.alt_start):
            m.d.sync += alt_status.eq(0b001)
        with m.If(self.trn_start):
            m.d.sync += trn_status.eq(0b001)
        m.d.sync += [self.update.eq(0), self.shadow_valid.eq(0)]

        # write lists: (register address, source) per job and step
        def source(name):  # (data, register word or None)
            if name in self.register_words:
                return self.reg_data, self.register_words[name]
            return getattr(self, name), None

        writes_of = {
            "imu": [(a[r], getattr(imu_words, f), None)
                    for r, f in zip(IMU_REGS, IMU_FIELDS, strict=True)],
            "alt": [(a[r], *source(f"alt_{r}")) for r in ALT_INPUTS],
            "trn": [(a[r], *source(f"trn_{r}")) for r in TRN_INPUTS],
            "cal": [(a[r], *source(r)) for r in CAL_INPUTS],
        }
        waddr = Signal(img.fields.aw)
        wdata = Signal(32)
        n_writes = Signal(range(len(CAL_INPUTS) + 1))
        with m.Switch(job):
            for name, writes in writes_of.items():
                with m.Case(JOBS.index(name)):
                    m.d.comb += n_writes.eq(len(writes))
                    with m.Switch(step):
                        for k, (addr, src, word) in enumerate(writes):
                            with m.Case(k):
                                m.d.comb += [waddr.eq(addr), wdata.eq(src)]
                                if word is not None:
                                    m.d.comb += self.reg_word.eq(word)
            with m.Default():
                m.d.comb += [n_writes.eq(1), waddr.eq(self.eng_addr),
                             wdata.eq(self.eng_wdata)]

        gate_addr = Signal(img.fields.aw)
        apply_prog = Signal(range(len(self.keys)))
        gate_prog = Signal(range(len(self.keys)))
        with m.If(job == JOBS.index("alt")):
            out = img.output_addr("alt_gate")
            m.d.comb += [gate_prog.eq(prog_no["alt_gate"]), apply_prog.eq(prog_no["alt_apply"]),
                         gate_addr.eq(Array([Const(out[n], img.fields.aw)
                                             for n in GATE_OUTPUTS])[step[:2]])]
        with m.Else():
            out = img.output_addr("trn_gate")
            m.d.comb += [gate_prog.eq(prog_no["trn_gate"]), apply_prog.eq(prog_no["trn_apply"]),
                         gate_addr.eq(Array([Const(out[n], img.fields.aw)
                                             for n in GATE_OUTPUTS])[step[:2]])]
        shadow_addr = Array([Const(a[n], img.fields.aw) for n in SHADOW_WORDS])
        n_shadow = len(SHADOW_WORDS)

        m.d.comb += core.host_wdata.eq(wdata)
        with m.FSM() as fsm:
            with m.State("IDLE"):
                m.d.sync += step.eq(0)
                with m.If(req["write"]):
                    m.d.sync += [job.eq(JOBS.index("write")), req["write"].eq(0)]
                    m.next = "WRITE"
                with m.Elif(req["read"]):
                    m.d.sync += [job.eq(JOBS.index("read")), req["read"].eq(0)]
                    m.next = "READ"
                with m.Elif(req["cal"]):
                    m.d.sync += [job.eq(JOBS.index("cal")), req["cal"].eq(0)]
                    m.next = "WRITE"
                with m.Elif(req["trn"]):
                    m.d.sync += [job.eq(JOBS.index("trn")), req["trn"].eq(0),
                                 trn_status.eq(0b001)]
                    m.next = "WRITE"
                with m.Elif(req["alt"]):
                    m.d.sync += [job.eq(JOBS.index("alt")), req["alt"].eq(0),
                                 alt_status.eq(0b001)]
                    m.next = "WRITE"
                with m.Elif(self.imu.valid & self.enable):
                    m.d.comb += self.imu.ready.eq(1)
                    m.d.sync += [job.eq(JOBS.index("imu")), imu_words.eq(self.imu.payload)]
                    m.next = "WRITE"
            with m.State("WRITE"):
                m.d.comb += [core.host_we.eq(1), core.host_waddr.eq(waddr)]
                m.d.sync += step.eq(step + 1)
                with m.If(step == n_writes - 1):
                    m.d.sync += step.eq(0)
                    with m.If((job == JOBS.index("write")) | (job == JOBS.index("cal"))):
                        m.next = "FINISH"
                    with m.Else():
                        m.next = "START"
            with m.State("READ"):
                m.d.comb += core.host_raddr.eq(self.eng_addr)
                m.next = "READ_DATA"
            with m.State("READ_DATA"):
                m.d.sync += self.eng_rdata.eq(core.host_rdata)
                m.next = "FINISH"
            with m.State("START"):
                m.d.comb += core.start.eq(1)
                with m.If(job == JOBS.index("imu")):
                    m.d.comb += core.prog.eq(prog_no["propagate"])
                with m.Else():
                    m.d.comb += core.prog.eq(gate_prog)
                m.d.sync += applying.eq(0)
                m.next = "RUN"
            with m.State("RUN"):
                with m.If(core.done):
                    m.d.sync += step.eq(0)
                    with m.If((job == JOBS.index("imu")) | applying):
                        with m.If(job == JOBS.index("imu")):
                            m.d.sync += propagations.eq(propagations + 1)
                        m.next = "READBACK"
                    with m.Else():
                        m.next = "GATE"
            with m.State("GATE"):  # read positive, accept, nis (one cycle latency)
                m.d.comb += core.host_raddr.eq(gate_addr)
                m.d.sync += step.eq(step + 1)
                with m.Switch(step):
                    with m.Case(1):
                        m.d.sync += positive.eq(core.host_rdata)
                    with m.Case(2):
                        m.d.sync += accept.eq(core.host_rdata)
                    with m.Case(3):
                        m.d.sync += [nis.eq(core.host_rdata), step.eq(0)]
                        m.next = "DECIDE"
            with m.State("DECIDE"):
                with m.If(job == JOBS.index("alt")):
                    m.d.sync += self.alt_nis.eq(nis)
                with m.Else():
                    m.d.sync += self.trn_nis.eq(nis)
                with m.If((positive == ONE) & (accept == ONE)):
                    m.next = "START_APPLY"
                with m.Else():
                    # rejected: nothing changed, no read-back
                    with m.If(job == JOBS.index("alt")):
                        m.d.sync += alt_status.eq(0b110)
                    with m.Else():
                        m.d.sync += trn_status.eq(0b110)
                    m.d.sync += self.update.eq(1)
                    m.next = "IDLE"
            with m.State("START_APPLY"):
                m.d.comb += [core.start.eq(1), core.prog.eq(apply_prog)]
                m.d.sync += applying.eq(1)
                m.next = "RUN"
            with m.State("READBACK"):  # address at step, data of step - 1
                m.d.comb += core.host_raddr.eq(shadow_addr[step])
                m.d.sync += step.eq(step + 1)
                with m.If(step != 0):
                    m.d.sync += self.shadow[(step - 1)[:len(step)]].eq(core.host_rdata)
                with m.If(step == n_shadow):
                    m.d.sync += self.shadow_valid.eq(1)
                    m.next = "FINISH"
            with m.State("FINISH"):
                with m.If(job == JOBS.index("alt")):
                    m.d.sync += [alt_status.eq(0b010), self.update.eq(1)]
                with m.If(job == JOBS.index("trn")):
                    m.d.sync += [trn_status.eq(0b010), self.update.eq(1)]
                with m.If(job == JOBS.index("imu")):
                    m.d.sync += self.update.eq(1)
                m.next = "IDLE"
        m.d.comb += self.busy.eq(req["write"] | req["read"] | req["trn"] | req["alt"]
                                 | req["cal"] | ~fsm.ongoing("IDLE"))
        return m
