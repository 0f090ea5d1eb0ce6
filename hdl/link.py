"""The host link (SPEC section 8): a framed command protocol over the 8N1 UART of ``hdl.uart``.

This module owns the protocol: the gateware that decodes it and the definitions the host imports
(``cosim.link_host``), as a Glasgow applet's component owns its commands. Nothing here is
re-typed on the host side.

Frame (both directions; docs/host_link.md)::

    SYNC | command | status | tag | length | payload[length] | crc[15:8] | crc[7:0]

- ``SYNC`` = 0xA5 starts a frame; the four header bytes are :class:`FrameHeader` (little-endian,
  ``command`` first). A request carries status 0; a reply echoes the request's command and tag
  with a :class:`Status`.
- The CRC is :data:`LINK_CRC` (CRC-16/IBM-3740, "CCITT-FALSE": poly 0x1021, init 0xFFFF) over the
  header and payload, sent high byte first, so that the CRC register over the whole frame after
  ``SYNC`` ends at the algorithm's residue (0): the gateware checks ``match_detected`` of
  Amaranth's ``lib.crc.Processor``; the host computes ``LINK_CRC.compute``.
- A frame that stalls (no byte for ``timeout_s``, default 10 ms) is dropped and answered
  ``TRUNCATED``; a CRC mismatch is answered ``BAD_CRC``; a good frame whose command the board does
  not decode ``UNKNOWN_COMMAND``; a wrong length ``BAD_LENGTH``. None of them is executed.
- Every command is idempotent (same request, same effect and reply), so the host may resend one
  whose reply it did not get (docs/host_link.md, "retries").

Rows travel as the genome's bytes (119 for 950 bits, ``genome_bytes``): byte j bit i is genome
bit 8j + i (SPEC section 3); :class:`RowAssembler` turns them back into 19-bit row writes as they
arrive. A ``LOAD_CONTROLLER`` frame writes the rows into the controller's *shadow* while it
arrives and commits only when its CRC checks: the double buffer is what keeps a corrupted frame
from ever driving the robot.

Board tops (pins ``rx: In(1)``, ``tx: Out(1)``; ``clk_freq_hz``, ``baud``):

- :class:`ControllerLinkTop`: ``ControllerEHW`` (an iCEBreaker);
- :class:`EvaluatorLinkTop`: ``EvaluatorEHW`` (``double_buffer=False`` for the iCEBreaker), one
  controller at a time (``p_max`` = 1);
- :class:`SystemLinkTop`: ``SystemTop``, both boards and the population streamer (a ULX3S).
"""

import enum as py_enum
import subprocess
import zlib

from amaranth.hdl import Array, Cat, Const, Module, Mux, Signal
from amaranth.lib import crc, data, enum, wiring
from amaranth.lib import stream
from amaranth.lib.wiring import In, Out

from ga.genome import GENOME_BITS, N_ROWS, ROW_BITS
from ga.motions import DEFAULT_DISTANCE_RULE, N_INPUTS, N_OUTPUTS
from hdl.controller_ehw import ControllerEHW
from hdl.evaluator_ehw import EvaluatorEHW
from hdl.ports import RESULT_LAYOUT, RowWriteSignature
from hdl.uart import DEFAULT_BAUD, UART

SYNC = 0xA5
LINK_CRC = crc.catalog.CRC16_IBM_3740(data_width=8)
CRC_BYTES = 2
GENOME_LAYOUT_VERSION = 1  # SPEC section 3's bit layout (ga.genome); bump when it changes
DEFAULT_TIMEOUT_S = 0.010  # inter-byte timeout inside a frame
MAX_PAYLOAD = 255
NAME_BYTES = 16


def genome_bytes() -> int:
    """Bytes that carry one genome: 119 for 950 bits (the last 2 bits are padding, 0)."""
    return (GENOME_BITS + 7) // 8


