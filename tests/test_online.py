"""The on-line model-based loop (cosim.online): determinism, resume, adaptation, the board interface."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cosim.boards import (
    ReferenceControllerBoard,
    ReferenceEvaluatorBoard,
    make_boards,
)
from cosim.online import OnlineConfig, OnlineRun, adaptation_figures, make_run
from ga.genome import validate_rows
from ga.operators import random_population
from ga.truth_table import truth_tables
from ga.world_model import WorldModel

# A short lifetime: a simple arena, a few targets, a small population (seconds, not minutes).
SMALL = dict(arena="one_obstacle", n_targets=4, population=40, tournament=5, generations_per_phase=3,
             max_leg_steps=300, loop_window=60)


def _figures(run: OnlineRun) -> dict:
    summary = run.summary()
    summary.pop("wall_time_s")
    summary.pop("hardware", None)  # holds a software timing beside the cycle counts
    return summary


def test_short_run_reaches_its_targets_and_is_deterministic():
    a = make_run(OnlineConfig(seed=3, **SMALL)).run()
    b = make_run(OnlineConfig(seed=3, **SMALL)).run()
    fa = _figures(a)
    assert fa["targets_reached"] == 4
    assert fa == _figures(b)
    assert a.motions == b.motions
    # Counting: every executed motion is one interaction of the world.
    assert fa["interactions"] == a.world.interactions == len(a.motions)
    assert fa["genetic_operations"] == fa["generations"] * SMALL["population"]
    assert fa["learning_phases"] == len(fa["phases"]) == sum(fa["phase_reasons"].values())
    assert fa["generations"] == fa["learning_phases"] * SMALL["generations_per_phase"]
    assert set(fa["phase_reasons"]) <= {"crash", "timeout", "loop"}
    # The evaluator board's model is exactly the host's mirror of the observations.
    assert a.evaluator.model == a.mirror
    assert fa["world_states"] == a.mirror.n_states


def test_other_seed_gives_another_lifetime():
    a = make_run(OnlineConfig(seed=3, **SMALL)).run()
    b = make_run(OnlineConfig(seed=4, **SMALL)).run()
    assert a.motions != b.motions


@pytest.mark.parametrize("options", [{}, {"mark_loops": "self", "escape": True, "targeted": 10,
                                          "model_update": "most_frequent", "loop_window": 15},
                                     {"loop_repeats": 4, "loop_reentries": 6, "loop_key": "motion",
                                      "escape_memory": True, "blame_phase_only": True, "loop_window": 15,
                                      "loop_still_mm": 40.0, "loop_patience": 2},
                                     {"loop_repeats": 4, "loop_reentries": 6, "loop_relax": 1,
                                      "relax_window": True, "escape_spread": "target", "loop_window": 15, "escape_rewrite": 5,
                                      "loop_radius_mm": 80.0},
                                     {"loop_repeats": 4, "loop_reentries": 6, "loop_window": 15,
                                      "escape_credit": True},
                                     {"loop_window": 15, "loop_penalty": 0.4},
                                     {"loop_window": 15, "distance_rule": "forward", "loop_cycles": 1,
                                      "download": "closest"}])
def test_resume_equals_uninterrupted(tmp_path, options):
    config = OnlineConfig(seed=5, **{**SMALL, **options})
    whole = make_run(config, out=tmp_path / "whole").run()
    assert len(whole.phases) >= 3, "the test needs a run with several learning phases"
    if options.get("mark_loops"):  # the replay must also restore the virtual crashes written after loop stops
        assert any(p.get("marked") for p in whole.phases[2:])
    part = make_run(config, out=tmp_path / "part").run(stop_after_phases=2)
    assert len(part.phases) == 2 and part.targets < config.n_targets
    resumed = make_run(config, out=tmp_path / "part", resume=True)
    assert resumed.interactions == part.interactions and resumed.evaluator.model == part.evaluator.model
    resumed.run()
    assert _figures(resumed) == _figures(whole)
    assert resumed.motions == whole.motions


def test_resume_refuses_another_config(tmp_path):
    from cosim.checkpoint import CheckpointError

    make_run(OnlineConfig(seed=5, **SMALL), out=tmp_path).run(stop_after_phases=1)
    with pytest.raises(CheckpointError, match="seed"):
        make_run(OnlineConfig(seed=6, **SMALL), out=tmp_path, resume=True)


def test_adaptation_blinds_the_bit_after_the_chosen_target():
    config = OnlineConfig(seed=3, **{**SMALL, "n_targets": 5}, blind_bit=0, blind_after_target=2)
    run = make_run(config).run()
    ad = run.summary()["adaptation"]
    assert ad["blinded_after_target"] == 2
    at = ad["blinded_at_interaction"]
    t2 = next(t for t in run.target_log if t["target"] == 2)
    assert at == t2["interactions"]
    # After the blinding no observed state has the front bit set; before, some may.
    assert all(s & 1 == 0 for s in run.state_log[at:])
    assert ad["per_target"] == [t["interactions"] - at for t in run.target_log if t["target"] > 2]
    # Same seed without the fault: identical up to the blinding.
    plain = make_run(OnlineConfig(seed=3, **{**SMALL, "n_targets": 5})).run()
    assert plain.motions[:at] == run.motions[:at]


def test_adaptation_figures_need_the_whole_window():
    log = [{"target": t, "interactions": 100 * t} for t in range(1, 12)]
    ad = adaptation_figures(log, after=2, blinded_at=200)
    assert ad["per_target"] == [100 * k for k in range(1, 9)]
    assert ad["interactions_for_next_targets"] == 800
    assert adaptation_figures(log[:6], 2, 200)["interactions_for_next_targets"] is None


class _InterfaceOnly:
    """Exposes only the board Protocol's methods of a wrapped board, and logs the calls."""

    def __init__(self, board, names, log):
        self._board, self._log = board, log
        for name in names:
            setattr(self, name, self._wrap(name))

    def _wrap(self, name):
        def call(*args):
            self._log.append(name)
            return getattr(self._board, name)(*args)
        return call

    @property
    def cycles(self):
        return self._board.cycles


