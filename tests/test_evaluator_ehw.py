"""EvaluatorEHW (hdl/evaluator_ehw.py) three ways on the shared cases (test_evaluator_cases.py):

(a) Amaranth's simulator against the reference ``ga.evaluator``, cycle budget 2N + 60 included;
(b) cocotb on the generated Verilog in Icarus (tests/cocotb_tb/tb_evaluator_ehw.py), same cases;
plus the handshake rules: writes while idle take effect at the next evaluation, a start (or a
model write) while busy is ignored, clear empties the model.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from amaranth.hdl import Shape
from amaranth.sim import Simulator
from test_evaluator_cases import case_rates, cases, constant_rows, random_model, rate_table, specific_rows

from ga.evaluator import evaluate_population
from ga.fail_rates import PRIOR_CODE
from ga.genome import N_ROWS
from ga.motions import OBSTACLE_MASK
from ga.world_model import WorldModel
from hdl.evaluator_ehw import RAM_DEPTH, EvaluatorEHW
from hdl.evaluator_sim import EvaluatorSimHost as SimHost
from hdl.ports import ModelEntry, ModelWriteSignature, RateWriteSignature, RowWriteSignature, write_rows

TB_DIR = Path(__file__).resolve().parent / "cocotb_tb"

# Constructor and port checks build components they never elaborate.
pytestmark = pytest.mark.filterwarnings("ignore::amaranth.hdl.UnusedElaboratable")


def run_sim(body, **options):
    """Run ``await body(host)`` in a fresh EvaluatorEHW(**options) under Amaranth's simulator."""
    dut = EvaluatorEHW(**options)

    async def testbench(ctx):
        host = SimHost(ctx, dut)
        await host.wait_ready()  # after reset the board sweeps its RAM (2048 cycles)
        await body(host)

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()


def reference_counts(pop, model, reflex):
    result = evaluate_population(pop, model, reflex)
    return [result.row(i) for i in range(len(pop))]


def test_amaranth_sim_matches_reference_on_shared_cases():
    seen = []

    async def body(host):
        for name, model, pop, reflex in cases():
            await host.ctx.tick()  # one idle cycle between cases
            host.ctx.set(host.dut.clear, 1)
            await host.tick()
            host.ctx.set(host.dut.clear, 0)
            await host.wait_ready()
            await host.write_model(model)
            await host.write_rates(case_rates(model))
            assert host.ctx.get(host.dut.n_states) == model.n_states, name
            want = reference_counts(pop, model, reflex)
            want_fails = evaluate_population(pop, model, reflex, rates=rate_table(case_rates(model))).fails
            n = model.n_states
            for i, rows in enumerate(pop):
                counts, cycles, cost = await host.evaluate(rows, reflex)
                assert counts == want[i], f"{name}, genome {i}: HDL {counts}, reference {want[i]}"
                assert host.fails() == want_fails[i], f"{name}, genome {i}: fails"
                assert cycles == n + 1, f"{name}: {cycles} cycles for N = {n}"
                assert cost <= 2 * n + 60, f"{name}: {cost} cycles per controller, N = {n}"
                seen.append((name, n, cost))

    run_sim(body)
    assert len(seen) == sum(len(pop) for _, _, pop, _ in cases())


def test_forward_distance_rule_matches_reference():
    """Both dist[a] rules in the HDL: the option ``distance_rule="covered"`` (the first reading,
    backward steps count) gives the reference's counts under that rule, another distance than the
    default ("forward", SPEC section 7)."""
    rng = np.random.default_rng(11)
    model = random_model(rng, 60, 400, 0.1)
    pop = specific_rows(rng, 6)
    want = evaluate_population(pop, model, True, distance_rule="covered")
    spec = evaluate_population(pop, model, True)
    assert (want.distance > spec.distance).any()  # the case exercises a backward step

    async def body(host):
        await host.write_model(model)
        for i, rows in enumerate(pop):
            counts, _, _ = await host.evaluate(rows, True)
            assert counts == want.row(i), f"genome {i}"

    run_sim(body, distance_rule="covered")
    with pytest.raises(ValueError, match="distance rule"):
        EvaluatorEHW(distance_rule="sideways")


