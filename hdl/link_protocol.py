"""The host link's protocol (SPEC section 8): a framed command protocol over the 8N1 UART of ``hdl.uart``.

This module owns the protocol: the definitions the host imports (``cosim.link.host``) and the
framing gateware of the board tops (:mod:`hdl.link_tops`), as a Glasgow applet's component owns
its commands. Nothing here is re-typed on the host side.

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

The board tops that decode it (``ControllerLinkTop``, ``EvaluatorLinkTop``, ``SystemLinkTop``)
are in :mod:`hdl.link_tops`.
"""

import enum as py_enum
import subprocess
import zlib

from amaranth.hdl import Cat, Module, Mux, Signal, signed
from amaranth.lib import crc, data, enum, stream, wiring
from amaranth.lib.wiring import In, Out

from ga.fail_rates import RATE_BITS
from ga.genome import GENOME_BITS, N_ROWS, ROW_BITS
from ga.motions import DISTANCE_RULES, N_INPUTS, N_OUTPUTS
from hdl.ports import RESULT_LAYOUT, RowWriteSignature

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
    WRITE_RATE = 0x25       # RATE_REQUEST: one failure-rate code (ga.fail_rates)
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
RATE_REQUEST = data.StructLayout({
    "state": N_INPUTS,      # the code of (state, motion) := code (hdl.ports.RateWriteSignature)
    "motion": N_OUTPUTS,
    "_pad": 8 - N_OUTPUTS,
    "code": RATE_BITS,
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
    "score": signed(24),    # its integer score (ga.hardware_ga.score: signed, less the fail count)
    "crashes": 16, "loops": 16, "distance": 16,
    "fails": 16,            # its failure-rate count F (ga.fail_rates)
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
    "distance_rule": 8,         # distance_rule_code: the rule the board's fitness counts (0: none)
})
COUNTERS_REPLY = data.StructLayout({
    "frames_ok": 32,            # frames executed
    "frames_rejected": 16,      # error replies sent
    "evaluator_cycles": 48,     # sum of the evaluations' cycles since reset
})


def distance_rule_code(rule: str | None) -> int:
    """IDENTIFY's ``distance_rule`` byte: 0 for a board without a fitness (the controller), else
    1 + the rule's index in ``ga.motions.DISTANCE_RULES``."""
    return 0 if rule is None else 1 + DISTANCE_RULES.index(rule)


def distance_rule_name(code: int) -> str | None:
    """The rule of IDENTIFY's ``distance_rule`` byte (None: the board has no fitness); ValueError
    for a code this host does not know."""
    if code == 0:
        return None
    if not 1 <= code <= len(DISTANCE_RULES):
        raise ValueError(f"unknown distance rule code {code!r}")
    return DISTANCE_RULES[code - 1]


def layout_bytes(layout) -> int:
    return (data.Layout.cast(layout).size + 7) // 8


RESULT_BYTES = layout_bytes(RESULT_REPLY)
RESULTS_PER_READ = MAX_PAYLOAD // RESULT_BYTES  # 36
ARG_BYTES = 4  # request bytes kept for the command (OBSERVE's, the largest)

# the payload length each command's request must have
REQUEST_LENGTH = {
    Command.IDENTIFY: 0,
    Command.READ_COUNTERS: 0,
    Command.LOAD_CONTROLLER: genome_bytes(),
    Command.SET_REFLEX: layout_bytes(REFLEX_REQUEST),
    Command.MOTION: layout_bytes(MOTION_REQUEST),
    Command.OBSERVE: layout_bytes(OBSERVE_REQUEST),
    Command.CLEAR: 0,
    Command.LOAD_GENOME: layout_bytes(LOAD_GENOME_REQUEST) + genome_bytes(),
    Command.EVALUATE: layout_bytes(EVALUATE_REQUEST),
    Command.READ_RESULTS: layout_bytes(READ_RESULTS_REQUEST),
    Command.WRITE_RATE: layout_bytes(RATE_REQUEST),
    Command.SEED: layout_bytes(SEED_REQUEST),
    Command.LEARN: layout_bytes(LEARN_REQUEST),
    Command.READ_GENOME: layout_bytes(READ_GENOME_REQUEST),
}
assert max(layout_bytes(layout) for layout in (OBSERVE_REQUEST, RATE_REQUEST, READ_RESULTS_REQUEST, SEED_REQUEST,
                                               LEARN_REQUEST, READ_GENOME_REQUEST)) <= ARG_BYTES