class Command(enum.Enum, shape=8):
    """The host's commands (request payload -> reply payload; layouts below)."""

    IDENTIFY = 0x01         # -> IDENTIFY_REPLY
    READ_COUNTERS = 0x02    # -> COUNTERS_REPLY
    LOAD_CONTROLLER = 0x10  # genome bytes (119): rows into the shadow, commit if the frame checks
    SET_REFLEX = 0x11       # REFLEX_REQUEST: the reflex enable (both boards on the system top)
    MOTION = 0x12           # MOTION_REQUEST -> MOTION_REPLY: sensor bits in, the motion out
    OBSERVE = 0x20          # OBSERVE_REQUEST: write a world-model entry, add both states to S
    CLEAR = 0x21            # empty the world model (2049 cycles)
    LOAD_GENOME = 0x22      # LOAD_GENOME_REQUEST + genome bytes: population slot `index`
    EVALUATE = 0x23         # EVALUATE_REQUEST -> EVALUATE_REPLY: slots 0..count-1
    READ_RESULTS = 0x24     # READ_RESULTS_REQUEST -> count x RESULT_REPLY
    SEED = 0x30             # SEED_REQUEST: the learning engine's generators (hdl.learner)
    LEARN = 0x31            # LEARN_REQUEST -> LEARN_REPLY: G generations on the chip
    READ_GENOME = 0x32      # READ_GENOME_REQUEST -> genome bytes of population slot `index`


class Status(enum.Enum, shape=8):
    OK = 0x00
    BAD_CRC = 0x01          # the frame's CRC does not check
    TRUNCATED = 0x02        # no byte for the inter-byte timeout inside a frame
    UNKNOWN_COMMAND = 0x03  # not a command this board decodes
    BAD_LENGTH = 0x04       # payload length wrong for the command
    BAD_ARGUMENT = 0x05     # e.g. a population slot beyond p_max
    NOT_LOADED = 0x06       # EVALUATE before a good LOAD_GENOME since the last rows were touched


class FrameHeader(data.Struct):
    """The four bytes after ``SYNC``, in both directions."""

    command: 8
    status: 8
    tag: 8      # chosen by the host per request, echoed in the reply: a late reply is recognised
    length: 8


HEADER_BYTES = data.Layout.cast(FrameHeader).size // 8

# -- payload layouts (little-endian byte streams of these structs) -------------------------------

REFLEX_REQUEST = data.StructLayout({"enable": 1, "_pad": 7})
MOTION_REQUEST = data.StructLayout({"state": N_INPUTS})
MOTION_REPLY = data.StructLayout({"motion": N_OUTPUTS, "_pad": 8 - N_OUTPUTS})
OBSERVE_REQUEST = data.StructLayout({
    "state": N_INPUTS,      # the from-state: entry (state, motion) is written, state joins S
    "motion": N_OUTPUTS,
    "crash": 1,             # the entry after the host's update rule (ga.world_model)
    "_pad": 4,
    "next": N_INPUTS,
    "reached": N_INPUTS,    # the state actually reached this time: joins S
})
LOAD_GENOME_REQUEST = data.StructLayout({"index": 16})  # then the genome bytes
EVALUATE_REQUEST = data.StructLayout({"count": 16})
EVALUATE_REPLY = data.StructLayout({"cycles": 32})
READ_RESULTS_REQUEST = data.StructLayout({"first": 16, "count": 8})
SEED_REQUEST = data.StructLayout({"seed": 32})
LEARN_REQUEST = data.StructLayout({
    "generations": 12,      # 1..4095
    "avoid_en": 1,          # download the escape child of (avoid_state, avoid_motion) if any
    "avoid_motion": N_OUTPUTS,
    "avoid_state": N_INPUTS,
    "serial": 8,            # a LEARN whose serial is the last executed one's only re-sends its reply
})
LEARN_REPLY = data.StructLayout({
    "cycles": 32,           # the engine's busy cycles (its register): ga.hardware_ga.learn_cycles - 1
    "index": 16,            # the download's population slot (READ_GENOME)
    "score": 24,            # its integer score (ga.hardware_ga.score)
    "crashes": 16, "loops": 16, "distance": 16,
    "escaped": 8,           # 1: the download is the escape child, not the best of the last pass
})
READ_GENOME_REQUEST = data.StructLayout({"index": 16})
# one controller's result: the evaluator's result word (hdl.ports.RESULT_LAYOUT) padded to bytes
RESULT_REPLY = data.StructLayout({"result": RESULT_LAYOUT,
                                  "_pad": -data.Layout.cast(RESULT_LAYOUT).size % 8})
