"""The failure rates (ga.fail_rates): codes, the fail count F, the host's marks, the fitness term."""

from __future__ import annotations

import numpy as np
import pytest

from cosim.online.run import OnlineConfig, make_run
from ga.evaluator import EvalResult, evaluate_population, fitness
from ga.fail_rates import (
    HORIZON,
    PRIOR_CODE,
    PROGRESS_STEPS,
    RATE_ONE,
    W_FAIL,
    FailureMarks,
    fail_counts,
    mirror_pooled,
    prior_codes,
    progress_codes,
    rate_codes,
)
from ga.hardware_ga import score
from ga.motions import MAX_MOTION_DISTANCE_MM, MIRROR_MOTION, MIRROR_STATE, N_MOTIONS, N_STATES, OBSTACLE_MASK, Motion
from ga.operators import random_population
from ga.truth_table import truth_tables
from ga.world_model import WorldModel


def _marks(pairs):
    failed = np.zeros((N_STATES, N_MOTIONS), dtype=np.int64)
    executed = np.zeros_like(failed)
    for (s, a), (f, e) in pairs.items():
        failed[s, a], executed[s, a] = f, e
    return failed, executed


def test_codes_round_half_up_in_integers():
    failed, executed = _marks({(1, 0): (0, 1), (1, 1): (1, 1), (1, 2): (0, 9), (1, 3): (40, 40),
                               (1, 4): (3, 7)})
    codes = rate_codes(failed, executed)
    assert codes.dtype == np.uint8
    assert codes[0, 0] == PRIOR_CODE == 25  # never executed: the prior 0.1
    assert codes[1, 0] == 13  # 25 / 2 = 12.5 -> 13
    assert codes[1, 1] == 138  # 275 / 2 = 137.5 -> 138
    assert codes[1, 2] == 3  # 25 / 10 = 2.5 -> 3
    assert codes[1, 3] == 245  # 10025 / 41 = 244.51 -> 245
    assert codes[1, 4] == 97  # 775 / 8 = 96.875 -> 97
    always = rate_codes(*_marks({(2, 0): (10**6, 10**6)}))
    assert always.max() <= RATE_ONE and always[2, 0] == RATE_ONE


@pytest.mark.parametrize("failed, executed", [(1, 0), (-1, 2)])
def test_codes_refuse_impossible_marks(failed, executed):
    with pytest.raises(ValueError, match="failed marks"):
        rate_codes(*_marks({(3, 3): (failed, executed)}))


def test_fail_count_is_the_plain_sum_over_obstacle_states_of_s():
    rng = np.random.default_rng(7)
    tables = truth_tables(random_population(rng, 20), reflex=True)
    states = np.sort(rng.choice(N_STATES, 60, replace=False))
    codes = rng.integers(0, RATE_ONE + 1, size=(N_STATES, N_MOTIONS)).astype(np.uint8)
    want = [sum(int(codes[s, t[s]]) for s in states if s & OBSTACLE_MASK) for t in tables]
    assert fail_counts(tables, states, codes).tolist() == want
    assert any(s & OBSTACLE_MASK == 0 for s in states) and min(want) > 0


def test_the_evaluator_counts_fails_only_with_codes():
    rng = np.random.default_rng(3)
    model = WorldModel()
    for _ in range(300):
        model.observe(int(rng.integers(N_STATES)), int(rng.integers(N_MOTIONS)), int(rng.integers(N_STATES)),
                      bool(rng.random() < 0.1))
    pop = random_population(rng, 30)
    plain = evaluate_population(pop, model)
    assert not plain.fails.any()
    with_codes = evaluate_population(pop, model, rates=prior_codes())
    assert [with_codes.row(i) for i in range(30)] == [plain.row(i) for i in range(30)]
    obstacle = int(((model.states & OBSTACLE_MASK) != 0).sum())
    assert (with_codes.fails == PRIOR_CODE * obstacle).all()


def test_fitness_term_and_the_integer_score_agree():
    """A sure failure weighs a crash; 10 D N x fitness is the engine's integer score, less F."""
    n = 40
    c, l, d = np.array([3, 3, 0]), np.array([1, 1, 5]), np.array([500, 500, 1200])
    f = np.array([0, RATE_ONE, 777])
    base = fitness(EvalResult(c, l, d), n)
    with_f = fitness(EvalResult(c, l, d, f), n)
    assert np.allclose(base - with_f, W_FAIL * f / (n * RATE_ONE))
    assert np.isclose(with_f[1], fitness(EvalResult(c + 1, l, d), n)[0])  # rate 1 = one more crash
    ints = score(c, l, d, n, f)
    assert (ints == score(c, l, d, n) - f).all()
    assert np.allclose(ints / (10 * MAX_MOTION_DISTANCE_MM * n), with_f)


