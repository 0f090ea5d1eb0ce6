"""Post hoc: every candidate of an off-line run's final race on the run's transfer seeds.

    python experiments/offline_final_candidates.py RUN_FOLDER [RUN_FOLDER ...]

A run folder of `ehw offline` with a final race (``--noisy-final-race``) keeps its candidates (the
last distinct elites) in ``checkpoint.json``. Each drives the run's 20 transfer noise seeds at the
run's transfer leg limit (`cosim.offline.noisy.transfer`): one line per run with the race's
winner and, per candidate, its failed legs in the race and its transfer fraction. It tells whether
a better final choice could lift the run (docs/research-log.md, off-line round 6); the transfer seeds are never
used by the run, so this is a check, not a selection rule.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from cosim.offline.noisy import transfer


def candidates(folder: Path) -> dict:
    state = json.loads((folder / "checkpoint.json").read_text())["state"]
    summary = json.loads((folder / "summary.json").read_text())
    race = summary["noisy_stage"]["final_race"]
    limit, seed = summary["transfer"]["max_leg_steps"], summary["seed"]
    arena = summary["config"]["arena"]
    rows = []
    for i, (_, genome) in enumerate(state["noisy"]["elites"]):
        t = transfer(genome, arena, limit, summary["config"]["n_targets"], seed, len(summary["transfer"]["noise_seeds"]))
        rows.append({"candidate": i, "race_failed_legs": race["failed_legs_clean_runs_mean_fitness"][i][0],
                     "transfer": t["all_targets_fraction"]})
    return {"run": str(folder), "winner": race["winner"], "candidates": rows}


if __name__ == "__main__":
    for arg in sys.argv[1:]:
        print(json.dumps(candidates(Path(arg))), flush=True)
