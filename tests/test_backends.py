"""The three board backends (SPEC section 9).

- The system top (controller EHW + evaluator EHW + population streamer) under cocotb on the
  shared evaluator cases and controller vectors (tests/cocotb_tb/tb_system.py).
- The cycle model of a population stream (``cosim.boards.hardware_time.stream_cycles``) against the
  simulated ``pop_cycles`` (Amaranth's simulator).
- Equivalence: one short on-line run (one obstacle, 3 targets, population 16, the failure rates
  on: ``ga.fail_rates``, codes written to the evaluator at each failure) on the reference,
  Amaranth and cocotb backends (cocotb on Icarus and on Verilator) gives the identical sequence of
  motions, downloaded controllers, evaluation results (fails included), interactions,
  generations and counts; the HDL backends report the same clock cycles, equal to the cycle
  model. The default config (no failure rates) on the HDL: the distance-rule run at the end.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from pre_tuning import pre_tuning

from cosim.online.run import OnlineConfig, OnlineRun, make_run

TB_DIR = Path(__file__).resolve().parent / "cocotb_tb"

pytestmark = pytest.mark.filterwarnings("ignore::amaranth.hdl.UnusedElaboratable")

# Short enough for `make test` (a few seconds per backend: 14 generations, 7 learning phases, with
# the GA's and detectors' values of before issue 36's tuning, under which this lifetime takes 84
# phases and no time-out), long enough for crash, loop and time-out phases, targets and rate codes
# written at each failure (seed 21 since honest sensing, issue 36; seed 25 since round 18's progress codes; seed 17 since
# round 16, seed 4 before).
SHORT = OnlineConfig(**pre_tuning(seed=21, arena="one_obstacle", n_targets=3, population=16, generations_per_phase=2,
                                  max_leg_steps=60, fail_rates=True))
# Summary keys that legitimately differ between backends.
BACKEND_KEYS = {"backend", "wall_time_s", "board_cycles", "hardware"}


def comparable(summary: dict) -> dict:
    return {k: v for k, v in summary.items() if k not in BACKEND_KEYS}


@pytest.fixture(scope="module")
def reference_run():
    from cosim.boards.amaranth_backend import LoggedBoards
    from cosim.boards.registry import make_boards

    boards = LoggedBoards(*make_boards("reference"))
    run = OnlineRun(SHORT, boards.controller, boards.evaluator, backend="reference").run()
    return run.summary(), boards.log.to_dict(run.motions), boards.evaluator.rates.copy()


@pytest.fixture(scope="module")
def amaranth_run():
    run = make_run(SHORT, "amaranth").run()
    return run.summary(), run.controller.log.to_dict(run.motions)


@pytest.fixture(scope="module")
def amaranth_sampled_run():
    """Spot-check mode: the HDL evaluates 3 controllers of each population, checked against the
    reference, whose counts drive the GA."""
    from cosim.boards.amaranth_backend import make_amaranth_boards

    controller, evaluator = make_amaranth_boards(sample=3)
    run = OnlineRun(SHORT, controller, evaluator, backend="amaranth").run()
    assert evaluator.simulated_cycles < evaluator.cycles
    return run.summary(), controller.log.to_dict(run.motions)


# The HDL runs build in build/sim/<build name>_*: the Icarus and the Verilator run each get their
# own name, and each pytest-xdist worker its own: a module fixture runs once in every worker that
# needs it, and two workers building in one folder corrupted each other's C++. The Verilator run
# is needed by one test only, so it is built once.
WORKER = os.environ.get("PYTEST_XDIST_WORKER", "main")


@pytest.fixture(scope="module")
def cocotb_run(tmp_path_factory):
    from cosim.launch.cocotb_sim import run_online_cocotb

    out = tmp_path_factory.mktemp("cocotb_online")
    summary = run_online_cocotb(SHORT, out, build_name=f"system_top_online_test_icarus_{WORKER}")
    return summary, json.loads((out / "board_log.json").read_text())


@pytest.fixture(scope="module")
def cocotb_verilator_run(tmp_path_factory):
    from cosim.launch.cocotb_sim import run_online_cocotb

    out = tmp_path_factory.mktemp("cocotb_verilator_online")
    summary = run_online_cocotb(SHORT, out, build_name=f"system_top_online_test_{WORKER}", simulator="verilator")
    return summary, json.loads((out / "board_log.json").read_text())


def test_short_run_exercises_the_loop(reference_run):
    from ga.fail_rates import PRIOR_CODE

    summary, log, rates = reference_run
    assert summary["targets_reached"] == SHORT.n_targets
    assert summary["learning_phases"] >= 3 and set(summary["phase_reasons"]) == {"crash", "loop", "timeout"}
    assert (rates != PRIOR_CODE).sum() >= 10  # codes written to the evaluator
    assert all(phase["best_fails"] > 0 for phase in summary["phases"])
    assert len(log["downloads"]) == summary["learning_phases"] + 1  # the random start, then one a phase
    assert len(log["evaluations"]) == summary["generations"]
    assert len(set(log["evaluations"])) > 1


def assert_identical(backend: str, run, reference_run) -> None:
    (summary, log), (ref_summary, ref_log) = run[:2], reference_run[:2]
    assert summary["backend"] == backend.split("_")[0]
    assert log["motions"] == ref_log["motions"]
    assert log["downloads"] == ref_log["downloads"]
    assert log["evaluations"] == ref_log["evaluations"]
    assert comparable(summary) == comparable(ref_summary)


@pytest.mark.parametrize("backend", ["amaranth", "amaranth_sampled", pytest.param("cocotb", marks=pytest.mark.cocotb)])
def test_backend_is_identical_to_reference(backend, reference_run, request):
    assert_identical(backend, request.getfixturevalue(f"{backend}_run"), reference_run)


@pytest.mark.cocotb
@pytest.mark.verilator
def test_verilator_is_identical_and_hdl_backends_count_the_same_cycles(amaranth_run, cocotb_run,
                                                                       cocotb_verilator_run, reference_run):
    assert_identical("cocotb_verilator", cocotb_verilator_run, reference_run)
    ama, coco, veri, ref = (run[0] for run in (amaranth_run, cocotb_run, cocotb_verilator_run, reference_run))
    assert ama["board_cycles"] == coco["board_cycles"] == veri["board_cycles"]
    assert ama["board_cycles"]["evaluator"] > 0 and ama["board_cycles"]["controller"] > 0
    for hw in (ama["hardware"], coco["hardware"], veri["hardware"]):
        assert hw["evaluator_cycles_source"] == "simulated"
        assert hw["evaluator_cycles"] == hw["evaluator_cycles_model"] == ref["hardware"]["evaluator_cycles"]
    assert ref["hardware"]["evaluator_cycles_source"] == "model"
    from cosim.boards.hardware_time import measured_clock

    hz, source = measured_clock()  # results/fpga.json's Fmax after make bitstream, else 12 MHz
    for hw in (ama["hardware"], coco["hardware"], veri["hardware"], ref["hardware"]):
        assert (hw["clock_hz"], hw["clock_source"]) == (hz, source)
    assert coco["hardware"]["evaluator_time_s"] == pytest.approx(coco["hardware"]["evaluator_cycles"] / hz)


def test_stream_cycle_model_matches_the_hdl():
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from test_evaluator_cases import random_model, specific_rows

    from cosim.boards.amaranth_backend import AmaranthSystem
    from cosim.boards.hardware_time import stream_cycles

    system = AmaranthSystem()
    host = system.host
    rng = np.random.default_rng(5)
    for n_pool, population in ((0, 3), (12, 4), (40, 2), (70, 3)):
        system.call(host.clear)
        n_states = 0
        if n_pool:
            model = random_model(rng, n_pool=n_pool, n_obs=3 * n_pool, p_crash=0.2)
            system.call(host.write_model, model)
            n_states = model.n_states
        _, cycles = system.call(host.evaluate, specific_rows(rng, population))
        assert cycles == stream_cycles(population, n_states), (n_states, population)
    assert stream_cycles(1000, 10) == stream_cycles(512, 10) + stream_cycles(488, 10)


def test_stream_cycle_model_errors():
    from cosim.boards.hardware_time import stream_cycles

    with pytest.raises(ValueError, match="-1"):
        stream_cycles(-1, 3)


def test_cocotb_backend_outside_the_simulator_says_how_to_start_it():
    from cosim.boards.registry import make_boards

    with pytest.raises(RuntimeError, match="inside the simulator"):
        make_boards("cocotb")


@pytest.mark.cocotb
def test_cocotb_system_top_matches_reference(tmp_path):
    from cosim.boards.cocotb_backend import P_MAX_ENV
    from cosim.boards.cocotb_run import run_cocotb
    from cosim.launch.cocotb_sim import write_system_verilog

    src = write_system_verilog(tmp_path, p_max=16)
    assert "initial \\$auto" in src.read_text()  # the time-0 fix (hdl.generate) found Yosys's trigger registers
    n_tests, _ = run_cocotb(sources=[src], toplevel="system_top", test_module="tb_system",
                            test_dir=TB_DIR, build_name="system_top_tb", extra_env={P_MAX_ENV: "16"})
    assert n_tests == 3


def test_streamer_ignores_writes_and_go_while_busy():
    """pop_we and go during a stream change nothing: results (rate codes written first: fails
    too) and cycles as without them."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from test_evaluator_cases import case_rates, random_model, rate_table, specific_rows

    from cosim.boards.amaranth_backend import AmaranthSystem
    from cosim.boards.hardware_time import stream_cycles
    from ga.evaluator import evaluate_population
    from hdl.system_top import genome_words, unpack_result

    system = AmaranthSystem()
    host, pins = system.host, system.pins
    rng = np.random.default_rng(11)
    model = random_model(rng, n_pool=20, n_obs=60, p_crash=0.2)
    pop = specific_rows(rng, 3)
    system.call(host.write_model, model)
    system.call(host.write_rates, case_rates(model))

    async def meddling_stream():
        await host.start_stream(genome_words(pop))
        for _ in range(60):  # mid-stream: overwrite every genome with an empty one, and go again
            assert pins.get("pop_busy")
            pins.set("pop_addr", int(rng.integers(len(pop))))
            pins.set("pop_data", 0)
            pins.set("pop_we", 1)
            pins.set("pop_size", 1)
            await pins.tick()
        pins.set("pop_we", 0)
        pins.set("go", 0)
        await pins.wait("pop_done")
        cycles = pins.get("pop_cycles")
        results = []
        for i in range(len(pop)):
            pins.set("res_addr", i)
            await pins.tick()
            results.append(unpack_result(pins.get("res_data")))
        return results, cycles

    results, cycles = system.call(meddling_stream)
    expected = evaluate_population(pop, model, True, rates=rate_table(case_rates(model)))
    assert results == [(*expected.row(i), int(expected.fails[i])) for i in range(len(pop))]
    assert expected.fails.min() > 0 and cycles == stream_cycles(len(pop), model.n_states)


