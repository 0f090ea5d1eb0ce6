"""cocotb testbench: SystemLinkTop (system_link_top.v) through its UART pins, with the host code
of the serial backend (``cosim.link.host``, ``cosim.link.boards``) over the uart backend's
simulated line (``cosim.link.simulated.SimulatedSerial``, cocotbext-uart).

- ``identify``: design, slots, counters;
- ``faults``: a flipped request byte (in a LOAD_CONTROLLER frame) and a flipped reply byte each
  cost exactly one resend, a dropped request byte (in a pipelined LOAD_GENOME frame) two (that
  genome and the one in flight behind it), and each session gives the reference's motions and
  counts (the boards check every result against the reference); the board counts the damaged
  requests as rejected;
- ``unknown_command``: a well-formed frame with a command the board does not decode is answered
  UNKNOWN_COMMAND, and the client's error names the line;
- ``silent_board``: a board that stops answering gives a LinkError naming the line after
  ``RETRIES`` resends, never a result.

Started from pytest by tests/test_link.py (with the short on-line run of cosim.launch.uart_sim in
the same simulation build).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import cocotb
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # tests/, for link_sim

from link_sim import FaultyStream  # noqa: E402

from cosim.launch.lifetime import CONFIG_ENV  # noqa: E402
from cosim.link.boards import LinkControllerBoard, LinkEvaluatorBoard  # noqa: E402
from cosim.link.host import RETRIES, LinkClient, LinkError, pack  # noqa: E402
from cosim.link.simulated import SIM_CLK_HZ, host_timeout_s, start_top  # noqa: E402
from ga.motions import DEFAULT_DISTANCE_RULE  # noqa: E402
from hdl.link_protocol import LINK_CRC, SYNC, FrameHeader  # noqa: E402

BAUD = float(os.environ.get("EHW_BAUD", SIM_CLK_HZ / 4))
# the build's dist[a] rule: the short on-line run's, when this runs beside it
RULE = json.loads(os.environ.get(CONFIG_ENV, "{}")).get("distance_rule", DEFAULT_DISTANCE_RULE)
P_MAX = int(os.environ.get("EHW_SYSTEM_P_MAX", "8"))


async def _line(dut):
    return await start_top(dut, BAUD, host_timeout_s(BAUD, P_MAX))


def _session(client: LinkClient, rng) -> None:
    """Controller and evaluator commands, every result checked against the reference."""
    controller = LinkControllerBoard(client, reflex=True, check=True)
    evaluator = LinkEvaluatorBoard(client, P_MAX, reflex=True, check=True, distance_rule=RULE)
    controller.load(rng.integers(0, 1 << 19, 50, dtype=np.uint32))
    for state in rng.integers(0, 256, 6):
        controller.motion(int(state))
    for _ in range(25):
        evaluator.observe(int(rng.integers(0, 64)), int(rng.integers(0, 8)), int(rng.integers(0, 64)),
                          bool(rng.random() < 0.2))
    evaluator.evaluate(rng.integers(0, 1 << 19, (P_MAX + 2, 50), dtype=np.uint32))


@cocotb.test()
async def identify(dut):
    from cocotb.task import bridge

    line = await _line(dut)

    def body():
        client = LinkClient(line)
        return client.identify(), client.read_counters()

    identity, counters = await bridge(body)()
    assert identity.design == "ehw-system", identity
    assert (identity.p_max, identity.layout_version) == (P_MAX, 1), identity
    # READ_COUNTERS counts itself: frames are counted when they are dispatched
    assert counters == {"frames_ok": 2, "frames_rejected": 0, "evaluator_cycles": 0}, counters


@cocotb.test()
async def faults(dut):
    from cocotb.task import bridge

    line = await _line(dut)
    # byte numbers from the start of the session: SET_REFLEX, SET_REFLEX, CLEAR frames
    # (8 + 8 + 7 bytes), then LOAD_CONTROLLER (126 bytes): byte 60 is inside its genome
    cases = [("flip", 60), ("drop", 60 + 126 + 6 * 8 + 25 * 11 + 40), ("reply_flip", 1)]

    def body():
        outcomes = []
        for i, (kind, at) in enumerate(cases):
            client = LinkClient(line)
            before = client.read_counters()["frames_rejected"]
            client.stream = stream = FaultyStream(line, kind, at)
            _session(client, np.random.default_rng(100 + i))  # raises on any wrong result
            client.stream = line
            rejected = client.read_counters()["frames_rejected"] - before
            outcomes.append((kind, stream.fired, client.stats.resends, rejected, dict(client.stats.reasons)))
        return outcomes

    # the drop hits a pipelined LOAD_GENOME: the board reads the next frame's SYNC as the damaged
    # frame's last CRC byte (BAD_CRC) and hunts for SYNC in what follows; the host resends the
    # damaged genome and the one in flight behind it
    expected = {"flip": {"board replied BAD_CRC": 1},
                "drop": {"pipelined reply BAD_CRC": 1, "in flight behind a failed frame": 1},
                "reply_flip": {"bad reply CRC": 1}}
    for kind, fired, resends, rejected, reasons in await bridge(body)():
        assert fired, kind
        assert reasons == expected[kind], (kind, reasons)
        assert resends == sum(expected[kind].values()), (kind, resends)
        assert (rejected >= 1) if kind == "drop" else rejected == (kind == "flip"), (kind, rejected)


@cocotb.test()
async def unknown_command(dut):
    from cocotb.task import bridge

    line = await _line(dut)

    def body():
        body = pack(FrameHeader, command=0x7F, status=0, tag=9, length=0)
        line.write(bytes([SYNC]) + body + LINK_CRC.compute(body).to_bytes(2, "big"))
        reply = line.read(1 + 4 + 2)
        return reply, LinkClient(line).read_counters()

    reply, counters = await bridge(body)()
    assert reply[:5] == bytes([SYNC, 0x7F, 0x03, 9, 0]), reply.hex()  # UNKNOWN_COMMAND, tag echoed
    assert counters["frames_rejected"] == 1, counters


@cocotb.test()
async def silent_board(dut):
    from cocotb.task import bridge

    line = await _line(dut)

    def body():
        client = LinkClient(FaultyStream(line, "silence", 0))
        try:
            client.motion(5)
        except LinkError as exc:
            return str(exc), client.stats
        return None, client.stats

    message, stats = await bridge(body)()
    assert message is not None, "a silent board gave a result"
    assert line.port in message and "MOTION" in message, message
    assert stats.resends == RETRIES and stats.requests == 1, stats
