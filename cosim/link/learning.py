"""The learning board (``cosim.boards.interfaces.LearningBoard``) over the host link: a ``LearnerLinkTop``
(``hdl.learner_link``, the ``ulx3s-learner`` bitstream) through a ``cosim.link.host.LinkClient``,
and the learning boards of the ``serial`` backend (``--ga hardware``: one ``ulx3s-learner`` on a
port) and, over its simulated line, of the ``uart`` backend (``cosim.launch.uart_sim``).

What crosses the link: the population once (LOAD_GENOME, pipelined), the seed (SEED), every
observation (OBSERVE, 4 bytes: the host keeps its copy of the world model for the update rule,
``cosim.link.boards.LinkModelBoard``), every changed failure-rate code (WRITE_RATE, 3 bytes, with
``--fail-rates``), and per learning phase one LEARN (4 bytes out, 18 back) and one READ_GENOME of
the download (119 bytes back), which the run then loads into the controller board beside the
engine (LOAD_CONTROLLER, 119 bytes out).

With ``check`` (default) the reference learning board (``ga.hardware_ga``) runs beside it and
:class:`cosim.link.boards.LinkMismatch` is raised at the first learn whose download, counts, fail
count, cycles or escape flag differ: the board never returns a wrong result silently.
"""

from __future__ import annotations

import numpy as np

from cosim.boards.interfaces import LearnResult
from cosim.boards.reference import ReferenceLearningBoard, checked_state_dict
from cosim.link.boards import LinkControllerBoard, LinkMismatch, LinkModelBoard
from cosim.link.host import LinkClient, LinkError, check_distance_rule, pack, unpack
from ga.motions import DEFAULT_DISTANCE_RULE
from hdl.link_protocol import (
    LEARN_REPLY,
    LEARN_REQUEST,
    READ_GENOME_REQUEST,
    SEED_REQUEST,
    Command,
    Design,
    genome_bytes,
    layout_bytes,
)

MAX_GENERATIONS = (1 << LEARN_REQUEST["generations"].width) - 1  # 4095