def test_overlapped_loading_matches_and_hides_the_rows():
    rng = np.random.default_rng(5)
    model = random_model(rng, 70, 400, 0.1)
    pop = specific_rows(rng, 6)
    n = model.n_states
    assert n >= 50

    async def body(host):
        await host.write_model(model)
        counts, cycles, total = await host.evaluate_overlapped(pop)
        assert counts == reference_counts(pop, model, True)
        assert cycles == [n + 1] * len(pop)
        # 50 cycles to load the first controller, then one evaluation (+1 start cycle) each.
        assert total <= 50 + len(pop) * (n + 2), total

    run_sim(body)


def test_single_buffer_variant_matches_and_ignores_rows_while_busy():
    """double_buffer=False: rows go to the array directly, accepted only while idle."""
    name, model, pop, reflex = cases()[-2]  # "medium"
    want = reference_counts(pop, model, reflex)

    async def body(host):
        ctx, dut = host.ctx, host.dut
        await host.write_model(model)
        for i, rows in enumerate(pop):
            counts, cycles, cost = await host.evaluate(rows, reflex)
            assert counts == want[i] and cycles == model.n_states + 1, (name, i)
        # Rows written while busy are dropped: the array keeps pop[0].
        await host.evaluate(pop[0], reflex)
        ctx.set(dut.start, 1)
        await host.tick()
        ctx.set(dut.start, 0)
        for r, word in enumerate(pop[1]):
            assert ctx.get(dut.busy)
            ctx.set(dut.row.addr, r)
            ctx.set(dut.row.data, int(word))
            ctx.set(dut.row.we, 1)
            await host.tick()
            if ctx.get(dut.done):
                break
        ctx.set(dut.row.we, 0)
        await host.wait_ready()
        assert host.results()[0] == want[0]
        ctx.set(dut.start, 1)  # run again without loading: the array still holds pop[0]
        await host.tick()
        ctx.set(dut.start, 0)
        await host.wait_ready()
        assert host.results()[0] == want[0]
        with pytest.raises(ValueError, match="double_buffer"):
            await host.evaluate_overlapped(pop)

    run_sim(body, double_buffer=False)


def test_transitions_written_while_idle_count_at_the_next_evaluation():
    rows = constant_rows(0)  # forward everywhere (no reflex): follows the forward transitions

    async def body(host):
        model = WorldModel()
        model.visit(1)
        await host.write_model(model)
        assert (await host.evaluate(rows, reflex=False))[0] == (0, 0, 0)  # unknown transition
        for s, s2, crash in [(1, 2, False), (2, 1, False), (2, 2, True), (2, 3, False)]:
            # the host applies the update rule, then writes the resulting entry and the states
            await host.observe(model, s, 0, s2, crash)
            counts = (await host.evaluate(rows, reflex=False))[0]
            assert counts == reference_counts(rows[None], model, False)[0], (s, s2, crash)
        assert counts == (1, 0, 50)  # the crash (kept over 2 -> 3) ends the trace 1 -> 2; 3 unknown

    run_sim(body)


def test_start_and_writes_while_busy_are_ignored():
    rng = np.random.default_rng(9)
    model = random_model(rng, 60, 300, 0.1)
    rows = specific_rows(rng, 1)[0]
    n = model.n_states

    async def body(host):
        ctx, dut = host.ctx, host.dut
        await host.write_model(model)
        ctx.set(dut.reflex_en, 1)
        await write_rows(host.pins, "row", rows, strobe="start")
        ctx.set(dut.start, 1)  # held high while busy: ignored
        # While busy: hold start high, write a crash to every entry of one state, add a state,
        # ask for a clear. All of it must be ignored.
        victim = int(model.states[0])
        ctx.set(dut.clear, 1)
        ctx.set(dut.state_value, int(np.flatnonzero(~model.in_set)[0]))
        ctx.set(dut.state_we, 1)
        done_pulses, busy_edges = 0, 0
        for motion in range(8 * 4):
            host.set_entry(victim, motion % 8, victim, 1)
            assert ctx.get(dut.busy) and not ctx.get(dut.ready)
            await host.tick()
            busy_edges += 1
            done_pulses += ctx.get(dut.done)
            if ctx.get(dut.done):
                break
        for name in ("start", "clear", "state_we", "model__we"):
            host.pins.set(name, 0)
        while not ctx.get(dut.done):
            await host.tick()
            busy_edges += 1
        assert busy_edges == n + 1  # the repeated start did not restart the run
        counts, cycles = host.results()
        assert cycles == n + 1 and ctx.get(dut.n_states) == n
        assert counts == reference_counts(rows[None], model, True)[0]
        await host.tick()
        assert not ctx.get(dut.done) and ctx.get(dut.ready)  # done is a one-cycle pulse
        assert (await host.evaluate(rows))[0] == counts  # the model was not touched

    run_sim(body)


