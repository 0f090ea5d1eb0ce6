"""Choose the tabular learners' hyper-parameters on the tuning seeds only (issue 16, honest tuning).

    python experiments/tune_tabular.py [--jobs 2] [--cluster local] [--out build/experiments/tuning]

For each learner (Q-learning, Dyna-Q, prioritized sweeping) and reward (shaped, unshaped) it runs
one lifetime (``peers.lifetime.run_lifetime``, the protocol of `make compare`) per grid point and
per seed of ``peers.tabular.TUNING_SEEDS`` (1001-1003), through the sweep executor of `make
compare` (cached: an interrupted tuning resumes), and picks the grid point of the lowest median
interactions to 64 targets (a capped lifetime counts as its cap; ties: the lower mean). It writes
``<out>/tabular.json`` (every grid point's figures and the choice) and prints the ``TUNED``
entries that peers/tabular.py holds. `make compare` reports other seeds (1..N by default) and
says in its table which seeds were used here.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import time
from pathlib import Path

import numpy as np

from cosim.compare.sweep import Cache, executor, run_sweep
from peers.lifetime import MAX_INTERACTIONS, SHAPINGS, run_lifetime
from peers.tabular import LEARNERS, TUNING_SEEDS, LearnerConfig

# The grid (S&B's examples and Kaelbling et al.'s use alpha 0.1-1, epsilon 0.01-0.1, n 5-50).
ALPHAS = (0.2, 0.5, 1.0)
EPSILONS = (0.02, 0.1)
GAMMAS = (0.9, 0.97)
PLANNING = (10,)  # Dyna-Q and prioritized sweeping only (5 and 20 cost more CPU than this machine had)


def grid(method: str) -> list[LearnerConfig]:
    planning = (0,) if method == "q-learning" else PLANNING
    return [LearnerConfig(alpha=a, epsilon=e, gamma=g, planning_steps=n)
            for a, e, g, n in itertools.product(ALPHAS, EPSILONS, GAMMAS, planning)]


def lifetime(task: dict) -> dict:
    cfg = task["config"]
    t0 = time.process_time()
    res = run_lifetime(task["method"].split("/")[0], task["seed"], shaping=cfg["shaping"],
                       config=LearnerConfig(**cfg["learner"]), max_interactions=cfg["max_interactions"])
    res.pop("target_interactions")
    res["cpu_s"] = round(time.process_time() - t0, 2)
    return res


def choose(tasks: list[dict], results: list[dict], field: str) -> tuple[list[dict], dict]:
    """Group the lifetimes by (row, grid point: ``task["config"][field]``); per row, the point of
    the lowest median interactions to 64 targets (a capped lifetime counts as its cap; ties: the
    lower mean). Returns every point's figures and {row: the chosen point's figures}. The
    deep-RL tuning (experiments/tune_deep.py) chooses the same way."""
    points: dict = {}
    for task, res in zip(tasks, results):
        key = (task["method"], json.dumps(task["config"][field], sort_keys=True))
        points.setdefault(key, []).append(res)
    table, chosen = [], {}
    for (row, point), runs in points.items():
        inter = [r["interactions"] for r in runs]
        entry = {"row": row, field: json.loads(point), "seeds": [r["seed"] for r in runs],
                 "interactions": inter, "median": float(np.median(inter)), "mean": float(np.mean(inter)),
                 "reached_64": sum(r["targets_reached"] >= 64 for r in runs),
                 "crashes": [r.get("crashes") for r in runs],
                 "cpu_s": round(sum(r["cpu_s"] for r in runs), 1)}
        table.append(entry)
        best = chosen.get(row)
        if best is None or (entry["median"], entry["mean"]) < (best["median"], best["mean"]):
            chosen[row] = entry
    return table, chosen


def progress_printer(n_tasks: int, every: int = 20):
    """``on_result`` of ``run_sweep``: a line every ``every`` lifetimes, with the wall time."""
    t0, done = time.perf_counter(), [0]

    def progress(task, result, cached):
        done[0] += 1
        if done[0] % every == 0 or done[0] == n_tasks:
            print(f"{done[0]}/{n_tasks} lifetimes ({time.perf_counter() - t0:.0f} s)", flush=True)

    return progress


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--cluster", default=None)
    p.add_argument("--out", type=Path, default=Path("build/experiments/tuning"))
    p.add_argument("--methods", default=",".join(LEARNERS))
    p.add_argument("--shaping", default=",".join(SHAPINGS))
    p.add_argument("--skip", action="append", default=[], metavar="METHOD/SHAPING",
                   help="leave a row out (its lifetimes did not fit the CPU at hand)")
    args = p.parse_args(argv)
    tasks = []
    for method in args.methods.split(","):
        for shaping in args.shaping.split(","):
            if f"{method}/{shaping}" in args.skip:
                continue
            for config in grid(method):
                tasks += [{"method": f"{method}/{shaping}", "seed": s,
                           "config": {"arena": "default", "shaping": shaping, "max_interactions": MAX_INTERACTIONS,
                                      "learner": dataclasses.asdict(config)}} for s in TUNING_SEEDS]
    t0 = time.perf_counter()
    with executor(args.jobs, args.cluster) as pool:
        results = run_sweep(lifetime, tasks, pool, Cache(args.out / "cache"), on_result=progress_printer(len(tasks)))
    table, chosen = choose(tasks, results, "learner")
    args.out.mkdir(parents=True, exist_ok=True)
    report = {"tuning_seeds": list(TUNING_SEEDS), "skipped": args.skip, "grid": {"alpha": ALPHAS, "epsilon": EPSILONS, "gamma": GAMMAS,
                                                           "planning_steps": PLANNING},
              "chosen": chosen, "points": table, "wall_s": round(time.perf_counter() - t0, 1)}
    (args.out / "tabular.json").write_text(json.dumps(report, indent=1) + "\n")
    print(f"wrote {args.out / 'tabular.json'}; TUNED entries for peers/tabular.py:")
    for row, entry in sorted(chosen.items()):
        method, shaping = row.split("/")
        fields = ", ".join(f"{k}={v!r}" for k, v in entry["learner"].items())
        print(f"    ({method!r}, {shaping!r}): LearnerConfig({fields}),  "
              f"# median {entry['median']:,.0f} on seeds {entry['seeds']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
