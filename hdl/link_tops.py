"""The board tops behind the host link (SPEC section 8): a board, the 8N1 UART of ``hdl.uart`` and
the framing of ``hdl.link_protocol`` (frames, commands, payload layouts; docs/host_link.md).

Board tops (pins ``rx: In(1)``, ``tx: Out(1)``; ``clk_freq_hz``, ``baud``):

- :class:`ControllerLinkTop`: ``ControllerEHW`` (an iCEBreaker);
- :class:`EvaluatorLinkTop`: ``EvaluatorEHW`` (``double_buffer=False`` for the iCEBreaker), one
  controller at a time (``p_max`` = 1);
- :class:`SystemLinkTop`: ``SystemTop``, both boards and the population streamer (a ULX3S).

A ``LOAD_CONTROLLER`` frame writes the rows into the controller's *shadow* while it arrives and
commits only when its CRC checks: the double buffer is what keeps a corrupted frame from ever
driving the robot.
"""

from amaranth.hdl import Array, Const, Module, Signal, Value
from amaranth.lib import data, wiring
from amaranth.lib.wiring import In, Out

from ga.genome import GENOME_BITS, ROW_BITS
from ga.motions import DEFAULT_DISTANCE_RULE, N_INPUTS
from hdl.controller_ehw import ControllerEHW
from hdl.evaluator_ehw import EvaluatorEHW
from hdl.link_protocol import (ARG_BYTES, DEFAULT_TIMEOUT_S, DESIGN_COMMANDS, EVALUATE_REPLY,
                               EVALUATE_REQUEST, GENOME_LAYOUT_VERSION, IDENTIFY_REPLY,
                               COUNTERS_REPLY, LOAD_GENOME_REQUEST, MAX_PAYLOAD, MOTION_REPLY,
                               MOTION_REQUEST, NAME_BYTES, OBSERVE_REQUEST, RATE_REQUEST,
                               READ_RESULTS_REQUEST, REFLEX_REQUEST, REQUEST_LENGTH, RESULT_BYTES, RESULT_REPLY,
                               RESULTS_PER_READ, Command, Design, FrameReceiver, FrameSender,
                               RowAssembler, Status, default_build_id, distance_rule_code,
                               layout_bytes)
from hdl.link_counters import COUNTERS_BASE, IDENTIFY_BASE, LinkCounters
from hdl.uart import DEFAULT_BAUD, UART


