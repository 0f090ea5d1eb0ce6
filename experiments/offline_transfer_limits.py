"""The transfer test of ``ehw offline`` at several leg limits (docs/research-log.md, off-line round 5): for each
summary.json, the fraction of the 20 noise seeds ``seed * 1000 + i`` on which its best controller
reaches every target with no crash and no leg time-out, at each limit; and the same for the
hand-written baseline (``sim_world.baseline``) on the first summary's noise seeds.

    python experiments/offline_transfer_limits.py SUMMARY [SUMMARY ...] [--limits 150,200,250,500]

Prints a Markdown table (one row a summary, one column a limit).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from cosim.offline.noisy import TRANSFER_TRIALS, _noisy_world, transfer
from sim_world.baseline import baseline_table
from sim_world.course import run_course


def baseline_fraction(arena: str, limit: int, n_targets: int, seed: int, trials: int) -> float:
    """``transfer``'s test for the hand-written baseline's truth table."""
    table = baseline_table()
    reached = [run_course(_noisy_world(arena, seed * 1000 + i), table, limit, n_targets=n_targets,
                          stop_on_crash=True).targets_reached for i in range(trials)]
    return float(np.mean([r >= n_targets for r in reached]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("summaries", nargs="+", type=Path, metavar="SUMMARY")
    ap.add_argument("--limits", default="150,200,250,500", help="leg limits, comma-separated")
    ap.add_argument("--trials", type=int, default=TRANSFER_TRIALS, help="noise seeds a summary")
    args = ap.parse_args(argv)
    try:
        limits = [int(v) for v in args.limits.split(",")]
        if min(limits) < 1 or args.trials < 1:
            raise ValueError("--limits and --trials must be positive")
        runs = [json.loads(p.read_text()) for p in args.summaries]
    except (ValueError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print("| summary | seed | interactions | " + " | ".join(f"leg limit {v}" for v in limits) + " |")
    print("|---|---|---|" + "---|" * len(limits))
    for path, s in zip(args.summaries, runs):
        arena, n = s["config"]["arena"], s["config"]["n_targets"]
        fractions = [transfer(s["best_genome"], arena, v, n, s["seed"], args.trials)["all_targets_fraction"]
                     for v in limits]
        print(f"| {path} | {s['seed']} | {s['interactions']:,} | " + " | ".join(f"{f:g}" for f in fractions) + " |")
    first = runs[0]
    arena, n = first["config"]["arena"], first["config"]["n_targets"]
    print(f"| hand-written baseline | {first['seed']} | - | "
          + " | ".join(f"{baseline_fraction(arena, v, n, first['seed'], args.trials):g}" for v in limits) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
