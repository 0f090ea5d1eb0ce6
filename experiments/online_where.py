"""Round 6's instrumentation of one default lifetime (docs/online.md, "Round 6"): where the
interactions go, how often a loop comes back, and the visit counts behind the world states and
transitions of the paper's table.

    python experiments/online_where.py [--seed 1] [--budget 20000] [--set field=value ...]

Runs ``cosim.online.run.make_run(OnlineConfig(seed=S, max_interactions=B, **settings))`` on the
reference boards and prints one JSON object:

- ``where_interactions_go``: the summary's breakdown (``cosim.online.report.interaction_breakdown``);
- ``clean``: the steps of each leg after its last failure, summed;
- ``loops``: loop stops, and how many ran again a loop met before (the same obstacle (state,
  motion) pairs, ``last_cycle`` below) in the lifetime and on the same leg, with the interactions
  of their failed segments (an upper bound of what a perfect loop memory could save);
- ``states``: states met, and how many were met at most 2 / at most 5 / at least 20 times;
  ``pairs``: (state, motion) pairs executed, and how many at most twice.
"""

from __future__ import annotations

import argparse
import bisect
import json
import sys
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from cosim.online.run import OnlineConfig, make_run  # noqa: E402
from cosim.online.report import interaction_breakdown  # noqa: E402
from ga.motions import OBSTACLE_MASK  # noqa: E402


def last_cycle(pairs, state: int, longest: int = 40) -> tuple:
    """The obstacle (state, motion) pairs of the last cycle back to ``state`` (the smallest p >= 2
    with pairs[-p] in ``state``); () if none."""
    for p in range(2, min(len(pairs), longest) + 1):
        if pairs[-p][0] == state:
            return tuple(sorted({(s, a) for s, a in pairs[-p:] if s & OBSTACLE_MASK}))
    return ()


def instrument(run) -> dict:
    phases, targets = run.phases, run.target_log
    at = [t["interactions"] for t in targets]
    # the state each motion was taken in: replayed from the lifetime's own records
    pre = run.pre_states
    motions = run.motions
    ends = [p["interactions"] for p in phases]
    clean = 0
    for j, t in enumerate(at):
        start = at[j - 1] if j else 0
        k = bisect.bisect_right(ends, t) - 1
        clean += t - max(start, ends[k] if k >= 0 else 0)
    seen_life, seen_leg, leg, last = set(), set(), -1, 0
    loops = {"stops": 0, "again_in_lifetime": 0, "their_interactions": 0, "again_on_leg": 0,
             "their_interactions_on_leg": 0}
    for p in phases:
        i = p["interactions"]
        k = bisect.bisect_right(at, i) - 1
        leg_start = at[k] if k >= 0 else 0
        segment = i - max(last, leg_start)
        last = i
        if p["targets"] != leg:
            seen_leg, leg = set(), p["targets"]
        if p["reason"] != "loop":
            continue
        pairs = list(zip(pre[max(leg_start, i - 64):i], motions[max(leg_start, i - 64):i]))
        loop = last_cycle(pairs, run.state_log[i - 1])
        loops["stops"] += 1
        if loop in seen_life:
            loops["again_in_lifetime"] += 1
            loops["their_interactions"] += segment
        if loop in seen_leg:
            loops["again_on_leg"] += 1
            loops["their_interactions_on_leg"] += segment
        seen_life.add(loop)
        seen_leg.add(loop)
    visits = Counter(pre)
    pair_visits = Counter(zip(pre, motions))
    return {
        "seed": run.config.seed, "interactions": run.interactions, "targets": run.targets,
        "where_interactions_go": interaction_breakdown(phases, targets, run.interactions),
        "clean": clean, "loops": loops,
        "states": {"met": len(visits), "at_most_2": sum(v <= 2 for v in visits.values()),
                   "at_most_5": sum(v <= 5 for v in visits.values()),
                   "at_least_20": sum(v >= 20 for v in visits.values())},
        "pairs": {"executed": len(pair_visits), "at_most_2": sum(v <= 2 for v in pair_visits.values())},
    }


class Recording:
    """Wraps OnlineRun.step to keep the state each motion was taken in."""

    @staticmethod
    def attach(run):
        run.pre_states = []
        step = run.step

        def recorded(motion, record=True):
            run.pre_states.append(run.state)
            return step(motion, record)

        run.step = recorded
        return run


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--budget", type=int, default=20_000)
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    a = p.parse_args(argv)
    settings = {k: json.loads(v) for k, _, v in (kv.partition("=") for kv in a.set)}
    run = Recording.attach(make_run(OnlineConfig(seed=a.seed, max_interactions=a.budget, **settings)))
    run.run()
    print(json.dumps(instrument(run)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