class _Link:
    """The front end every top shares, and the signals its command states use."""

    def __init__(self, m, top):
        self.uart = m.submodules.uart = UART(top.clk_freq_hz, top.baud)
        self.rcv = m.submodules.receiver = FrameReceiver(top.timeout_cycles)
        self.snd = m.submodules.sender = FrameSender()
        self.asm = m.submodules.rows = RowAssembler()
        m.d.comb += [self.uart.rx.eq(top.rx), top.tx.eq(self.uart.tx)]
        wiring.connect(m, self.uart.rx_data, self.rcv.data)
        wiring.connect(m, self.snd.data, self.uart.tx_data)

        self.command = Signal(8)   # the command being answered
        self.tag = Signal(8)
        self.status = Signal(8)
        self.length = Signal(8)    # reply payload bytes
        self.reply = Signal(8 * 32)  # reply payload (byte i = bits 8i..8i+7) unless a top overrides
        self.args = Signal(8 * ARG_BYTES)  # the first request payload bytes
        # IDENTIFY's reply and the counters of READ_COUNTERS live in a block RAM
        identity = IDENTIFY_REPLY.const(top.identity()).as_value().value
        self.counters = m.submodules.counters = LinkCounters(
            identity.to_bytes(layout_bytes(IDENTIFY_REPLY), "little"))

        rcv = self.rcv
        with m.If(rcv.byte_valid & (rcv.index < ARG_BYTES)):
            m.d.sync += self.args.word_select(rcv.index[:2], 8).eq(rcv.byte)
        # genome bytes into rows: LOAD_CONTROLLER's whole payload, LOAD_GENOME's after the index
        cmd = rcv.header.command
        offset = layout_bytes(LOAD_GENOME_REQUEST)
        genome_byte = (((cmd == Command.LOAD_CONTROLLER.value))
                       | ((cmd == Command.LOAD_GENOME.value) & (rcv.index >= offset)))
        m.d.comb += [
            self.asm.restart.eq(rcv.begin),
            self.asm.byte.eq(rcv.byte),
            self.asm.valid.eq(rcv.byte_valid & genome_byte),
            self.snd.header.command.eq(self.command),
            self.snd.header.tag.eq(self.tag),
            self.snd.header.status.eq(self.status),
            self.snd.header.length.eq(self.length),
            self.snd.byte.eq(self.reply.word_select(self.snd.index[:5], 8)),
        ]
        with m.If(self.command == Command.IDENTIFY.value):
            m.d.comb += [self.counters.addr.eq(IDENTIFY_BASE + self.snd.index),
                         self.snd.byte.eq(self.counters.data)]
        with m.If(self.command == Command.READ_COUNTERS.value):
            m.d.comb += [self.counters.addr.eq(COUNTERS_BASE + self.snd.index),
                         self.snd.byte.eq(self.counters.data)]

    def rows_for(self, m, command: Command, port):
        """Drive the row-write ``port`` from the assembler, writing only in a frame of ``command``."""
        m.d.comb += [port.addr.eq(self.asm.row.addr), port.data.eq(self.asm.row.data),
                     port.we.eq(self.writes(command))]

    def writes(self, command: Command):
        """The assembler writes a row of a ``command`` frame in this cycle."""
        return self.asm.row.we & (self.rcv.header.command == command.value)

    def args_as(self, layout):
        return data.View(layout, self.args[:data.Layout.cast(layout).size])

    def reply_as(self, layout):
        return data.View(layout, self.reply[:data.Layout.cast(layout).size])

    def serve(self, m, command: Command, value):
        """Send the reply payload of ``command`` straight from ``value`` (a view or value of its
        layout that holds still from the command state to the end of the reply), byte by byte as
        the sender asks, instead of copying it into ``reply`` first: no flip-flops for it."""
        value = Value.cast(value)
        n_bytes = (len(value) + 7) // 8
        index = self.snd.index[:max(1, (n_bytes - 1).bit_length())]
        with m.If(self.command == command.value):
            m.d.comb += self.snd.byte.eq(value.word_select(index, 8))

    def answer(self, m, status: Status, length=0):
        """Send a reply (from a command state): ``status``, ``length`` payload bytes."""
        m.d.sync += [self.status.eq(status.value), self.length.eq(length)]
        m.next = "Reply"