def test_loop_uses_only_the_board_interface():
    log: list[str] = []
    controller = _InterfaceOnly(ReferenceControllerBoard(), ("load", "set_reflex", "motion"), log)
    evaluator = _InterfaceOnly(ReferenceEvaluatorBoard(), ("observe", "evaluate"), log)
    config = OnlineConfig(seed=3, **SMALL)
    run = OnlineRun(config, controller, evaluator).run()
    assert _figures(run) | {"backend": None} == _figures(make_run(config).run()) | {"backend": None}
    assert log.count("observe") == run.interactions
    assert log.count("evaluate") == run.generations


def test_reference_boards_follow_the_models():
    rng = np.random.default_rng(0)
    pop = random_population(rng, 3)
    controller, evaluator = make_boards("reference")
    controller.load(pop[1])
    table = truth_tables(pop[1], reflex=True)
    assert [controller.motion(s) for s in range(256)] == table.tolist()
    controller.set_reflex(False)
    assert [controller.motion(s) for s in range(256)] == truth_tables(pop[1], reflex=False).tolist()
    with pytest.raises(ValueError, match="one genome"):
        controller.load(pop)
    model = WorldModel()
    for s, a, s2, c in [(1, 0, 2, False), (2, 3, 2, True), (2, 0, 1, False)]:
        evaluator.observe(s, a, s2, c)
        model.observe(s, a, s2, c)
    counts = evaluator.evaluate(pop)
    from ga.evaluator import evaluate_population

    ref = evaluate_population(validate_rows(pop), model)
    assert np.array_equal(counts.crashes, ref.crashes) and np.array_equal(counts.loops, ref.loops)
    assert np.array_equal(counts.distance, ref.distance)


def test_unknown_backend_is_refused():
    with pytest.raises(ValueError, match="unknown backend"):
        make_boards("vhdl")


def main(argv):
    """``ehw sim ...`` (the on-line command line)."""
    from cosim.cli import main as ehw

    return ehw(["sim", *argv])


def test_command_line_writes_summary_and_plots(tmp_path, capsys):
    rc = main(["--seed", "2", "--arena", "empty", "--targets", "3", "--population", "20",
               "--generations-per-phase", "2", "--out", str(tmp_path), "--no-progress"])
    assert rc == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    for key in ("interactions", "generations", "genetic_operations", "world_states", "transitions",
                "targets_reached", "best_genome", "seed", "wall_time_s", "learning_phases", "phase_reasons"):
        assert key in summary
    assert summary["targets_reached"] == 3
    assert (tmp_path / "fig9_trajectory.png").stat().st_size > 1000
    assert (tmp_path / "fig10_targets_states.png").exists()
    assert "paper" in capsys.readouterr().out


def test_continue_past_64_reports_the_64th_target_and_fig11(tmp_path, capsys):
    rc = main(["--seed", "2", "--arena", "empty", "--population", "20", "--generations-per-phase", "2",
               "--continue-past-64", "2", "--out", str(tmp_path), "--no-progress"])
    assert rc == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["targets_reached"] == 66
    at64 = summary["at_64_targets"]
    assert at64["target"] == 64 and at64["interactions"] < summary["interactions"]
    assert (tmp_path / "fig11_continued.png").exists()
    out = capsys.readouterr().out
    assert f"{at64['interactions']:,}" in out and "continued to 66 targets" in out