def test_clear_sweeps_the_model():
    rng = np.random.default_rng(3)
    model = random_model(rng, 20, 100, 0.3)
    rows = constant_rows(3)

    async def body(host):
        ctx, dut = host.ctx, host.dut
        await host.write_model(model)
        await host.write_rates((s, 3, 0) for s in model.states)
        assert (await host.evaluate(rows, reflex=False))[0] != (0, 0, 0)
        assert host.fails() == 0
        ctx.set(dut.clear, 1)
        await host.tick()
        ctx.set(dut.clear, 0)
        edges = 0
        while ctx.get(dut.busy):
            await host.tick()
            edges += 1
        assert edges == RAM_DEPTH and ctx.get(dut.n_states) == 0
        for s in model.states:  # S again, but no transition: every one is unknown
            await host.add_state(s)
        assert (await host.evaluate(rows, reflex=False))[0] == (0, 0, 0)
        assert host.fails() == PRIOR_CODE * int(((model.states & OBSTACLE_MASK) != 0).sum()) > 0

    run_sim(body)


def test_every_port_entry_survives_the_nine_bit_word():
    """The RAM word (``hdl.ports.ModelEntry``: 9 bits, so the 2048 entries fit one 2048 x 9 block
    RAM) keeps what the port's {next, crash, valid} says: each of the four (crash, valid), written
    in place over the previous one, with next states equal to the coding's own values (UNKNOWN,
    CRASH) or not, counts as the reference's model of that entry (a crash entry's next, which the
    word drops, is not the reference's either: never read)."""
    assert Shape.cast(ModelEntry).width == 9
    s, rows = 40, constant_rows(3)  # every state takes motion 3
    for t in (ModelEntry.UNKNOWN, ModelEntry.CRASH, 200):
        expected = []
        for crash, valid in ((0, 1), (1, 1), (1, 0), (0, 1), (0, 0)):
            model = WorldModel()
            for a in range(8):
                model.observe(t, a, s, False)  # t goes back to s: a loop when s goes to t
                if valid:
                    model.observe(s, a, t, bool(crash))
            expected.append(reference_counts(rows[None, :], model, reflex=False)[0])

        async def body(host, t=t):
            for state in (s, t):
                await host.add_state(state)
            for a in range(8):
                await host.write_entry(t, a, s, 0)
            got = []
            for crash, valid in ((0, 1), (1, 1), (1, 0), (0, 1), (0, 0)):
                for a in range(8):
                    await host.write_entry(s, a, t, crash, valid)
                got.append((await host.evaluate(rows, reflex=False))[0])
            assert got == expected

        run_sim(body)
    assert len({tuple(e) for e in expected}) > 2  # the cases differ: loop, crash, unknown


def test_world_model_ram_is_one_ecp5_block_ram(tmp_path):
    """Yosys's ECP5 memory mapping puts the learner lane's evaluator's world-model RAM into one
    DP16KD (2048 x 9: the trace loop closes on one block; the 10 bits of {next, crash, valid}
    took two, docs/learner.md "Resources and clock"), and the failure-rate codes into a second
    (2048 x 8, read beside it). Through map_ram only: seconds, not minutes."""
    from amaranth.back import rtlil

    from formal.yosys import INSTALL_HINT, available, run_script

    if not available():
        pytest.skip(f"formal extra not installed: {INSTALL_HINT}")
    dut = EvaluatorEHW(double_buffer=True, lookahead=True)  # as hdl.learner_lane.Lane has it
    (tmp_path / "top.il").write_text(rtlil.convert(dut, name="top", emit_src=False))
    run = run_script("read_rtlil top.il\nsynth_ecp5 -top top -run :map_ffram\n"
                     "select -assert-count 2 t:DP16KD\nselect -assert-count 2 t:DP16KD r:DATA_WIDTH_B=9\n"
                     "select -assert-count 1 t:DP16KD n:rate_ram.* %i\n",
                     tmp_path)
    assert run.returncode == 0, run.tail()


