"""Model-based evaluator: reference speed (NumPy vs the pseudo-code) and the HDL's cycle cost.

- ``evaluator_evals_per_s``: controllers per second of ``ga.evaluator.evaluate_population`` on a
  world model of 100 states, population 500 (truth tables included), best of 30, one core.
- ``evaluator_speedup_vs_python``: against ``evaluate_python`` (the SPEC pseudo-code with the
  row-by-row motion) measured in the same run; ``..._vs_pseudo_code_on_tables`` against the
  pseudo-code alone (``trace_counts`` given the truth tables), the fairer comparison of the
  trace algorithm itself.
- ``evaluator_cycles_per_state``: mean over the benchmark models of the HDL's clock cycles per
  controller / N, loading included, with the next controller's rows written while the current one
  runs (the board's normal mode); ``..._sequential``: rows first, then the evaluation.
  Measured in Amaranth's simulator.
- ``evaluator_ehw_evals_per_s``: controllers per second of the EHW evaluator in SystemTop (the
  streamer's exact cycle model, ``cosim.boards.hardware_time.stream_cycles``, population 500 on 100
  states) at the measured Fmax of its FPGA build (``..._clock``: which build, from
  results/fpga.json, or the named 12 MHz default without one); ``..._single_buffered`` the same
  for the two-iCEBreaker evaluator board (rows first, then the evaluation) at its own build's Fmax.
"""

from __future__ import annotations

import numpy as np

from benchmarks import best_time
from ga.evaluator import evaluate_population, evaluate_python, trace_counts
from ga.genome import N_ROWS
from ga.motions import REFLEX_STATES
from ga.truth_table import truth_tables
from ga.world_model import WorldModel

SEED = 2026
POPULATION = 500
HDL_MODEL_SIZES = (10, 25, 50, 100, 150)
HDL_CONTROLLERS = 4



def learned_model(rng: np.random.Generator, n_states: int, per_state: int = 4, p_crash: float = 0.1) -> WorldModel:
    """A model of exactly ``n_states`` states with about ``per_state`` known motions each: random
    transitions among the states, some crashes, a few free-space states."""
    pool = rng.choice(np.setdiff1d(np.arange(256), REFLEX_STATES), size=n_states, replace=False)
    pool[: min(4, n_states // 10)] = REFLEX_STATES[: min(4, n_states // 10)]
    model = WorldModel()
    for s in pool:
        model.visit(int(s))
        for a in rng.choice(8, size=per_state, replace=False):
            model.observe(int(s), int(a), int(rng.choice(pool)), bool(rng.random() < p_crash))
    assert model.n_states == n_states
    return model


def specific_rows(rng: np.random.Generator, count: int, p_literal: float = 0.65) -> np.ndarray:
    """Genomes of specific rows (about 5 literals each, SPEC section 11)."""
    connected = rng.random((count, N_ROWS, 8)) < p_literal
    negated = rng.random((count, N_ROWS, 8)) < 0.5
    rows = np.where(connected, np.left_shift(1, 2 * np.arange(8) + negated), 0).sum(axis=2)
    return rows.astype(np.uint32) | (rng.integers(0, 8, size=(count, N_ROWS), dtype=np.uint32) << 16)


def reference_figures(rng) -> dict:
    model = learned_model(rng, 100)
    pop = specific_rows(rng, POPULATION)
    evaluate_population(pop, model)  # warm up
    fast = best_time(lambda: evaluate_population(pop, model), 30) / POPULATION
    few = pop[:8]
    slow = best_time(lambda: [evaluate_python(g, model) for g in few], 2) / len(few)
    tables = truth_tables(few)
    pseudo = best_time(lambda: [trace_counts(t, model) for t in tables], 5) / len(few)
    result = evaluate_population(few, model)
    assert all(result.row(i) == evaluate_python(g, model) for i, g in enumerate(few))
    return {
        "evaluator_evals_per_s": round(1.0 / fast),
        "evaluator_500_ms": round(fast * POPULATION * 1e3, 3),
        "evaluator_python_evals_per_s": round(1.0 / slow, 1),
        "evaluator_speedup_vs_python": round(slow / fast, 1),
        "evaluator_speedup_vs_pseudo_code_on_tables": round(pseudo / fast, 1),
        "evaluator_model_states": model.n_states,
        "evaluator_model_transitions": model.n_transitions,
    }


def hardware_figures(rng) -> dict:
    from hdl.evaluator_sim import simulate_population

    per_state, per_state_seq, worst_margin = [], [], None
    for n in HDL_MODEL_SIZES:
        model = learned_model(rng, n)
        pop = specific_rows(rng, HDL_CONTROLLERS)
        want = evaluate_population(pop, model)
        for overlap, sink in ((True, per_state), (False, per_state_seq)):
            counts, cycles, total = simulate_population(model, pop, overlap=overlap)
            assert counts == [want.row(i) for i in range(len(pop))], (n, overlap)
            per_controller = total / len(pop)
            assert per_controller <= 2 * n + 60, (n, overlap, per_controller)
            margin = 2 * n + 60 - per_controller
            worst_margin = margin if worst_margin is None else min(worst_margin, margin)
            sink.append(per_controller / n)
    from cosim.boards.hardware_time import measured_clock, stream_cycles

    n_states = 100
    hz, source = measured_clock()
    per_controller_seq = float(np.interp(n_states, HDL_MODEL_SIZES, np.array(per_state_seq) * HDL_MODEL_SIZES))
    hz_sb, source_sb = measured_clock("icebreaker-evaluator")
    return {
        "evaluator_ehw_evals_per_s": round(POPULATION * hz / stream_cycles(POPULATION, n_states)),
        "evaluator_ehw_evals_per_s_clock": f"{hz / 1e6:g} MHz, {source}",
        "evaluator_ehw_evals_per_s_single_buffered": round(hz_sb / per_controller_seq),
        "evaluator_ehw_evals_per_s_single_buffered_clock": f"{hz_sb / 1e6:g} MHz, {source_sb}",
        "evaluator_cycles_per_state": round(float(np.mean(per_state)), 3),
        "evaluator_cycles_per_state_sequential": round(float(np.mean(per_state_seq)), 3),
        "evaluator_cycles_per_state_by_n": {str(n): round(v, 3) for n, v in zip(HDL_MODEL_SIZES, per_state)},
        "evaluator_cycles_margin_min": round(float(worst_margin), 1),  # min over models of 2N+60 - cycles
    }


def run() -> dict:
    rng = np.random.default_rng(SEED)
    figures = reference_figures(rng)
    figures.update(hardware_figures(rng))
    return figures
