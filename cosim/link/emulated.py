"""The ``emulated`` backend: the serial backend's host code over a Python model of the
``ehw-system`` board (``hdl.link_tops.SystemLinkTop``) at the protocol level, no HDL simulator.

    ehw sim --backend emulated --targets 4 [--line-faults flip=1e-4,drop=1e-4,silence=1e-3,reset=3]

:class:`EmulatedSystemBoard` is the board as the host sees it through the line: it hunts for
``SYNC``, checks the CRC, answers ``BAD_CRC`` / ``TRUNCATED`` / ``UNKNOWN_COMMAND`` /
``BAD_LENGTH`` / ``BAD_ARGUMENT`` as the gateware does (docs/host_link.md) and executes the
commands on the reference models (``ga.truth_table``, the world-model arrays, ``ga.evaluator``);
every frame layout, command and the CRC come from ``hdl.link_protocol`` through
``cosim.link.host``. :class:`EmulatedLine` is its pyserial-like stream: bytes written reach the
board at once; a read that finds a frame unfinished is the board's inter-byte timeout (the
frame is dropped and answered ``TRUNCATED``), and a read that finds nothing returns at once
(the host's reply timeout, without the wait). ``board_reset()`` is a power glitch: every RAM,
register and counter back to its reset value.

It is the fast line for whole lifetimes with ``--line-faults`` (``cosim.link.faults``): the
board model is checked against the gateware only through the protocol's tests (tests/test_link.py
runs the same host code against the real top in Amaranth's simulator); the bit-exact check of
the gateware's results is the ``uart`` backend's.
"""

from __future__ import annotations

import numpy as np

from cosim.boards.registry import register_backend
from cosim.link.host import LinkClient, crc16, encode_frame, pack, unpack
from ga.motions import DEFAULT_DISTANCE_RULE
from hdl.link_protocol import (
    COUNTERS_REPLY,
    CRC_BYTES,
    EVALUATE_REPLY,
    EVALUATE_REQUEST,
    GENOME_LAYOUT_VERSION,
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
    REQUEST_LENGTH,
    RESULT_REPLY,
    RESULTS_PER_READ,
    SYNC,
    Command,
    Design,
    FrameHeader,
    Status,
    distance_rule_code,
    layout_bytes,
)

P_MAX = 512  # SystemLinkTop's population slots (hdl.system_top.P_MAX)
CLK_FREQ_HZ = 25_000_000  # the ULX3S's oscillator, as the uart backend's simulated top
SYSTEM_COMMANDS = (Command.IDENTIFY, Command.READ_COUNTERS, Command.LOAD_CONTROLLER, Command.SET_REFLEX,
                   Command.MOTION, Command.OBSERVE, Command.CLEAR, Command.LOAD_GENOME, Command.EVALUATE,
                   Command.READ_RESULTS, Command.WRITE_RATE)


def _rows(genome: bytes) -> np.ndarray:
    from ga.genome import rows_from_int

    return rows_from_int(int.from_bytes(genome, "little"))


