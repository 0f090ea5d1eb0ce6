"""The off-line method's noisy stage (cosim.offline.noisy) and the course's skipped legs."""

import json

import numpy as np
import pytest

from cosim.offline.noisy import NoisyRun, NoisyStage, Records, drive_noisy, noise_seeds, table_key
from cosim.offline.run import default_ga_config, run_offline
from ga.motions import Motion
from sim_world.course import run_course
from sim_world.world import DEFAULT_NOISE, World

SMALL = dict(arena="empty", max_leg_steps=60, n_targets=3, progress=False, plots=False, transfer_trials=2,
             ga_config=default_ga_config(population=6, tournament=2))


def _forward_table():
    return np.full(256, int(Motion.FORWARD), dtype=np.uint8)


def test_skipped_legs_try_every_leg_and_stop_at_max_failures():
    world = World("one_obstacle")
    stuck = np.full(256, int(Motion.TURN_LEFT), dtype=np.uint8)  # never reaches anything: time-outs
    res = run_course(world, stuck, 20, n_targets=5, skip_failed_legs=True)
    assert (res.targets_reached, res.failed_legs, res.steps) == (0, 5, 100)
    assert len(res.failure_states) == 5 and not res.timed_out
    res = run_course(world, stuck, 20, n_targets=5, skip_failed_legs=True, max_failures=2)
    assert (res.failed_legs, res.steps) == (2, 40)
    # Without the option the first time-out ends the run, as before.
    res = run_course(world, stuck, 20, n_targets=5)
    assert res.timed_out and res.steps == 20 and res.failed_legs == 0


def test_a_crash_fails_its_leg_and_the_next_leg_starts():
    world = World("one_obstacle")
    res = run_course(world, _forward_table(), 150, n_targets=64, skip_failed_legs=True)
    assert res.crashes == res.failed_legs >= 1
    assert res.targets_reached + res.failed_legs == 64


def test_leg_noise_seeds_make_a_leg_independent_of_the_legs_before():
    world = World("default", noise=DEFAULT_NOISE)
    table = _forward_table()
    seed = lambda leg: [7, leg]  # noqa: E731
    # Leg 1 onwards starts at positions[0] either way; with per-leg seeds its outcome is the same
    # whether the run began at the start pose or at leg 1's pose.
    a = run_course(world, table, 60, n_targets=3, skip_failed_legs=True, record=True, leg_noise_seed=seed)
    b = run_course(world, table, 60, n_targets=3, skip_failed_legs=True, record=True,
                   leg_noise_seed=lambda leg: [7, leg + 1], start=0)
    relocated = [i for i, p in enumerate(a.trajectory) if p[3] == "relocate"][0]
    poses = lambda traj: [p[:3] for p in traj]  # noqa: E731
    assert poses(a.trajectory[relocated:]) == poses(b.trajectory[:len(a.trajectory) - relocated])


def test_common_noise_seeds_are_new_each_generation_and_never_the_transfer_s():
    assert noise_seeds(1, 5, 2) == [[170017, 1, 5, 0], [170017, 1, 5, 1]]
    assert noise_seeds(1, 5, 2) != noise_seeds(1, 6, 2)
    world = World("one_obstacle", noise=DEFAULT_NOISE)
    rows = np.zeros(50, dtype=np.uint32)
    one = drive_noisy(world, rows, 60, 4, noise_seeds(1, 0, 1)[0], 4)
    assert one == drive_noisy(world, rows, 60, 4, noise_seeds(1, 0, 1)[0], 4)  # the same seed, the same run
    assert isinstance(one, NoisyRun) and one.clean_legs + one.failed_legs <= 4


def test_records_average_every_run_and_accept_only_clean_records():
    rec = Records()
    clean = NoisyRun(3.9, 3, 0, 100, None, frozenset(), frozenset())
    bad = NoisyRun(1.5, 1, 2, 80, 17, frozenset(), frozenset())
    rec.add("a", clean)
    rec.add("a", clean)
    assert rec.accepted("a", 2) and not rec.accepted("a", 3)
    rec.add("a", bad)
    assert rec.score("a") == pytest.approx((3.9 * 2 + 1.5) / 3)
    assert not rec.accepted("a", 3)
    assert Records(json.loads(json.dumps(rec.to_dict()))).summary("a") == rec.summary("a")
    with pytest.raises(ValueError, match="trials"):
        NoisyStage(trials=-1)