class _LinkTop(wiring.Component):
    """What the three tops share: pins, parameters, dispatch, IDENTIFY, READ_COUNTERS, replies.

    A subclass sets ``DESIGN`` and ``P_MAX``, builds its boards in ``_boards`` and adds one
    ``Run<Command>`` state per decoded command (beyond the two shared ones) in ``_states``.
    """

    DESIGN: Design
    distance_rule: str | None = None  # the rule the board's fitness counts (None: it has no fitness)
    rx: In(1, init=1)
    tx: Out(1, init=1)

    def __init__(self, clk_freq_hz: float, baud: float = DEFAULT_BAUD, *,
                 timeout_s: float = DEFAULT_TIMEOUT_S, build_id: int | None = None, **params):
        from hdl.uart import uart_divisor

        uart_divisor(clk_freq_hz, baud)  # refuses a baud the clock cannot make, now
        if not timeout_s > 0:
            raise ValueError(f"timeout_s must be positive, got {timeout_s!r}")
        self.clk_freq_hz = clk_freq_hz
        self.baud = baud
        self.timeout_s = timeout_s
        byte_cycles = 10 * round(clk_freq_hz / baud)
        self.timeout_cycles = max(4 * byte_cycles, round(timeout_s * clk_freq_hz))
        self.params = params
        self.build_id = (default_build_id(self.DESIGN, {"clk": clk_freq_hz, "baud": baud, **params})
                         if build_id is None else int(build_id))
        if not 0 <= self.build_id < 1 << 32:
            raise ValueError(f"build_id must fit 32 bits, got {build_id!r}")
        super().__init__()

    @property
    def commands(self) -> tuple:
        return DESIGN_COMMANDS[self.DESIGN]

    def identity(self) -> dict:
        name = self.DESIGN.value.encode()
        return {"design": int.from_bytes(name.ljust(NAME_BYTES, b"\0"), "little"),
                "layout_version": GENOME_LAYOUT_VERSION, "build_id": self.build_id,
                "p_max": self.P_MAX, "clk_freq_hz": round(self.clk_freq_hz), "baud": round(self.baud),
                "distance_rule": distance_rule_code(self.distance_rule)}

    def elaborate(self, platform):
        m = Module()
        link = _Link(m, self)
        self._boards(m, link)
        rcv = link.rcv
        with m.FSM(init="Listen"):
            with m.State("Listen"):
                with m.If(rcv.truncated):
                    m.d.sync += [link.command.eq(rcv.header.command), link.tag.eq(rcv.header.tag)]
                    m.d.comb += link.counters.count_rejected.eq(1)
                    link.answer(m, Status.TRUNCATED)
                with m.Elif(rcv.done):
                    m.d.sync += [link.command.eq(rcv.header.command), link.tag.eq(rcv.header.tag)]
                    with m.If(~rcv.ok):
                        m.d.comb += link.counters.count_rejected.eq(1)
                        link.answer(m, Status.BAD_CRC)
                    with m.Else():
                        with m.Switch(rcv.header.command):
                            for command in self.commands:
                                with m.Case(command.value):
                                    with m.If(rcv.header.length != REQUEST_LENGTH[command]):
                                        m.d.comb += link.counters.count_rejected.eq(1)
                                        link.answer(m, Status.BAD_LENGTH)
                                    with m.Else():
                                        m.d.comb += link.counters.count_ok.eq(1)
                                        m.next = _state(command)
                            with m.Default():
                                m.d.comb += link.counters.count_rejected.eq(1)
                                link.answer(m, Status.UNKNOWN_COMMAND)
            # both replies are read from the counters' RAM, once its update of this frame is done
            with m.State(_state(Command.IDENTIFY)):
                with m.If(~link.counters.busy):
                    link.answer(m, Status.OK, layout_bytes(IDENTIFY_REPLY))
            with m.State(_state(Command.READ_COUNTERS)):
                with m.If(~link.counters.busy):
                    link.answer(m, Status.OK, layout_bytes(COUNTERS_REPLY))
            self._states(m, link)
            with m.State("Reply"):
                m.d.comb += link.snd.start.eq(1)
                m.next = "Send"
            with m.State("Send"):
                with m.If(~link.snd.busy):
                    m.next = "Listen"
        return m

    def _boards(self, m, link):
        raise NotImplementedError

    def _states(self, m, link):
        raise NotImplementedError

    # -- command states the tops share (each top passes its boards' ports) -------------------

    @staticmethod
    def _motion_states(m, link, ctl):
        """MOTION: sensor bits into the controller for a cycle, its registered motion back."""
        x = Signal(N_INPUTS)
        m.d.comb += ctl.x.eq(x)
        with m.State(_state(Command.MOTION)):
            m.d.sync += x.eq(link.args_as(MOTION_REQUEST).state)
            m.next = "MotionWait"
        with m.State("MotionWait"):  # x is on the array; the motion register takes it at this edge
            m.next = "MotionRead"
        with m.State("MotionRead"):
            m.d.sync += link.reply_as(MOTION_REPLY).motion.eq(ctl.motion)
            link.answer(m, Status.OK, layout_bytes(MOTION_REPLY))

    @staticmethod
    def _model_states(m, link, ev):
        """OBSERVE (entry + from-state, then the reached state: 2 cycles) and CLEAR on an
        evaluator whose ports are ``model`` (hdl.ports.ModelWriteSignature), ``state_*``,
        ``clear``, ``ready``."""
        req = link.args_as(OBSERVE_REQUEST)
        with m.State(_state(Command.OBSERVE)):
            with m.If(ev.ready):
                m.d.comb += [ev.model.state.eq(req.state), ev.model.motion.eq(req.motion),
                             ev.model.next.eq(req.next), ev.model.crash.eq(req.crash),
                             ev.model.valid.eq(1), ev.model.we.eq(1),
                             ev.state_value.eq(req.state), ev.state_we.eq(1)]
                m.next = "ObserveReached"
        with m.State("ObserveReached"):
            m.d.comb += [ev.state_value.eq(req.reached), ev.state_we.eq(1)]
            link.answer(m, Status.OK)
        with m.State(_state(Command.CLEAR)):
            with m.If(ev.ready):
                m.d.comb += ev.clear.eq(1)
                m.next = "ClearWait"
        with m.State("ClearWait"):
            with m.If(ev.ready):
                link.answer(m, Status.OK)

    @staticmethod
    def _rate_states(m, link, ev):
        """WRITE_RATE on an evaluator whose ports are ``rate`` (hdl.ports.RateWriteSignature) and
        ``ready``: the code is written in the first cycle the evaluator is idle."""
        req = link.args_as(RATE_REQUEST)
        with m.State(_state(Command.WRITE_RATE)):
            with m.If(ev.ready):
                m.d.comb += [ev.rate.state.eq(req.state), ev.rate.motion.eq(req.motion),
                             ev.rate.code.eq(req.code), ev.rate.we.eq(1)]
                link.answer(m, Status.OK)


