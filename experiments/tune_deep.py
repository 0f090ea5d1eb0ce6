"""Choose DQN's and PPO's hyper-parameters on the tuning seeds only (issue 16, honest tuning).

    python experiments/tune_deep.py [--jobs 1] [--methods dqn,ppo] [--shaping shaped,unshaped]
                                    [--cluster local] [--out build/experiments/tuning]

Needs the optional extra (`make rl`). For DQN and PPO and each reward (shaped, unshaped) it runs
one lifetime (``peers.deep.run_deep_lifetime``, the protocol of `make compare`, through
``cosim.compare.run.run_task``: the same task, so the same cache key) per point of ``GRID`` and per
seed of ``peers.tabular.TUNING_SEEDS`` (1001-1003), through the sweep executor (cached: an
interrupted tuning resumes), and picks the point of the lowest median interactions to 64 targets
as experiments/tune_tabular.py does (a capped lifetime counts as its cap; ties: the lower mean).
Every point is ``peers.deep.HYPER`` (the fixed settings) with the grid's values over it. It writes
``<out>/deep.json`` and prints the ``TUNED`` entries that peers/deep.py holds.
"""

from __future__ import annotations

import argparse
import itertools
import json
import time
from pathlib import Path

import numpy as np

from cosim.compare.run import run_task
from cosim.compare.sweep import Cache, executor, run_sweep
from peers.deep import HYPER
from peers.lifetime import MAX_INTERACTIONS, SHAPINGS
from peers.tabular import TUNING_SEEDS

# The grid, small for the CPU at hand (a DQN lifetime ~10-20 CPU s, a PPO one ~20-30 s, shaped;
# the shared machine gave each about a tenth of a core): the learning rate (SB3's defaults: DQN
# 1e-4, PPO 3e-4) and, for DQN, the exploration schedule (the fraction of the 100,000-step cap
# over which epsilon falls to its final 0.02). DQN's grid brackets the values set by hand before
# (HYPER: 5e-4, 0.05); PPO keeps HYPER's rollout (n_steps 512).
GRID = {
    "dqn": {"learning_rate": (2.5e-4, 1e-3), "exploration_fraction": (0.02, 0.05)},
    "ppo": {"learning_rate": (3e-4, 1e-3)},
}


def choose(tasks: list[dict], results: list[dict], field: str) -> tuple[list[dict], dict]:
    """Group the lifetimes by (row, grid point: ``task["config"][field]``); per row, the point of
    the lowest median interactions to 64 targets (a capped lifetime counts as its cap; ties: the
    lower mean). Returns every point's figures and {row: the chosen point's figures}. The rule of
    experiments/tune_tabular.py (each script stands alone)."""
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


def progress_printer(n_tasks: int):
    """``on_result`` of ``run_sweep``: a line a lifetime, with the wall time."""
    t0, done = time.perf_counter(), [0]

    def progress(task, result, cached):
        done[0] += 1
        print(f"{done[0]}/{n_tasks} lifetimes ({time.perf_counter() - t0:.0f} s)", flush=True)

    return progress


def grid(method: str) -> list[dict]:
    names = list(GRID[method])
    return [{**HYPER[method], **dict(zip(names, values))}
            for values in itertools.product(*(GRID[method][n] for n in names))]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--jobs", type=int, default=1)
    p.add_argument("--cluster", default=None)
    p.add_argument("--out", type=Path, default=Path("build/experiments/tuning"))
    p.add_argument("--methods", default=",".join(GRID))
    p.add_argument("--shaping", default=",".join(SHAPINGS))
    args = p.parse_args(argv)
    tasks = []
    for method in args.methods.split(","):
        for shaping in args.shaping.split(","):
            for hyper in grid(method):
                config = {"arena": "default", "shaping": shaping, "max_interactions": MAX_INTERACTIONS, "hyper": hyper}
                tasks += [{"method": f"{method}/{shaping}", "kind": "deep", "seed": s, "config": config}
                          for s in TUNING_SEEDS]
    t0 = time.perf_counter()
    with executor(args.jobs, args.cluster) as pool:
        results = run_sweep(run_task, tasks, pool, Cache(args.out / "cache"),
                            on_result=progress_printer(len(tasks)))
    table, chosen = choose(tasks, results, "hyper")
    args.out.mkdir(parents=True, exist_ok=True)
    report = {"tuning_seeds": list(TUNING_SEEDS), "grid": GRID, "fixed": HYPER, "chosen": chosen, "points": table,
              "wall_s": round(time.perf_counter() - t0, 1)}
    (args.out / "deep.json").write_text(json.dumps(report, indent=1) + "\n")
    print(f"wrote {args.out / 'deep.json'}; TUNED entries for peers/deep.py:")
    for row, entry in sorted(chosen.items()):
        method, shaping = row.split("/")
        values = {k: entry["hyper"][k] for k in GRID[method]}
        print(f"    ({method!r}, {shaping!r}): {values!r},  # median {entry['median']:,.0f} on seeds {entry['seeds']}")
    for entry in table:
        values = ", ".join(f"{k}={entry['hyper'][k]}" for k in GRID[entry["row"].split("/")[0]])
        print(f"{entry['row']:14s} {values:45s} median {entry['median']:>9,.0f}  {entry['interactions']}  "
              f"CPU {entry['cpu_s']} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
