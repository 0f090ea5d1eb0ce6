"""cocotb testbench: the generated system_top Verilog (controller EHW + evaluator EHW + population
streamer) driven through ``hdl.system_top.SystemHost``, the protocol the cocotb backend uses.

- evaluator: the shared evaluator cases (tests/test_evaluator_cases.py) streamed as one population
  per world model, with their failure-rate codes written after a clear, results (fails included)
  against ``ga.evaluator``; the cycles of a stream against the bound
  P * max(N + 2, 50) + N + 4;
- a population larger than the streamer's RAM (split into streams) and a one-controller stream;
- world-model writes through ``observe`` (update rule on the host, crash entries kept);
- controller: a few shared vectors downloaded, all 256 motions against ``ga.truth_table``, with a
  population stream in between (the two boards are independent).

Started from pytest by tests/test_backends.py.
"""

from __future__ import annotations

import sys
from pathlib import Path

import cocotb
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # tests/, for the shared cases

from test_evaluator_cases import case_rates, cases, rate_table, specific_rows  # noqa: E402

from cosim.boards.cocotb_backend import CocotbSystem  # noqa: E402
from ga.evaluator import evaluate_population  # noqa: E402
from ga.fail_rates import prior_codes  # noqa: E402
from ga.truth_table import truth_tables  # noqa: E402
from ga.world_model import WorldModel  # noqa: E402


def expected(pop, model, reflex, rates=None):
    """(crashes, loops, distance, fails) of each controller; ``rates``: the board's codes (default:
    a cleared board's)."""
    result = evaluate_population(pop, model, reflex, rates=prior_codes() if rates is None else rates)
    return [(*result.row(i), int(result.fails[i])) for i in range(len(pop))]


@cocotb.test()
async def evaluator_cases(dut):
    system = CocotbSystem(dut)
    await system.start()
    host = system.host
    for name, model, pop, reflex in cases():
        await host.clear()
        await host.write_model(model)
        await host.write_rates(case_rates(model))
        host.set_reflex(reflex)
        counts, cycles = await host.evaluate(pop)
        assert counts == expected(pop, model, reflex, rate_table(case_rates(model))), name
        n = model.n_states
        assert cycles <= len(pop) * max(n + 2, 50) + n + 4, (name, cycles, len(pop), n)


@cocotb.test()
async def streams_and_observe(dut):
    system = CocotbSystem(dut)
    await system.start()
    host = system.host
    rng = np.random.default_rng(7)
    mirror = WorldModel()
    pool = rng.choice(256, size=30, replace=False)
    for _ in range(120):
        s, s2 = (int(v) for v in rng.choice(pool, 2))
        a, crashed = int(rng.integers(8)), bool(rng.random() < 0.2)
        await host.observe(s, a, s2, crashed)
        mirror.observe(s, a, s2, crashed)
    assert dut.ev_n_states.value.to_unsigned() == mirror.n_states
    host.set_reflex(True)
    pop = specific_rows(rng, 2 * host.p_max + 3)  # three streams
    counts, _ = await host.evaluate(pop)
    assert counts == expected(pop, mirror, True)
    counts, cycles = await host.evaluate(pop[:1])  # one controller
    assert counts == expected(pop[:1], mirror, True)
    assert cycles == 53 + mirror.n_states, cycles  # go, 50 rows, N + 1, pop_done


@cocotb.test()
async def controller_motions(dut):
    from vectors import population

    _, genomes = population()
    system = CocotbSystem(dut)
    await system.start()
    host = system.host
    rng = np.random.default_rng(3)
    for i in (0, 7, 30, 55, len(genomes) - 1):
        rows = genomes[i]
        reflex = bool(i % 2)
        host.set_reflex(reflex)
        await host.load(rows)
        if i == 30:  # a stream between the download and the motions changes nothing
            await host.evaluate(specific_rows(rng, 3))
        table = truth_tables(rows, reflex=reflex)
        got = [await host.motion(s) for s in range(256)]
        assert got == table.tolist(), i
