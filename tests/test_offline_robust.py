"""The off-line method's robust stage (cosim.offline_robust) and the world's systematic motor error."""

import json
import math

import numpy as np
import pytest

from cosim.offline import default_ga_config, run_offline
from cosim.offline_robust import RobustStage
from ga.motions import Motion
from sim_world.world import Bias, World

SMALL = dict(arena="one_obstacle", max_leg_steps=80, n_targets=6, progress=False, plots=False, transfer_trials=2,
             ga_config=default_ga_config(population=6, tournament=2))
STAGE = RobustStage(bias_deg=(1.0, 3.0), translations=(0.1,))


def test_a_bias_turns_and_stretches_every_motion_the_same_way():
    plain, biased = World("empty"), World("empty", bias=Bias(rotation_deg=2.0, translation_scale=1.2))
    for w in (plain, biased):
        w.place((1000.0, 1000.0, 0.0))
    for _ in range(3):
        plain.step(int(Motion.FORWARD))
        biased.step(int(Motion.FORWARD))
    assert plain.pose[0] == pytest.approx(1150.0) and plain.pose[2] == 0.0
    assert biased.pose[2] == pytest.approx(math.radians(6.0))
    # The midpoint rule: the k-th step goes along the heading (2k - 1) degrees, 60 mm long.
    x = 1000.0 + sum(60.0 * math.cos(math.radians(2 * k - 1)) for k in (1, 2, 3))
    assert biased.pose[0] == pytest.approx(x)
    biased.step(int(Motion.TURN_LEFT))
    plain.step(int(Motion.TURN_LEFT))
    assert biased.pose[2] - plain.pose[2] == pytest.approx(math.radians(8.0))
    assert World("empty", bias=Bias()).bias is None  # zero: the plain world
    for bad in (dict(rotation_deg=math.nan), dict(translation_scale=0.0)):
        with pytest.raises(ValueError):
            Bias(**bad)
    with pytest.raises(TypeError, match="Bias"):
        World("empty", bias=2.0)


def test_the_stage_has_two_mirrored_scenarios_a_level_and_checks_its_parameters():
    plus, minus = STAGE.scenarios(1)
    assert plus == Bias(3.0, 1.1) and minus == Bias(-3.0, 1.1)
    assert RobustStage(bias_deg=(2,), translations=(0.1, -0.1)).scenarios(0) == \
        (Bias(2.0, 1.1), Bias(-2.0, 1.1), Bias(2.0, 0.9), Bias(-2.0, 0.9))
    assert RobustStage(bias_deg=(2,), translations=(0.1, -0.1), paired=True).scenarios(0) == \
        (Bias(2.0, 1.1), Bias(-2.0, 0.9))
    assert STAGE.combined([2.0, 5.0]) == 7.0 and RobustStage(bias_deg=(1,), combine="min").combined([2.0, 5.0]) == 2.0
    assert not RobustStage().enabled and STAGE.levels == 2
    for bad in (dict(bias_deg=(0.0,)), dict(bias_deg=(50,)), dict(translations=(0.7,)), dict(translations=()), dict(combine="mean"),
                dict(max_generations=0), dict(budget=-1), dict(budget_factor=0.5)):
        with pytest.raises(ValueError):
            RobustStage(**bad)


def test_the_robust_stage_follows_the_noise_free_one_passes_its_levels_and_is_counted(tmp_path):
    plain = run_offline(1, generations_cap=300, out=tmp_path / "plain", **SMALL)
    robust = run_offline(1, generations_cap=300, out=tmp_path / "robust", robust=STAGE, **SMALL)
    r = robust["robust_stage"]
    assert plain["reached_all_targets"] and r["accepted"]
    assert r["from_generation"] == plain["generations"] + 1
    assert robust["generations"] == plain["generations"] + r["generations"] and r["generations"] >= 2
    assert robust["interactions"] == plain["interactions"] + r["interactions"] > plain["interactions"]
    assert [lv["bias_deg"] for lv in r["levels_passed"]] == [1.0, 3.0]
    assert r["robust_targets"] == [6, 6] and r["robust_bias_deg"] == 3.0
    assert robust["config"]["robust_stage"] == STAGE.to_dict() and "robust_stage" not in plain["config"]
    history = json.loads((tmp_path / "robust" / "history.json").read_text())
    assert [h.get("stage", 1) for h in history].count(2) == r["generations"]
    # The elite's perturbed fitness never falls within a level: the runs are deterministic.
    for level in (0, 1):
        f = [h["robust_fitness"] for h in history if h.get("robust_level") == level]
        assert f == sorted(f)
    # Its final controller reaches every target in both perturbed worlds (checked anew here).
    from ga.genome import rows_from_hex
    from ga.truth_table import truth_tables
    from sim_world.course import run_course

    table = truth_tables(rows_from_hex(robust["best_genome"]), reflex=True)
    for bias in STAGE.scenarios(1):
        assert run_course(World("one_obstacle", bias=bias), table, 80, n_targets=6).targets_reached == 6
    with pytest.raises(ValueError, match="exclude"):
        from cosim.offline_noisy import NoisyStage

        run_offline(1, out=tmp_path / "both", robust=STAGE, noisy=NoisyStage(trials=1), **SMALL)