def test_unknown_simulator_is_refused(monkeypatch):
    from cosim.boards.cocotb_run import SIM_ENV, run_cocotb, simulator_default

    monkeypatch.setenv(SIM_ENV, "modelsim")
    with pytest.raises(ValueError, match="modelsim"):
        simulator_default()
    monkeypatch.delenv(SIM_ENV)
    assert simulator_default() == "icarus"
    with pytest.raises(ValueError, match="ghdl"):
        run_cocotb(sources=[], toplevel="x", test_module="x", test_dir=".", simulator="ghdl")


def test_first_reading_distance_rule_on_the_amaranth_boards():
    """The option distance_rule="covered" (the paper's first reading; the default is SPEC section
    7's "forward") reaches the evaluator EHW: every population is evaluated on the HDL and checked
    against the reference under the same rule (a mismatch raises), and the lifetime is the
    reference's, another one than under the default dist[a]. Its first 6 learning phases (12
    populations of 16 on the HDL; the whole lifetime, 58 phases, took 62-76 s of the suite).
    Without the failure rates (the default): the HDL boards' fails are ignored."""
    import dataclasses

    config = dataclasses.replace(SHORT, seed=1, distance_rule="covered", fail_rates=False)
    hdl = make_run(config, "amaranth").run(stop_after_phases=6)
    assert hdl.evaluator.reference.distance_rule == "covered" and len(hdl.phases) == 6
    reference = make_run(config, "reference").run(stop_after_phases=6)
    default = make_run(dataclasses.replace(config, distance_rule="forward"), "reference").run(stop_after_phases=6)
    assert comparable(hdl.summary()) == comparable(reference.summary())
    assert hdl.motions == reference.motions != default.motions