IDENTIFY_REPLY = data.StructLayout({
    "design": 8 * NAME_BYTES,   # ASCII, NUL-padded
    "layout_version": 8,        # GENOME_LAYOUT_VERSION
    "build_id": 32,
    "p_max": 16,                # population slots (1: one controller at a time)
    "clk_freq_hz": 32,
    "baud": 32,
})
COUNTERS_REPLY = data.StructLayout({
    "frames_ok": 32,            # frames executed
    "frames_rejected": 16,      # error replies sent
    "evaluator_cycles": 48,     # sum of the evaluations' cycles since reset
})


def _layout_bytes(layout) -> int:
    return (data.Layout.cast(layout).size + 7) // 8


RESULT_BYTES = _layout_bytes(RESULT_REPLY)
RESULTS_PER_READ = MAX_PAYLOAD // RESULT_BYTES  # 51
ARG_BYTES = 4  # request bytes kept for the command (OBSERVE's, the largest)

# the payload length each command's request must have
REQUEST_LENGTH = {
    Command.IDENTIFY: 0,
    Command.READ_COUNTERS: 0,
    Command.LOAD_CONTROLLER: genome_bytes(),
    Command.SET_REFLEX: _layout_bytes(REFLEX_REQUEST),
    Command.MOTION: _layout_bytes(MOTION_REQUEST),
    Command.OBSERVE: _layout_bytes(OBSERVE_REQUEST),
    Command.CLEAR: 0,
    Command.LOAD_GENOME: _layout_bytes(LOAD_GENOME_REQUEST) + genome_bytes(),
    Command.EVALUATE: _layout_bytes(EVALUATE_REQUEST),
    Command.READ_RESULTS: _layout_bytes(READ_RESULTS_REQUEST),
    Command.SEED: _layout_bytes(SEED_REQUEST),
    Command.LEARN: _layout_bytes(LEARN_REQUEST),
    Command.READ_GENOME: _layout_bytes(READ_GENOME_REQUEST),
}
assert max(_layout_bytes(layout) for layout in (OBSERVE_REQUEST, READ_RESULTS_REQUEST, SEED_REQUEST,
                                                LEARN_REQUEST, READ_GENOME_REQUEST)) <= ARG_BYTES


class Design(py_enum.Enum):
    """What a board answers to IDENTIFY, and which commands it decodes."""

    CONTROLLER = "ehw-controller"
    EVALUATOR = "ehw-evaluator"
    SYSTEM = "ehw-system"
    LEARNER = "ehw-learner"


_CONTROLLER_COMMANDS = (Command.LOAD_CONTROLLER, Command.SET_REFLEX, Command.MOTION)
_EVALUATOR_COMMANDS = (Command.SET_REFLEX, Command.OBSERVE, Command.CLEAR, Command.LOAD_GENOME,
                       Command.EVALUATE, Command.READ_RESULTS)
DESIGN_COMMANDS = {
    Design.CONTROLLER: (Command.IDENTIFY, Command.READ_COUNTERS) + _CONTROLLER_COMMANDS,
    Design.EVALUATOR: (Command.IDENTIFY, Command.READ_COUNTERS) + _EVALUATOR_COMMANDS,
    Design.SYSTEM: (Command.IDENTIFY, Command.READ_COUNTERS) + _CONTROLLER_COMMANDS
                   + tuple(c for c in _EVALUATOR_COMMANDS if c not in _CONTROLLER_COMMANDS),
    Design.LEARNER: (Command.IDENTIFY, Command.READ_COUNTERS) + _CONTROLLER_COMMANDS
                    + (Command.OBSERVE, Command.CLEAR, Command.LOAD_GENOME, Command.SEED,
                       Command.LEARN, Command.READ_GENOME),
}