def test_the_robust_stage_resumes_bit_for_bit_and_pool_equals_serial(tmp_path):
    straight = run_offline(2, generations_cap=300, out=tmp_path / "a", robust=STAGE, **SMALL)
    first = straight["robust_stage"]["from_generation"]

    class Stop(Exception):
        pass

    def stop(entry):
        if entry["generation"] == first:
            raise Stop

    with pytest.raises(Stop):
        run_offline(2, generations_cap=300, out=tmp_path / "b", robust=STAGE, on_generation=stop, **SMALL)
    resumed = run_offline(2, generations_cap=300, out=tmp_path / "b", robust=STAGE, resume=True, **SMALL)
    pooled = run_offline(2, generations_cap=300, out=tmp_path / "c", robust=STAGE, workers=2, **SMALL)
    volatile = ("wall_time_s", "workers", "simulated_interactions")
    for other in (resumed, pooled):
        assert {k: v for k, v in other.items() if k not in volatile} == \
            {k: v for k, v in straight.items() if k not in volatile}


def test_the_budget_ends_the_robust_stage(tmp_path):
    plain = run_offline(1, generations_cap=300, out=tmp_path / "plain", **SMALL)
    budget = plain["interactions"] + 1
    s = run_offline(1, generations_cap=300, out=tmp_path / "b", robust=RobustStage(bias_deg=(20.0,), budget=budget),
                    **SMALL)
    r = s["robust_stage"]
    assert not r["accepted"] and r["generations"] == 1 and s["interactions"] >= budget
    # No level passed: the result is the noise-free best the stage started from.
    assert s["best_genome"] == r["noise_free_best"]["genome"] and s["reached_all_targets"]
    assert s["best_genome"] == plain["best_genome"]


def test_a_level_left_half_done_returns_the_elite_of_the_level_before(tmp_path):
    """The result is the elite that passed the last level passed; the budget factor ends the run."""
    stage = RobustStage(bias_deg=(1.0, 20.0), translations=(0.1,), combine="min", budget_factor=30.0)
    s = run_offline(1, generations_cap=300, out=tmp_path, robust=stage, **SMALL)
    r = s["robust_stage"]
    noise_free = r["noise_free_best"]["run_interactions"]
    assert [lv["bias_deg"] for lv in r["levels_passed"]] == [1.0] and not r["accepted"]
    assert 30 * noise_free <= s["interactions"] and s["generations"] < 300
    assert r["robust_level"] == 0 and r["robust_targets"] == [6, 6]  # the level-1 elite, not the last
    history = json.loads((tmp_path / "history.json").read_text())
    assert history[-1]["robust_level"] == 1 and min(history[-1]["robust_targets"]) < 6


def test_the_command_line_checks_the_robust_options(tmp_path, monkeypatch, capsys):
    from cosim.cli import main

    monkeypatch.chdir(tmp_path)
    for args, word in ((["--robust-bias-deg", "x"], "--robust-bias-deg"),
                       (["--robust-bias-deg", "60"], "bias"),
                       (["--robust-bias-deg", "2", "--robust-translations", "0.9"], "translations"),
                       (["--robust-bias-deg", "2", "--noisy-trials", "1"], "exclude"),
                       (["--robust-budget", "-1"], "--robust-budget")):
        capsys.readouterr()
        status = main(["offline", "--quiet", "--no-plots", "--out", "run", *args])
        err = capsys.readouterr().err.strip().splitlines()
        assert status == 2 and len(err) == 1 and err[0].startswith("error: ") and word in err[0], (args, err)
    assert not (tmp_path / "run" / "summary.json").exists()


def test_a_robust_run_resumes_with_its_options_from_config_toml(tmp_path, monkeypatch, capsys):
    from cosim.cli import main

    monkeypatch.chdir(tmp_path)
    tiny = ["--arena", "empty", "--max-leg-steps", "40", "--quiet", "--no-plots", "--transfer-trials", "0"]
    robust = ["--robust-bias-deg", "2,3", "--robust-translations=0.1,-0.1", "--robust-paired", "--robust-combine", "min"]
    assert main(["offline", *tiny, *robust, "--generations-cap", "1", "--out", "run"]) == 0
    assert 'robust_bias_deg = "2,3"' in (tmp_path / "run/config.toml").read_text()
    assert main(["offline", "--resume", "--out", "run", "--generations-cap", "2"]) == 0
    summary = json.loads((tmp_path / "run/summary.json").read_text())
    assert summary["generations"] == 2
    assert summary["config"]["robust_stage"]["bias_deg"] == [2.0, 3.0] and summary["config"]["robust_stage"]["paired"]
