"""Reference evaluator of SPEC section 7: the vectorised NumPy version against the pseudo-code."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from ga.evaluator import (EvalResult, evaluate_population, evaluate_python, evaluate_tables, fitness,
                          trace_counts)
from ga.genome import N_ROWS
from ga.motions import MAX_MOTION_DISTANCE_MM, MOTION_DISTANCE_MM, Motion, REFLEX_STATES, make_state
from ga.world_model import WorldModel

FREE_STATES = [int(s) for s in REFLEX_STATES]  # no obstacle bit: a self-transition is progress


def random_model(rng, n_pool, n_obs, p_crash, p_free=0.3, motions=8):
    """A model learned from ``n_obs`` random observations among ``n_pool`` states."""
    model = WorldModel()
    pool = rng.choice(256, size=n_pool, replace=False)
    pool[rng.random(n_pool) < p_free] = rng.choice(FREE_STATES)  # free-space states (repeats ok)
    pool = np.unique(pool)
    model.visit(int(pool[0]))
    for _ in range(n_obs):
        s, s2 = (int(v) for v in rng.choice(pool, 2))
        if rng.random() < 0.2:
            s2 = s  # self-transitions, with and without obstacle bits
        model.observe(s, int(rng.integers(motions)), s2, bool(rng.random() < p_crash))
    return model


def random_tables(rng, count, motions):
    """Truth tables drawing each state's motion from ``motions`` (few motions: more hits)."""
    return rng.choice(np.asarray(motions, dtype=np.uint8), size=(count, 256))


def assert_agrees(tables, model, distance_rule="covered"):
    result = evaluate_tables(tables, model, distance_rule)
    for i, table in enumerate(tables):
        assert result.row(i) == trace_counts(table, model, distance_rule), f"table {i}"
    return result


@settings(max_examples=300)
@given(seed=st.integers(0, 2**32 - 1), n_pool=st.integers(1, 20), n_obs=st.integers(0, 80),
       p_crash=st.sampled_from([0.0, 0.1, 0.5, 1.0]), n_motions=st.integers(1, 8),
       distance_rule=st.sampled_from(["covered", "forward"]))
def test_vectorised_agrees_with_pseudo_code(seed, n_pool, n_obs, p_crash, n_motions, distance_rule):
    rng = np.random.default_rng(seed)
    motions = rng.choice(8, size=n_motions, replace=False)
    model = random_model(rng, n_pool, n_obs, p_crash, motions=8 if n_obs % 2 else n_motions)
    assert_agrees(random_tables(rng, 20, motions), model, distance_rule)


def test_forward_distance_rule_pays_only_forward_translation():
    """dist[a]: SPEC section 7's "forward" (the default) counts forward translation only (forward,
    forward-left, forward-right); the first reading, "covered", every translation, with the same
    maximum."""
    from ga.motions import motion_distances

    assert motion_distances().tolist() == motion_distances("forward").tolist() == [50, 0, 0, 0, 50, 50, 0, 0]
    assert motion_distances("covered").tolist() == MOTION_DISTANCE_MM.tolist() == [50, 50, 0, 0, 50, 50, 50, 50]
    wall = make_state(1 << 3, 1)  # obstacle left, ball left
    model = WorldModel()
    model.observe(wall, Motion.BACKWARD_RIGHT, 0, False)
    back = np.full((1, 256), Motion.BACKWARD_RIGHT, dtype=np.uint8)
    assert evaluate_tables(back, model, "covered").row(0) == (0, 0, 50)
    assert evaluate_tables(back, model).row(0) == evaluate_tables(back, model, "forward").row(0) == (0, 0, 0)
    with pytest.raises(ValueError, match="distance rule"):
        motion_distances("backward")


