"""The host's side of the link protocol of ``hdl.link_protocol``: frames, retries, the board commands.

:class:`LinkClient` talks to one board through a *byte stream*: any object with pyserial's
``write(data)``, ``read(n)`` (returns fewer than ``n`` bytes when its ``timeout`` passes),
``reset_input_buffer()`` and a ``port`` name. A real board is a ``serial.Serial``
(``cosim.link.boards``); the simulated board top is a line in a cocotb simulation
(``cosim.launch.uart_sim``). The client is the same code for both.

Every frame layout, command, status and the CRC come from ``hdl.link_protocol``; nothing is re-typed.

Retries: a request whose reply does not come within the stream's timeout, comes with a bad CRC,
or says BAD_CRC / TRUNCATED (the board saw the request damaged) is sent again, at most
``retries`` more times, then :class:`LinkError` names the port. The reply must echo the
request's tag (a counter): a late reply to an earlier try is skipped, never taken for this one.
Every command is idempotent, so a request executed twice (its first reply lost) does no harm.

Board resets (a power glitch, a USB re-plug): the board then forgets its world model, rate codes,
controller and population. The host counts the frames the board confirmed (OK replies); after a
failed try, before the resend, it reads the board's own count (READ_COUNTERS): a count below the
host's means the board restarted, and the host replays what the board held from its mirror (the
``on_reset`` hooks of the boards over this client, ``cosim.link.boards``) before the resend.
"""

from __future__ import annotations

import binascii
import functools
from dataclasses import dataclass, field

from amaranth.lib import data

from base.errors import UserError
from hdl.link_protocol import (
    COUNTERS_REPLY,
    CRC_BYTES,
    EVALUATE_REPLY,
    EVALUATE_REQUEST,
    HEADER_BYTES,
    IDENTIFY_REPLY,
    LINK_CRC,
    LOAD_GENOME_REQUEST,
    MOTION_REPLY,
    MOTION_REQUEST,
    NAME_BYTES,
    OBSERVE_REQUEST,
    RATE_REQUEST,
    READ_RESULTS_REQUEST,
    REFLEX_REQUEST,
    RESULT_BYTES,
    RESULT_REPLY,
    RESULTS_PER_READ,
    SYNC,
    Command,
    Design,
    FrameHeader,
    Status,
    genome_bytes,
)

RETRIES = 3  # resends of one request after an error reply or a timeout
PIPELINE = 2  # LOAD_GENOME frames in flight (the board answers one while the next arrives)
RETRY_STATUSES = (Status.BAD_CRC, Status.TRUNCATED)
MAX_FRAME = 1 + HEADER_BYTES + 255 + CRC_BYTES  # the longest frame either way (262 bytes)
NOISE_BYTES = 2 * MAX_FRAME  # bytes without SYNC before a try counts as failed: a line of noise
LATE_REPLIES = 2 * PIPELINE + 2  # replies of other tags one try skips before it counts as failed
RESTORES = 5  # restores of one board reset before LinkError (a reset during the restore starts it again)


class _ResetDuringRestore(Exception):
    """The board reset again while its state was being restored: start the restore again."""


class LinkError(UserError):
    """A board that is absent, silent, of the wrong design, or that refused a request: one
    ``error:`` line naming the port (``base.errors``)."""


class NotLoaded(LinkError):
    """EVALUATE answered NOT_LOADED: the genome must be loaded again first."""


class StaleBitstream(LinkError):
    """A board that answers IDENTIFY in a form this host cannot use: a bitstream to rebuild."""


@functools.cache
def _layout(layout) -> data.Layout:
    return data.Layout.cast(layout)


@functools.cache
def _layout_bytes(layout) -> int:
    return (_layout(layout).size + 7) // 8


def pack(layout, **fields) -> bytes:
    """``fields`` as the little-endian bytes of ``layout`` (the gateware's view of them)."""
    value = _layout(layout).const(fields).as_value().value
    return value.to_bytes(_layout_bytes(layout), "little")


def unpack(layout, payload: bytes):
    """The fields of ``layout`` from its little-endian bytes (a ``data.Const``)."""
    return data.Const(_layout(layout), int.from_bytes(payload[:_layout_bytes(layout)], "little"))


def crc16(body: bytes) -> int:
    """``LINK_CRC.compute(body)`` at C speed: CRC-16/IBM-3740 is the CCITT CRC of the standard
    library's ``binascii.crc_hqx`` with the catalogue entry's initial value 0xFFFF (no reflection,
    no final XOR; tests/test_link_faults.py checks the two agree). 0 over a frame with its CRC."""
    return binascii.crc_hqx(body, 0xFFFF)


