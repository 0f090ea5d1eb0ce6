"""The two board interfaces of ``cosim.boards.interfaces`` over the host link (``cosim.link.host``), and the
``serial`` backend: real boards on serial ports (pyserial).

    make sim BACKEND=serial PORT=/dev/ttyUSB1                 one ULX3S (ehw-system)
    make sim BACKEND=serial PORT=/dev/ttyUSB1 PORT2=/dev/ttyUSB3   two iCEBreakers (controller, evaluator)

(``ehw sim --backend serial --port ... [--port2 ...] [--baud ...]``, or ``EHW_PORT``,
``EHW_PORT2``, ``EHW_BAUD`` in the environment; with ``--ga hardware`` one ``ulx3s-learner``
board: ``cosim.link.learning``.) The same board classes serve the ``uart`` backend
(``cosim.launch.uart_sim``), where the stream is the simulated serial line of the board top in Verilator.

- :class:`LinkControllerBoard`: LOAD_CONTROLLER (rows + commit in one frame), SET_REFLEX, MOTION.
- :class:`LinkModelBoard`: the ``observe`` of every board that holds a world model (this
  evaluator, ``cosim.link.learning.LinkLearningBoard``).
- :class:`LinkEvaluatorBoard`: keeps the host's copy of the world model (the update rule of SPEC
  section 7 needs the current entry, as ``hdl.system_top.SystemHost``) and sends the resulting
  entry with OBSERVE; writes failure-rate codes with WRITE_RATE, one a frame; evaluates a
  population in chunks of the board's ``p_max`` slots: LOAD_GENOME each (pipelined,
  ``LinkClient.load_genomes``), EVALUATE, READ_RESULTS (crashes, loops, distance, fails). A chunk
  answered NOT_LOADED (a damaged frame touched a single-buffered evaluator's rows) is loaded
  again, at most ``retries`` times.

Each board keeps the host's mirror of what it wrote to the board (the controller's rows and
reflex; the world model, rate codes and the population chunk in work) and restores it when the
client detects a board reset (``LinkClient.on_reset``: docs/host_link.md, "board resets"); the
mirror is updated before each request, so a request resent after a restore finds the board as
the host expects it.

With ``check`` (default) each board keeps the reference model beside it and raises
:class:`LinkMismatch` at the first motion or count that differs: a board never returns a wrong
result silently.
"""

from __future__ import annotations

import numpy as np

from base import environ
from cosim.boards.interfaces import BoardMismatch, EvalCounts
from cosim.boards.reference import ReferenceControllerBoard, ReferenceEvaluatorBoard, checked_motion
from cosim.boards.registry import register_backend
from cosim.link.host import RETRIES, LinkClient, LinkError, NotLoaded
from ga.motions import DEFAULT_DISTANCE_RULE
from hdl.link_protocol import Design
from hdl.uart import DEFAULT_BAUD

PORT_ENV, PORT2_ENV, BAUD_ENV = "EHW_PORT", "EHW_PORT2", "EHW_BAUD"
SERIAL_TIMEOUT_S = 1.0  # a reply takes < 30 ms at 115,200 baud (the longest: 255 bytes + EVALUATE)


class LinkMismatch(BoardMismatch):
    """A board behind the link disagreed with the reference model."""


class LinkControllerBoard:
    """ControllerBoard over a ``LinkClient`` (a controller or system board)."""

    def __init__(self, client: LinkClient, reflex: bool = True, check: bool = True):
        self.client = client
        self.cycles = 0  # the board does not count: its time is the link's (client.stats)
        self.reference = ReferenceControllerBoard(reflex=reflex) if check else None
        self.reflex, self.rows = bool(reflex), np.zeros(50, dtype=np.uint32)  # the host's mirror
        self.client.set_reflex(reflex)
        self.client.on_reset.append(self.restore)

    def restore(self) -> None:
        """After a board reset: the reflex and the controller again (``LinkClient.on_reset``)."""
        self.client.set_reflex(self.reflex)
        self.client.load_controller(self.rows)

    def load(self, rows: np.ndarray) -> None:
        from ga.genome import validate_rows

        rows = validate_rows(rows)
        if rows.ndim != 1:
            raise ValueError(f"a controller board holds one genome (50,), got shape {rows.shape!r}")
        self.rows = rows.copy()
        self.client.load_controller(rows)
        if self.reference is not None:
            self.reference.load(rows)

    def set_reflex(self, enabled: bool) -> None:
        self.reflex = bool(enabled)
        self.client.set_reflex(enabled)
        if self.reference is not None:
            self.reference.set_reflex(enabled)

    def motion(self, state: int) -> int:
        return checked_motion(self.client.motion, state, self.reference, self.client.port, LinkMismatch)


