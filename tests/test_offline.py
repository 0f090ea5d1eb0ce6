"""The off-line runner: serial == process pool, resume == uninterrupted, checkpoint checks, outputs."""

import json

import pytest

from base.checkpoint import CheckpointError
from cosim.cli.main import main as ehw
from cosim.offline.run import default_ga_config, run_offline

SMALL = dict(arena="one_obstacle", max_leg_steps=80, n_targets=64, progress=False, plots=False,
             transfer_trials=0, ga_config=default_ga_config(population=8, tournament=3))
VOLATILE = ("wall_time_s", "workers", "figures", "simulated_interactions")  # cache is per session


def _stable(summary):
    return {k: v for k, v in summary.items() if k not in VOLATILE}


def _checkpoint_state(out):
    state = json.loads((out / "checkpoint.json").read_text())["state"]
    state.pop("wall_time_s")
    state.pop("simulated_interactions")
    return state


def test_serial_equals_process_pool(tmp_path):
    serial = run_offline(3, generations_cap=4, workers=1, out=tmp_path / "s", **SMALL)
    pooled = run_offline(3, generations_cap=4, workers=2, out=tmp_path / "p", **SMALL)
    assert _stable(serial) == _stable(pooled)
    assert _checkpoint_state(tmp_path / "s") == _checkpoint_state(tmp_path / "p")
    assert serial["generations"] == 4 and serial["genetic_operations"] == 32
    assert serial["interactions"] > 0 and serial["world_states"] > 0


class Interrupt(Exception):
    pass


def test_resume_equals_uninterrupted(tmp_path):
    straight = run_offline(5, generations_cap=7, out=tmp_path / "a", **SMALL)

    def stop_at_3(entry):
        if entry["generation"] == 3:
            raise Interrupt

    with pytest.raises(Interrupt):
        run_offline(5, generations_cap=7, out=tmp_path / "b", on_generation=stop_at_3, **SMALL)
    assert json.loads((tmp_path / "b" / "checkpoint.json").read_text())["state"]["ga"]["generation"] == 3
    resumed = run_offline(5, generations_cap=7, out=tmp_path / "b", resume=True, **SMALL)
    assert _stable(resumed) == _stable(straight)
    assert _checkpoint_state(tmp_path / "a") == _checkpoint_state(tmp_path / "b")
    history = json.loads((tmp_path / "b" / "history.json").read_text())
    assert [h["generation"] for h in history] == list(range(1, 8))


def test_stops_when_the_best_reaches_every_target(tmp_path):
    cfg = dict(SMALL, arena="empty", n_targets=2)
    summary = run_offline(1, generations_cap=200, out=tmp_path, **cfg)
    assert summary["reached_all_targets"] and summary["targets_reached"] == 2
    assert summary["generations"] < 200
    # Resuming a finished run evaluates nothing more.
    again = run_offline(1, generations_cap=200, out=tmp_path, resume=True, **cfg)
    assert _stable(again) == _stable(summary)


def test_resume_with_another_config_is_refused(tmp_path):
    run_offline(2, generations_cap=1, out=tmp_path, **SMALL)
    with pytest.raises(CheckpointError, match="seed: saved 2, now 9"):
        run_offline(9, generations_cap=2, out=tmp_path, resume=True, **SMALL)
    with pytest.raises(CheckpointError, match="max_leg_steps"):
        run_offline(2, generations_cap=2, out=tmp_path, resume=True, **dict(SMALL, max_leg_steps=81))


def test_resume_from_a_corrupt_checkpoint_is_refused(tmp_path):
    run_offline(2, generations_cap=1, out=tmp_path, **SMALL)
    (tmp_path / "checkpoint.json").write_text('{"format": 1, "kind": "model_free", "conf')
    with pytest.raises(CheckpointError, match="corrupt"):
        run_offline(2, generations_cap=2, out=tmp_path, resume=True, **SMALL)


def test_command_line_writes_summary_figures_and_transfer(tmp_path, capsys):
    out = tmp_path / "run"
    ehw(["offline", "--seed", "4", "--generations-cap", "2", "--arena", "empty", "--max-leg-steps", "60",
          "--out", str(out), "--quiet"])
    summary = json.loads((out / "summary.json").read_text())
    for key in ("interactions", "generations", "genetic_operations", "world_states", "transitions",
                "targets_reached", "best_genome", "seed", "wall_time_s", "transfer"):
        assert key in summary
    assert len(summary["best_genome"]) == 238 and summary["seed"] == 4
    assert len(summary["transfer"]["targets_without_crash"]) == 20
    assert summary["transfer"]["max_leg_steps"] == 60  # the run's own leg limit by default
    assert (out / "fig5_trajectory.png").stat().st_size > 1000
    assert (out / "fig6_best_per_generation.png").stat().st_size > 1000
    assert "wrote" in capsys.readouterr().out


def test_evaluator_cache_gives_the_driven_result():
    import numpy as np

    from cosim.offline.run import Evaluator, evaluate
    from ga.operators import random_population
    from sim_world.world import World

    pop = random_population(np.random.default_rng(0), 6)
    pop = np.concatenate([pop, pop[:3]])  # repeated genomes are driven once
    with Evaluator("one_obstacle", 80) as evaluator:
        got = evaluator(pop)
        assert evaluator.simulated_steps == sum(e.steps for e in got[:6])
    world = World("one_obstacle")
    assert got == [evaluate(world, g, 80) for g in pop]
    # A full cache is emptied without losing this call's hits.
    more = np.concatenate([pop[:3], random_population(np.random.default_rng(1), 3)])
    with Evaluator("one_obstacle", 80, cache_size=7) as small:
        assert small(pop[:6]) == got[:6]
        assert small(more) == [evaluate(world, g, 80) for g in more]


def test_transfer_leg_steps_sets_the_transfer_runs_limit(tmp_path, capsys):
    from cosim.offline.noisy import transfer

    out = tmp_path / "run"
    ehw(["offline", "--seed", "4", "--generations-cap", "2", "--arena", "empty", "--max-leg-steps", "60",
         "--out", str(out), "--quiet", "--no-plots", "--transfer-trials", "2", "--transfer-leg-steps", "500"])
    t = json.loads((out / "summary.json").read_text())["transfer"]
    assert t["max_leg_steps"] == 500 and "(leg limit 500)" in capsys.readouterr().out
    best = json.loads((out / "summary.json").read_text())["best_genome"]
    assert transfer(best, "empty", 1, 3, 4, trials=2)["targets_without_crash"] == [0, 0]  # every leg times out
    assert min(transfer(best, "empty", 500, 3, 4, trials=2)["targets_without_crash"]) > 0
    assert ehw(["offline", "--transfer-leg-steps", "-1", "--out", str(tmp_path / "bad"), "--quiet"]) != 0
    assert "error: --transfer-leg-steps must be at least 0" in capsys.readouterr().err