def encode_frame(command: Command, payload: bytes = b"", *, tag: int = 0, status: Status = Status.OK) -> bytes:
    """One frame: SYNC, header, payload, CRC (high byte first)."""
    if len(payload) > 255:
        raise ValueError(f"a frame carries at most 255 payload bytes, got {len(payload)!r}")
    header = pack(FrameHeader, command=Command(command).value, status=Status(status).value,
                  tag=tag, length=len(payload))
    body = header + bytes(payload)
    return bytes([SYNC]) + body + crc16(body).to_bytes(CRC_BYTES, "big")


def genome_payload(rows) -> bytes:
    """The 119 bytes of one genome (50 row words): byte j bit i is genome bit 8j + i."""
    from ga.genome import int_from_rows

    return int_from_rows(rows).to_bytes(genome_bytes(), "little")


@dataclass(frozen=True)
class Identity:
    """What a board answers to IDENTIFY."""

    design: str
    layout_version: int
    build_id: int
    p_max: int
    clk_freq_hz: int
    baud: int
    distance_rule: str | None = None  # the rule the board's fitness counts (None: it has none)


def check_distance_rule(port: str, identity: Identity, rule: str) -> None:
    """A clear error unless the board's fitness counts the run's distance rule ``rule``: a
    bitstream is built for one rule (a circuit constant), and a board of the other one would
    disagree with the run's reference at the first controller whose distances differ."""
    if identity.distance_rule != rule:
        raise LinkError(f"{port}: the board's fitness counts the {identity.distance_rule!r} distance rule, "
                        f"this run {rule!r}: run with --distance {identity.distance_rule}, or rebuild the "
                        "bitstream for the run's rule")


@dataclass
class LinkStats:
    """What crossed the link: bytes each way, requests, resends and the reasons for them;
    ``by_command``: command name -> [bytes sent, bytes received] (resends included), whose sums
    are ``bytes_sent`` and ``bytes_received``."""

    bytes_sent: int = 0
    bytes_received: int = 0
    requests: int = 0
    resends: int = 0
    bytes_resent: int = 0  # request bytes sent again (resends; not the restores)
    resets: int = 0  # board resets detected (its frame count went back)
    restores: int = 0  # restores of the board's state from the host's mirror
    restore_restarts: int = 0  # restores started again: the board reset while one ran
    restore_bytes: int = 0  # bytes both ways of the restores
    reasons: dict = field(default_factory=dict)
    by_command: dict = field(default_factory=dict)

    def note(self, reason: str) -> None:
        self.reasons[reason] = self.reasons.get(reason, 0) + 1

    def count(self, command: "Command", sent: int, received: int) -> None:
        """Add ``sent`` and ``received`` bytes to ``command``'s entry of ``by_command``."""
        entry = self.by_command.setdefault(Command(command).name, [0, 0])
        entry[0] += sent
        entry[1] += received


