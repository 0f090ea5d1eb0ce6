"""GA figures: time per generation outside fitness evaluation (population 500), and how often one
mutation changes the motion of a given world state (SPEC section 11)."""

from __future__ import annotations

import time

import numpy as np

from ga import operators as op
from ga.evolution import GAConfig, GeneticAlgorithm
from ga.genome import N_ROWS, ROW_BITS
from ga.motions import N_STATES, REFLEX_STATES
from ga.truth_table import truth_tables

_FREE = np.setdiff1d(np.arange(N_STATES), REFLEX_STATES)  # states the array decides


def _overhead() -> dict:
    # The on-line experiment's shape: population 500, tournament 20, elitism.
    ga = GeneticAlgorithm(GAConfig(population=500, tournament=20), np.random.default_rng(2026))
    fitness_rng = np.random.default_rng(7)
    fitness = [fitness_rng.random(500) for _ in range(60)]
    for f in fitness[:10]:  # warm up
        ga.tell(f)
    times = []
    for f in fitness[10:]:
        t0 = time.perf_counter()
        ga.ask()
        ga.tell(f)
        times.append(time.perf_counter() - t0)
    return {
        "ga_generation_overhead_s": round(float(np.median(times)), 6),
        "ga_generation_overhead_p90_s": round(float(np.percentile(times, 90)), 6),
    }


def _state_change(pop, mutated, sites_changed) -> float:
    """P(the motion of one given state changes) per mutation site, at low rates (changes/sites)."""
    changed = truth_tables(pop)[:, _FREE] != truth_tables(mutated)[:, _FREE]
    return float(changed.mean(axis=1).sum() / max(sites_changed, 1))


def _mutation_effects() -> dict:
    rng = np.random.default_rng(11)
    pop = op.random_population(rng, 2000)
    fields = op.literal_fields(pop)
    out = {}
    m = op.mutate_literals(rng, pop, 0.002)
    out["literal"] = _state_change(pop, m, int((op.literal_fields(m) != fields).sum()))
    m = op.mutate_outputs(rng, pop, 0.004)
    out["output_bit"] = _state_change(pop, m, int(np.unpackbits((m ^ pop).view(np.uint8)).sum()))
    m = op.switch_rows(rng, pop, 0.01)
    out["row_switch"] = _state_change(pop, m, int((m != pop).sum()))
    m = op.replace_rows(rng, pop, 0.01)
    out["row_replace"] = _state_change(pop, m, int((m != pop).sum()))
    # The baseline SPEC section 11 warns about: uniformly random bits, one raw bit flipped.
    uniform = rng.integers(0, 1 << ROW_BITS, size=(2000, N_ROWS), dtype=np.uint32)
    flips = uniform.copy()
    flips[np.arange(2000), rng.integers(0, N_ROWS, 2000)] ^= (
        np.uint32(1) << rng.integers(0, ROW_BITS, 2000).astype(np.uint32)
    )
    out["raw_bit_on_uniform_genomes"] = _state_change(uniform, flips, 2000)
    return {f"ga_p_state_change_{k}": round(v, 5) for k, v in out.items()}


def run() -> dict:
    return {**_overhead(), **_mutation_effects()}
