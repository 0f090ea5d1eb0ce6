"""The reactive baseline proves the default arena fair (SPEC section 11: arena traps)."""

from __future__ import annotations

import numpy as np

from ga.motions import OBSTACLE_MASK, REFLEX_TABLE, X_FRONT, Motion
from sim_world.baseline import (
    FRONT_ONLY_STATES,
    TUNING_RUNS,
    baseline_table,
    evaluate_legs,
    revert_to_rules,
    rules_table,
    run_baseline,
    tune_table,
)
from sim_world.course import DEFAULT_MAX_LEG_STEPS
from sim_world.world import DEFAULT_NOISE


def test_table_keeps_the_reflex():
    for table in (baseline_table(), rules_table()):
        assert table.shape == (256,) and table.dtype == np.uint8 and table.max() < 8
        reflex = REFLEX_TABLE >= 0
        assert np.array_equal(table[reflex], REFLEX_TABLE[reflex])


def test_front_only_obstacle_backs_off():
    # The lesson of the held-out failures: with only x0 set, a forward motion turned into the obstacle.
    table = baseline_table()
    assert FRONT_ONLY_STATES == {(1 << X_FRONT) | sector << 6 for sector in range(4)}
    for state in FRONT_ONLY_STATES:
        assert table[state] not in (Motion.FORWARD, Motion.FORWARD_LEFT, Motion.FORWARD_RIGHT)


def test_baseline_reaches_64_targets_noise_free():
    res = run_baseline("default")
    assert res.targets_reached == 64 and not res.crashed and not res.timed_out
    # The longest leg (280 interactions: one leg with many front-only back-offs) leaves the limit a margin.
    assert max(res.leg_steps) < 0.6 * DEFAULT_MAX_LEG_STEPS


def test_baseline_reaches_64_targets_at_default_noise():
    res = run_baseline("default", DEFAULT_NOISE, seed=0)
    assert res.targets_reached == 64 and not res.crashed and not res.timed_out


def test_baseline_on_held_out_noise_seeds():
    # Seeds >= 100 were never used by the tuning (TUNING_RUNS).
    assert max(seed for _, noise, seed in TUNING_RUNS if noise is not None) < 100
    for seed in (100, 101, 102):
        res = run_baseline("default", DEFAULT_NOISE, seed=seed)
        assert res.targets_reached == 64, (seed, res.crashed, res.timed_out)


def test_baseline_in_the_simpler_arenas():
    for arena in ("one_obstacle", "empty"):
        res = run_baseline(arena)
        assert res.targets_reached == 64 and not res.crashed and not res.timed_out, arena


def test_evaluate_legs_counts_failures():
    runs = [("empty", None, 0)]
    cost, steps, fails = evaluate_legs(baseline_table(), runs)
    assert cost == 0 and not fails and steps > 64
    # A table that always goes straight ahead (reflex kept) fails some legs of the empty arena,
    # each noise-free failure weighing NOISE_FREE_WEIGHT.
    straight = np.where(REFLEX_TABLE >= 0, REFLEX_TABLE, Motion.FORWARD).astype(np.uint8)
    cost, _, fails = evaluate_legs(straight, runs)
    assert cost > 0 and len(fails) == cost // 10
    assert all(s & OBSTACLE_MASK for f in fails for s in f)


def test_tune_table_never_makes_things_worse():
    runs = [("empty", None, 0)]
    straight = np.where(REFLEX_TABLE >= 0, REFLEX_TABLE, Motion.FORWARD).astype(np.uint8)
    before = evaluate_legs(straight, runs)[:2]
    tuned = tune_table(straight, runs, 0.5, np.random.default_rng(0), log=lambda _: None)
    assert evaluate_legs(tuned, runs)[:2] <= before
    reflex = REFLEX_TABLE >= 0
    assert np.array_equal(tuned[reflex], REFLEX_TABLE[reflex])


def test_tune_table_keeps_frozen_states():
    runs = [("empty", None, 0)]
    straight = np.where(REFLEX_TABLE >= 0, REFLEX_TABLE, Motion.FORWARD).astype(np.uint8)
    frozen = frozenset(range(256))
    tuned = tune_table(straight, runs, 0.2, np.random.default_rng(1), frozen=frozen, log=lambda _: None)
    assert np.array_equal(tuned, straight)


def test_revert_to_rules_undoes_neutral_changes_only_where_not_frozen():
    runs = [("empty", None, 0)]
    rules = rules_table()
    # States with every obstacle bit set never occur in the empty arena: changing them is neutral.
    neutral = [OBSTACLE_MASK | sector << 6 for sector in range(4)]
    table = rules.copy()
    table[neutral] = (rules[neutral] + 1) % 8
    front = sorted(FRONT_ONLY_STATES)[0]
    table[front] = (rules[front] + 1) % 8
    out = revert_to_rules(table, runs, frozen={front}, log=lambda _: None)
    assert np.array_equal(out[neutral], rules[neutral])
    assert out[front] == table[front]
    assert evaluate_legs(out, runs)[0] <= evaluate_legs(table, runs)[0]