class LinkClient:
    """The board commands over a byte stream (see the module docstring).

    Parameters
    ----------
    stream
        pyserial-like: ``write``, ``read`` (with a timeout), ``reset_input_buffer``, ``port``.
    retries : int
        Resends of one request before :class:`LinkError` (default 3).
    """

    def __init__(self, stream, *, retries: int = RETRIES):
        if retries < 0:
            raise ValueError(f"retries must be >= 0, got {retries!r}")
        self.stream = stream
        self.retries = retries
        self.port = str(getattr(stream, "port", None) or getattr(stream, "name", "the link"))
        self.stats = LinkStats()
        self.identity: Identity | None = None  # set by expect()
        self._tag = 0
        self.on_reset: list = []  # callables that restore the board's state (cosim.link.boards)
        self.confirmed = 0  # frames the board executed for sure: its count can only be higher
        self._probing = self._restoring = False

    # -- framing ------------------------------------------------------------------------------

    def _read_exactly(self, n: int) -> bytes | None:
        got = self.stream.read(n)
        self.stats.bytes_received += len(got)
        return bytes(got) if len(got) == n else None

    def _read_reply(self):
        """(header, payload) of the next frame, or a reason string: timeout / bad CRC."""
        for _ in range(NOISE_BYTES):  # skip to SYNC (a line that only brings noise: a failed try)
            first = self._read_exactly(1)
            if first is None:
                return "timeout"
            if first[0] == SYNC:
                break
        else:
            return f"noise: no SYNC in {NOISE_BYTES} bytes"
        header_bytes = self._read_exactly(HEADER_BYTES)
        if header_bytes is None:
            return "timeout"
        header = unpack(FrameHeader, header_bytes)
        rest = self._read_exactly(header.length + CRC_BYTES)
        if rest is None:
            return "timeout"
        if crc16(header_bytes + rest) != LINK_CRC.residue():
            return "bad reply CRC"
        return header, rest[:header.length]

    def request(self, command: Command, payload: bytes = b"", *, reply_length: int | None = None) -> bytes:
        """Send ``command`` with ``payload``; return the reply payload of an OK reply."""
        command = Command(command)
        self.stats.requests += 1
        sent, received = self.stats.bytes_sent, self.stats.bytes_received
        try:
            return self._request(command, payload, reply_length)
        finally:
            self.stats.count(command, self.stats.bytes_sent - sent, self.stats.bytes_received - received)

    def _request(self, command: Command, payload: bytes, reply_length: int | None) -> bytes:
        last = "no reply"
        for attempt in range(self.retries + 1):
            if attempt:
                self.stats.resends += 1
                self.stats.note(last)
                self.stream.reset_input_buffer()
                self._check_reset(command)
            self._tag = (self._tag + 1) % 256
            frame = encode_frame(command, payload, tag=self._tag)
            self.stream.write(frame)
            self.stats.bytes_sent += len(frame)
            self.stats.bytes_resent += len(frame) if attempt else 0
            for _ in range(LATE_REPLIES + 1):
                reply = self._read_reply()
                if isinstance(reply, str):
                    last = reply
                    break
                header, body = reply
                status = header.status
                if status in (s.value for s in RETRY_STATUSES):
                    last = f"board replied {Status(status).name}"
                    break
                if header.tag != self._tag:
                    continue  # a late reply to an earlier try
                if header.command != command.value:
                    raise LinkError(f"{self.port}: reply to {command.name} carries command "
                                    f"{header.command:#04x}: not this protocol's board?")
                if status == Status.NOT_LOADED.value:
                    raise NotLoaded(f"{self.port}: {command.name} answered NOT_LOADED")
                if status == Status.UNKNOWN_COMMAND.value:
                    raise LinkError(f"{self.port}: the board does not decode {command.name} "
                                    "(a board of another design?)")
                if status != Status.OK.value:
                    name = Status(status).name if status in {s.value for s in Status} else hex(status)
                    raise LinkError(f"{self.port}: {command.name} refused: {name}")
                if reply_length is not None and len(body) != reply_length:
                    raise LinkError(f"{self.port}: {command.name} replied {len(body)} bytes, "
                                    f"expected {reply_length}")
                self.confirmed += 1
                return body
            else:
                last = f"{LATE_REPLIES + 1} replies of other tags"
        raise LinkError(f"{self.port}: no good reply to {command.name} after {self.retries + 1} "
                        f"tries (last: {last}); is the board connected, configured and running?")

    # -- board resets ---------------------------------------------------------------------------

    def _check_reset(self, during: Command = Command.LOAD_GENOME) -> None:
        """After a failed try of ``during``: did the board restart? (its frame count below
        :attr:`confirmed`) If so, restore its state through the ``on_reset`` hooks. Only where
        hooks are set; a board that answers neither is a dead line (LinkError)."""
        if not self.on_reset or self._probing:
            return
        self._probing = True
        try:
            board_count = self.read_counters()["frames_ok"]
        except LinkError as exc:
            if type(exc) is not LinkError:
                raise
            raise LinkError(f"{self.port}: the line went dead during {during.name}: no good reply to it nor "
                            f"to READ_COUNTERS after {self.retries + 1} tries each; is the board connected, "
                            "configured and running?") from None
        finally:
            self._probing = False
        reset = board_count < self.confirmed
        self.confirmed = board_count
        if not reset:
            return
        self.stats.resets += 1
        if self._restoring:
            raise _ResetDuringRestore()
        self._restore()

    def _restore(self) -> None:
        sent, received = self.stats.bytes_sent, self.stats.bytes_received
        try:
            for _ in range(RESTORES):
                self._restoring = True
                try:
                    for hook in self.on_reset:
                        hook()
                    self.stats.restores += 1
                    return
                except _ResetDuringRestore:
                    self.stats.restore_restarts += 1
                    continue
                finally:
                    self._restoring = False
            raise LinkError(f"{self.port}: the board reset {RESTORES} times while its state was "
                            "being restored: is its power supply or cable failing?")
        finally:
            self.stats.restore_bytes += self.stats.bytes_sent - sent + self.stats.bytes_received - received

    # -- the commands ---------------------------------------------------------------------------

    def identify(self) -> Identity:
        return self._identity(self.request(Command.IDENTIFY))

    def _identity(self, body: bytes) -> Identity:
        from hdl.link_protocol import distance_rule_name

        n = _layout_bytes(IDENTIFY_REPLY)
        if len(body) == n - 1:
            raise StaleBitstream(f"{self.port}: IDENTIFY replied {len(body)} bytes, expected {n}: a bitstream "
                                 "built before IDENTIFY reported the distance rule; rebuild it (make bitstream)")
        if len(body) != n:
            raise LinkError(f"{self.port}: IDENTIFY replied {len(body)} bytes, expected {n}")
        reply = unpack(IDENTIFY_REPLY, body)
        name = int(reply.design).to_bytes(NAME_BYTES, "little").rstrip(b"\0").decode("ascii", "replace")
        try:
            rule = distance_rule_name(int(reply.distance_rule))
        except ValueError:
            raise StaleBitstream(f"{self.port}: the board reports distance rule code {int(reply.distance_rule)}, "
                                 "which this host does not know") from None
        return Identity(design=name, layout_version=reply.layout_version, build_id=reply.build_id,
                        p_max=reply.p_max, clk_freq_hz=reply.clk_freq_hz, baud=reply.baud, distance_rule=rule)

    def expect(self, *designs: Design, distance_rule: str | None = None) -> Identity:
        """IDENTIFY, and a clear error unless the board is one of ``designs`` with this genome layout
        (and, given ``distance_rule``, a fitness that counts that rule)."""
        from hdl.link_protocol import GENOME_LAYOUT_VERSION

        try:
            identity = self.identify()
        except StaleBitstream:
            raise
        except LinkError as exc:
            raise LinkError(f"{self.port}: no board answers IDENTIFY ({exc})") from None
        names = [d.value for d in designs]
        if identity.design not in names:
            raise LinkError(f"{self.port}: the board is {identity.design!r}, expected "
                            f"{' or '.join(repr(n) for n in names)}")
        self.identity = identity
        if identity.layout_version != GENOME_LAYOUT_VERSION:
            raise LinkError(f"{self.port}: the board's genome layout is version {identity.layout_version}, "
                            f"this host's is {GENOME_LAYOUT_VERSION}: rebuild the bitstream")
        if distance_rule is not None:
            check_distance_rule(self.port, identity, distance_rule)
        return identity

    def read_counters(self) -> dict:
        reply = unpack(COUNTERS_REPLY, self.request(Command.READ_COUNTERS))
        return {"frames_ok": reply.frames_ok, "frames_rejected": reply.frames_rejected,
                "evaluator_cycles": reply.evaluator_cycles}

    def load_controller(self, rows) -> None:
        self.request(Command.LOAD_CONTROLLER, genome_payload(rows), reply_length=0)

    def set_reflex(self, enabled: bool) -> None:
        self.request(Command.SET_REFLEX, pack(REFLEX_REQUEST, enable=int(bool(enabled))), reply_length=0)

    def motion(self, state: int) -> int:
        reply = self.request(Command.MOTION, pack(MOTION_REQUEST, state=int(state)),
                             reply_length=_layout_bytes(MOTION_REPLY))
        return int(unpack(MOTION_REPLY, reply).motion)

    def observe(self, state: int, motion: int, next_state: int, crash: bool, reached: int) -> None:
        """Write entry (state, motion) := {next_state, crash, valid}; add state and reached to S."""
        self.request(Command.OBSERVE, pack(OBSERVE_REQUEST, state=int(state), motion=int(motion),
                                           crash=int(bool(crash)), next=int(next_state),
                                           reached=int(reached)), reply_length=0)

    def clear(self) -> None:
        self.request(Command.CLEAR, reply_length=0)

    def write_rate(self, state: int, motion: int, code: int) -> None:
        """The failure-rate code of (state, motion) := code (``ga.fail_rates``)."""
        self.request(Command.WRITE_RATE, pack(RATE_REQUEST, state=int(state), motion=int(motion),
                                              code=int(code)), reply_length=0)

    def load_genome(self, index: int, rows) -> None:
        self.request(Command.LOAD_GENOME, pack(LOAD_GENOME_REQUEST, index=int(index)) + genome_payload(rows),
                     reply_length=0)

    def load_genomes(self, population, window: int = PIPELINE) -> None:
        """LOAD_GENOME of genome i into slot i for every genome, pipelined: the next frame goes out
        before the last reply is read (at most ``window`` unanswered), so the line never idles
        waiting for a reply. When a reply is not a clean OK for its frame, the pipeline is
        drained: that genome and the ones in flight behind it go again one at a time through
        :meth:`request` (with its retries; late replies are skipped by their tags)."""
        payloads = [pack(LOAD_GENOME_REQUEST, index=i) + genome_payload(rows) for i, rows in enumerate(population)]
        sent, received = self.stats.bytes_sent, self.stats.bytes_received
        redo_from, in_flight = self._pipeline(payloads, window)
        self.stats.count(Command.LOAD_GENOME, self.stats.bytes_sent - sent, self.stats.bytes_received - received)
        if redo_from is None:
            return
        self._check_reset()  # a reset loses the frames in flight: restore before the redo
        for index in range(redo_from, len(payloads)):
            if index > redo_from and index < redo_from + in_flight:
                self.stats.resends += 1
                self.stats.note("in flight behind a failed frame")
            if index < redo_from + in_flight:  # sent before, sent again (counted again by request())
                self.stats.requests -= 1
                self.stats.bytes_resent += 1 + HEADER_BYTES + len(payloads[index]) + CRC_BYTES
            self.request(Command.LOAD_GENOME, payloads[index], reply_length=0)

    def _pipeline(self, payloads, window: int) -> tuple[int | None, int]:
        """Send the LOAD_GENOME frames ``window`` ahead of their replies: (None, 0) when every
        reply was a clean OK, else (the first genome to load again, the frames then in flight)."""
        pending: list[tuple[int, int]] = []  # (tag, index) in flight
        for index, payload in enumerate(payloads):
            self._tag = (self._tag + 1) % 256
            frame = encode_frame(Command.LOAD_GENOME, payload, tag=self._tag)
            self.stream.write(frame)
            self.stats.bytes_sent += len(frame)
            self.stats.requests += 1
            pending.append((self._tag, index))
            if len(pending) >= window:
                tag, first = pending.pop(0)
                if not self._settled(tag):
                    return first, 1 + len(pending)  # the failed frame and the ones sent after it
        while pending:
            tag, first = pending.pop(0)
            if not self._settled(tag):
                return first, 1 + len(pending)
        return None, 0

    def _settled(self, tag: int) -> bool:
        """Read the reply to the pipelined LOAD_GENOME ``tag``: True for a clean OK; else note why
        (and count the resend that follows)."""
        reply = self._read_reply()
        if isinstance(reply, str):
            reason = reply
        else:
            header, body = reply
            if header.tag == tag and header.status == Status.OK.value and not body:
                self.confirmed += 1
                return True
            name = Status(header.status).name if header.status in {s.value for s in Status} else hex(header.status)
            reason = f"pipelined reply {name}" + ("" if header.tag == tag else " (another tag)")
        self.stats.note(reason)
        self.stats.resends += 1
        self.stream.reset_input_buffer()
        return False

    def evaluate(self, count: int) -> int:
        """Evaluate population slots 0..count-1; the board's cycles for it."""
        reply = self.request(Command.EVALUATE, pack(EVALUATE_REQUEST, count=int(count)),
                             reply_length=_layout_bytes(EVALUATE_REPLY))
        return int(unpack(EVALUATE_REPLY, reply).cycles)

    def read_results(self, first: int, count: int) -> list[tuple[int, int, int, int]]:
        """(crashes, loops, distance, fails) of slots first..first+count-1."""
        out = []
        for start in range(first, first + count, RESULTS_PER_READ):
            n = min(RESULTS_PER_READ, first + count - start)
            reply = self.request(Command.READ_RESULTS, pack(READ_RESULTS_REQUEST, first=start, count=n),
                                 reply_length=n * RESULT_BYTES)
            for i in range(n):
                r = unpack(RESULT_REPLY, reply[i * RESULT_BYTES:(i + 1) * RESULT_BYTES]).result
                out.append((int(r.crashes), int(r.loops), int(r.distance), int(r.fails)))
        return out