@settings(max_examples=20)
@given(seed=st.integers(0, 2**32 - 1), reflex=st.booleans())
def test_population_agrees_with_pseudo_code_on_genomes(seed, reflex):
    rng = np.random.default_rng(seed)
    model = random_model(rng, int(rng.integers(1, 60)), int(rng.integers(0, 300)), 0.1)
    # Specific rows (about 5 literals each) so that motions vary from state to state.
    literal = rng.integers(0, 4, size=(4, N_ROWS, 8))  # 0, 1: don't care; 2: x; 3: NOT x
    rows = np.zeros((4, N_ROWS), dtype=np.uint32)
    for i in range(8):
        rows |= (np.where(literal[..., i] == 2, 1 << 2 * i, 0) | np.where(literal[..., i] == 3, 2 << 2 * i, 0)).astype(np.uint32)
    rows |= rng.integers(0, 8, size=(4, N_ROWS), dtype=np.uint32) << 16
    result = evaluate_population(rows, model, reflex)
    for i in range(4):
        assert result.row(i) == evaluate_python(rows[i], model, reflex)
    assert evaluate_population(rows[0], model, reflex).row(0) == result.row(0)


def test_large_random_models_agree():
    rng = np.random.default_rng(7)
    for n_pool in (50, 100, 256):
        model = random_model(rng, n_pool, 6 * n_pool, 0.1)
        assert_agrees(random_tables(rng, 200, range(8)), model)
        assert_agrees(random_tables(rng, 200, [0, 1]), model)


def test_empty_model():
    result = evaluate_tables(np.zeros((3, 256), dtype=np.uint8), WorldModel())
    assert result.crashes.tolist() == result.loops.tolist() == result.distance.tolist() == [0, 0, 0]
    assert fitness(result, 0).tolist() == [0.0, 0.0, 0.0]


def test_single_state_unknown_transition():
    model = WorldModel()
    model.visit(5)
    assert assert_agrees(np.zeros((1, 256), np.uint8), model).row(0) == (0, 0, 0)


@pytest.mark.parametrize("state, loops", [(make_state(0, 0), 0), (make_state(0b000001, 0), 1),
                                          (make_state(0b100000, 2), 1)])
def test_self_transition(state, loops):
    """Free space: staying in the same state is progress; with an obstacle bit it is a loop."""
    model = WorldModel()
    model.observe(state, Motion.FORWARD, state, False)
    result = assert_agrees(np.zeros((1, 256), np.uint8), model)
    assert result.row(0) == (0, loops, MOTION_DISTANCE_MM[Motion.FORWARD])


def test_all_crash_model():
    model = WorldModel()
    states = [3, 9, 70, 200]
    for s in states:
        for a in range(8):
            model.observe(s, a, s, True)
    result = assert_agrees(random_tables(np.random.default_rng(1), 50, range(8)), model)
    assert (result.crashes == len(states)).all() and not result.loops.any() and not result.distance.any()
    assert np.allclose(fitness(result, len(states)), 0.4)


def test_hand_made_cycle_and_tail():
    """1 -> 2 -> 3 -> 2 (a loop of two), 4 -> 3 (already tested), 5 crashes, 6 unknown."""
    model = WorldModel()
    for s, s2 in [(1, 2), (2, 3), (3, 2), (4, 3)]:
        model.observe(s, Motion.TURN_LEFT if s == 4 else Motion.FORWARD, s2, False)
    model.observe(5, Motion.FORWARD, 5, True)
    model.visit(6)
    table = np.zeros(256, np.uint8)
    table[4] = Motion.TURN_LEFT
    result = assert_agrees(table[None], model)
    assert result.row(0) == (1, 1, 3 * MOTION_DISTANCE_MM[Motion.FORWARD])


def test_fitness_formula():
    result = EvalResult(np.array([0, 2]), np.array([0, 1]), np.array([0, 250]))
    n = 10
    expected = [0.9, 0.5 * (1 - 0.2) + 0.4 * (1 - 0.1) + 0.1 * 250 / (n * MAX_MOTION_DISTANCE_MM)]
    assert np.allclose(fitness(result, n), expected)
    with pytest.raises(ValueError):
        fitness(result, -1)


def test_bad_inputs():
    with pytest.raises(ValueError):
        evaluate_tables(np.zeros((2, 255), np.uint8), WorldModel())
    with pytest.raises(ValueError):
        evaluate_python(np.zeros((2, N_ROWS), np.uint32), WorldModel())