class EmulatedSystemBoard:
    """The ``ehw-system`` board's protocol on the reference models (see the module docstring)."""

    def __init__(self, distance_rule: str = DEFAULT_DISTANCE_RULE, baud: int = 115_200, p_max: int = P_MAX):
        self.distance_rule, self.baud, self.p_max = distance_rule, int(baud), int(p_max)
        self.reset()

    def reset(self) -> None:
        """Power-on state: no controller, reflex on, an empty model, prior rate codes, counters 0."""
        from ga.fail_rates import prior_codes
        from ga.world_model import WorldModel

        self.rows = np.zeros(50, dtype=np.uint32)
        self.reflex = True
        self.model = WorldModel()  # written entry by entry as OBSERVE carries them
        self.rates = prior_codes()
        self.slots: dict[int, np.ndarray] = {}
        self.results = np.zeros((0, 4), dtype=np.int64)
        self.frames_ok = self.frames_rejected = self.evaluator_cycles = 0
        self._table = None

    # -- one frame ------------------------------------------------------------------------------

    def answer(self, header, payload: bytes) -> bytes:
        """The reply frame to a frame whose CRC checked."""
        try:
            command = Command(header.command)
        except ValueError:
            command = None
        if command not in SYSTEM_COMMANDS:
            return self.reject(header, Status.UNKNOWN_COMMAND)
        if len(payload) != REQUEST_LENGTH[command]:
            return self.reject(header, Status.BAD_LENGTH)
        reply = getattr(self, "_" + command.name.lower())(payload)
        if isinstance(reply, Status):
            return self.reject(header, reply)
        self.frames_ok += 1
        return encode_frame(command, reply, tag=header.tag)

    def reject(self, header, status: Status) -> bytes:
        self.frames_rejected += 1
        return bytes([SYNC]) + _reply_body(header.command, header.tag, status)

    # -- the commands (each returns the reply payload or an error Status) ----------------------

    def _identify(self, payload):
        name = Design.SYSTEM.value.encode().ljust(NAME_BYTES, b"\0")
        return pack(IDENTIFY_REPLY, design=int.from_bytes(name, "little"), layout_version=GENOME_LAYOUT_VERSION,
                    build_id=0, p_max=self.p_max, clk_freq_hz=CLK_FREQ_HZ, baud=self.baud,
                    distance_rule=distance_rule_code(self.distance_rule))

    def _read_counters(self, payload):
        return pack(COUNTERS_REPLY, frames_ok=self.frames_ok + 1, frames_rejected=self.frames_rejected,
                    evaluator_cycles=self.evaluator_cycles % (1 << 48))

    def _load_controller(self, payload):
        self.rows, self._table = _rows(payload), None  # committed whole: the frame checked
        return b""

    def _set_reflex(self, payload):
        self.reflex, self._table = bool(unpack(REFLEX_REQUEST, payload).enable), None
        return b""

    def _motion(self, payload):
        from ga.truth_table import truth_tables

        if self._table is None:
            self._table = truth_tables(self.rows, reflex=self.reflex)
        return pack(MOTION_REPLY, motion=int(self._table[int(unpack(MOTION_REQUEST, payload).state)]))

    def _observe(self, payload):
        req = unpack(OBSERVE_REQUEST, payload)
        s, a = int(req.state), int(req.motion)
        self.model.valid[s, a], self.model.crash[s, a], self.model.next_state[s, a] = True, bool(req.crash), int(req.next)
        self.model.in_set[s] = self.model.in_set[int(req.reached)] = True
        return b""

    def _clear(self, payload):
        from ga.fail_rates import prior_codes
        from ga.world_model import WorldModel

        self.model, self.rates = WorldModel(), prior_codes()
        return b""

    def _write_rate(self, payload):
        req = unpack(RATE_REQUEST, payload)
        self.rates[int(req.state), int(req.motion)] = int(req.code)
        return b""

    def _load_genome(self, payload):
        index = int(unpack(LOAD_GENOME_REQUEST, payload).index)
        if index >= self.p_max:
            return Status.BAD_ARGUMENT
        self.slots[index] = _rows(payload[layout_bytes(LOAD_GENOME_REQUEST):])
        return b""

    def _evaluate(self, payload):
        from cosim.boards.hardware_time import stream_cycles
        from ga.evaluator import evaluate_population

        count = int(unpack(EVALUATE_REQUEST, payload).count)
        if not 1 <= count <= self.p_max:
            return Status.BAD_ARGUMENT
        empty = np.zeros(50, dtype=np.uint32)  # a slot never loaded since reset holds zeros
        population = np.stack([self.slots.get(i, empty) for i in range(count)])
        r = evaluate_population(population, self.model, reflex=self.reflex, distance_rule=self.distance_rule,
                                rates=self.rates)
        self.results = np.stack([r.crashes, r.loops, r.distance, r.fails], axis=1).astype(np.int64)
        cycles = stream_cycles(count, self.model.n_states, self.p_max)
        self.evaluator_cycles += cycles
        return pack(EVALUATE_REPLY, cycles=cycles % (1 << 32))

    def _read_results(self, payload):
        req = unpack(READ_RESULTS_REQUEST, payload)
        first, count = int(req.first), int(req.count)
        if count == 0 or count > RESULTS_PER_READ or first + count > self.p_max:
            return Status.BAD_ARGUMENT
        out = b""
        for i in range(first, first + count):
            c = self.results[i] if i < len(self.results) else (0, 0, 0, 0)
            out += pack(RESULT_REPLY, result={"crashes": int(c[0]), "loops": int(c[1]),
                                              "distance": int(c[2]), "fails": int(c[3])})
        return out