def test_constructor_and_ports():
    with pytest.raises(ValueError, match="0"):
        EvaluatorEHW(k=0)
    dut = EvaluatorEHW()
    members = dut.signature.members
    width = {name: Shape.cast(member.shape).width for name, member in members.items() if member.is_port}
    # the shared ports of hdl.ports, as the controller's and the system top's
    assert members["row"].signature == RowWriteSignature(N_ROWS).flip()
    assert members["model"].signature == ModelWriteSignature().flip()
    assert [len(dut.row.addr), len(dut.row.data), len(dut.model.state), len(dut.model.next)] == [6, 19, 8, 8]
    assert members["rate"].signature == RateWriteSignature().flip()
    assert (width["crashes"], width["loops"], width["distance"], width["fails"], width["cycles"]) == (9, 9, 16, 16, 16)


def test_verilog_ports(tmp_path):
    from hdl.generate import write_verilog

    text = write_verilog("evaluator_ehw", tmp_path).read_text()
    header = text[text.index("module evaluator_ehw("):]
    header = header[:header.index(";")]
    ports = set(re.findall(r"\w+", header)) - {"module", "evaluator_ehw"}
    for name in ("clk", "rst", "row__addr", "row__data", "row__we", "model__we", "start", "busy", "done",
                 "crashes", "loops", "distance", "fails", "cycles", "rate__code", "rate__we"):
        assert name in ports


def test_cocotb_verilog_forward_distance_rule_matches_reference(tmp_path):
    """The option distance_rule="forward" in the generated Verilog (the third way of the test above)."""
    from amaranth.back import verilog

    from cosim.boards.cocotb_run import icarus_time_zero_fix, run_cocotb

    src = tmp_path / "evaluator_ehw.v"
    text = verilog.convert(EvaluatorEHW(distance_rule="forward"), name="evaluator_ehw", emit_src=False)
    src.write_text(icarus_time_zero_fix(text))  # Icarus: Yosys's time-0 blocks (cosim.boards.cocotb_run)
    n_tests, _ = run_cocotb(
        sources=[src], toplevel="evaluator_ehw", test_module="tb_evaluator_ehw", test_dir=TB_DIR,
        build_name="evaluator_ehw_forward", testcase="distance_rule_matches_reference",
        extra_env={"EHW_DISTANCE_RULE": "forward"},
    )
    assert n_tests == 1


def test_state_set_helpers_equal_bit_select_and_shift_for_every_index():
    """The evaluator's bit test and one-hot (``_bit_of``, ``_one_hot``: word muxes, no wide shift)
    are the functions of ``bits.bit_select(index, 1)`` and ``1 << index``, for all 256 indices."""
    from amaranth.hdl import Module, Signal

    from hdl.evaluator_ehw import _bit_of, _one_hot

    m = Module()
    bits, index = Signal(256), Signal(8)
    bit = _bit_of(m, bits, index, "bit")
    hot = _one_hot(m, index, 256, "hot")
    pattern = int.from_bytes(np.random.default_rng(12).bytes(32), "little")
    seen = []

    async def testbench(ctx):
        for value in (pattern, ~pattern & ((1 << 256) - 1)):
            ctx.set(bits, value)
            for i in range(256):
                ctx.set(index, i)
                assert ctx.get(bit) == (value >> i) & 1, (i, value)
                assert ctx.get(hot) == 1 << i, i
                seen.append(i)

    sim = Simulator(m)
    sim.add_testbench(testbench)
    sim.run()
    assert len(seen) == 512