def test_the_noisy_stage_follows_the_noise_free_one_and_is_counted(tmp_path):
    stage = NoisyStage(trials=2, accept_runs=4)
    plain = run_offline(1, generations_cap=60, out=tmp_path / "plain", **SMALL)
    noisy = run_offline(1, generations_cap=60, out=tmp_path / "noisy", noisy=stage, **SMALL)
    n = noisy["noisy_stage"]
    assert plain["reached_all_targets"] and noisy["reached_all_targets"] and n["accepted"]
    assert n["from_generation"] == plain["generations"] + 1
    assert noisy["generations"] == plain["generations"] + n["generations"] and n["generations"] >= 2
    assert noisy["interactions"] == plain["interactions"] + n["interactions"] > plain["interactions"]
    assert n["noisy_runs"] >= 4 and n["noisy_clean_runs"] == n["noisy_runs"]
    assert noisy["config"]["noisy_stage"] == stage.to_dict() and "noisy_stage" not in plain["config"]
    history = json.loads((tmp_path / "noisy" / "history.json").read_text())
    assert [h.get("stage", 1) for h in history].count(2) == n["generations"]
    assert len(noisy["transfer"]["targets_without_crash"]) == 2


def test_the_noisy_stage_resumes_bit_for_bit_and_pool_equals_serial(tmp_path):
    stage = NoisyStage(trials=2, accept_runs=4)
    straight = run_offline(2, generations_cap=60, out=tmp_path / "a", noisy=stage, **SMALL)
    first = straight["noisy_stage"]["from_generation"]

    class Stop(Exception):
        pass

    def stop(entry):
        if entry["generation"] == first:
            raise Stop

    with pytest.raises(Stop):
        run_offline(2, generations_cap=60, out=tmp_path / "b", noisy=stage, on_generation=stop, **SMALL)
    resumed = run_offline(2, generations_cap=60, out=tmp_path / "b", noisy=stage, resume=True, **SMALL)
    pooled = run_offline(2, generations_cap=60, out=tmp_path / "c", noisy=stage, workers=2, **SMALL)
    volatile = ("wall_time_s", "workers", "simulated_interactions")
    for other in (resumed, pooled):
        assert {k: v for k, v in other.items() if k not in volatile} == \
            {k: v for k, v in straight.items() if k not in volatile}


def test_the_race_keeps_the_champion_unless_the_challenger_wins_again():
    from cosim.offline.noisy import _drive_one, noisy_generation
    from ga.operators import random_population

    pop = random_population(np.random.default_rng(3), 6)
    calls, raced = [], 0

    def run_map(fn, tasks):
        calls.append(len(tasks))
        return [_drive_one(t) for t in tasks]

    for generation in range(6):
        records = Records()
        stage = NoisyStage(trials=1, race=3)
        keys, runs, fitness, _, steps, _ = noisy_generation(run_map, pop, stage, records, 1, generation,
                                                            "one_obstacle", 80, 6)
        top = int(np.argmax(fitness))
        first = max(range(6), key=lambda i: (runs[i][0].fitness, -i))
        if first == 0:
            assert calls[-1] == 6 and records.data[keys[0]][0] == 1  # no race
            continue
        raced += 1
        assert calls[-2:] == [6, 6] and records.data[keys[0]][0] == 1 + 3 == records.data[keys[first]][0]
        raced_champion = records.data[keys[0]][2] - runs[0][0].fitness
        raced_challenger = records.data[keys[first]][2] - runs[first][0].fitness
        assert top == (first if raced_challenger > raced_champion else 0)
        assert steps > sum(r[0].steps for r in runs)  # the race's runs are counted
    assert raced >= 2


def test_the_budget_ends_the_noisy_stage(tmp_path):
    cfg = dict(SMALL, arena="one_obstacle", n_targets=8, max_leg_steps=80)
    s = run_offline(1, generations_cap=400, out=tmp_path, noisy=NoisyStage(trials=1, accept_runs=1000, budget=3000),
                    **cfg)
    n = s["noisy_stage"]
    assert not n["accepted"] and 3000 <= n["interactions"] and n["generations"] >= 1
    assert s["generations"] < 400


def test_table_key_is_the_truth_table():
    rows = np.zeros(50, dtype=np.uint32)
    assert table_key(rows) == table_key(rows.copy()) and len(table_key(rows)) == 16


# -- Round 5: the stage from generation 0, the leg soft limit, scaled noise, the final race --------


