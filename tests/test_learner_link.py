# amaranth: UnusedElaboratable=no
"""The learning board behind the host link (hdl/learner_link.py, cosim/link_learning.py): the
``ulx3s-learner`` top in Amaranth's simulator, bit by bit through the UART line model
(tests/link_sim.py), driven by the host's LinkLearningBoard, equals the reference learning board
(ga.hardware_ga) on a short learn: two phases, the second with the escape; a LEARN resent with
the same serial is not run again; the controller board beside the engine gives the reference's
motions."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.boards import ReferenceLearningBoard
from cosim.link_boards import LinkControllerBoard
from cosim.link_host import LinkClient, LinkError, pack, unpack
from cosim.link_learning import LinkLearningBoard
from ga import hardware_ga as hg
from ga.motions import OBSTACLE_MASK
from ga.operators import random_population
from hdl.learner_link import LearnerLinkTop
from hdl.link_protocol import LEARN_REPLY, LEARN_REQUEST, Command
from link_sim import AmaranthSerial

CLK, BAUD = 1e6, 250_000  # divisor 4: the fastest the UART runs
CONFIG = hg.HardwareGAConfig(population=6, tournament=2, lanes=2, literal_rate=0.05, output_rate=0.1,
                             switch_rate=0.2, replace_rate=0.1)
SEED = 99


def _walk(rng, count):
    out, s = [], int(rng.integers(64))
    for _ in range(count):
        a, crashed = int(rng.integers(8)), bool(rng.random() < 0.2)
        s2 = s if crashed else int(rng.integers(64))
        out.append((s, a, s2, crashed))
        s = s2
    return out


def test_learner_top_over_the_link_equals_the_reference():
    top = LearnerLinkTop(CLK, BAUD, config=CONFIG, timeout_s=1e-4, build_id=0x5EED)
    line = AmaranthSerial(top, timeout_cycles=40_000, name="amaranth LearnerLinkTop")
    client = LinkClient(line)
    line.run_cycles(2100)  # the lanes' evaluators sweep their RAMs after reset
    identity = client.identify()
    assert (identity.design, identity.p_max, identity.build_id) == ("ehw-learner", CONFIG.population, 0x5EED)

    rng = np.random.default_rng(SEED)
    population = random_population(rng, CONFIG.population)
    board = LinkLearningBoard(client, CONFIG, SEED, population, check=True)
    reference = ReferenceLearningBoard(CONFIG, SEED, population)
    for obs in _walk(rng, 12):
        board.observe(*obs)
        reference.observe(*obs)
    first = board.learn(2)  # check=True: equal to the reference beside it, or LinkMismatch
    want = reference.learn(2)
    assert np.array_equal(first.rows, want.rows) and first.cycles == want.cycles == hg.learn_cycles(
        reference.model.n_states, CONFIG, 2)
    for obs in _walk(rng, 6):
        board.observe(*obs)
        reference.observe(*obs)
    blamed = next(s for s in range(256) if s & OBSTACLE_MASK)
    second = board.learn(1, avoid=(blamed, 3))
    want = reference.learn(1, avoid=(blamed, 3))
    assert (second.crashes, second.loops, second.distance, second.escaped) == \
        (want.crashes, want.loops, want.distance, want.escaped)
    assert client.read_counters()["evaluator_cycles"] == first.cycles + second.cycles - 2  # busy cycles

    # the same serial again: the last reply, not a third learn (the reference would differ)
    again = pack(LEARN_REQUEST, generations=1, avoid_en=1, avoid_state=blamed, avoid_motion=3,
                 serial=board._serial)
    reply = unpack(LEARN_REPLY, client.request(Command.LEARN, again))
    assert int(reply.cycles) + 1 == second.cycles and np.array_equal(board.read_genome(int(reply.index)), second.rows)
    with pytest.raises(LinkError, match="BAD_ARGUMENT"):
        board.read_genome(CONFIG.population)

    controller = LinkControllerBoard(client, reflex=True, check=True)
    controller.load(second.rows)
    assert [controller.motion(s) for s in (0, 5, 0x80, 0xFF)]  # check=True: the reference's


def test_serial_learning_board_errors_name_the_port(monkeypatch):
    from cosim.link_learning import make_serial_learning_boards

    population = random_population(np.random.default_rng(1), CONFIG.population)
    monkeypatch.delenv("EHW_PORT", raising=False)
    with pytest.raises(LinkError, match="needs a port"):
        make_serial_learning_boards(CONFIG, 1, population)
    with pytest.raises(LinkError, match="loop://"):  # pyserial's echo line: no board answers
        make_serial_learning_boards(CONFIG, 1, population, port="loop://", baud=115_200)