class LinkLearningBoard(LinkModelBoard):
    """LearningBoard over a ``LinkClient`` to an ``ehw-learner`` board (see the module docstring).

    The board's engine is a circuit constant: ``config`` must be the one it was built with (its
    population is checked against IDENTIFY's ``p_max``; the lanes and rates are the build's)."""

    def __init__(self, client: LinkClient, config, seed: int, population, reflex: bool = True,
                 distance_rule: str = DEFAULT_DISTANCE_RULE, check: bool = True):
        from ga.world_model import WorldModel

        self.client = client
        identity = client.identity or client.expect(Design.LEARNER)
        check_distance_rule(client.port, identity, distance_rule)
        if identity.p_max != config.population:
            raise LinkError(f"{client.port}: the board's engine holds {identity.p_max} individuals, "
                            f"the run's population is {config.population} (--population)")
        self.config = config
        self.model = WorldModel()  # the host's copy (the update rule needs the current entry)
        self.reference = (ReferenceLearningBoard(config, seed, population, reflex, distance_rule)
                          if check else None)
        self.cycles = 0
        self._serial = 0
        client.set_reflex(reflex)
        client.clear()
        client.request(Command.SEED, pack(SEED_REQUEST, seed=int(seed) & 0xFFFFFFFF), reply_length=0)
        self._load(population)
        client.on_reset.append(self.restore)

    def restore(self) -> None:
        """A board reset (``LinkClient.on_reset``) loses the engine's generators and population,
        which the host does not mirror: the run stops with one error line, its checkpoint kept."""
        raise LinkError(f"{self.client.port}: the learner board reset (its frame count went back); the "
                        "learning engine's population and generators cannot be restored from the host: "
                        "--resume continues the run from its last checkpoint")

    def _load(self, population) -> None:
        from ga.genome import validate_rows

        population = validate_rows(population)
        if population.shape != (self.config.population, 50):
            raise ValueError(f"the population is ({self.config.population}, 50), got {population.shape!r}")
        self.client.load_genomes(population)

    def load_population(self, population) -> None:
        self._load(population)
        if self.reference is not None:
            self.reference.load_population(population)

    state_dict = checked_state_dict  # the reference's engine state (no load_state: resume replays)

    def read_genome(self, index: int) -> np.ndarray:
        from ga.genome import rows_from_int

        reply = self.client.request(Command.READ_GENOME, pack(READ_GENOME_REQUEST, index=int(index)),
                                    reply_length=genome_bytes())
        return np.asarray(rows_from_int(int.from_bytes(reply, "little")), dtype=np.uint32)

    def learn(self, generations: int, avoid: tuple[int, int] | None = None) -> LearnResult:
        if not 1 <= int(generations) <= MAX_GENERATIONS:
            raise ValueError(f"a LEARN runs 1..{MAX_GENERATIONS} generations, got {generations!r}")
        self._serial = self._serial % 255 + 1  # never 0: the board's serial after reset
        state, motion = avoid if avoid is not None else (0, 0)
        payload = pack(LEARN_REQUEST, generations=int(generations), avoid_en=int(avoid is not None),
                       avoid_state=int(state), avoid_motion=int(motion), serial=self._serial)
        reply = unpack(LEARN_REPLY, self.client.request(Command.LEARN, payload, reply_length=layout_bytes(LEARN_REPLY)))
        rows = self.read_genome(int(reply.index))
        # the learn's clock edges, as on every backend: the busy cycles and the edge leaving Idle
        result = LearnResult(rows, int(reply.crashes), int(reply.loops), int(reply.distance),
                             cycles=int(reply.cycles) + 1, escaped=bool(reply.escaped), fails=int(reply.fails))
        self.cycles += result.cycles
        if self.reference is not None:
            want = self.reference.learn(generations, avoid)
            got_counts = (result.crashes, result.loops, result.distance, result.fails)
            want_counts = (want.crashes, want.loops, want.distance, want.fails)
            if not (np.array_equal(want.rows, rows) and got_counts == want_counts
                    and want.cycles == result.cycles and want.escaped == result.escaped):
                raise LinkMismatch(f"{self.client.port}: learn({generations}, avoid={avoid}) gave {got_counts} in "
                                   f"{result.cycles} cycles (escaped {result.escaped}), the reference "
                                   f"{want_counts} in {want.cycles} (escaped {want.escaped}); downloads "
                                   f"equal: {np.array_equal(want.rows, rows)} (the board's lanes and rates "
                                   f"are its bitstream's: the run's are {self.config!r})")
        return result


def learning_boards_over(client: LinkClient, config, seed: int, population, *, reflex: bool = True,
                         distance_rule: str = DEFAULT_DISTANCE_RULE, check: bool = True):
    """(controller board, learning board) of the ``ehw-learner`` board behind ``client``, both
    over its one link: the controller board beside the engine drives the robot with the downloads.
    Checks the board's design first; the controller board starts empty, as the reference."""
    client.expect(Design.LEARNER)
    controller = LinkControllerBoard(client, reflex=reflex, check=check)
    controller.load(np.zeros(50, dtype=np.uint32))
    learning = LinkLearningBoard(client, config, seed, population, reflex=reflex,
                                 distance_rule=distance_rule, check=check)
    return controller, learning


def make_serial_learning_boards(config, seed: int, population, *, reflex: bool = True,
                                distance_rule: str = DEFAULT_DISTANCE_RULE, check: bool = True,
                                port: str | None = None, baud: float | None = None):
    """The ``serial`` backend's boards with ``--ga hardware``: (controller board, learning board)
    of one ``ulx3s-learner`` board on a serial port (default ``EHW_PORT``, ``EHW_BAUD``; ``ehw sim
    --port``, ``--baud``), a device or any pyserial URL."""
    from base import environ
    from cosim.link.boards import BAUD_ENV, PORT_ENV, _baud_from_env, open_port

    port = port or environ.read(PORT_ENV)
    if not port:
        raise LinkError(f"the serial backend needs a port: with --ga hardware one ulx3s-learner board, "
                        f"--port /dev/ttyUSB1 (make sim BACKEND=serial PORT=...; or {PORT_ENV}=..., "
                        f"{BAUD_ENV}=...)")
    client = LinkClient(open_port(port, _baud_from_env() if baud is None else baud))
    return learning_boards_over(client, config, seed, population, reflex=reflex,
                                distance_rule=distance_rule, check=check)