def default_build_id(design: Design, params: dict) -> int:
    """A 32-bit build id: CRC-32 of the design, its parameters and the source's git commit."""
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True,
                              timeout=5, cwd=__file__.rsplit("/", 2)[0]).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        head = ""
    return zlib.crc32(repr((design.value, GENOME_LAYOUT_VERSION, sorted(params.items()), head)).encode())


# -- framing gateware ------------------------------------------------------------------------------


class FrameReceiver(wiring.Component):
    """Bytes from the UART -> frames: header, payload bytes as they arrive, then the CRC verdict.

    Parameters
    ----------
    timeout_cycles : int
        A frame with no byte for this many cycles is dropped (``truncated``).

    Ports
    -----
    data : In(stream.Signature(8))
        Received bytes (always ready). Outside a frame, bytes other than ``SYNC`` are skipped.
    header : Out(FrameHeader)
        The frame's header, valid from ``begin`` until the next frame's header arrives.
    begin : Out(1)
        Pulse: the header is complete (payload bytes follow).
    byte : Out(8), index : Out(8), byte_valid : Out(1)
        Each payload byte and its position, with a one-cycle pulse.
    done : Out(1), ok : Out(1)
        Pulse at the end of a frame; ``ok``: the CRC checks (valid with ``done``).
    truncated : Out(1)
        Pulse: the frame stalled and was dropped.
    """

    data: In(stream.Signature(8))
    header: Out(FrameHeader)
    begin: Out(1)
    byte: Out(8)
    index: Out(8)
    byte_valid: Out(1)
    done: Out(1)
    ok: Out(1)
    truncated: Out(1)

    def __init__(self, timeout_cycles: int):
        if not isinstance(timeout_cycles, int) or timeout_cycles < 1:
            raise ValueError(f"timeout_cycles must be a positive int, got {timeout_cycles!r}")
        self.timeout_cycles = timeout_cycles
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        check = m.submodules.crc = LINK_CRC.create()
        got = self.data.valid
        position = Signal(8)  # header byte, payload byte or CRC byte within its part
        silent = Signal(range(self.timeout_cycles + 1))  # cycles since the last byte
        in_frame = Signal()

        m.d.comb += [self.data.ready.eq(1), check.data.eq(self.data.payload)]
        m.d.sync += [self.begin.eq(0), self.byte_valid.eq(0), self.done.eq(0), self.truncated.eq(0)]
        with m.If(got | ~in_frame):
            m.d.sync += silent.eq(0)
        with m.Else():
            m.d.sync += silent.eq(silent + 1)
        stalled = in_frame & (silent == self.timeout_cycles)

        with m.FSM(init="Sync"):
            with m.State("Sync"):
                with m.If(got & (self.data.payload == SYNC)):
                    m.d.comb += check.start.eq(1)
                    m.d.sync += position.eq(0)
                    m.next = "Header"
            with m.State("Header"):
                m.d.comb += in_frame.eq(1)
                with m.If(stalled):
                    m.d.sync += self.truncated.eq(1)
                    m.next = "Sync"
                with m.Elif(got):
                    m.d.comb += check.valid.eq(1)
                    m.d.sync += [self.header.as_value().word_select(position[:2], 8).eq(self.data.payload),
                                 position.eq(position + 1)]
                    with m.If(position == HEADER_BYTES - 1):  # the length byte (the last field)
                        m.d.sync += [self.begin.eq(1), position.eq(0)]
                        with m.If(self.data.payload == 0):
                            m.next = "Crc"
                        with m.Else():
                            m.next = "Payload"
            with m.State("Payload"):
                m.d.comb += in_frame.eq(1)
                with m.If(stalled):
                    m.d.sync += self.truncated.eq(1)
                    m.next = "Sync"
                with m.Elif(got):
                    m.d.comb += check.valid.eq(1)
                    m.d.sync += [self.byte.eq(self.data.payload), self.index.eq(position),
                                 self.byte_valid.eq(1), position.eq(position + 1)]
                    with m.If(position == self.header.length - 1):
                        m.d.sync += position.eq(0)
                        m.next = "Crc"
            with m.State("Crc"):
                m.d.comb += in_frame.eq(1)
                with m.If(stalled):
                    m.d.sync += self.truncated.eq(1)
                    m.next = "Sync"
                with m.Elif(got):
                    m.d.comb += check.valid.eq(1)
                    m.d.sync += position.eq(position + 1)
                    with m.If(position == CRC_BYTES - 1):
                        m.next = "Check"
            with m.State("Check"):
                # the CRC register has taken the last byte: the residue means the frame checks
                m.d.sync += [self.done.eq(1), self.ok.eq(check.match_detected)]
                m.next = "Sync"
        return m


