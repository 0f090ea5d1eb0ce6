# amaranth: UnusedElaboratable=no
"""The host link (hdl/link_protocol.py, hdl/link_tops.py, cosim/link/host.py, cosim/link/boards.py,
cosim/launch/uart_sim.py).

- Frames: the host's encoder against the gateware's definitions (CRC residue, header layout).
- Amaranth's simulator, bit by bit through the UART line model (tests/link_sim.py): the
  controller top (iCEBreaker) answers IDENTIFY, loads rows and gives the reference's motions; the
  single-buffered evaluator top evaluates like the reference, failure-rate codes (WRITE_RATE) and
  fails included; a damaged frame is answered and not executed (the committed controller stays;
  a touched evaluator answers NOT_LOADED until a good load, and the board class reloads by
  itself), nor is a WRITE_RATE of the wrong length (BAD_LENGTH).
- Verilator (one build): the uart backend's short on-line run (failure rates on) equals the
  reference run, and the fault tests of tests/cocotb_tb/tb_link.py (flipped / dropped / silent) pass.
- The serial backend's errors: no port, a port that cannot be opened, a board of the wrong design.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from link_sim import AmaranthSerial, FaultyStream
from pre_tuning import pre_tuning

from cosim.link.host import LinkClient, LinkError, encode_frame, genome_payload, pack, unpack
from hdl.link_protocol import (
    CRC_BYTES,
    HEADER_BYTES,
    LINK_CRC,
    REQUEST_LENGTH,
    RESULT_BYTES,
    RESULT_REPLY,
    SYNC,
    Command,
    FrameHeader,
    Status,
    genome_bytes,
)
from hdl.link_tops import ControllerLinkTop, EvaluatorLinkTop

TB_DIR = Path(__file__).resolve().parent / "cocotb_tb"
CLK, BAUD = 1e6, 250_000  # divisor 4: the fastest the UART runs
SEED = 13


def test_frame_encoding_matches_the_gateware_definitions():
    frame = encode_frame(Command.MOTION, b"\x2a", tag=7)
    assert frame[0] == SYNC and len(frame) == 1 + HEADER_BYTES + 1 + CRC_BYTES
    header = unpack(FrameHeader, frame[1:1 + HEADER_BYTES])
    assert (header.command, header.status, header.tag, header.length) == (Command.MOTION.value, 0, 7, 1)
    assert LINK_CRC.compute(frame[1:]) == LINK_CRC.residue() == 0  # what the receiver checks
    assert REQUEST_LENGTH[Command.LOAD_GENOME] == 2 + genome_bytes() == 121
    assert REQUEST_LENGTH[Command.WRITE_RATE] == 3
    from hdl.ports import pack_result

    word = pack_result(256, 3, 65535, 64000)  # RESULT_REPLY: the result word padded to bytes
    assert RESULT_BYTES == 7 and unpack(RESULT_REPLY, word.to_bytes(RESULT_BYTES, "little")).result.fails == 64000
    rows = np.random.default_rng(SEED).integers(0, 1 << 19, 50, dtype=np.uint32)
    payload = genome_payload(rows)
    assert len(payload) == 119 and int.from_bytes(payload, "little") & ((1 << 19) - 1) == rows[0]
    assert pack(FrameHeader, command=1, status=2, tag=3, length=4) == bytes([1, 2, 3, 4])
    with pytest.raises(ValueError, match="255"):
        encode_frame(Command.MOTION, bytes(256))


def test_row_assembler_writes_the_genome_rows_bit_serially():
    """RowAssembler against ga.genome: random genomes, bytes as close as it allows, a restart
    mid-genome; every row once, in order, equal to the reference rows."""
    from amaranth.sim import Simulator

    from hdl.link_protocol import RowAssembler

    rng = np.random.default_rng(SEED)
    genomes = [rng.integers(0, 1 << 19, 50, dtype=np.uint32) for _ in range(3)]
    dut = RowAssembler()
    writes = []

    genome = [0]

    async def bench(ctx):
        for k, rows in enumerate(genomes):
            genome[0] = k
            ctx.set(dut.restart, 1)
            await ctx.tick()
            ctx.set(dut.restart, 0)
            payload = genome_payload(rows)
            if k == 1:  # a restart after half a genome: the next one starts at row 0
                payload = payload[:60]
            for byte in payload:
                ctx.set(dut.byte, byte)
                ctx.set(dut.valid, 1)
                await ctx.tick()
                ctx.set(dut.valid, 0)
                await ctx.tick().repeat(RowAssembler.BYTE_CYCLES)  # the closest bytes may come
            await ctx.tick().repeat(2 * RowAssembler.BYTE_CYCLES)

    async def monitor(ctx):
        async for _, _, we, addr, data in ctx.tick().sample(dut.row.we, dut.row.addr, dut.row.data):
            if we:
                writes.append((genome[0], addr, data))

    sim = Simulator(dut)
    sim.add_clock(1e-6)
    sim.add_testbench(bench)
    sim.add_process(monitor)
    sim.run()
    expect = [(k, r, int(rows[r])) for k, rows in enumerate(genomes) for r in range(50 if k != 1 else 25)]
    assert writes == expect


def _client(top, timeout_cycles=20_000):
    line = AmaranthSerial(top, timeout_cycles=timeout_cycles, name=f"amaranth {type(top).__name__}")
    return LinkClient(line), line


def test_controller_top_identifies_loads_and_moves():
    from ga.truth_table import truth_tables

    client, line = _client(ControllerLinkTop(CLK, BAUD, timeout_s=1e-4, build_id=0x1234))
    identity = client.identify()
    assert (identity.design, identity.build_id, identity.p_max, identity.baud) == ("ehw-controller", 0x1234, 0, BAUD)
    assert identity.distance_rule is None  # the controller has no fitness
    rng = np.random.default_rng(SEED)
    rows = rng.integers(0, 1 << 19, 50, dtype=np.uint32)
    client.set_reflex(False)
    client.load_controller(rows)
    states = rng.integers(0, 256, 8)
    table = truth_tables(rows, reflex=False)
    assert [client.motion(int(s)) for s in states] == [int(table[s]) for s in states]

    # a flipped byte inside a LOAD_CONTROLLER frame: BAD_CRC, resent, and the motions are the new
    # controller's; the damaged copy never reached the array (it would have without the commit rule)
    other = rng.integers(0, 1 << 19, 50, dtype=np.uint32)
    client.stream = FaultyStream(line, "flip", 40)
    client.load_controller(other)
    assert client.stats.resends == 1 and client.stats.reasons == {"board replied BAD_CRC": 1}
    table = truth_tables(other, reflex=False)
    assert [client.motion(int(s)) for s in states] == [int(table[s]) for s in states]
    assert client.read_counters()["frames_rejected"] == 1

    # a command this board does not decode: a clear error, and nothing changed
    with pytest.raises(LinkError, match="does not decode EVALUATE.*another design"):
        client.evaluate(1)


def test_damaged_controller_frame_is_never_committed():
    """Without a resend: the frame that failed its CRC leaves the running controller in place."""
    from ga.truth_table import truth_tables

    client, line = _client(ControllerLinkTop(CLK, BAUD, timeout_s=1e-4))
    rng = np.random.default_rng(SEED + 1)
    rows, other = rng.integers(0, 1 << 19, (2, 50), dtype=np.uint32)
    client.set_reflex(False)
    client.load_controller(rows)
    frame = bytearray(encode_frame(Command.LOAD_CONTROLLER, genome_payload(other), tag=99))
    frame[30] ^= 0x01
    line.write(bytes(frame))
    reply = line.read(1 + HEADER_BYTES + CRC_BYTES)
    assert unpack(FrameHeader, reply[1:5]).status == Status.BAD_CRC.value
    table = truth_tables(rows, reflex=False)
    assert [client.motion(s) for s in (0, 77, 200)] == [int(table[s]) for s in (0, 77, 200)]


def test_single_buffered_evaluator_top_matches_the_reference():
    from test_evaluator_cases import constant_rows

    from cosim.boards.reference import ReferenceEvaluatorBoard
    from cosim.link.boards import LinkEvaluatorBoard
    from ga.evaluator import evaluate_population
    from ga.fail_rates import RATE_ONE, prior_codes

    client, line = _client(EvaluatorLinkTop(CLK, BAUD, double_buffer=False, timeout_s=1e-4), 20_000)
    line.run_cycles(2100)  # the evaluator sweeps its RAM after reset
    identity = client.identify()
    assert (identity.p_max, identity.distance_rule) == (1, "forward")
    board = LinkEvaluatorBoard(client, 1, reflex=True, check=True)
    reference = ReferenceEvaluatorBoard(reflex=True)
    rng = np.random.default_rng(SEED)
    for _ in range(12):
        s, m, n, crash = int(rng.integers(0, 32)), int(rng.integers(0, 8)), int(rng.integers(0, 32)), bool(rng.random() < 0.3)
        board.observe(s, m, n, crash)
        reference.observe(s, m, n, crash)
    rates = [(int(s), a, int(rng.integers(0, RATE_ONE + 1))) for s in board.model.states[:6] for a in (0, 5)]
    board.write_rates(rates)  # WRITE_RATE, one code a frame
    reference.write_rates(rates)
    pop = np.vstack([rng.integers(0, 1 << 19, (1, 50), dtype=np.uint32), constant_rows(0)])
    counts = board.evaluate(pop)  # check=True: equal to the reference, or LinkMismatch
    want = reference.evaluate(pop)
    assert np.array_equal(counts.distance, want.distance) and counts.cycles == 2 * (board.model.n_states + 1)
    assert np.array_equal(counts.fails, want.fails)
    assert not np.array_equal(counts.fails, evaluate_population(pop, board.model, rates=prior_codes()).fails)

    # WRITE_RATE of the wrong length: BAD_LENGTH, and the code stays (constant_rows(0) counts it)
    s = max(int(s) for s in board.model.states)
    line.write(encode_frame(Command.WRITE_RATE, bytes([s, 0, 255, 255]), tag=49))
    assert unpack(FrameHeader, line.read(7)[1:5]).status == Status.BAD_LENGTH.value

    # a LOAD_GENOME frame damaged after its rows went in: BAD_CRC, and EVALUATE refuses to run
    # on the touched rows until a good load
    frame = bytearray(encode_frame(Command.LOAD_GENOME, pack_index(0) + genome_payload(pop[1]), tag=50))
    frame[60] ^= 0x04
    line.write(bytes(frame))
    assert unpack(FrameHeader, line.read(7)[1:5]).status == Status.BAD_CRC.value
    with pytest.raises(LinkError, match="NOT_LOADED"):
        client.evaluate(1)
    last = board.evaluate(pop[1:])  # the board class reloads
    assert last.fails[0] == want.fails[1]
    before, after = client.read_counters(), client.read_counters()
    assert before["evaluator_cycles"] == counts.cycles + last.cycles and before["frames_rejected"] == 2
    assert after == {**before, "frames_ok": before["frames_ok"] + 1}


def test_link_counters_add_with_carries_across_bytes():
    """LinkCounters against Python integers: the byte-serial adds carry across bytes and wrap at
    the field's width; IDENTIFY's bytes are read back as given; a reset clears the counters."""
    from amaranth.hdl import ResetInserter, Signal
    from amaranth.sim import Simulator

    from hdl.link_counters import COUNTERS_BASE, IDENTIFY_BASE, LinkCounters
    from hdl.link_protocol import COUNTERS_REPLY, IDENTIFY_REPLY, layout_bytes

    rng = np.random.default_rng(SEED)
    identity = bytes(rng.integers(0, 256, layout_bytes(IDENTIFY_REPLY), dtype=np.uint8))
    dut = LinkCounters(identity)
    reset = Signal()
    adds = [int(a) for a in rng.integers(0, 1 << 32, 70, dtype=np.uint64)]
    seen = {}

    async def read(ctx, base, n):
        out = bytearray()
        for i in range(n):
            ctx.set(dut.addr, base + i)
            await ctx.tick()
            out.append(ctx.get(dut.data))
        return bytes(out)

    async def pulse(ctx, port):
        ctx.set(port, 1)
        await ctx.tick()
        ctx.set(port, 0)
        while ctx.get(dut.busy):
            await ctx.tick()

    async def bench(ctx):
        await ctx.tick().until(~dut.busy)  # the sweep after reset
        seen["identity"] = await read(ctx, IDENTIFY_BASE, len(identity))
        for i in range(300):
            await pulse(ctx, dut.count_ok)
            if i % 3 == 0:
                await pulse(ctx, dut.count_rejected)
        for a in adds:
            ctx.set(dut.cycles, a)
            await pulse(ctx, dut.add_cycles)
        seen["counters"] = await read(ctx, COUNTERS_BASE, layout_bytes(COUNTERS_REPLY))
        ctx.set(reset, 1)  # a reset sweeps the counters (the RAM itself keeps its bytes)
        await ctx.tick()
        ctx.set(reset, 0)
        await ctx.tick().until(~dut.busy)
        seen["after reset"] = await read(ctx, COUNTERS_BASE, layout_bytes(COUNTERS_REPLY))
        seen["identity after reset"] = await read(ctx, IDENTIFY_BASE, len(identity))

    sim = Simulator(ResetInserter(reset)(dut))
    sim.add_clock(1e-6)
    sim.add_testbench(bench)
    sim.run()
    assert seen["identity"] == identity
    got = unpack(COUNTERS_REPLY, seen["counters"])
    assert (got.frames_ok, got.frames_rejected, got.evaluator_cycles) == (300, 100, sum(adds) % (1 << 48))
    assert sum(adds) >= 1 << 32  # the adds carried into the fifth byte
    assert seen["after reset"] == bytes(layout_bytes(COUNTERS_REPLY))
    assert seen["identity after reset"] == identity


def pack_index(index: int) -> bytes:
    from hdl.link_protocol import LOAD_GENOME_REQUEST

    return pack(LOAD_GENOME_REQUEST, index=index)


def test_truncated_frame_is_answered_and_dropped():
    client, line = _client(ControllerLinkTop(CLK, BAUD, timeout_s=1e-4))
    line.write(encode_frame(Command.MOTION, b"\x05", tag=3)[:-2])  # the CRC never comes
    reply = line.read(7)
    assert unpack(FrameHeader, reply[1:5]).status == Status.TRUNCATED.value
    assert client.motion(5) == 0  # the link recovers: an empty controller drives forward (0)


# -- Verilator: the uart backend and the faults through the simulated line -------------------------


@pytest.mark.verilator
def test_uart_backend_short_run_equals_reference_and_faults(tmp_path, monkeypatch):
    from cosim.boards.cocotb_run import run_cocotb
    from cosim.launch.uart_sim import TOPLEVEL, prepare_uart_run
    from cosim.online.run import OnlineConfig, make_run
    from hdl.uart import max_baud

    # 18 generations, 194 interactions, crash, loop and time-out phases, the failure rates on (rate
    # codes written at each failure); population 10 on 8 slots: every evaluation is two chunks
    # (seed 10 since honest sensing, issue 36: seed 1 now takes 76 generations); the GA's and
    # detectors' values of before issue 36's tuning (under the tuned ones: 94 generations, no time-out)
    config = OnlineConfig(**pre_tuning(seed=10, arena="one_obstacle", n_targets=3, population=10,
                                       generations_per_phase=2, max_leg_steps=60, fail_rates=True))
    source, env = prepare_uart_run(config, tmp_path, baud=max_baud(25e6), p_max=8,
                                   build_name=f"{TOPLEVEL}_test")
    monkeypatch.syspath_prepend(str(TB_DIR))  # cocotb imports tb_link from the launcher's sys.path
    n_tests, _ = run_cocotb(sources=[source], toplevel=TOPLEVEL, test_module="cosim.launch.uart_test,tb_link",
                            test_dir=TB_DIR, build_name=f"{TOPLEVEL}_test", extra_env=env,
                            simulator="verilator")
    assert n_tests == 5
    summary = json.loads((tmp_path / "summary.json").read_text())
    reference = make_run(config).run().summary()
    keys = {"backend", "wall_time_s", "board_cycles", "hardware"}
    assert {k: v for k, v in summary.items() if k not in keys} == {k: v for k, v in reference.items() if k not in keys}
    link = json.loads((tmp_path / "link.json").read_text())["controller"]
    assert link["resends"] == 0 and link["bytes_sent"] > 126 * config.population * summary["generations"]
    assert link["by_command"]["WRITE_RATE"][0] >= 10 * 10  # frames of 10 bytes
    assert set(summary["phase_reasons"]) == {"crash", "loop", "timeout"}


# -- the serial backend's errors ------------------------------------------------------------------


def test_serial_backend_errors_name_the_port(monkeypatch, tmp_path, capsys):
    from cosim.cli.main import main

    monkeypatch.delenv("EHW_PORT", raising=False)
    assert main(["sim", "--backend", "serial", "--out", str(tmp_path / "run"), "--force", "--quiet"]) == 2
    assert "error: the serial backend needs a port" in capsys.readouterr().err
    monkeypatch.setenv("EHW_PORT", str(tmp_path / "ttyNONE"))
    assert main(["sim", "--backend", "serial", "--out", str(tmp_path / "run"), "--force", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and "ttyNONE: cannot open the serial port" in err and err.count("\n") == 1
    # a port that answers, but not with this protocol's replies (pyserial's loop:// echoes)
    monkeypatch.setenv("EHW_PORT", "loop://")
    assert main(["sim", "--backend", "serial", "--out", str(tmp_path / "run"), "--force", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: loop://: no board answers IDENTIFY") and err.count("\n") == 1, err


def test_wrong_design_and_silent_board_are_named():
    from cosim.link.boards import boards_over

    client, _ = _client(ControllerLinkTop(CLK, BAUD, timeout_s=1e-4))
    with pytest.raises(LinkError, match="amaranth ControllerLinkTop: the board is 'ehw-controller', expected 'ehw-system'"):
        boards_over([client])

    class Silent:
        port = "/dev/ttyFAKE"

        def write(self, data):
            return len(data)

        def read(self, n):
            return b""

        def reset_input_buffer(self):
            pass

    with pytest.raises(LinkError, match="/dev/ttyFAKE: no board answers IDENTIFY.*after 4 tries"):
        boards_over([LinkClient(Silent())])


def test_a_board_of_another_distance_rule_or_protocol_is_named():
    """IDENTIFY carries the distance rule the board's fitness counts (a circuit constant): a run of
    the other rule stops at IDENTIFY with one line naming both rules, not at the first controller
    whose distances differ; a bitstream whose IDENTIFY is a byte short (built before the rule was
    reported) is told to be rebuilt."""
    from cosim.link.boards import boards_over
    from cosim.link.emulated import EmulatedLine, EmulatedSystemBoard
    from hdl.link_protocol import IDENTIFY_REPLY, distance_rule_code, distance_rule_name, layout_bytes

    assert [distance_rule_name(distance_rule_code(r)) for r in (None, "covered", "forward")] == [None, "covered", "forward"]
    with pytest.raises(ValueError, match="unknown distance rule code 3"):
        distance_rule_name(3)
    assert LinkClient(EmulatedLine(EmulatedSystemBoard("covered"))).identify().distance_rule == "covered"
    boards_over([LinkClient(EmulatedLine(EmulatedSystemBoard("covered")))], distance_rule="covered")
    with pytest.raises(LinkError, match="counts the 'covered' distance rule, this run 'forward': run with --distance covered"):
        boards_over([LinkClient(EmulatedLine(EmulatedSystemBoard("covered")))], distance_rule="forward")

    class Stale(EmulatedSystemBoard):  # IDENTIFY without its last byte, as before the rule was in it
        def _identify(self, payload):
            return super()._identify(payload)[:-1]

    n = layout_bytes(IDENTIFY_REPLY)
    with pytest.raises(LinkError, match=f"IDENTIFY replied {n - 1} bytes, expected {n}: a bitstream built before"):
        boards_over([LinkClient(EmulatedLine(Stale()))])
