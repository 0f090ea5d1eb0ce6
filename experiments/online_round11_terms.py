"""Round 11 (docs/online.md, "Round 11"): does a revised distance term rank the hand-written
baseline above the downloaded controller? One lifetime of ``experiments.online_round11.Round11``
(VARIANT and its parameters); after every learning phase the download and the baseline
(``sim_world.baseline``) are scored on the phase's model under each rule of ``RULES``; the means
over the phases are printed, and in how many phases the baseline ranks above the download.

    python experiments/online_round11_terms.py SEED BUDGET [VARIANT] [key=value ...]
    python experiments/online_round11_terms.py 1 4000                       # today's defaults
    python experiments/online_round11_terms.py 1 4000 distance untried=1    # that rule's own downloads
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments.online_round7 import parse_kv  # noqa: E402
from experiments.online_round8 import run_one  # noqa: E402
from experiments.online_round11 import DEFAULT_PARAMS, Round11, credited_distance  # noqa: E402
from ga.evaluator import MAX_MOTION_DISTANCE_MM, W_CRASHES, W_DISTANCE, W_LOOPS, evaluate_tables  # noqa: E402
from ga.motions import OBSTACLE_MASK  # noqa: E402
from ga.truth_table import truth_tables  # noqa: E402

# (name, untried, obstacle_any, away, w_distance): the SPEC first.
RULES = (("SPEC", 0.0, False, False, W_DISTANCE), ("untried=1", 1.0, False, False, W_DISTANCE),
         ("untried=0.5", 0.5, False, False, W_DISTANCE), ("obstacle_any=1", 0.0, True, False, W_DISTANCE),
         ("obstacle_any=1 untried=0.5", 0.5, True, False, W_DISTANCE),
         ("obstacle_any=1 untried=1", 1.0, True, False, W_DISTANCE),
         ("away=1", 0.0, False, True, W_DISTANCE), ("away=1 obstacle_any=1", 0.0, True, True, W_DISTANCE),
         ("w_distance=0.2", 0.0, False, False, 0.2),
         ("w_distance=0.02", 0.0, False, False, 0.02), ("w_distance=0", 0.0, False, False, 0.0))


class Terms(Round11):
    """Round 11's lifetime; per phase and rule: (D download, D baseline, fitness gap), and the
    SPEC crash and loop gaps and untried obstacle entries."""

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self.by_rule: list[np.ndarray] = []  # phases x (rules, 3)
        self.spec: list[np.ndarray] = []  # phases x (crash gap, loop gap, untried download, untried baseline)

    def learn(self, reason, steps, state, motion, detector=""):
        super().learn(reason, steps, state, motion, detector)
        if self.best_rows is None or not self.mirror.n_states:
            return
        m, n = self.mirror, self.mirror.n_states
        rule = self.config.distance_rule
        both = np.stack([truth_tables(self.best_rows[None], reflex=self.config.reflex)[0], self.base_table])
        c = evaluate_tables(both, m, rule)
        crash_gap = W_CRASHES * (c.crashes[1] - c.crashes[0]) / n
        loop_gap = W_LOOPS * (c.loops[1] - c.loops[0]) / n
        rows = []
        for _, untried, obstacle_any, away, w in RULES:
            d = credited_distance(both, m, rule, untried, obstacle_any, away)
            rows.append([d[0], d[1], crash_gap + loop_gap + w * (d[0] - d[1]) / (n * MAX_MOTION_DISTANCE_MM)])
        self.by_rule.append(np.array(rows))
        s = m.states.astype(np.int64)
        obstacle = s[(s & OBSTACLE_MASK) != 0]
        untried = (~m.valid[obstacle[None, :], both[:, obstacle]]).sum(axis=1)
        self.spec.append(np.array([crash_gap, loop_gap, *untried], dtype=float))


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
    t, spec = np.array(runs[0].by_rule), np.array(runs[0].spec)
    print(f"seed {seed}, {variant} {params}: {r['interactions']} interactions, {r['targets']} targets, "
          f"{len(t)} learning phases; means over the phases")
    print(f"SPEC crash term gap {spec[:, 0].mean():.4f}, loop term gap {spec[:, 1].mean():.4f} "
          f"(baseline below the download by); untried obstacle entries download {spec[:, 2].mean():.1f}, "
          f"baseline {spec[:, 3].mean():.1f}")
    print("| rule | D download (mm) | D baseline (mm) | fitness gap (baseline below by) | phases baseline above |")
    print("|---|---|---|---|---|")
    for i, (name, *_) in enumerate(RULES):
        print(f"| {name} | {t[:, i, 0].mean():,.0f} | {t[:, i, 1].mean():,.0f} | {t[:, i, 2].mean():.4f} "
              f"| {int((t[:, i, 2] < 0).sum())} of {len(t)} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
