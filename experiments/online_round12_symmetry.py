"""Round 12 (docs/online.md, "Round 12"): is a mirrored observation as good a prediction as a real one?

    python experiments/online_round12_symmetry.py build/sim1_cycle/checkpoint.json   # a lifetime's motions
    python experiments/online_round12_symmetry.py --random 20000 --seed 1            # random motions

The observations (s, a) -> s2 or a crash of one lifetime (the motions of an on-line checkpoint
replayed in the noisy world, no learning) or of a random walk (uniform random motions, the course's
relocations at each target). For every observation, in order, two predictions of its outcome:
*real*, the latest outcome of the same pair (s, a) before it (what SPEC section 7's model holds,
without the crash permanence), and *mirrored*, the mirror image of the latest outcome of the
mirrored pair (m(s), m(a)) (what round 12's mirrored writes put in the model). Printed: how often
each was available and right, over all observations and over those where both were available
(pairs that are their own mirror image left out); the same with the most frequent outcome so far
instead of the latest (``mode``: no recency, a test of the world's symmetry rather than of the
robot's staying in one place), and the most frequent of the pair's and its mirror's outcomes
pooled (``pooled``); and the crash shares of a pair and of its mirror.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from base.checkpoint import read_checkpoint  # noqa: E402
from cosim.online.run import CHECKPOINT_KIND, OnlineConfig, make_run  # noqa: E402
from ga.motions import MIRROR_MOTION, MIRROR_STATE, N_MOTIONS, OBSTACLE_MASK  # noqa: E402
from sim_world.course import Course  # noqa: E402
from sim_world.world import DEFAULT_NOISE, World  # noqa: E402


def replayed(path: Path) -> list[tuple[int, int, int, bool]]:
    """The observations of an on-line checkpoint's motions, replayed (no learning phase)."""
    config, state = read_checkpoint(path, CHECKPOINT_KIND)
    run = make_run(OnlineConfig(**config))
    out = []
    for motion in bytes.fromhex(state["motions"]):
        s = run.state
        step = run.step(motion, record=False)
        out.append((s, motion, int(step.state), bool(step.crashed)))
    return out


def random_walk(n: int, seed: int) -> list[tuple[int, int, int, bool]]:
    """``n`` uniform random motions in the noisy default world, relocated at each target."""
    world = World("default", noise=DEFAULT_NOISE, seed=seed)
    course, rng = Course.of(world), np.random.default_rng(seed)
    s, targets, out = world.reset_to_start(), 0, []
    for motion in rng.integers(0, N_MOTIONS, n).tolist():
        step = world.step(motion)
        out.append((s, motion, int(step.state), bool(step.crashed)))
        s = step.state
        if step.reached and not step.crashed:
            targets += 1
            s = course.relocate(world, targets % 64)
    return out


def scores(observations) -> dict:
    """How often the real and the mirrored prediction were available and right (module docstring)."""
    latest: dict[tuple[int, int], tuple[bool, int]] = {}
    seen_all: dict[tuple[int, int], Counter] = {}
    counts = {k: 0 for k in ("observations", "real_known", "real_right", "mirror_known", "mirror_right",
                             "both_known", "both_real_right", "both_mirror_right",
                             "obstacle_both_known", "obstacle_real_right", "obstacle_mirror_right",
                             "both_real_mode_right", "both_mirror_mode_right", "both_pooled_mode_right")}
    for s, a, s2, crashed in observations:
        ms, ma = int(MIRROR_STATE[s]), int(MIRROR_MOTION[a])
        outcome = (crashed, s if crashed else s2)
        if (ms, ma) != (s, a):
            counts["observations"] += 1
            real = latest.get((s, a))
            seen = latest.get((ms, ma))
            mirror = None if seen is None else (seen[0], s if seen[0] else int(MIRROR_STATE[seen[1]]))
            for name, guess in (("real", real), ("mirror", mirror)):
                if guess is not None:
                    counts[f"{name}_known"] += 1
                    counts[f"{name}_right"] += guess == outcome
            if real is not None and mirror is not None:
                for prefix in ("both", "obstacle") if s & OBSTACLE_MASK else ("both",):
                    counts[f"{prefix}_both_known" if prefix == "obstacle" else "both_known"] += 1
                    counts[f"{prefix}_real_right"] += real == outcome
                    counts[f"{prefix}_mirror_right"] += mirror == outcome
                # the most frequent outcome so far instead of the latest (ties: the earliest met)
                real_mode = seen_all[(s, a)].most_common(1)[0][0]
                mode = seen_all[(ms, ma)].most_common(1)[0][0]
                mirror_mode = (mode[0], s if mode[0] else int(MIRROR_STATE[mode[1]]))
                counts["both_real_mode_right"] += real_mode == outcome
                counts["both_mirror_mode_right"] += mirror_mode == outcome
                pooled = seen_all[(s, a)] + Counter({(c, s if c else int(MIRROR_STATE[x])): k
                                                     for (c, x), k in seen_all[(ms, ma)].items()})
                counts["both_pooled_mode_right"] += pooled.most_common(1)[0][0] == outcome
        latest[(s, a)] = outcome
        seen_all.setdefault((s, a), Counter())[outcome] += 1
    tally = np.zeros((256, N_MOTIONS, 2))
    for s, a, _, crashed in observations:
        tally[s, a, int(crashed)] += 1
    runs = tally.sum(axis=2)
    both = (runs >= 5) & (runs[MIRROR_STATE][:, MIRROR_MOTION] >= 5)
    share = tally[..., 1] / np.maximum(runs, 1)
    mirrored_share = share[MIRROR_STATE][:, MIRROR_MOTION]
    counts["crash_pairs_compared"] = int(both.sum())
    counts["crash_share_mean_abs_difference"] = round(float(np.abs(share - mirrored_share)[both].mean()), 3) \
        if both.any() else None
    return counts


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("checkpoint", nargs="?", type=Path)
    p.add_argument("--random", type=int, default=0, metavar="N", help="N random motions instead")
    p.add_argument("--seed", type=int, default=1)
    a = p.parse_args(argv)
    if bool(a.checkpoint) == bool(a.random):
        p.error("a checkpoint or --random N")
    obs = random_walk(a.random, a.seed) if a.random else replayed(a.checkpoint)
    print(json.dumps({"source": str(a.checkpoint or f"random {a.random} seed {a.seed}"), **scores(obs)}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