def _state(command: Command) -> str:
    """The FSM state that runs ``command``: ``RunLoadGenome`` for LOAD_GENOME."""
    return "Run" + "".join(part.capitalize() for part in command.name.split("_"))


class _Ports:
    """A board's ports under the names the shared command states use (SystemTop's ``ev_*`` and
    ``ctl_*`` ports seen as an evaluator's and a controller's)."""

    def __init__(self, **ports):
        self.__dict__.update(ports)


class ControllerLinkTop(_LinkTop):
    """The controller board (``ControllerEHW``) behind the host link: one iCEBreaker.

    Decodes IDENTIFY, READ_COUNTERS, LOAD_CONTROLLER, SET_REFLEX, MOTION.

    Parameters
    ----------
    clk_freq_hz : float; baud : float (default 115,200); timeout_s : float (default 10 ms);
    build_id : int (default: :func:`default_build_id`)

    Ports
    -----
    rx : In(1), tx : Out(1)
        The UART's pins.
    """

    DESIGN = Design.CONTROLLER
    P_MAX = 0

    def _boards(self, m, link):
        self._ctl = m.submodules.ctl = ControllerEHW()
        self._reflex = Signal()
        link.rows_for(m, Command.LOAD_CONTROLLER, self._ctl.row)
        m.d.comb += self._ctl.reflex_en.eq(self._reflex)

    def _states(self, m, link):
        _controller_states(m, link, self._ctl, commit=self._ctl.commit, reflex=[self._reflex])


def _controller_states(m, link, ctl, *, commit, reflex):
    """LOAD_CONTROLLER (the commit: the rows are in the shadow already), SET_REFLEX, MOTION."""
    with m.State(_state(Command.LOAD_CONTROLLER)):
        m.d.comb += commit.eq(1)
        link.answer(m, Status.OK)
    with m.State(_state(Command.SET_REFLEX)):
        m.d.sync += [r.eq(link.args_as(REFLEX_REQUEST).enable) for r in reflex]
        link.answer(m, Status.OK)
    _LinkTop._motion_states(m, link, ctl)


