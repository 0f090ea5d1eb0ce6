"""Round 10 (docs/online.md, "Round 10"): which term of the fitness ranks the hand-written
baseline below the downloaded controller. One lifetime of ``experiments.online_round10.Round10``;
after every learning phase the download and the baseline (``sim_world.baseline``) are scored on the
phase's model, term by term; the means over the phases are printed.

    python experiments/online_round10_terms.py SEED BUDGET [VARIANT] [key=value ...]
    python experiments/online_round10_terms.py 1 4000                       # today's defaults
    python experiments/online_round10_terms.py 1 4000 likely cycles=3 replace=1 crashfreq=1
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments.online_round7 import parse_kv  # noqa: E402
from experiments.online_round8 import run_one  # noqa: E402
from experiments.online_round9 import two_cycle_odds  # noqa: E402
from experiments.online_round10 import DEFAULT_PARAMS, Round10, cycle_odds, likely_cycles  # noqa: E402
from ga.evaluator import MAX_MOTION_DISTANCE_MM, W_CRASHES, W_DISTANCE, W_LOOPS, evaluate_tables  # noqa: E402
from ga.motions import OBSTACLE_MASK  # noqa: E402
from ga.truth_table import truth_tables  # noqa: E402

NAMES = ("SPEC crashes", "SPEC loops", "SPEC distance", "likely 2-cycles", "likely 3-cycles",
         "expected crashes", "untried obstacle entries", "N",
         "fitness gap: crash term", "fitness gap: loop term", "fitness gap: distance term")


class Terms(Round10):
    """Round 10's lifetime, each phase's terms kept in ``terms`` (phases, len(NAMES), 2)."""

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self.terms: list[np.ndarray] = []

    def learn(self, reason, steps, state, motion, detector=""):
        super().learn(reason, steps, state, motion, detector)
        if self.best_rows is None or not self.mirror.n_states:
            return
        m, n = self.mirror, self.mirror.n_states
        both = np.stack([truth_tables(self.best_rows[None], reflex=self.config.reflex)[0], self.base_table])
        c = evaluate_tables(both, m, self.config.distance_rule)
        s = m.states.astype(np.int64)
        obstacle = s[(s & OBSTACLE_MASK) != 0]
        shares = self.back_shares()
        odds2 = two_cycle_odds(both.astype(np.int64), self.outcomes(), obstacle, shares).sum(axis=1)
        odds3 = cycle_odds(both, *likely_cycles(shares, obstacle, 3))
        expected = self.crash_shares()[s[None, :], both[:, s]].sum(axis=1)
        untried = (~m.valid[obstacle[None, :], both[:, obstacle]]).sum(axis=1)
        gaps = [W_CRASHES * (c.crashes[1] - c.crashes[0]) / n, W_LOOPS * (c.loops[1] - c.loops[0]) / n,
                W_DISTANCE * (c.distance[0] - c.distance[1]) / (n * MAX_MOTION_DISTANCE_MM)]
        self.terms.append(np.array([c.crashes, c.loops, c.distance, odds2, odds3, expected, untried, [n, n],
                                    *[[g, g] for g in gaps]], dtype=float))


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    seed, budget = int(argv[0]), int(argv[1])
    variant = argv[2] if len(argv) > 2 else "default"
    params = parse_kv(argv[3:])
    runs = []

    class Kept(Terms):
        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            runs.append(self)

    r = run_one(variant, seed, budget, {}, params, Kept, DEFAULT_PARAMS)
    t = np.array(runs[0].terms)
    print(f"seed {seed}, {variant} {params}: {r['interactions']} interactions, {r['targets']} targets, "
          f"{len(t)} learning phases; means over the phases")
    for i, name in enumerate(NAMES):
        if name.startswith("fitness gap"):
            print(f"{name:28s} {t[:, i, 0].mean():9.4f}  (baseline's fitness below the download's by this term)")
        else:
            print(f"{name:28s} download {t[:, i, 0].mean():9.2f}  baseline {t[:, i, 1].mean():9.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