class LinkModelBoard:
    """What every board over the link that holds a world model shares (``LinkEvaluatorBoard``,
    ``cosim.link.learning.LinkLearningBoard``): the host keeps a copy of the model (``model``;
    the update rule of SPEC section 7 needs the current entry, as ``hdl.system_top.SystemHost``)
    and OBSERVE carries the entry it results in, so a resent OBSERVE does no harm; the reference
    beside the board (``reference``, None without ``check``) observes the same transition."""

    client: LinkClient
    model: object  # ga.world_model.WorldModel, the host's copy
    reference = None

    @property
    def reference_time_s(self):
        return None if self.reference is None else self.reference.time_s

    def observe(self, state: int, motion: int, next_state: int, crashed: bool) -> None:
        state, motion, next_state = int(state), int(motion), int(next_state)
        self.model.observe(state, motion, next_state, bool(crashed))
        self.client.observe(state, motion, int(self.model.next_state[state, motion]),
                            bool(self.model.crash[state, motion]), reached=next_state)
        if self.reference is not None:
            self.reference.observe(state, motion, next_state, crashed)

    def write_rates(self, changes) -> None:
        """One WRITE_RATE frame a code (``ga.fail_rates``; a learner top: every lane's rate RAM)."""
        changes = [tuple(map(int, change)) for change in changes]
        for state, motion, code in changes:
            if getattr(self, "rates", None) is not None:
                self.rates[state, motion] = code  # the mirror first: a restore then holds it
            self.client.write_rate(state, motion, code)
        if self.reference is not None:
            self.reference.write_rates(changes)


