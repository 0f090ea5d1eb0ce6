"""The off-line transfer study (experiments/offline_transfer_failures.py, offline_transfer_limits.py,
offline_final_candidates.py): the diagnosis, the leg limits and the final race's candidates."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from ga.genome import hex_from_rows

SCRIPT = Path(__file__).resolve().parent.parent / "experiments" / "offline_transfer_failures.py"


def test_diagnosis_names_the_failing_step():
    spec = importlib.util.spec_from_file_location("offline_transfer_failures", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    # An empty controller: forward wherever the reflex does not decide -> into the first obstacle.
    rows = module.diagnose(hex_from_rows(np.zeros(50, dtype=np.uint32)), "default", 150, trials=2,
                           first_seed=5)
    assert [r["seed"] for r in rows] == [5, 6]
    for r in rows:
        assert r["kind"] in ("crash", "time-out") and r["targets"] < 64
        if r["kind"] == "crash":
            assert 0 <= r["state"] < 256 and r["motion"] in range(8) and r["clearance_mm"] >= 0


def test_transfer_limits_tabulates_each_summary_and_the_baseline(tmp_path, capsys):
    import json

    from cosim.offline.run import default_ga_config, run_offline

    spec = importlib.util.spec_from_file_location("offline_transfer_limits", SCRIPT.with_name("offline_transfer_limits.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    run_offline(4, generations_cap=2, out=tmp_path / "run", arena="empty", max_leg_steps=60, n_targets=3,
                progress=False, plots=False, transfer_trials=0, ga_config=default_ga_config(population=6, tournament=2))
    summary = tmp_path / "run" / "summary.json"
    assert module.main([str(summary), "--limits", "1,500", "--trials", "2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].endswith("| leg limit 1 | leg limit 500 |") and len(lines) == 4
    assert lines[2].split(" | ")[3] == "0"  # a leg limit of 1 step times every leg out
    assert lines[3].startswith("| hand-written baseline") and lines[3].split(" | ")[3] == "0"
    assert lines[3].endswith("| 1 |")  # the baseline reaches 3 targets in the empty arena
    assert json.loads(summary.read_text())["seed"] == 4
    assert module.main([str(summary), "--limits", "0"]) == 2
    assert capsys.readouterr().err.startswith("error: ")


def test_final_candidates_scores_every_candidate_of_the_final_race(tmp_path, capsys):
    from cosim.offline.noisy import NoisyStage
    from cosim.offline.run import default_ga_config, run_offline

    spec = importlib.util.spec_from_file_location("offline_final_candidates",
                                                  SCRIPT.with_name("offline_final_candidates.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    stage = NoisyStage(trials=1, race=2, accept_runs=1000, budget=6000, from_start=True, leg_soft_steps=40,
                       final_race=2, final_candidates=3)
    s = run_offline(1, generations_cap=20, out=tmp_path, noisy=stage, arena="one_obstacle", max_leg_steps=80,
                    n_targets=4, progress=False, plots=False, transfer_trials=2,
                    ga_config=default_ga_config(population=6, tournament=2))
    got = module.candidates(tmp_path)
    race = s["noisy_stage"]["final_race"]
    assert got["run"] == str(tmp_path) and got["winner"] == race["winner"]
    assert [c["candidate"] for c in got["candidates"]] == list(range(race["candidates"]))
    for c, (failed, *_rest) in zip(got["candidates"], race["failed_legs_clean_runs_mean_fitness"]):
        assert c["race_failed_legs"] == failed and c["transfer"] in (0.0, 0.5, 1.0)  # 2 transfer seeds
    # the winner's transfer is the run's own
    assert got["candidates"][race["winner"]]["transfer"] == s["transfer"]["all_targets_fraction"]
