"""HDL-in-the-loop figures: simulated clock cycles per second of the two HDL backends, on the
system top (controller EHW + evaluator EHW + population streamer) driven by ``SystemHost``.

    .venv/bin/python -m benchmarks bench_hdl

The workload is the learning phase's: a world model of ``N_STATES`` states (random, fixed seed),
one population of ``POPULATION`` controllers streamed through the evaluator (written, one
``go``, one wait, results read back), then ``INTERACTIONS`` execution-phase steps (a motion and
an observation each) through the board interface from a blocking thread (cocotb: ``bridge`` /
``resume``, as the experiment runs). Cycles/s counts every clock edge the call spent, transfers
included, per CPU second of the simulating process (``time.process_time``: steady on a shared
machine; ``*_per_wall_s`` beside it). The cocotb figures come from a cocotb test in this module
run by ``run_cocotb`` (the simulator and the cocotb Python run in one process), once on Icarus
(``cocotb_*``) and once on Verilator (``cocotb_verilator_*``).
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from base import environ

N_STATES = 84  # the paper's |S| at the 64th target
POPULATION = 100
INTERACTIONS = 300
RESULT_ENV = "EHW_BENCH_OUT"


def _workload(seed: int = 2026):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
    from test_evaluator_cases import random_model, specific_rows

    rng = np.random.default_rng(seed)
    model = random_model(rng, n_pool=N_STATES, n_obs=4 * N_STATES, p_crash=0.15)
    pop = specific_rows(rng, POPULATION)
    steps = [(int(rng.integers(256)), int(rng.integers(8)), int(rng.integers(256)), bool(rng.random() < 0.1))
             for _ in range(INTERACTIONS)]
    return model, pop, steps


def _measure(system, controller, evaluator, model, pop, steps) -> dict:
    """Blocking: the board calls, timed (``system.call`` runs a SystemHost job)."""
    host = system.host
    system.call(host.write_model, model)
    t0, c0 = time.perf_counter(), time.process_time()
    edges0 = host.evaluator_cycles + host.transfer_cycles
    counts = evaluator.evaluate(pop)
    t_eval, c_eval = time.perf_counter() - t0, time.process_time() - c0
    eval_edges = host.evaluator_cycles + host.transfer_cycles - edges0
    controller.load(pop[0])
    t0, c0 = time.perf_counter(), time.process_time()
    for s, a, s2, crashed in steps:
        controller.motion(s)
        evaluator.observe(s, a, s2, crashed)
    t_steps, c_steps = time.perf_counter() - t0, time.process_time() - c0
    return {
        "n_states": model.n_states,
        "eval_cycles": int(counts.cycles),
        # per CPU second of the simulating process (steady on a shared machine), and per wall second
        "eval_cycles_per_s": eval_edges / c_eval,
        "eval_cycles_per_wall_s": eval_edges / t_eval,
        "controllers_per_s": len(pop) / c_eval,
        "interactions_per_s": len(steps) / c_steps,
    }


# -- cocotb: a test run inside the simulator ------------------------------------------------------------

try:
    import cocotb
except ImportError:  # pragma: no cover
    cocotb = None

if cocotb is not None:

    @cocotb.test()
    async def throughput(dut):
        from cocotb.task import bridge

        from cosim.boards.amaranth_backend import HDLControllerBoard, HDLEvaluatorBoard
        from cosim.boards.cocotb_backend import CocotbSystem

        system = CocotbSystem(dut)
        await system.start()
        controller = HDLControllerBoard(system, check=False)
        evaluator = HDLEvaluatorBoard(system, check=False)
        figures = await bridge(_measure)(system, controller, evaluator, *_workload())
        Path(environ.read(RESULT_ENV)).write_text(json.dumps(figures))


def cocotb_figures(simulator: str = "icarus") -> dict:
    from cosim.boards.cocotb_run import REPO_ROOT, run_cocotb
    from cosim.launch.cocotb_sim import write_system_verilog

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "bench.json"
        src = write_system_verilog(tmp)
        run_cocotb(sources=[src], toplevel="system_top", test_module="benchmarks.bench_hdl",
                   test_dir=REPO_ROOT, build_name="system_top_bench", testcase="throughput",
                   extra_env={RESULT_ENV: str(out)}, waves=False, simulator=simulator)
        return json.loads(out.read_text())


def amaranth_figures() -> dict:
    from cosim.boards.amaranth_backend import AmaranthSystem, HDLControllerBoard, HDLEvaluatorBoard

    system = AmaranthSystem()
    controller = HDLControllerBoard(system, check=False)
    evaluator = HDLEvaluatorBoard(system, check=False)
    return _measure(system, controller, evaluator, *_workload())


def reference_figures() -> dict:
    from cosim.boards.registry import make_boards

    model, pop, steps = _workload()
    _, evaluator = make_boards("reference")
    evaluator.model = model.copy()
    evaluator.evaluate(pop)  # warm up
    t0 = time.process_time()
    for _ in range(10):
        evaluator.evaluate(pop)
    return {"controllers_per_s": 10 * len(pop) / (time.process_time() - t0)}


def run() -> dict:
    coco = cocotb_figures("icarus")
    veri = cocotb_figures("verilator")
    ama = amaranth_figures()
    ref = reference_figures()
    return {
        # cocotb_* = cocotb on Icarus; cocotb_verilator_* = the same test on Verilator
        "cocotb_cycles_per_s": round(coco["eval_cycles_per_s"]),
        "cocotb_verilator_cycles_per_s": round(veri["eval_cycles_per_s"]),
        "cocotb_verilator_controllers_per_s": round(veri["controllers_per_s"], 1),
        "cocotb_verilator_interactions_per_s": round(veri["interactions_per_s"], 1),
        "amaranth_cycles_per_s": round(ama["eval_cycles_per_s"]),
        "cocotb_cycles_per_wall_s": round(coco["eval_cycles_per_wall_s"]),
        "amaranth_cycles_per_wall_s": round(ama["eval_cycles_per_wall_s"]),
        "cocotb_controllers_per_s": round(coco["controllers_per_s"], 1),
        "amaranth_controllers_per_s": round(ama["controllers_per_s"], 1),
        "reference_controllers_per_s": round(ref["controllers_per_s"]),
        "cocotb_interactions_per_s": round(coco["interactions_per_s"], 1),
        "amaranth_interactions_per_s": round(ama["interactions_per_s"], 1),
        "hdl_bench_model_states": coco["n_states"],
        "hdl_bench_eval_cycles_per_controller": round(coco["eval_cycles"] / POPULATION, 2),
    }


if __name__ == "__main__":
    print(json.dumps(run(), indent=1))