def test_the_stage_from_the_start_has_no_noise_free_stage_and_a_final_race_counted(tmp_path):
    cfg = dict(SMALL, arena="one_obstacle", n_targets=4, max_leg_steps=80)
    stage = NoisyStage(trials=1, race=2, accept_runs=1000, budget=6000, from_start=True, leg_soft_steps=40,
                       final_race=2, final_candidates=3)
    s = run_offline(1, generations_cap=50, out=tmp_path, noisy=stage, **cfg)
    n = s["noisy_stage"]
    history = json.loads((tmp_path / "history.json").read_text())
    assert n["from_generation"] == 1 and n["generations"] == s["generations"] and all(e["stage"] == 2 for e in history)
    assert s["config"]["noisy_stage"] == stage.to_dict() and stage.to_dict()["from_start"] is True
    race = n["final_race"]
    assert 1 <= race["candidates"] <= 3 and len(race["failed_legs_clean_runs_mean_fitness"]) == race["candidates"]
    assert s["interactions"] == n["interactions"] == history[-1]["interactions"] + race["interactions"]
    assert race["interactions"] > 0
    # The defaults of the round-5 fields stay out of the config (older checkpoints still resume).
    assert "from_start" not in NoisyStage(trials=1).to_dict()


def test_a_long_clean_leg_costs_part_of_a_leg():
    world = World("empty", noise=DEFAULT_NOISE)
    rows = np.zeros(50, dtype=np.uint32)  # the reflex alone: it reaches the ball in the empty arena
    plain = drive_noisy(world, rows, 150, 3, [1, 2], 4)
    soft = drive_noisy(world, rows, 150, 3, [1, 2], 4, leg_soft_steps=10)
    assert plain.clean_legs == soft.clean_legs == 3 and plain.steps == soft.steps > 30
    assert soft.fitness < plain.fitness
    assert drive_noisy(world, rows, 150, 3, [1, 2], 4, leg_soft_steps=1000).fitness == plain.fitness
    with pytest.raises(ValueError, match="leg_soft_steps"):
        NoisyStage(trials=1, leg_soft_steps=-1)


def test_near_misses_count_motions_ending_close_to_an_obstacle_and_cost_fitness():
    world = World("one_obstacle")
    forward = _forward_table()
    counts = [run_course(world, forward, 60, n_targets=3, skip_failed_legs=True, near_miss_mm=m).near_misses
              for m in (0.0, 30.0, 300.0)]
    assert counts[0] == 0 < counts[2] and counts[1] <= counts[2]
    world = World("one_obstacle", noise=DEFAULT_NOISE)
    plain = drive_noisy(world, np.zeros(50, dtype=np.uint32), 60, 3, [1, 2], 4)
    near = drive_noisy(world, np.zeros(50, dtype=np.uint32), 60, 3, [1, 2], 4, near_miss_mm=300.0,
                       near_miss_cost=0.5)
    assert near.steps == plain.steps and near.fitness < plain.fitness


def test_backward_motions_beside_or_behind_an_obstacle_are_counted_and_cost_fitness():
    from sim_world.baseline import baseline_table

    world = World("one_obstacle")
    backward = np.full(256, int(Motion.BACKWARD_RIGHT), dtype=np.uint8)
    res = run_course(world, backward, 40, n_targets=2, skip_failed_legs=True, count_backs=True)
    assert 0 < res.obstacle_backs <= res.steps
    assert run_course(world, backward, 40, n_targets=2, skip_failed_legs=True).obstacle_backs == 0
    # The hand-written baseline backs off only when the obstacle is ahead alone.
    assert run_course(world, baseline_table(), 150, n_targets=4, count_backs=True).obstacle_backs == 0
    rows = np.zeros(50, dtype=np.uint32)
    rows[0] = 0b111 << 16  # one row with no literal fires everywhere: BACKWARD_RIGHT outside the reflex
    noisy = World("one_obstacle", noise=DEFAULT_NOISE)
    plain = drive_noisy(noisy, rows, 40, 2, [1, 2], 4)
    costly = drive_noisy(noisy, rows, 40, 2, [1, 2], 4, back_cost=0.5)
    assert costly.steps == plain.steps and costly.fitness < plain.fitness


def _stage_of(options: dict) -> NoisyStage:
    return NoisyStage(**{k[len("noisy_"):]: v for k, v in options.items() if k.startswith("noisy_")})