class FrameSender(wiring.Component):
    """A reply frame -> bytes for the UART: ``SYNC``, header, payload fetched by index, CRC.

    Ports
    -----
    data : Out(stream.Signature(8))
        Bytes to send.
    start : In(1), header : In(FrameHeader)
        Send a frame with this header (taken when idle).
    index : Out(8), byte : In(8)
        The payload byte the sender wants, and that byte (needed 2 cycles after ``index``
        changes: a synchronous RAM read fits).
    busy : Out(1)
    """

    data: Out(stream.Signature(8))
    start: In(1)
    header: In(FrameHeader)
    index: Out(8)
    byte: In(8)
    busy: Out(1)

    FETCH_CYCLES = 2

    def __init__(self):
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        check = m.submodules.crc = LINK_CRC.create()
        header = Signal(FrameHeader)
        position = Signal(8)
        wait = Signal(range(self.FETCH_CYCLES + 1))
        sent = self.data.valid & self.data.ready

        m.d.comb += [self.index.eq(position), check.data.eq(self.data.payload)]
        with m.FSM(init="Idle"):
            with m.State("Idle"):
                with m.If(self.start):
                    m.d.sync += header.eq(self.header)
                    m.next = "Sync"
            with m.State("Sync"):
                m.d.comb += [self.busy.eq(1), self.data.payload.eq(SYNC), self.data.valid.eq(1),
                             check.start.eq(sent)]
                with m.If(sent):
                    m.d.sync += position.eq(0)
                    m.next = "Header"
            with m.State("Header"):
                m.d.comb += [self.busy.eq(1), self.data.valid.eq(1), check.valid.eq(sent),
                             self.data.payload.eq(header.as_value().word_select(position[:2], 8))]
                with m.If(sent):
                    m.d.sync += position.eq(position + 1)
                    with m.If(position == HEADER_BYTES - 1):
                        m.d.sync += [position.eq(0), wait.eq(self.FETCH_CYCLES)]
                        with m.If(header.length == 0):
                            m.next = "Crc"
                        with m.Else():
                            m.next = "Fetch"
            with m.State("Fetch"):
                m.d.comb += self.busy.eq(1)
                m.d.sync += wait.eq(wait - 1)
                with m.If(wait == 1):
                    m.next = "Payload"
            with m.State("Payload"):
                m.d.comb += [self.busy.eq(1), self.data.valid.eq(1), check.valid.eq(sent),
                             self.data.payload.eq(self.byte)]
                with m.If(sent):
                    m.d.sync += [position.eq(position + 1), wait.eq(self.FETCH_CYCLES)]
                    m.next = "Fetch"
                    with m.If(position == header.length - 1):
                        m.d.sync += position.eq(0)
                        m.next = "Crc"
            with m.State("Crc"):
                m.d.comb += [self.busy.eq(1), self.data.valid.eq(1),
                             self.data.payload.eq(Mux(position == 0, check.crc[8:], check.crc[:8]))]
                with m.If(sent):
                    m.d.sync += position.eq(position + 1)
                    with m.If(position == CRC_BYTES - 1):
                        m.next = "Idle"
        return m


