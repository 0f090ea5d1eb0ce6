"""Round 8's instrumentation (docs/online.md, "Round 8"): where a lifetime's cycle stops are
blamed, inside the cycle that stopped the leg or outside it.

    python experiments/online_blame_check.py SEED BUDGET RULE     # RULE: leg (rounds 1-7) or cycle
    python experiments/online_blame_check.py 1 20000 leg

Prints the interactions, the targets and the counts: cycle stops (``cycles``), those blamed on a
pair of their cycle (``cycles_in_cycle``) or outside it (``cycles_outside``), and the cycles'
lengths and numbers of obstacle pairs.
"""

from __future__ import annotations

import sys
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from cosim.online.run import OnlineConfig, OnlineRun, make_run  # noqa: E402
from experiments.online_round7 import cycle_pairs  # noqa: E402
from ga.motions import OBSTACLE_MASK  # noqa: E402


class BlameCheck(OnlineRun):
    """A lifetime that classes each cycle stop's blamed pair against the stop's cycle."""

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self.stats: Counter = Counter()

    def learn(self, reason, steps, state, motion, detector=""):
        if reason == "loop":
            cycle = cycle_pairs(self.track)
            self.stats[detector] += 1
            if cycle:
                where = "_in_cycle" if (state, motion) in cycle else "_outside"
                self.stats[detector + where] += 1
                self.stats[f"cycle_len_{len(cycle)}"] += 1
                self.stats[f"obstacle_pairs_{sum(1 for s, _ in cycle if s & OBSTACLE_MASK)}"] += 1
        super().learn(reason, steps, state, motion, detector)


def main(argv=None) -> int:
    seed, budget, rule = (sys.argv[1:] if argv is None else argv)
    config = OnlineConfig(seed=int(seed), max_interactions=int(budget), loop_blame=rule)
    base = make_run(config)
    run = BlameCheck(config, base.controller, base.evaluator).run()
    print(run.interactions, run.targets, dict(sorted(run.stats.items())))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
