"""The evaluator path of the cocotb backend on Verilator, per CPU second: the table "Speeding up
the Verilator run" of docs/hdl_in_the_loop.md.

    .venv/bin/python experiments/verilator_throughput.py [--clock inside|gpi] [--populations 10]

Builds ``system_top`` (``--clock gpi``: cocotb's GPI clock drives its clk input, as the benches
do) or ``system_top_clocked`` (``--clock inside``: the clock generated in the Verilog, as the
lifetime run does) in Verilator and streams populations of 500 controllers through the evaluator
EHW on a random world model of 65 states (fixed seed), every result checked against the
reference, from cocotb's bridge thread as the lifetime does. Prints (and writes to
``build/experiments/verilator_throughput_<clock>.json``) the clock edges per CPU second of the
simulating process (Verilated model, cocotb and the Python host together) and a digest of the
results (equal across variants and commits when the evaluator is bit-exact).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT_ENV = "EHW_THROUGHPUT_OUT"
POPULATIONS_ENV = "EHW_THROUGHPUT_POPULATIONS"


def _measure(system, evaluator, populations: int) -> dict:
    """Blocking (the bridge thread): write the model, stream the populations, time it."""
    sys.path.insert(0, str(ROOT / "tests"))
    from test_evaluator_cases import random_model, specific_rows

    rng = np.random.default_rng(2026)
    model = random_model(rng, n_pool=84, n_obs=4 * 84, p_crash=0.15)
    pops = [specific_rows(rng, 500) for _ in range(populations)]
    host = system.host
    system.call(host.reflex, True)
    system.call(host.write_model, model)
    evaluator.reference.model = model.copy()
    c0, t0 = time.process_time(), time.perf_counter()
    edges0 = host.evaluator_cycles + host.transfer_cycles
    digest = 0
    for pop in pops:
        counts = evaluator.evaluate(pop)  # checked against the reference (BoardMismatch)
        digest = hash((digest, tuple(counts.crashes.tolist()), tuple(counts.distance.tolist())))
    cpu = time.process_time() - c0
    edges = host.evaluator_cycles + host.transfer_cycles - edges0
    return {"n_states": model.n_states, "populations": populations, "edges": edges, "cpu_s": round(cpu, 3),
            "wall_s": round(time.perf_counter() - t0, 3), "edges_per_cpu_s": round(edges / cpu),
            "digest": digest & 0xFFFFFFFF}


try:
    import cocotb
except ImportError:  # pragma: no cover
    cocotb = None

if cocotb is not None:

    @cocotb.test()
    async def throughput(dut):
        from cocotb.task import bridge

        from cosim.boards.amaranth_backend import HDLEvaluatorBoard
        from cosim.boards.cocotb_backend import CocotbSystem

        system = CocotbSystem(dut)
        await system.start()
        evaluator = HDLEvaluatorBoard(system, check=True)
        figures = await bridge(_measure)(system, evaluator, int(os.environ[POPULATIONS_ENV]))
        Path(os.environ[OUT_ENV]).write_text(json.dumps(figures))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--clock", choices=("inside", "gpi"), default="inside")
    parser.add_argument("--populations", type=int, default=10)
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT))
    from cosim.boards.cocotb_backend import CLOCK_INSIDE_ENV
    from cosim.launch.cocotb_sim import CLOCKED_TOPLEVEL, TOPLEVEL, write_system_verilog
    from cosim.boards.cocotb_run import SIM_BUILD, run_cocotb

    inside = args.clock == "inside"
    name = f"verilator_throughput_{args.clock}"
    out = ROOT / "build" / "experiments" / f"{name}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    source = write_system_verilog(SIM_BUILD / f"{name}_verilog", clock_inside=inside)
    run_cocotb(sources=[source], toplevel=CLOCKED_TOPLEVEL if inside else TOPLEVEL,
               test_module="experiments.verilator_throughput", test_dir=ROOT, build_name=name,
               testcase="throughput", waves=False, simulator="verilator", timing=inside,
               extra_env={OUT_ENV: str(out), POPULATIONS_ENV: str(args.populations),
                          CLOCK_INSIDE_ENV: str(int(inside))})
    figures = json.loads(out.read_text())
    print(f"# .venv/bin/python experiments/verilator_throughput.py --clock {args.clock} --populations {args.populations}")
    print(" ".join(f"{key}={value}" for key, value in figures.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
