"""The on-line model-based loop (cosim.online.run): determinism, resume, adaptation, the board interface."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cosim.boards.reference import ReferenceControllerBoard, ReferenceEvaluatorBoard
from cosim.boards.registry import make_boards
from cosim.cli.main import main
from cosim.cli.online import build_parser, config_from_args
from cosim.online.config import option
from cosim.online.report import adaptation_figures, summary_table
from cosim.online.run import OnlineConfig, OnlineRun, make_run
from ga.genome import validate_rows
from ga.motions import OBSTACLE_MASK
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


@pytest.mark.parametrize("options", [{}, {"loop_window": 15, "loop_reentries": 0, "loop_repeats": 6},
                                     {"loop_window": 15, "distance_rule": "covered", "loop_cycles": 0},
                                     {"fail_rates": False}])
def test_resume_equals_uninterrupted(tmp_path, options):
    config = OnlineConfig(seed=9, **{**SMALL, **options})  # 5-6 learning phases under every option
    whole = make_run(config, out=tmp_path / "whole").run()
    assert len(whole.phases) >= 3, "the test needs a run with several learning phases"
    part = make_run(config, out=tmp_path / "part").run(stop_after_phases=2)
    assert len(part.phases) == 2 and part.targets < config.n_targets
    resumed = make_run(config, out=tmp_path / "part", resume=True)
    assert resumed.interactions == part.interactions and resumed.evaluator.model == part.evaluator.model
    assert (resumed.evaluator.rates == part.evaluator.rates).all()
    resumed.run()
    assert _figures(resumed) == _figures(whole)
    assert resumed.motions == whole.motions


def test_resume_refuses_another_config(tmp_path):
    from base.checkpoint import CheckpointError

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
    evaluator = _InterfaceOnly(ReferenceEvaluatorBoard(), ("observe", "write_rates", "evaluate"), log)
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


def ehw_sim(argv):
    """``ehw sim ...`` (the on-line command line)."""
    from cosim.cli.main import main as ehw

    return ehw(["sim", *argv])


def test_command_line_writes_summary_and_plots(tmp_path, capsys):
    rc = ehw_sim(["--seed", "2", "--arena", "empty", "--targets", "3", "--population", "20",
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
    rc = ehw_sim(["--seed", "2", "--arena", "empty", "--population", "20", "--generations-per-phase", "2",
               "--continue-past-64", "2", "--out", str(tmp_path), "--no-progress"])
    assert rc == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["targets_reached"] == 66
    at64 = summary["at_64_targets"]
    assert at64["target"] == 64 and at64["interactions"] < summary["interactions"]
    assert (tmp_path / "fig11_continued.png").exists()
    out = capsys.readouterr().out
    assert f"{at64['interactions']:,}" in out and "continued to 66 targets" in out


def test_distance_rule_reaches_the_evaluator_and_changes_the_lifetime():
    """dist[a] "forward" (SPEC section 7, the default) or "covered" (the paper's first reading):
    the same seed gives the same lifetime, the rules different ones, and the table says which."""
    def lifetime(rule):
        run = make_run(OnlineConfig(seed=1, **{**SMALL, "distance_rule": rule})).run()
        assert run.evaluator.distance_rule == rule
        return run

    a, b, first = lifetime("forward"), lifetime("forward"), lifetime("covered")
    assert a.motions == b.motions and a.targets == 4
    assert a.motions != first.motions
    assert "dist[a] = covered" in summary_table(first.summary())
    assert "dist[a]" not in summary_table(a.summary())


def test_phase_records_name_the_detector_and_the_escape():
    run = make_run(OnlineConfig(seed=10, **{**SMALL, "loop_window": 15})).run()
    loops = [p for p in run.phases if p["reason"] == "loop"]
    assert loops and {p["detector"] for p in loops} <= {"window", "reentries", "repeats", "cycles"}
    assert all("detector" not in p for p in run.phases if p["reason"] != "loop")
    for p in run.phases:  # the downloaded controller avoids the blamed motion when escaped
        if p.get("escaped"):
            assert p["changed"] and p["new_motion"] != p["motion"]


@pytest.mark.parametrize("ga", ["host", "hardware"])
def test_cycle_stops_are_blamed_in_the_cycle_that_stopped_the_leg(ga):
    """``loop_blame`` "cycle" (the default, round 8): a cycle stop is put on the robot's current
    state when it has an obstacle bit (the cycle starts there), so the escape changes the next
    motion, with the host GA and on the learning board alike (its escape gets the phase's pair);
    "leg" (rounds 1-7), the leg's most frequent obstacle pair, is another pair in some stops, and
    the two give other lifetimes."""
    def cycle_stops(rule):
        config = OnlineConfig(seed=5, max_interactions=1000, population=100, loop_blame=rule, ga=ga)
        run = make_run(config).run()
        stops = [p for p in run.phases if p.get("detector") == "cycles"]
        assert stops
        here = [run.state_log[p["interactions"] - 1] for p in stops]  # the state at the stop
        return run, [(p["state"], now) for p, now in zip(stops, here) if now & OBSTACLE_MASK]

    run, pairs = cycle_stops("cycle")
    assert pairs and all(blamed == now for blamed, now in pairs)
    legacy, pairs = cycle_stops("leg")
    assert any(blamed != now for blamed, now in pairs)
    assert legacy.motions != run.motions


def test_defaults_and_command_line():
    """SPEC section 7's defaults; ``--distance covered --loop-cycles 0`` is the first reading."""
    default = config_from_args(build_parser().parse_args([]))
    assert default == OnlineConfig()
    options = {a.dest for a in build_parser()._actions}
    for field in OnlineConfig().to_dict():  # every field has its option (named in the errors)
        assert option(field).lstrip("-").replace("-", "_") in options | {"targets"}, field
    assert (default.distance_rule, default.loop_cycles, default.loop_blame) == ("forward", 1, "cycle")
    assert config_from_args(build_parser().parse_args(["--loop-blame", "leg"])).loop_blame == "leg"
    args = build_parser().parse_args(["--distance", "covered", "--loop-cycles", "0", "--no-escape",
                                      "--continue-past-64", "3", "--loop-radius-mm", "40"])
    config = config_from_args(args)
    assert (config.distance_rule, config.loop_cycles, config.escape, config.n_targets,
            config.loop_radius_mm) == ("covered", 0, False, 67, 40.0)


@pytest.mark.parametrize("field, value, message", [
    ("loop_window", -3, "--loop-window must be >= 0, got -3"),
    ("n_targets", 0, "--targets must be >= 1, got 0"),
    ("population", 2.5, "--population must be an integer, got 2.5"),
    ("loop_radius_mm", float("nan"), "--loop-radius-mm must be a finite distance >= 0, got nan"),
    ("literal_rate", 1.5, "--literal-rate must be a rate in [0, 1], got 1.5"),
    ("distance_rule", "backward", "--distance must be one of covered, forward, got 'backward'"),
    ("elitism", 600, "--elitism must be in 0..population, got 600"),
    ("blind_bit", 7, "--blind-bit and --blind-after-target go together"),
    ("escape", 1, "--escape must be True or False, got 1"),
    ("loop_blame", "phase", "--loop-blame must be one of cycle, leg, got 'phase'"),
])
def test_config_refuses_bad_values_naming_the_option(field, value, message):
    with pytest.raises(ValueError) as info:
        OnlineConfig(**{field: value})
    assert message in str(info.value)
    with pytest.raises(ValueError, match="--blind-bit must be an IR bit 0..5, got 7"):
        OnlineConfig(blind_bit=7, blind_after_target=3)


def test_command_line_error_is_one_line_and_status_2(capsys):
    assert main(["sim", "--loop-window", "-3", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err == "error: --loop-window must not be negative, got -3\n"


def test_dropped_options_are_gone():
    help_text = build_parser().format_help()
    for name in ("--mark-loops", "--targeted", "--download", "--loop-penalty", "--escape-spread",
                 "--model-update", "--loop-key", "--loop-relax", "--escape-credit", "--blame-phase-only"):
        assert name not in help_text


def test_interaction_breakdown_on_hand_made_records():
    from cosim.online.report import interaction_breakdown

    phases = [{"interactions": 10, "reason": "crash", "state": 1, "motion": 0},
              {"interactions": 25, "reason": "loop", "state": 1, "motion": 3},
              {"interactions": 40, "reason": "loop", "state": 1, "motion": 3}]
    targets = [{"target": 1, "interactions": 20}, {"target": 2, "interactions": 30}]
    got = interaction_breakdown(phases, targets, 50, block=1)
    # failed segments: 0-10, 20-25 (after target 1), 30-40 (after target 2)
    assert got == {"in_failed_segments": 25, "per_failure": 8.33, "first_leg": 20,
                   "per_block": [20, 10, 20], "block": 1, "repeated_blames": 1}
    run = make_run(OnlineConfig(seed=5, **SMALL)).run()
    where = run.summary()["where_interactions_go"]
    assert 0 < where["in_failed_segments"] <= run.interactions
    assert sum(where["per_block"]) == run.interactions