class LinkEvaluatorBoard(LinkModelBoard):
    """EvaluatorBoard over a ``LinkClient`` (an evaluator or system board with ``p_max`` slots)."""

    def __init__(self, client: LinkClient, p_max: int, reflex: bool = True, check: bool = True,
                 distance_rule: str = DEFAULT_DISTANCE_RULE, retries: int = RETRIES):
        from ga.fail_rates import prior_codes
        from ga.world_model import WorldModel

        if p_max < 1:
            raise ValueError(f"an evaluator board has at least one population slot, got p_max={p_max!r}")
        self.client = client
        self.p_max = int(p_max)
        self.retries = retries
        self.model = WorldModel()  # the host's copy
        self.cycles = 0  # the evaluator's own cycles, from the EVALUATE replies
        self.reference = ReferenceEvaluatorBoard(reflex=reflex, distance_rule=distance_rule) if check else None
        self.reflex, self.rates = bool(reflex), prior_codes()  # the host's mirror, with model
        self._chunk_in_work = None  # (rows, evaluated): the population chunk on the board
        self.client.set_reflex(reflex)
        self.client.clear()  # every rate code at PRIOR_CODE too, as the reference's
        self.client.on_reset.append(self.restore)

    def restore(self) -> None:
        """After a board reset (``LinkClient.on_reset``): the reflex, the world model entry by
        entry (OBSERVE carries the entry; the states of S no entry names ride on the first
        entry's ``reached``), the rate codes that are not the prior, and the chunk in work
        (loaded again, and evaluated again if it was: EVALUATE is deterministic)."""
        from ga.fail_rates import PRIOR_CODE

        client, model = self.client, self.model
        client.set_reflex(self.reflex)
        client.clear()
        entries = model.entries()
        for state, motion, next_state, crash in entries:
            client.observe(state, motion, next_state, bool(crash), reached=next_state)
        named = set(entries[:, 0].tolist()) | set(entries[:, 2].tolist())
        for extra in (int(s) for s in model.states if int(s) not in named):
            state, motion, next_state, crash = entries[0]
            client.observe(state, motion, next_state, bool(crash), reached=extra)
        for state, motion in zip(*np.nonzero(self.rates != PRIOR_CODE)):
            client.write_rate(int(state), int(motion), int(self.rates[state, motion]))
        if self._chunk_in_work is not None:
            rows, evaluated = self._chunk_in_work
            client.load_genomes(rows)
            if evaluated:
                client.evaluate(len(rows))

    def _chunk(self, rows) -> tuple[list, int]:
        for attempt in range(self.retries + 1):
            self._chunk_in_work = (rows, False)
            self.client.load_genomes(rows)
            try:
                cycles = self.client.evaluate(len(rows))
            except NotLoaded:
                if attempt == self.retries:
                    raise LinkError(f"{self.client.port}: EVALUATE still NOT_LOADED after "
                                    f"{self.retries + 1} loads") from None
                continue
            self._chunk_in_work = (rows, True)
            results = self.client.read_results(0, len(rows))
            self._chunk_in_work = None
            return results, cycles
        raise AssertionError("unreachable")

    def evaluate(self, population: np.ndarray) -> EvalCounts:
        from ga.genome import validate_rows

        population = validate_rows(population)
        if population.ndim != 2:
            raise ValueError(f"a population is (P, 50), got shape {population.shape!r}")
        counts, cycles = [], 0
        for first in range(0, len(population), self.p_max):
            chunk_counts, chunk_cycles = self._chunk(population[first:first + self.p_max])
            counts += chunk_counts
            cycles += chunk_cycles
        self.cycles += cycles
        arr = np.asarray(counts, dtype=np.int64).reshape(-1, 4)
        result = EvalCounts(crashes=arr[:, 0], loops=arr[:, 1], distance=arr[:, 2], fails=arr[:, 3],
                            cycles=cycles)
        if self.reference is not None:
            expected = self.reference.evaluate(population)
            for name in ("crashes", "loops", "distance", "fails"):
                got, want = getattr(result, name), np.asarray(getattr(expected, name))
                if not np.array_equal(got, want):
                    i = int(np.flatnonzero(got != want)[0])
                    raise LinkMismatch(f"{self.client.port}: {name} of controller {i} is {got[i]}, "
                                       f"the reference gives {want[i]}")
        return result


def boards_over(clients, reflex: bool = True, check: bool = True, distance_rule: str = DEFAULT_DISTANCE_RULE):
    """(controller board, evaluator board) over one client (an ``ehw-system`` board) or two
    (``ehw-controller``, ``ehw-evaluator``); checks each board's design first."""
    if len(clients) == 1:
        identity = clients[0].expect(Design.SYSTEM, distance_rule=distance_rule)
        controller_client = evaluator_client = clients[0]
    elif len(clients) == 2:
        clients[0].expect(Design.CONTROLLER)
        identity = clients[1].expect(Design.EVALUATOR, distance_rule=distance_rule)
        controller_client, evaluator_client = clients
    else:
        raise ValueError(f"one port (a system board) or two (controller, evaluator), got {len(clients)!r}")
    controller = LinkControllerBoard(controller_client, reflex=reflex, check=check)
    controller.load(np.zeros(50, dtype=np.uint32))  # both boards start empty, as the reference
    evaluator = LinkEvaluatorBoard(evaluator_client, identity.p_max, reflex=reflex, check=check,
                                   distance_rule=distance_rule)
    return controller, evaluator


# -- the serial backend --------------------------------------------------------------------------


def open_port(port: str, baud: float):
    """A pyserial port on ``port`` (a device or a pyserial URL), or a ``LinkError`` naming it."""
    try:
        import serial
    except ImportError:  # pragma: no cover - pyserial is a dependency
        raise LinkError("the serial backend needs pyserial: pip install -e . (make sim does)") from None
    try:  # a device path, or any pyserial URL (socket://host:port, rfc2217://..., loop://)
        return serial.serial_for_url(port, baudrate=int(baud), timeout=SERIAL_TIMEOUT_S,
                                     write_timeout=SERIAL_TIMEOUT_S)
    except (serial.SerialException, OSError, ValueError) as exc:
        raise LinkError(f"{port}: cannot open the serial port ({exc})") from None


