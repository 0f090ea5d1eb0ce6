"""GA operators: well-formed rows, specificity, tournament pressure, state-targeted mutation."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from ga import operators as op
from ga.genome import N_ROWS, ROW_MASK
from ga.truth_table import firing_sets, truth_tables


def _well_formed(pop):
    pop = np.asarray(pop)
    assert pop.dtype == np.uint32
    assert (pop <= ROW_MASK).all()
    assert not (op.literal_fields(pop) == op.CONTRADICTION).any()


def test_random_population_shape_and_form():
    pop = op.random_population(np.random.default_rng(0), 64)
    assert pop.shape == (64, N_ROWS)
    _well_formed(pop)


def test_random_rows_are_specific():
    rng = np.random.default_rng(1)
    pop = op.random_population(rng, 200, off_p=0.0)
    connected = (op.literal_fields(pop) != op.DONT_CARE).sum(-1)
    assert 5.3 < connected.mean() < 6.2  # the paper's 5-6 literals per term
    states = np.unpackbits(firing_sets(pop).view(np.uint8), axis=-1).sum(-1)
    assert np.median(states) <= 8
    assert (op.row_outputs(pop) != 0).all()


def test_off_fraction():
    pop = op.random_population(np.random.default_rng(2), 200, off_p=0.5)
    assert 0.45 < op.is_off(pop).mean() < 0.55


@given(st.integers(0, 2**32 - 1), st.floats(0, 0.2), st.floats(0, 0.2), st.floats(0, 0.2), st.floats(0, 0.2))
def test_mutations_keep_rows_well_formed(seed, lr, orate, sr, rr):
    rng = np.random.default_rng(seed)
    pop = op.random_population(rng, 5)
    out = op.mutate(rng, pop, lr, orate, sr, rr)
    _well_formed(out)
    assert out.shape == pop.shape


def test_mutation_rate_is_per_site():
    rng = np.random.default_rng(3)
    pop = op.random_population(rng, 400)
    out = op.mutate_literals(rng, pop, 0.01)
    changed = (op.literal_fields(out) != op.literal_fields(pop)).mean()
    assert 0.008 < changed < 0.012
    assert np.array_equal(op.row_outputs(out), op.row_outputs(pop))  # literals only
    out = op.mutate_outputs(rng, pop, 0.01)
    assert np.array_equal(out & 0xFFFF, pop & 0xFFFF)  # outputs only
    flips = np.unpackbits((out ^ pop).view(np.uint8)).sum() / (pop.size * 3)
    assert 0.008 < flips < 0.012


def test_literal_mutation_keeps_specificity():
    rng = np.random.default_rng(4)
    pop = op.random_population(rng, 100)
    before = (op.literal_fields(pop) != 0).mean()
    for _ in range(50):
        pop = op.mutate_literals(rng, pop, 0.05)
    after = (op.literal_fields(pop) != 0).mean()
    assert abs(after - before) < 0.05


def test_switch_rows_toggles_outputs_keeps_literals():
    rng = np.random.default_rng(5)
    pop = op.random_population(rng, 10)
    out = op.switch_rows(rng, pop, 1.0)
    assert np.array_equal(out & 0xFFFF, pop & 0xFFFF)
    assert np.array_equal(op.row_outputs(out) == 0, op.row_outputs(pop) != 0)


def test_zero_rates_change_nothing():
    rng = np.random.default_rng(6)
    pop = op.random_population(rng, 10)
    assert np.array_equal(op.mutate(rng, pop, 0, 0, 0, 0), pop)


def test_tournament_pressure():
    rng = np.random.default_rng(7)
    fitness = np.arange(20.0)
    winners = op.tournament(rng, fitness, 20000, 5)
    # P(best of 5 draws with replacement is the top individual) = 1 - (19/20)^5 = 0.226
    assert abs((winners == 19).mean() - (1 - (19 / 20) ** 5)) < 0.015
    assert (winners == 0).mean() < 1e-3  # the worst wins only if drawn 5 times: 20^-5
    # size 1: no pressure, every individual wins about equally often (2,000 draws of 20: 100 each)
    uniform = np.bincount(op.tournament(rng, fitness, 2000, 1), minlength=20)
    assert uniform.shape == (20,) and uniform.min() > 60 and uniform.max() < 140


def test_elite_order():
    assert list(op.elite([1.0, 5.0, 3.0, 5.0], 3)) == [1, 3, 2]


@pytest.mark.parametrize("crossover", sorted(op.CROSSOVERS))
def test_crossover_takes_whole_rows(crossover):
    rng = np.random.default_rng(8)
    a, b = op.random_population(rng, 30), op.random_population(rng, 30)
    child = op.CROSSOVERS[crossover](rng, a, b)
    assert ((child == a) | (child == b)).all()
    assert (child != a).any() and (child != b).any()


def test_row_fires_matches_reference():
    rng = np.random.default_rng(9)
    pop = op.random_population(rng, 3, off_p=0.0)
    sets = np.unpackbits(firing_sets(pop).view(np.uint8), axis=-1, bitorder="little")
    for s in (0, 17, 200, 255):
        assert np.array_equal(op.row_fires(pop, s), sets[..., s] == 1)


@given(st.integers(0, 2**32 - 1), st.integers(0, 255), st.integers(0, 7))
def test_set_state_motion(seed, state, motion):
    rng = np.random.default_rng(seed)
    g = op.random_population(rng, 1)[0]
    h = op.set_state_motion(rng, g, state, motion)
    _well_formed(h)
    assert op.motion_in_state(h, state) == motion
    assert truth_tables(h, reflex=False)[state] == motion


def test_avoid_state_motion_changes_motion():
    rng = np.random.default_rng(10)
    g = op.random_population(rng, 1)[0]
    for s in range(0, 256, 7):
        assert op.motion_in_state(op.avoid_state_motion(rng, g, s), s) != op.motion_in_state(g, s)


def test_set_state_motion_is_local():
    rng = np.random.default_rng(11)
    changed = []
    for _ in range(200):
        g = op.random_population(rng, 1)[0]
        s, m = int(rng.integers(256)), int(rng.integers(8))
        h = op.set_state_motion(rng, g, s, m)
        changed.append((truth_tables(h, reflex=False) != truth_tables(g, reflex=False)).sum())
    assert np.mean(changed) < 16


def test_bad_arguments_are_quoted():
    rng = np.random.default_rng(12)
    with pytest.raises(ValueError, match="1.5"):
        op.random_population(rng, 3, literal_p=1.5)
    with pytest.raises(ValueError, match="9"):
        op.set_state_motion(rng, op.random_population(rng, 1)[0], 3, 9)


def test_diversity_counts_behaviours_and_entropy_on_the_given_states():
    from ga.diversity import diversity
    from ga.truth_table import truth_tables

    g = op.random_population(np.random.default_rng(4), 2)
    states = [1, 3, 65]
    same = diversity(np.stack([g[0]] * 4), states)
    assert same == {"distinct_behaviours": 1, "mean_entropy_bits": 0.0}
    mixed = diversity(np.stack([g[0], g[0], g[1], g[1]]), states)
    differ = (truth_tables(g[0]) != truth_tables(g[1]))[states]
    assert differ.any() and mixed["distinct_behaviours"] == 2
    assert mixed["mean_entropy_bits"] == round(differ.mean(), 4)  # 1 bit where the two differ
    assert diversity(g, []) == {"distinct_behaviours": 0, "mean_entropy_bits": 0.0}