def test_marks_judge_the_last_pairs_of_a_failed_leg_once_each():
    marks = FailureMarks()
    for _ in range(3):
        marks.executed_pair(9, 1, reached=False)
    marks.executed_pair(9, 2, reached=True)  # the leg reached its target: nothing pending
    assert marks.pending == []
    steps = [(10 + i, 0) for i in range(HORIZON + 2)] + [(10, 0)]
    for s, a in steps:
        marks.executed_pair(s, a, reached=False)
    marks.failure()
    failed = {(int(s), int(a)) for s, a in zip(*np.nonzero(marks.failed))}
    assert failed == set(steps[-HORIZON:]) and marks.failed.max() == 1
    assert (10, 0) in failed and (11, 0) not in failed and marks.pending == []
    assert marks.executed[9, 1] == 3 and marks.failed[9, 1] == 0


def test_changes_are_what_the_board_does_not_hold():
    marks = FailureMarks()
    assert marks.changes() == []
    marks.executed_pair(65, 3, reached=False)
    marks.failure()
    assert marks.changes() == [(65, 3, 138)]
    assert marks.changes() == []
    marks.executed_pair(65, 3, reached=True)
    assert marks.changes() == [(65, 3, (2 * (RATE_ONE + PRIOR_CODE) + 3) // 6)]


def test_mirror_pooling_adds_the_mirror_pairs_counts():
    s = 0b000010 | (1 << 6)  # front-right obstacle, target sector 1
    m = int(MIRROR_STATE[s])
    assert m != s
    counts = np.zeros((N_STATES, N_MOTIONS), dtype=np.int64)
    counts[s, Motion.TURN_LEFT] = 3
    counts[m, Motion.TURN_RIGHT] = 4
    counts[0, Motion.FORWARD] = 5  # a symmetric pair: its own counts twice
    pooled = mirror_pooled(counts)
    assert pooled[s, Motion.TURN_LEFT] == pooled[m, Motion.TURN_RIGHT] == 7
    assert pooled[0, Motion.FORWARD] == 10 and pooled.sum() == 2 * counts.sum()
    assert MIRROR_MOTION[Motion.TURN_LEFT] == Motion.TURN_RIGHT


def test_mirror_marks_warn_the_mirror_pair():
    s = 0b000010 | (1 << 6)
    m, a = int(MIRROR_STATE[s]), int(Motion.FORWARD_LEFT)
    plain, pooled = FailureMarks(), FailureMarks(mirror=True)
    for marks in (plain, pooled):
        marks.executed_pair(s, a, reached=False)
        marks.failure()
    assert plain.changes() == [(s, a, 138)]
    code = (2 * (RATE_ONE + PRIOR_CODE) + 2) // 4  # (1 + 0) failed of (1 + 0) executed, pooled
    assert sorted(pooled.changes()) == sorted([(s, a, code), (m, int(MIRROR_MOTION[a]), code)])
    codes = pooled.codes()
    assert (codes == codes[np.ix_(MIRROR_STATE, MIRROR_MOTION)]).all()


SMALL = dict(arena="one_obstacle", n_targets=4, population=40, tournament=5, generations_per_phase=3,
             max_leg_steps=300, loop_window=60)


def test_lifetime_writes_the_marks_codes_to_the_board():
    run = make_run(OnlineConfig(seed=5, fail_rates=True, **SMALL)).run()
    assert run.marks.failed.sum() > 0
    assert (run.evaluator.rates == run.marks.written).all()  # as of the last learning phase
    assert any(p["best_fails"] > 0 for p in run.phases)
    assert run.marks.mirror and (run.marks.written == run.marks.written[np.ix_(MIRROR_STATE, MIRROR_MOTION)]).all()
    plain = make_run(OnlineConfig(seed=5, fail_rates=False, **SMALL)).run()
    assert plain.marks is None and all(p["best_fails"] == 0 for p in plain.phases)
    own = make_run(OnlineConfig(seed=5, rate_mirror=False, **SMALL)).run()
    assert not own.marks.mirror and (own.evaluator.rates == own.marks.written).all()


def test_progress_gain_is_the_distance_won_over_the_next_steps_or_to_the_ball():
    """Each pair's gain is its distance to the ball less the distance PROGRESS_STEPS steps later;
    a leg that reaches the ball first gives every pending pair its whole distance."""
    marks = FailureMarks(mirror=False, progress=1.0)
    d = 1000.0
    for i in range(PROGRESS_STEPS + 1):  # state 1 forward, 10 mm closer each step
        marks.executed_pair(1, 0, reached=False, before_mm=d, after_mm=d - 10)
        d -= 10
    assert marks.gain_n[1, 0] == 2 and marks.gain[1, 0] == 2 * 10 * PROGRESS_STEPS
    marks.executed_pair(2, 3, reached=True, before_mm=d, after_mm=5.0)  # reaches the ball
    assert marks.gain_pending == []
    assert marks.gain_n[1, 0] == PROGRESS_STEPS + 1 and marks.gain_n[2, 3] == 1 and marks.gain[2, 3] == d
    assert marks.gain[1, 0] == 160 + sum(range(920, 981, 10))  # the 7 pending pairs: their whole distance
    plain = FailureMarks(mirror=False)  # no progress: nothing measured
    plain.executed_pair(1, 0, reached=False, before_mm=100.0, after_mm=0.0)
    assert plain.gain_n.sum() == 0


def test_progress_codes_add_the_deficit_against_the_states_best_pair():
    gain = np.zeros((N_STATES, N_MOTIONS))
    count = np.zeros_like(gain)
    gain[5, 0], count[5, 0] = 400.0, 2  # mean 200 mm: the state's best
    gain[5, 2], count[5, 2] = 40.0, 1  # mean 40 mm
    gain[6, 1], count[6, 1] = -100.0, 1  # another state: the mean of all fills its others
    codes = prior_codes()
    out = progress_codes(codes, gain, count, weight=2.0)
    per_mm = 2.0 * RATE_ONE / (W_FAIL * MAX_MOTION_DISTANCE_MM * PROGRESS_STEPS)  # 2.5 codes a mm
    fill = (400.0 + 40.0 - 100.0) / 4
    assert out[5, 0] == PRIOR_CODE
    assert out[5, 2] == min(RATE_ONE, int(np.floor(PRIOR_CODE + per_mm * 160 + 0.5)))
    assert out[5, 1] == min(RATE_ONE, int(np.floor(PRIOR_CODE + per_mm * (200 - fill) + 0.5)))
    assert out[5, 2] == int(np.floor(PRIOR_CODE + per_mm * 160 + 0.5)) - 0 or out[5, 2] == RATE_ONE
    half = progress_codes(codes, gain, count, weight=0.25)  # 0.3125 codes a mm: nothing clipped
    assert half[5, 2] == int(np.floor(PRIOR_CODE + 0.3125 * 160 + 0.5)) == 75
    assert out[6, 0] == PRIOR_CODE and out[6, 1] == RATE_ONE  # 185 mm below the fill: clipped
    assert (progress_codes(codes, gain, count, weight=0.0) == codes).all()


def test_progress_weight_is_checked_and_rides_on_the_rate_codes():
    with pytest.raises(ValueError, match="--progress-weight must be a finite weight >= 0"):
        OnlineConfig(progress_weight=-1.0)
    assert OnlineConfig(progress_weight=3.0, fail_rates=False).progress_weight == 0.0  # no codes to ride on
    from cosim.cli.online import build_parser, config_from_args

    args = build_parser().parse_args(["--no-fail-rates", "--progress-weight", "3"])
    with pytest.raises(ValueError, match="--progress-weight needs --fail-rates"):
        config_from_args(args)
    assert config_from_args(build_parser().parse_args(["--no-fail-rates"])).progress_weight == 0.0
    run = make_run(OnlineConfig(seed=5, progress_weight=3.0, **SMALL)).run()
    assert run.marks.progress == 3.0 and run.marks.gain_n.sum() > 0
    assert (run.evaluator.rates == run.marks.written).all()
    assert (run.marks.codes() == progress_codes(
        rate_codes(mirror_pooled(run.marks.failed), mirror_pooled(run.marks.executed)),
        mirror_pooled(run.marks.gain), mirror_pooled(run.marks.gain_n), 3.0)).all()
    plain = make_run(OnlineConfig(seed=5, progress_weight=0.0, **SMALL)).run()
    assert plain.marks.gain_n.sum() == 0 and OnlineConfig().progress_weight > 0  # on by default (round 18; tuned in issue 36)
    assert [p["best_fails"] for p in run.phases] != [p["best_fails"] for p in plain.phases]