def _reply_body(command: int, tag: int, status: Status) -> bytes:
    body = pack(FrameHeader, command=int(command), status=status.value, tag=int(tag), length=0)
    return body + crc16(body).to_bytes(CRC_BYTES, "big")


class EmulatedLine:
    """A pyserial-like stream onto an :class:`EmulatedSystemBoard` (see the module docstring)."""

    timeout = 0.0  # nothing to wait for: the board answers as the bytes arrive

    def __init__(self, board: EmulatedSystemBoard | None = None, name: str = "emulated ehw-system board"):
        self.board = board if board is not None else EmulatedSystemBoard()
        self.port = name
        self._rx = bytearray()  # host -> board, not yet a whole frame
        self._tx = bytearray()  # board -> host

    def write(self, data: bytes) -> int:
        self._rx += bytes(data)
        self._decode()
        return len(data)

    def _decode(self) -> None:
        rx = self._rx
        while rx:
            if rx[0] != SYNC:  # hunt for the start of a frame
                del rx[0]
                continue
            if len(rx) < 1 + HEADER_BYTES:
                return
            header = unpack(FrameHeader, bytes(rx[1:1 + HEADER_BYTES]))
            end = 1 + HEADER_BYTES + header.length + CRC_BYTES
            if len(rx) < end:
                return  # the rest may still come (or the inter-byte timeout, at the next read)
            body = bytes(rx[1:end])
            del rx[:end]
            if crc16(body) != LINK_CRC.residue():
                self._tx += self.board.reject(header, Status.BAD_CRC)
            else:
                self._tx += self.board.answer(header, body[HEADER_BYTES:HEADER_BYTES + header.length])

    def read(self, n: int) -> bytes:
        if len(self._tx) < n and len(self._rx) > 0:  # a frame stalled: the inter-byte timeout
            known = bytes(self._rx[1:1 + HEADER_BYTES]).ljust(HEADER_BYTES, b"\0")  # the header so far
            self._tx += self.board.reject(unpack(FrameHeader, known), Status.TRUNCATED)
            self._rx.clear()
        out = bytes(self._tx[:n])
        del self._tx[:n]
        return out

    def reset_input_buffer(self) -> None:
        self._tx.clear()

    def board_reset(self) -> None:
        """A power glitch: the board's state and whatever was on the line are lost."""
        self.board.reset()
        self._rx.clear()
        self._tx.clear()


def make_emulated_boards(reflex: bool = True, distance_rule: str = DEFAULT_DISTANCE_RULE, check: bool = True):
    """(controller board, evaluator board) of ``cosim.link.boards`` over an emulated ehw-system
    board, behind ``EHW_LINE_FAULTS`` (``--line-faults``) if set."""
    from cosim.link.boards import boards_over
    from cosim.link.faults import faulty

    line = faulty(EmulatedLine(EmulatedSystemBoard(distance_rule)))
    return boards_over([LinkClient(line)], reflex=reflex, check=check, distance_rule=distance_rule)


register_backend("emulated", make_emulated_boards)