class EvaluatorLinkTop(_LinkTop):
    """The evaluator board (``EvaluatorEHW``) behind the host link: one controller at a time
    (``p_max`` = 1). ``double_buffer=False`` for the iCE40UP5K (SPEC section 8).

    Decodes IDENTIFY, READ_COUNTERS, SET_REFLEX, OBSERVE, CLEAR, WRITE_RATE, LOAD_GENOME (slot 0),
    EVALUATE (count 1; replies the evaluator's ``cycles``), READ_RESULTS (first 0, count 1).

    LOAD_GENOME writes the rows straight into the evaluator as they arrive, so a frame that fails
    after touching them clears ``loaded``, and EVALUATE answers NOT_LOADED until a good
    LOAD_GENOME: an evaluation never runs on a half-written controller.
    """

    DESIGN = Design.EVALUATOR
    P_MAX = 1

    def __init__(self, clk_freq_hz: float, baud: float = DEFAULT_BAUD, *, double_buffer: bool = True,
                 distance_rule: str = DEFAULT_DISTANCE_RULE, **kwargs):
        self.double_buffer = bool(double_buffer)
        self.distance_rule = distance_rule
        super().__init__(clk_freq_hz, baud, double_buffer=self.double_buffer,
                         distance_rule=distance_rule, **kwargs)

    def _boards(self, m, link):
        ev = self._ev = m.submodules.ev = EvaluatorEHW(double_buffer=self.double_buffer,
                                                       distance_rule=self.distance_rule)
        self._reflex = Signal()
        self._loaded = Signal()
        link.rows_for(m, Command.LOAD_GENOME, ev.row)
        m.d.comb += [ev.reflex_en.eq(self._reflex),
                     link.counters.cycles.eq(ev.cycles)]  # a result register: holds until the next
        with m.If(link.writes(Command.LOAD_GENOME)):
            m.d.sync += self._loaded.eq(0)
        # the evaluator's result registers change only at the edge that ends an evaluation, and
        # only EVALUATE starts one (its reply follows ``done``): served in place
        cycles, result = Signal(EVALUATE_REPLY), Signal(RESULT_REPLY)
        m.d.comb += [cycles.cycles.eq(ev.cycles), result.result.crashes.eq(ev.crashes),
                     result.result.loops.eq(ev.loops), result.result.distance.eq(ev.distance),
                     result.result.fails.eq(ev.fails)]
        link.serve(m, Command.EVALUATE, cycles)
        link.serve(m, Command.READ_RESULTS, result)

    def _states(self, m, link):
        ev = self._ev
        with m.State(_state(Command.SET_REFLEX)):
            m.d.sync += self._reflex.eq(link.args_as(REFLEX_REQUEST).enable)
            link.answer(m, Status.OK)
        self._model_states(m, link, ev)
        self._rate_states(m, link, ev)
        with m.State(_state(Command.LOAD_GENOME)):
            with m.If(link.args_as(LOAD_GENOME_REQUEST).index != 0):
                link.answer(m, Status.BAD_ARGUMENT)
            with m.Else():
                m.d.sync += self._loaded.eq(1)
                link.answer(m, Status.OK)
        with m.State(_state(Command.EVALUATE)):
            with m.If(link.args_as(EVALUATE_REQUEST).count != 1):
                link.answer(m, Status.BAD_ARGUMENT)
            with m.Elif(~self._loaded):
                link.answer(m, Status.NOT_LOADED)
            with m.Elif(ev.ready):
                m.d.comb += ev.start.eq(1)
                m.next = "EvaluateWait"
        with m.State("EvaluateWait"):
            with m.If(ev.done):
                m.d.comb += link.counters.add_cycles.eq(1)
                link.answer(m, Status.OK, layout_bytes(EVALUATE_REPLY))
        with m.State(_state(Command.READ_RESULTS)):
            req = link.args_as(READ_RESULTS_REQUEST)
            with m.If((req.first != 0) | (req.count != 1)):
                link.answer(m, Status.BAD_ARGUMENT)
            with m.Else():
                link.answer(m, Status.OK, RESULT_BYTES)


