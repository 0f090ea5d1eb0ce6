"""Shared cases for the evaluator board: the same world models and genomes for the reference, the
Amaranth simulator (test_evaluator_ehw.py) and cocotb on the Verilog (cocotb_tb/tb_evaluator_ehw.py).

Also a few checks that the cases themselves cover what they claim (loops, crashes, free-space
self-loops, unknown transitions), so that a board passing them has been exercised.
"""

from __future__ import annotations

import numpy as np

from ga.evaluator import evaluate_population, evaluate_python
from ga.fail_rates import RATE_ONE, prior_codes
from ga.genome import N_ROWS
from ga.motions import REFLEX_STATES, make_state
from ga.world_model import WorldModel

CASE_SEED = 2026
GENOMES_PER_CASE = 3


def specific_rows(rng: np.random.Generator, count: int, p_literal: float = 0.65) -> np.ndarray:
    """(count, 50) genomes of specific rows: each literal connected (x or NOT x) with probability
    ``p_literal`` (about 5 literals a row, SPEC section 11), random outputs."""
    connected = rng.random((count, N_ROWS, 8)) < p_literal
    negated = rng.random((count, N_ROWS, 8)) < 0.5
    shift = 2 * np.arange(8) + negated
    rows = np.where(connected, np.left_shift(1, shift), 0).sum(axis=2).astype(np.uint32)
    return rows | (rng.integers(0, 8, size=(count, N_ROWS), dtype=np.uint32) << 16)


def constant_rows(motion: int) -> np.ndarray:
    """A genome whose one empty row fires always and drives ``motion``: F = motion everywhere."""
    rows = np.zeros(N_ROWS, dtype=np.uint32)
    rows[0] = motion << 16
    return rows


def random_model(rng, n_pool: int, n_obs: int, p_crash: float, motions=range(8), p_self=0.2) -> WorldModel:
    model = WorldModel()
    pool = rng.choice(256, size=n_pool, replace=False)
    free = rng.random(n_pool) < 0.25
    pool[free] = rng.choice(REFLEX_STATES, size=int(free.sum()))
    pool = np.unique(pool)
    model.visit(int(pool[0]))
    motions = np.asarray(list(motions))
    for _ in range(n_obs):
        s, s2 = (int(v) for v in rng.choice(pool, 2))
        if rng.random() < p_self:
            s2 = s
        model.observe(s, int(rng.choice(motions)), s2, bool(rng.random() < p_crash))
    return model


def case_rates(model: WorldModel, seed: int = CASE_SEED) -> list[tuple[int, int, int]]:
    """Failure-rate codes (``ga.fail_rates``) for the pairs of half the states of S, the others
    left at the prior: (state, motion, code) writes, codes 0..RATE_ONE."""
    rng = np.random.default_rng([seed, model.n_states])
    states = [int(s) for s in model.states if rng.random() < 0.5]
    return [(s, a, int(rng.integers(0, RATE_ONE + 1))) for s in states for a in range(8)]


def rate_table(changes) -> np.ndarray:
    """The (256, 8) codes a cleared board holds after ``changes``."""
    table = prior_codes()
    for s, a, code in changes:
        table[s, a] = code
    return table


def cases(seed: int = CASE_SEED):
    """[(name, model, population (P, 50) uint32, reflex)] with a fixed seed."""
    rng = np.random.default_rng(seed)
    out = []

    def add(name, model, extra=(), reflex=True):
        pop = [constant_rows(0), *extra, *specific_rows(rng, GENOMES_PER_CASE)]
        out.append((name, model, np.array(pop, dtype=np.uint32), reflex))

    add("empty", WorldModel())
    single = WorldModel()
    single.visit(9)
    add("single state, unknown", single)
    loop = WorldModel()
    loop.observe(make_state(0b000100, 1), 0, make_state(0b000100, 1), False)  # obstacle: a loop
    loop.observe(make_state(0, 0), 0, make_state(0, 0), False)  # free space: progress
    add("self-transitions", loop, reflex=False)
    crash = WorldModel()
    for s in (3, 70, 130, 255):
        for a in range(8):
            crash.observe(s, a, s, True)
    add("all crash", crash)
    add("small", random_model(rng, 8, 40, 0.1), [constant_rows(1)])
    add("forward only", random_model(rng, 30, 60, 0.05, motions=[0]), [constant_rows(0)], reflex=False)
    add("medium", random_model(rng, 40, 200, 0.1), [constant_rows(4)])
    add("large", random_model(rng, 130, 800, 0.1), [constant_rows(5)])
    return out


def test_cases_are_exercising():
    totals = np.zeros(3, dtype=np.int64)
    sizes = []
    for name, model, pop, reflex in cases():
        result = evaluate_population(pop, model, reflex)
        totals += [result.crashes.sum(), result.loops.sum(), result.distance.sum()]
        sizes.append(model.n_states)
        assert result.row(1) == evaluate_python(pop[1], model, reflex), name
    assert (totals > 0).all(), totals
    assert max(sizes) >= 100 and min(sizes) == 0