class RowAssembler(wiring.Component):
    """Genome bytes (bit 8j + i = byte j bit i) -> the 50 row writes of SPEC section 3.

    Ports
    -----
    restart : In(1)
        Start a new genome at row 0.
    byte : In(8), valid : In(1)
        The next genome byte.
    row : Out(RowWriteSignature(50))
        The boards' row-write port: one write whenever 19 bits are in (registered).
    """

    def __init__(self):
        super().__init__({
            "restart": In(1),
            "byte": In(8),
            "valid": In(1),
            "row": Out(RowWriteSignature(N_ROWS)),
        })

    def elaborate(self, platform):
        m = Module()
        pending = Signal(ROW_BITS + 8)  # bits not yet in a row (< 19), LSB first
        have = Signal(range(ROW_BITS + 8))
        row = Signal(range(N_ROWS + 1))
        merged = Signal(ROW_BITS + 8)
        m.d.comb += merged.eq(pending | (self.byte << have))
        m.d.sync += self.row.we.eq(0)
        with m.If(self.restart):
            m.d.sync += [pending.eq(0), have.eq(0), row.eq(0)]
        with m.Elif(self.valid & (row < N_ROWS)):
            with m.If(have + 8 >= ROW_BITS):
                m.d.sync += [self.row.addr.eq(row), self.row.data.eq(merged[:ROW_BITS]),
                             self.row.we.eq(1), pending.eq(merged[ROW_BITS:]),
                             have.eq(have + 8 - ROW_BITS), row.eq(row + 1)]
            with m.Else():
                m.d.sync += [pending.eq(merged), have.eq(have + 8)]
        return m