class SystemLinkTop(_LinkTop):
    """Both boards and the population streamer (``SystemTop``) behind one host link: a ULX3S.

    Decodes every :class:`Command`. LOAD_GENOME fills a genome buffer as the frame arrives and
    writes it into population slot ``index`` only when the frame checks; EVALUATE streams slots
    0..count-1 (``go``) and replies ``pop_cycles``; READ_RESULTS reads the results RAM.
    """

    DESIGN = Design.SYSTEM

    def __init__(self, clk_freq_hz: float, baud: float = DEFAULT_BAUD, *, p_max: int | None = None,
                 distance_rule: str = DEFAULT_DISTANCE_RULE, **kwargs):
        from hdl.system_top import P_MAX

        self.P_MAX = P_MAX if p_max is None else int(p_max)
        self.distance_rule = distance_rule
        super().__init__(clk_freq_hz, baud, p_max=self.P_MAX, distance_rule=distance_rule, **kwargs)

    def _boards(self, m, link):
        from hdl.system_top import SystemTop

        top = self._top = m.submodules.system = SystemTop(p_max=self.P_MAX, distance_rule=self.distance_rule)
        self._reflex = Signal()
        rows = link.asm.row
        genome = self._genome = Signal(GENOME_BITS)
        with m.If(link.writes(Command.LOAD_GENOME)):
            m.d.sync += genome.word_select(rows.addr, ROW_BITS).eq(rows.data)
        link.rows_for(m, Command.LOAD_CONTROLLER, top.ctl_row)
        m.d.comb += [
            top.ctl_reflex_en.eq(self._reflex), top.ev_reflex_en.eq(self._reflex),
            top.pop_data.eq(genome),
            link.counters.cycles.eq(top.pop_cycles),  # holds from pop_done to the next go
        ]
        # READ_RESULTS: payload byte i is byte i % RESULT_BYTES of result first + i // RESULT_BYTES
        # (tables, not dividers)
        req = link.args_as(READ_RESULTS_REQUEST)
        which = Array(Const(i // RESULT_BYTES, 8) for i in range(MAX_PAYLOAD + 1))
        part = Array(Const(i % RESULT_BYTES, range(RESULT_BYTES)) for i in range(MAX_PAYLOAD + 1))
        index = link.snd.index
        result = Signal(8 * RESULT_BYTES)
        m.d.comb += [top.res_addr.eq(req.first + which[index]), result.eq(top.res_data.as_value())]
        with m.If(link.command == Command.READ_RESULTS.value):
            m.d.comb += link.snd.byte.eq(result.word_select(part[index], 8))

    def _states(self, m, link):
        top = self._top
        ev = _Ports(
            model=top.ev_model, rate=top.ev_rate, state_value=top.ev_state_value, state_we=top.ev_state_we,
            clear=top.ev_clear, ready=top.ev_ready & ~top.pop_busy)
        ctl = _Ports(x=top.ctl_x, motion=top.ctl_motion)
        _controller_states(m, link, ctl, commit=top.ctl_commit, reflex=[self._reflex])
        self._model_states(m, link, ev)
        self._rate_states(m, link, ev)
        with m.State(_state(Command.LOAD_GENOME)):
            index = link.args_as(LOAD_GENOME_REQUEST).index
            with m.If(index >= self.P_MAX):
                link.answer(m, Status.BAD_ARGUMENT)
            with m.Elif(ev.ready):
                m.d.comb += [top.pop_addr.eq(index), top.pop_we.eq(1)]
                link.answer(m, Status.OK)
        with m.State(_state(Command.EVALUATE)):
            count = link.args_as(EVALUATE_REQUEST).count
            with m.If((count == 0) | (count > self.P_MAX)):
                link.answer(m, Status.BAD_ARGUMENT)
            with m.Elif(ev.ready):
                m.d.comb += [top.pop_size.eq(count), top.go.eq(1)]
                m.next = "EvaluateWait"
        with m.State("EvaluateWait"):
            with m.If(top.pop_done):
                m.d.sync += link.reply_as(EVALUATE_REPLY).cycles.eq(top.pop_cycles)
                m.d.comb += link.counters.add_cycles.eq(1)
                link.answer(m, Status.OK, layout_bytes(EVALUATE_REPLY))
        with m.State(_state(Command.READ_RESULTS)):
            req = link.args_as(READ_RESULTS_REQUEST)
            bad = (req.count == 0) | (req.count > RESULTS_PER_READ) | (req.first + req.count > self.P_MAX)
            with m.If(bad):
                link.answer(m, Status.BAD_ARGUMENT)
            with m.Else():
                link.answer(m, Status.OK, req.count * RESULT_BYTES)