def test_the_config_files_name_only_offline_options_and_the_default_is_the_robust_stage():
    import argparse
    import dataclasses
    import tomllib
    from pathlib import Path

    from cosim.offline import run as offline
    from cosim.offline.noisy import ROBUST_MAX_LEG_STEPS, ROBUST_STAGE

    parser = offline.add_arguments(argparse.ArgumentParser())
    dests = {a.dest for a in parser._actions}
    defaults = vars(parser.parse_args([]))
    # `ehw offline` with no option: the noisy stage from the first generation (issue 17, round 6) ...
    assert _stage_of(defaults) == ROBUST_STAGE and defaults["max_leg_steps"] == ROBUST_MAX_LEG_STEPS
    assert defaults["transfer_leg_steps"] == 0  # the transfer at the run's own leg limit
    experiments = Path(__file__).parents[1] / "experiments"
    # ... round 6's Q, whose file spells it out, and round 5's O, the same but a final race on 10 seeds ...
    cfg = tomllib.loads((experiments / "offline_round6.toml").read_text())
    assert set(cfg) <= dests and cfg["max_leg_steps"] == ROBUST_MAX_LEG_STEPS
    assert _stage_of({**vars(parser.parse_args(["--noisy-trials", "0"])), **cfg}) == ROBUST_STAGE
    cfg = tomllib.loads((experiments / "offline_round5.toml").read_text())
    assert set(cfg) <= dests and cfg["noisy_from_start"] is True and cfg["noisy_trials"] == 1
    assert _stage_of({**defaults, **cfg}) == dataclasses.replace(ROBUST_STAGE, final_race=10)
    # ... and the paper's noise-free method, run_offline's default, is a file away.
    cfg = tomllib.loads((experiments / "offline_paper.toml").read_text())
    assert set(cfg) <= dests and cfg["max_leg_steps"] == offline.DEFAULT_MAX_LEG_STEPS
    assert _stage_of({**defaults, **cfg}).trials == offline.DEFAULT_NOISY.trials == 0
    assert "noisy_stage" not in offline.run_config(1, "default", 150, 64, offline.default_ga_config(),
                                                   _stage_of({**defaults, **cfg}))


def test_the_gate_keeps_the_champion_when_the_challenger_fails_it():
    from cosim.offline.noisy import noisy_generation
    from ga.operators import random_population

    pop = random_population(np.random.default_rng(3), 6)
    run_map = lambda fn, tasks: [fn(t) for t in tasks]  # noqa: E731
    challenged = 0
    for generation in range(6):
        stage = NoisyStage(trials=1)
        plain = noisy_generation(run_map, pop, stage, Records(), 1, generation, "one_obstacle", 80, 6)[2]
        asked = []
        shut = noisy_generation(run_map, pop, stage, Records(), 1, generation, "one_obstacle", 80, 6,
                                gate=lambda rows: asked.append(rows) or (False, 0))[2]
        open_ = noisy_generation(run_map, pop, stage, Records(), 1, generation, "one_obstacle", 80, 6,
                                 gate=lambda rows: (True, 0))[2]
        assert open_ == plain
        top = int(np.argmax(plain))
        if top != 0:
            challenged += 1
            assert len(asked) == 1 and np.array_equal(asked[0], pop[top]) and int(np.argmax(shut)) == 0
        else:
            assert asked == [] and shut == plain
    assert challenged >= 2


def test_after_the_gate_every_elite_still_reaches_every_target_noise_free(tmp_path):
    cfg = dict(SMALL, arena="one_obstacle", n_targets=8, max_leg_steps=80)
    stage = NoisyStage(trials=1, accept_runs=1000, keep_noise_free=True, leg_steps=100, budget_factor=2.0,
                       max_failures=8)
    s = run_offline(1, generations_cap=400, out=tmp_path, noisy=stage, **cfg)
    n = s["noisy_stage"]
    first = n["noise_free_best"]
    assert first["generations"] == n["from_generation"] - 1 and first["targets_reached"] == 8
    assert first["interactions"] + n["interactions"] == s["interactions"]
    assert 2.0 * first["interactions"] <= n["interactions"] and s["generations"] < 400  # the budget factor
    history = json.loads((tmp_path / "history.json").read_text())
    assert all(h["best_targets"] == 8 for h in history if h.get("stage") == 2)
    assert s["reached_all_targets"] and s["transfer"]["max_leg_steps"] == 100
    assert first["transfer"]["noise_seeds"] == s["transfer"]["noise_seeds"]