class Design(py_enum.Enum):
    """What a board answers to IDENTIFY, and which commands it decodes."""

    CONTROLLER = "ehw-controller"
    EVALUATOR = "ehw-evaluator"
    SYSTEM = "ehw-system"
    LEARNER = "ehw-learner"


_CONTROLLER_COMMANDS = (Command.LOAD_CONTROLLER, Command.SET_REFLEX, Command.MOTION)
_EVALUATOR_COMMANDS = (Command.SET_REFLEX, Command.OBSERVE, Command.CLEAR, Command.LOAD_GENOME,
                       Command.EVALUATE, Command.READ_RESULTS, Command.WRITE_RATE)
DESIGN_COMMANDS = {
    Design.CONTROLLER: (Command.IDENTIFY, Command.READ_COUNTERS) + _CONTROLLER_COMMANDS,
    Design.EVALUATOR: (Command.IDENTIFY, Command.READ_COUNTERS) + _EVALUATOR_COMMANDS,
    Design.SYSTEM: (Command.IDENTIFY, Command.READ_COUNTERS) + _CONTROLLER_COMMANDS
                   + tuple(c for c in _EVALUATOR_COMMANDS if c not in _CONTROLLER_COMMANDS),
    Design.LEARNER: (Command.IDENTIFY, Command.READ_COUNTERS) + _CONTROLLER_COMMANDS
                    + (Command.OBSERVE, Command.CLEAR, Command.WRITE_RATE, Command.LOAD_GENOME, Command.SEED,
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

    The CRC is bit-serial (:data:`LINK_CRC` at ``data_width=1``, most significant bit first, the
    same CRC as the byte-wide one): each byte sent is fed in over the next ``CRC_CYCLES``
    cycles, and the next byte is offered only then (the UART takes 10 bit times, at least 40
    cycles, over a byte anyway). A third of the byte-wide CRC's logic cells on the iCE40.

    Ports
    -----
    data : Out(stream.Signature(8))
        Bytes to send.
    start : In(1), header : In(FrameHeader)
        Send a frame with this header (taken when idle; ``header`` must hold until ``busy``
        falls: it is read as the frame goes out, not copied).
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
    CRC_CYCLES = 8

    def __init__(self):
        super().__init__()

    def elaborate(self, platform):
        m = Module()
        check = m.submodules.crc = crc.catalog.CRC16_IBM_3740(data_width=1).create()
        header = self.header
        position = Signal(8)
        wait = Signal(range(self.FETCH_CYCLES + 1))
        feed = Signal(8)  # the last byte sent, its bits not yet in the CRC on top
        feed_left = Signal(range(self.CRC_CYCLES + 1))
        fed = feed_left == 0
        sent = self.data.valid & self.data.ready

        m.d.comb += [self.index.eq(position), check.data.eq(feed[7]), check.valid.eq(~fed)]
        with m.If(~fed):
            m.d.sync += [feed.eq(feed << 1), feed_left.eq(feed_left - 1)]

        def crc_byte():  # the byte on the line goes into the CRC
            with m.If(sent):
                m.d.sync += [feed.eq(self.data.payload), feed_left.eq(self.CRC_CYCLES)]

        with m.FSM(init="Idle"):
            with m.State("Idle"):
                with m.If(self.start):
                    m.next = "Sync"
            with m.State("Sync"):
                m.d.comb += [self.busy.eq(1), self.data.payload.eq(SYNC), self.data.valid.eq(1),
                             check.start.eq(sent)]
                with m.If(sent):
                    m.d.sync += position.eq(0)
                    m.next = "Header"
            with m.State("Header"):
                m.d.comb += [self.busy.eq(1), self.data.valid.eq(fed),
                             self.data.payload.eq(header.as_value().word_select(position[:2], 8))]
                crc_byte()
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
                m.d.comb += [self.busy.eq(1), self.data.valid.eq(fed), self.data.payload.eq(self.byte)]
                crc_byte()
                with m.If(sent):
                    m.d.sync += [position.eq(position + 1), wait.eq(self.FETCH_CYCLES)]
                    m.next = "Fetch"
                    with m.If(position == header.length - 1):
                        m.d.sync += position.eq(0)
                        m.next = "Crc"
            with m.State("Crc"):
                m.d.comb += [self.busy.eq(1), self.data.valid.eq(fed),
                             self.data.payload.eq(Mux(position == 0, check.crc[8:], check.crc[:8]))]
                with m.If(sent):
                    m.d.sync += position.eq(position + 1)
                    with m.If(position == CRC_BYTES - 1):
                        m.next = "Idle"
        return m


class RowAssembler(wiring.Component):
    """Genome bytes (bit 8j + i = byte j bit i) -> the 50 row writes of SPEC section 3.

    Bit-serial: a byte is shifted into the 19-bit row register one bit a cycle (8 cycles), and a
    row is written when its 19th bit is in. No barrel shifter: about a third of the logic cells
    of a byte-wide assembler on the iCE40 (docs/fpga.md). A byte must come at least
    ``BYTE_CYCLES + 1`` cycles after the last one; the UART delivers one every 10 bit times,
    at least 40 cycles (``hdl.uart.MIN_DIVISOR``).

    Ports
    -----
    restart : In(1)
        Start a new genome at row 0.
    byte : In(8), valid : In(1)
        The next genome byte.
    row : Out(RowWriteSignature(50))
        The boards' row-write port: one write (a one-cycle ``we``) whenever 19 bits are in, at
        most ``BYTE_CYCLES + 1`` cycles after the ``valid`` of the byte that completes the row.
    """

    BYTE_CYCLES = 8  # cycles to shift one byte in

    def __init__(self):
        super().__init__({
            "restart": In(1),
            "byte": In(8),
            "valid": In(1),
            "row": Out(RowWriteSignature(N_ROWS)),
        })

    def elaborate(self, platform):
        m = Module()
        byte = Signal(8)                               # the byte being shifted in, LSB next
        bits_left = Signal(range(self.BYTE_CYCLES + 1))
        shreg = Signal(ROW_BITS)                       # the row's bits so far, the newest on top
        have = Signal(range(ROW_BITS))                 # bits of the row in shreg
        row = Signal(range(N_ROWS + 1))
        shift = (bits_left != 0) & (row < N_ROWS)

        m.d.comb += [self.row.addr.eq(row), self.row.data.eq(shreg)]
        m.d.sync += self.row.we.eq(0)
        with m.If(self.row.we):
            m.d.sync += row.eq(row + 1)
        with m.If(self.restart):
            m.d.sync += [bits_left.eq(0), have.eq(0), row.eq(0)]
        with m.Elif(self.valid):
            m.d.sync += [byte.eq(self.byte), bits_left.eq(self.BYTE_CYCLES)]
        with m.Elif(shift):
            m.d.sync += [shreg.eq(Cat(shreg[1:], byte[0])), byte.eq(byte >> 1),
                         bits_left.eq(bits_left - 1)]
            with m.If(have == ROW_BITS - 1):  # the row is complete after this shift
                m.d.sync += [have.eq(0), self.row.we.eq(1)]
            with m.Else():
                m.d.sync += have.eq(have + 1)
        return m
