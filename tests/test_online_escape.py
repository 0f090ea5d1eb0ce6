"""Round-3 options of the on-line loop (cosim.online): relaxing loop detectors, spread escape."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.online import OnlineConfig, make_run
from cosim.boards import EvalCounts
from ga.motions import OBSTACLE_MASK
from ga.operators import random_population
from ga.truth_table import truth_tables

SMALL = dict(arena="one_obstacle", n_targets=4, population=40, tournament=5, generations_per_phase=3,
             max_leg_steps=300, loop_window=60)


def _loop(targets: int) -> dict:
    return {"reason": "loop", "targets": targets}


def test_loop_relax_doubles_the_detectors_per_k_stops_at_one_target():
    run = make_run(OnlineConfig(seed=1, **{**SMALL, "loop_window": 50, "loop_reentries": 6,
                                           "loop_repeats": 4, "loop_relax": 3}))
    assert run.loop_limits() == (50, 6, 4)
    run.phases = [_loop(0)] * 2 + [{"reason": "crash", "targets": 0}] * 5
    assert run.loop_limits() == (50, 6, 4)  # crashes do not count
    run.phases.append(_loop(0))
    assert run.loop_limits() == (50, 12, 8)  # the window stays unless relax_window
    run.phases += [_loop(0)] * 3
    assert run.loop_limits() == (50, 24, 16)
    run.targets = 1  # a new target: the stops of the earlier one no longer count
    assert run.loop_limits() == (50, 6, 4)
    wide = make_run(OnlineConfig(seed=1, **{**SMALL, "loop_window": 50, "loop_relax": 3,
                                            "relax_window": True, "loop_reentries": 0,
                                            "loop_repeats": 0}))
    wide.phases = [_loop(0)] * 7
    assert wide.loop_limits() == (200, 0, 0)
    patient = make_run(OnlineConfig(seed=1, **{**SMALL, "loop_reentries": 6, "loop_patience": 2}))
    patient.phases = [_loop(0)] * 2
    assert patient.loop_limits() == (60, 0, 0)


def test_relaxed_window_stops_no_leg_before_its_threshold():
    run = make_run(OnlineConfig(seed=5, **{**SMALL, "loop_window": 15, "loop_relax": 1,
                                           "relax_window": True})).run()
    stops: dict[int, int] = {}
    levels = []
    for p in run.phases:
        if p["reason"] != "loop":
            continue
        level = stops.get(p["targets"], 0)
        stops[p["targets"]] = level + 1
        if p["detector"] == "window" and p["leg_steps"] == p["execution_steps"]:
            assert p["execution_steps"] >= 15 * 2 ** level, p
            levels.append(level)
    assert max(levels) >= 2, "the test needs a leg with several loop stops"


def _spread_setup(mode: str):
    run = make_run(OnlineConfig(seed=2, **{**SMALL, "escape_spread": mode}))
    rng = np.random.default_rng(7)
    pop = random_population(rng, 30)
    tables = truth_tables(pop, reflex=True)
    obstacle = [s for s in range(256) if s & OBSTACLE_MASK][:40]
    # The failed leg: individual 0's motions in 40 obstacle states, plus free-space steps (ignored).
    run.pre_states = obstacle + [64, 128]
    run.motions = [int(tables[0, s]) for s in obstacle] + [2, 3]
    run.interactions, run.leg_start = len(run.motions), 0
    zeros = np.zeros(30, dtype=np.int64)
    counts = EvalCounts(crashes=zeros.copy(), loops=zeros.copy(), distance=zeros.copy())
    fitness = np.linspace(1.0, 0.5, 30)  # individual 0 is the fittest
    repeats = np.array([sum(tables[i, s] == tables[0, s] for s in obstacle) for i in range(30)])
    return run, pop, counts, fitness, repeats


def test_spread_escape_downloads_the_individual_repeating_fewest_failed_steps():
    run, pop, counts, fitness, repeats = _spread_setup("leg")
    record: dict = {}
    chosen = run._spread_escape(pop, counts, fitness, 0, record)
    fewest = np.flatnonzero(repeats == repeats.min())
    assert chosen == fewest[0]  # ties: the fittest (the lowest index here)
    assert record["repeated_steps"] == [40, int(repeats.min()), 40] and record["escaped"]
    # An individual worse on the model's crashes is never chosen, however different it is.
    counts.crashes[chosen] = 1
    again = run._spread_escape(pop, counts, fitness, 0, {})
    assert again != chosen and repeats[again] == np.sort(repeats[np.arange(30) != chosen])[0]


def test_spread_escape_target_mode_adds_every_failed_leg_since_the_target():
    run, pop, counts, fitness, repeats = _spread_setup("target")
    run.phases = [{"reason": "loop", "targets": 0, "leg_start": 0, "interactions": 20},
                  {"reason": "loop", "targets": 5, "leg_start": 20, "interactions": 42}]
    run.leg_start = 20
    record: dict = {}
    run._spread_escape(pop, counts, fitness, 0, record)
    assert record["repeated_steps"][2] == 20 + 20  # steps 0-19 (earlier loop) + 20-39 (this leg)
    run.config = OnlineConfig(seed=2, **{**SMALL, "escape_spread": "leg"})
    record = {}
    run._spread_escape(pop, counts, fitness, 0, record)
    assert record["repeated_steps"][2] == 20


def test_spread_escape_mode_is_checked():
    with pytest.raises(ValueError, match="escape_spread"):
        OnlineConfig(escape_spread="all")


def _scripted(run, states):
    """Make ``run.world.step`` return ``states`` in turn (no crash, no target, the ball 1 m away)."""
    from sim_world.world import Step

    it = iter(states)
    run.world.step = lambda motion: Step(next(it), False, False, 1000.0)


@pytest.mark.parametrize("motions, expected", [((0, 0), 1), ((2, 3), 3)])
def test_loop_radius_counts_only_reentries_at_the_same_place(motions, expected):
    """Entering state 1 every other step: moving on (forward, 50 mm a step) is no loop; turning
    left and right in place is."""
    run = make_run(OnlineConfig(seed=1, **{**SMALL, "loop_reentries": 6, "loop_radius_mm": 60.0}))
    _scripted(run, [2, 1] * 3)
    for k in range(6):
        run._advance(motions[k % 2])
    assert run.entries[1] == expected
    plain = make_run(OnlineConfig(seed=1, **{**SMALL, "loop_reentries": 6, "loop_radius_mm": 0.0}))
    _scripted(plain, [2, 1] * 3)
    for k in range(6):
        plain._advance(motions[k % 2])
    assert plain.entries[1] == 3  # without the radius every re-entry counts


def test_odometry_dead_reckons_the_commanded_motions():
    run = make_run(OnlineConfig(seed=1, **SMALL))
    _scripted(run, [2] * 4)
    for motion in (0, 2, 4, 1):  # forward, turn left, forward-left, backward
        run._advance(motion)
    import math

    h = math.radians(22.5)
    x = 50 + 50 * math.cos(h + h / 2) - 50 * math.cos(2 * h)
    y = 50 * math.sin(h + h / 2) - 50 * math.sin(2 * h)
    assert run.odometry == pytest.approx([x, y, 2 * h])


def test_rewrite_escape_downloads_new_untried_motions_in_the_loop_states():
    run = make_run(OnlineConfig(seed=2, **{**SMALL, "escape_rewrite": 10}))
    rng = np.random.default_rng(3)
    pop = random_population(rng, 30)
    fittest = pop[0]
    table = truth_tables(fittest, reflex=True)
    s1, s2 = 1, 66  # obstacle front / ball front; obstacle front-left / ball left
    a1, a2 = int(table[s1]), int(table[s2])
    crash = next(m for m in range(8) if m != a1)
    for board in (run.evaluator, run.mirror):  # a crash the model knows: never chosen
        board.observe(s1, crash, s1, True)
        board.observe(s1, a1, s2, False)
        board.observe(s2, a2, s1, False)
    run.pre_states = [s1, s2] * 5
    run.motions = [a1, a2] * 5
    run.interactions, run.leg_start = 10, 0
    zeros = np.zeros(30, dtype=np.int64)
    counts = EvalCounts(crashes=zeros.copy(), loops=zeros + 1, distance=zeros.copy())
    before = run.genetic_operations
    record: dict = {}
    rows = run._rewrite_escape(fittest, counts, 0, pop[5], record)
    new = truth_tables(rows, reflex=True)
    assert record["rewritten"] and sorted(record["rewritten_states"]) == [s1, s2]
    assert new[s1] not in (a1, crash) and new[s2] != a2
    assert run.genetic_operations == before + 10
    assert np.array_equal(run.ga.ask()[-1], rows)  # it joins the population
    # Nothing no worse on the model than the fittest: the plain escape's choice is kept.
    strict = EvalCounts(crashes=zeros.copy(), loops=zeros - 1, distance=zeros.copy())
    assert np.array_equal(run._rewrite_escape(fittest, strict, 0, pop[5], {}), pop[5])


def test_blame_table_counts_failed_legs_minus_legs_that_reached_the_target():
    run = make_run(OnlineConfig(seed=2, **{**SMALL, "escape_credit": True}))
    run.pre_states = [1, 1, 2, 1, 2, 3, 1, 1]
    run.motions = [0, 0, 5, 0, 6, 0, 0, 3]
    run.interactions = 8
    # steps 0-2: a leg stopped as a loop; 3-4: a crash phase; 5-7: a leg that reached the target
    run.phases = [{"reason": "loop", "targets": 0, "leg_start": 0, "interactions": 3},
                  {"reason": "crash", "targets": 0, "interactions": 5}]
    run.target_log = [{"target": 1, "interactions": 8}]
    blame = run._blame_table()
    assert blame[1, 0] == 2 - 1 and blame[2, 5] == 1 and blame[2, 6] == 0  # crash legs: neutral
    assert blame[3, 0] == -1 and blame[1, 3] == -1
    assert blame.sum() == 3 - 3
    assert run._blame_table({"leg_start": 3, "interactions": 5})[2, 6] == 1


def test_credit_choice_prefers_the_least_blamed_individual_no_worse_on_the_model():
    run = make_run(OnlineConfig(seed=2, **{**SMALL, "escape_credit": True}))
    pop = random_population(np.random.default_rng(4), 30)
    tables = truth_tables(pop, reflex=True)
    for board in (run.evaluator, run.mirror):
        board.observe(1, 0, 2, False)
        board.observe(2, 0, 1, False)
    # individual 0 (the fittest) looped through its motions in states 1 and 2
    run.pre_states, run.motions = [1, 2] * 4, [int(tables[0, 1]), int(tables[0, 2])] * 4
    run.interactions = 8
    run.phases = [{"reason": "loop", "targets": 0, "leg_start": 0, "interactions": 8}]
    zeros = np.zeros(30, dtype=np.int64)
    counts = EvalCounts(crashes=zeros.copy(), loops=zeros.copy(), distance=zeros.copy())
    fitness = np.linspace(1.0, 0.5, 30)
    record: dict = {}
    chosen = run._credit_choice(pop, counts, fitness, 0, record)
    penalty = 4 * (tables[:, 1] == tables[0, 1]) + 4 * (tables[:, 2] == tables[0, 2])
    assert chosen == int(np.flatnonzero(penalty == penalty.min())[0])
    assert record["blame"] == [8, int(penalty.min())]
    counts.loops[chosen] = 1  # worse on the model's loops: excluded
    assert run._credit_choice(pop, counts, fitness, 0, {}) != chosen


def test_loop_penalty_lowers_the_fitness_of_controllers_that_repeat_a_blamed_pair():
    """Option loop_penalty (NOT the SPEC fitness): W / N less per blamed pair of the current leg
    that a controller would choose again; pairs of earlier legs, crashes and free-space states
    are not blamed."""
    from cosim import online

    run = make_run(OnlineConfig(seed=2, **{**SMALL, "loop_penalty": 0.4}))
    state = 1  # F/F: an obstacle state, the controller decides
    run.targets = 3
    run.phases = [
        {"reason": "loop", "targets": 3, "state": state, "motion": 0},
        {"reason": "timeout", "targets": 3, "state": 72, "motion": 6},
        {"reason": "loop", "targets": 3, "state": state, "motion": 0},  # the same pair: counted once
        {"reason": "loop", "targets": 2, "state": 4, "motion": 1},  # an earlier leg
        {"reason": "crash", "targets": 3, "state": 2, "motion": 5},
        {"reason": "loop", "targets": 3, "state": 64, "motion": 0},  # free space: the reflex decides
    ]
    assert run._leg_blames() == [(1, 0), (72, 6)]
    pop = random_population(np.random.default_rng(0), 200)
    tables = truth_tables(pop, reflex=True)
    repeats = online._repeats(pop, run._leg_blames(), True)
    assert np.array_equal(repeats, (tables[:, 1] == 0).astype(int) + (tables[:, 72] == 6))
    assert repeats.max() == 2 and repeats.min() == 0

    told = []
    tell = run.ga.tell
    run.ga.tell = lambda fitness: (told.append(np.array(fitness)), tell(fitness))[1]
    evaluate = run.evaluator.evaluate
    seen = []
    run.evaluator.evaluate = lambda p: (seen.append(p.copy()), evaluate(p))[1]
    run.evaluator.observe(1, 0, 1, False)
    run.mirror.observe(1, 0, 1, False)
    run._learn("loop", 5, state, 0)
    n = run.mirror.n_states
    for p, fitness in zip(seen, told):
        plain = online.model_fitness(evaluate(p), n)
        assert np.allclose(plain - fitness, 0.4 * online._repeats(p, [(1, 0), (72, 6)], True) / n)
        assert (plain != fitness).any()


@pytest.mark.parametrize("rounds, motions, fires_at", [(1, (2, 3), 3), (2, (2, 3), 5), (1, (0, 0), None)])
def test_loop_cycles_stops_once_the_robot_went_round_a_simple_cycle(rounds, motions, fires_at):
    """States 1 -> 2 -> 1 -> ... (the ball never closer): turning in place closes the cycle after
    ``rounds`` rounds (the first step only sets the closest approach); moving on 50 mm a step is
    no loop by odometry."""
    run = make_run(OnlineConfig(seed=1, **{**SMALL, "loop_cycles": rounds, "loop_radius_mm": 60.0}))
    run.state = 1
    _scripted(run, [2, 1] * 5)
    fired = None
    for k in range(10):
        run._advance(motions[k % 2])
        if fired is None and run._cycled(rounds):
            fired = k + 1
    assert fired == fires_at


def test_closest_download_keeps_the_behaviour_of_the_visited_states():
    """Among individuals tied for the best fitness, "closest" picks the one that changes the
    running controller's motion in the least visited states; the escape's restriction holds."""
    run = make_run(OnlineConfig(seed=1, **{**SMALL, "download": "closest"}))
    rng = np.random.default_rng(3)
    pop = random_population(rng, 8)
    run.best_rows = pop[5].copy()
    run.pre_states = list(range(256))  # every state visited once
    fitness = np.array([0.1, 0.2, 0.9, 0.3, 0.2, 0.9, 0.5, 0.9])
    record = {}
    assert run._closest(pop, fitness, 2, None, record) == 5  # the running controller itself
    assert record["ties"] == 3
    eligible = np.ones(8, dtype=bool)
    eligible[5] = False
    current = truth_tables(pop[5][None])[0]
    changed = (truth_tables(pop[[2, 7]]) != current).sum(axis=1)
    assert run._closest(pop, fitness, 2, eligible, {}) == (2, 7)[int(np.argmin(changed))]
    with pytest.raises(ValueError, match="download"):
        OnlineConfig(download="best")


def test_forward_distance_option_is_deterministic_and_changes_the_lifetime():
    """``distance_rule="forward"`` (NOT the SPEC) reaches the evaluator board: the same seed gives
    the same lifetime, another than under the SPEC's dist[a], and the summary says so."""
    from cosim.online import summary_table

    def lifetime(rule):
        run = make_run(OnlineConfig(seed=2, **{**SMALL, "distance_rule": rule})).run()
        assert run.evaluator.distance_rule == rule
        return run

    a, b, spec = lifetime("forward"), lifetime("forward"), lifetime("covered")
    assert a.motions == b.motions and a.targets == 4
    assert a.motions != spec.motions
    assert "NOT the SPEC" in summary_table(a.summary())
    assert "NOT the SPEC" not in summary_table(spec.summary())
    with pytest.raises(ValueError, match="distance_rule"):
        OnlineConfig(distance_rule="backward")


def test_command_line_flags_of_round_5_reach_the_config():
    from cosim.online import build_parser, config_from_args

    args = build_parser().parse_args(["--distance", "forward", "--loop-cycles", "1", "--download", "closest"])
    config = config_from_args(args)
    assert (config.distance_rule, config.loop_cycles, config.download) == ("forward", 1, "closest")
    default = config_from_args(build_parser().parse_args([]))
    assert (default.distance_rule, default.loop_cycles, default.download) == ("covered", 0, "first")