# -- the board tops --------------------------------------------------------------------------------


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
        self.frames_ok = Signal(32)
        self.frames_rejected = Signal(16)
        self.evaluator_cycles = Signal(48)

        rcv = self.rcv
        with m.If(rcv.byte_valid & (rcv.index < ARG_BYTES)):
            m.d.sync += self.args.word_select(rcv.index[:2], 8).eq(rcv.byte)
        # genome bytes into rows: LOAD_CONTROLLER's whole payload, LOAD_GENOME's after the index
        cmd = rcv.header.command
        offset = _layout_bytes(LOAD_GENOME_REQUEST)
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
                "p_max": self.P_MAX, "clk_freq_hz": round(self.clk_freq_hz), "baud": round(self.baud)}

    def elaborate(self, platform):
        m = Module()
        link = _Link(m, self)
        self._boards(m, link)
        rcv = link.rcv
        with m.FSM(init="Listen"):
            with m.State("Listen"):
                with m.If(rcv.truncated):
                    m.d.sync += [link.command.eq(rcv.header.command), link.tag.eq(rcv.header.tag),
                                 link.frames_rejected.eq(link.frames_rejected + 1)]
                    link.answer(m, Status.TRUNCATED)
                with m.Elif(rcv.done):
                    m.d.sync += [link.command.eq(rcv.header.command), link.tag.eq(rcv.header.tag)]
                    with m.If(~rcv.ok):
                        m.d.sync += link.frames_rejected.eq(link.frames_rejected + 1)
                        link.answer(m, Status.BAD_CRC)
                    with m.Else():
                        with m.Switch(rcv.header.command):
                            for command in self.commands:
                                with m.Case(command.value):
                                    with m.If(rcv.header.length != REQUEST_LENGTH[command]):
                                        m.d.sync += link.frames_rejected.eq(link.frames_rejected + 1)
                                        link.answer(m, Status.BAD_LENGTH)
                                    with m.Else():
                                        m.d.sync += link.frames_ok.eq(link.frames_ok + 1)
                                        m.next = _state(command)
                            with m.Default():
                                m.d.sync += link.frames_rejected.eq(link.frames_rejected + 1)
                                link.answer(m, Status.UNKNOWN_COMMAND)
            with m.State(_state(Command.IDENTIFY)):
                m.d.sync += link.reply_as(IDENTIFY_REPLY).eq(IDENTIFY_REPLY.const(self.identity()))
                link.answer(m, Status.OK, _layout_bytes(IDENTIFY_REPLY))
            with m.State(_state(Command.READ_COUNTERS)):
                view = link.reply_as(COUNTERS_REPLY)
                m.d.sync += [view.frames_ok.eq(link.frames_ok),
                             view.frames_rejected.eq(link.frames_rejected),
                             view.evaluator_cycles.eq(link.evaluator_cycles)]
                link.answer(m, Status.OK, _layout_bytes(COUNTERS_REPLY))
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
            link.answer(m, Status.OK, _layout_bytes(MOTION_REPLY))

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

    Decodes IDENTIFY, READ_COUNTERS, SET_REFLEX, OBSERVE, CLEAR, LOAD_GENOME (slot 0), EVALUATE
    (count 1; replies the evaluator's ``cycles``), READ_RESULTS (first 0, count 1).

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
        m.d.comb += ev.reflex_en.eq(self._reflex)
        with m.If(link.writes(Command.LOAD_GENOME)):
            m.d.sync += self._loaded.eq(0)

    def _states(self, m, link):
        ev = self._ev
        with m.State(_state(Command.SET_REFLEX)):
            m.d.sync += self._reflex.eq(link.args_as(REFLEX_REQUEST).enable)
            link.answer(m, Status.OK)
        self._model_states(m, link, ev)
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
                m.d.sync += [link.reply_as(EVALUATE_REPLY).cycles.eq(ev.cycles),
                             link.evaluator_cycles.eq(link.evaluator_cycles + ev.cycles)]
                link.answer(m, Status.OK, _layout_bytes(EVALUATE_REPLY))
        with m.State(_state(Command.READ_RESULTS)):
            req = link.args_as(READ_RESULTS_REQUEST)
            with m.If((req.first != 0) | (req.count != 1)):
                link.answer(m, Status.BAD_ARGUMENT)
            with m.Else():
                result = link.reply_as(RESULT_REPLY).result
                m.d.sync += [result.crashes.eq(ev.crashes), result.loops.eq(ev.loops),
                             result.distance.eq(ev.distance)]
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
        ]
        # READ_RESULTS: payload byte i is byte i % 5 of result first + i // 5 (tables, not dividers)
        req = link.args_as(READ_RESULTS_REQUEST)
        which = Array(Const(i // RESULT_BYTES, 8) for i in range(MAX_PAYLOAD + 1))
        part = Array(Const(i % RESULT_BYTES, 3) for i in range(MAX_PAYLOAD + 1))
        index = link.snd.index
        result = Signal(8 * RESULT_BYTES)
        m.d.comb += [top.res_addr.eq(req.first + which[index]), result.eq(top.res_data.as_value())]
        with m.If(link.command == Command.READ_RESULTS.value):
            m.d.comb += link.snd.byte.eq(result.word_select(part[index], 8))

    def _states(self, m, link):
        top = self._top
        ev = _Ports(
            model=top.ev_model, state_value=top.ev_state_value, state_we=top.ev_state_we, clear=top.ev_clear,
            ready=top.ev_ready & ~top.pop_busy)
        ctl = _Ports(x=top.ctl_x, motion=top.ctl_motion)
        _controller_states(m, link, ctl, commit=top.ctl_commit, reflex=[self._reflex])
        self._model_states(m, link, ev)
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
                m.d.sync += [link.reply_as(EVALUATE_REPLY).cycles.eq(top.pop_cycles),
                             link.evaluator_cycles.eq(link.evaluator_cycles + top.pop_cycles)]
                link.answer(m, Status.OK, _layout_bytes(EVALUATE_REPLY))
        with m.State(_state(Command.READ_RESULTS)):
            req = link.args_as(READ_RESULTS_REQUEST)
            bad = (req.count == 0) | (req.count > RESULTS_PER_READ) | (req.first + req.count > self.P_MAX)
            with m.If(bad):
                link.answer(m, Status.BAD_ARGUMENT)
            with m.Else():
                link.answer(m, Status.OK, req.count * RESULT_BYTES)