def _baud_from_env() -> float:
    return environ.read(BAUD_ENV, float(DEFAULT_BAUD))


def make_serial_boards(reflex: bool = True, distance_rule: str = DEFAULT_DISTANCE_RULE, check: bool = True,
                       port: str | None = None, port2: str | None = None, baud: float | None = None):
    """The boards on serial ports (default ``EHW_PORT``, ``EHW_PORT2``, ``EHW_BAUD``)."""
    port = port or environ.read(PORT_ENV)
    port2 = port2 or environ.read(PORT2_ENV)
    if not port:
        raise LinkError(f"the serial backend needs a port: make sim BACKEND=serial PORT=/dev/ttyUSB1 "
                        f"[PORT2=...] (or {PORT_ENV}=...)")
    from cosim.link.faults import faulty

    baud = _baud_from_env() if baud is None else baud
    clients = [LinkClient(faulty(open_port(p, baud))) for p in ([port] if port2 is None else [port, port2])]
    return boards_over(clients, reflex=reflex, check=check, distance_rule=distance_rule)


register_backend("serial", make_serial_boards)


def link_summary(controller, evaluator) -> dict:
    """The link's figures of a run: bytes each way (in all and per command), requests, resends
    (per client; one entry, ``controller``, where both boards share it)."""
    from cosim.link.faults import injected_faults

    out = {}
    for role, board in (("controller", controller), ("evaluator", evaluator)):
        stats = board.client.stats
        identity = board.client.identity
        out[role] = {"port": board.client.port,
                     "board": None if identity is None else {"design": identity.design, "build_id": f"{identity.build_id:08x}",
                                                             "clk_freq_hz": identity.clk_freq_hz, "baud": identity.baud},
                     "bytes_sent": stats.bytes_sent,
                     "bytes_received": stats.bytes_received, "requests": stats.requests,
                     "resends": stats.resends, "resend_reasons": dict(stats.reasons),
                     "bytes_resent": stats.bytes_resent, "resets_detected": stats.resets,
                     "restores": stats.restores, "restore_restarts": stats.restore_restarts,
                     "restore_bytes": stats.restore_bytes,
                     "faults_injected": injected_faults(board.client),
                     "by_command": {name: list(v) for name, v in sorted(stats.by_command.items())}}
        if controller.client is evaluator.client:
            break
    return out


def write_link_summary(run, out) -> dict:
    """``out/link.json``: :func:`link_summary` of a run on link boards (``cosim.online.run.OnlineRun``)."""
    import json
    from pathlib import Path

    link = link_summary(run.controller, run.evaluator)
    (Path(out) / "link.json").write_text(json.dumps(link, indent=1) + "\n")
    return link


def link_lines(link: dict) -> list[str]:
    """One line per client of a ``link.json``: what crossed the link."""
    lines = []
    for role, figures in link.items():
        lines.append(f"link ({role}): {figures['bytes_sent']:,} bytes sent, {figures['bytes_received']:,} "
                     f"received, {figures['requests']:,} requests, {figures['resends']} resends")
        injected = figures.get("faults_injected")
        if injected:
            lines.append(f"line faults ({role}): injected " + ", ".join(f"{k} {v}" for k, v in injected.items())
                         + f"; detected {sum(figures['resend_reasons'].values())} failed tries, "
                         f"{figures['resets_detected']} board resets; recovered by {figures['resends']} "
                         f"resends ({figures['bytes_resent']:,} bytes) and {figures['restores']} restores "
                         f"({figures.get('restore_restarts', 0)} started again, {figures['restore_bytes']:,} bytes)")
    return lines


def fault_summary(link: dict) -> dict | None:
    """The line faults of a run's ``link.json`` for its summary: injected, detected, recovered."""
    found = {role: f for role, f in link.items() if f.get("faults_injected")}
    if not found:
        return None
    return {role: {"injected": f["faults_injected"], "failed_tries": dict(f["resend_reasons"]),
                   "resets_detected": f["resets_detected"], "resends": f["resends"],
                   "bytes_resent": f["bytes_resent"], "restores": f["restores"],
                   "restore_restarts": f.get("restore_restarts", 0),
                   "restore_bytes": f["restore_bytes"]} for role, f in found.items()}
