"""Round 16 of the on-line search (docs/online.md, "Round 16"): how the host marks the failures
behind the rate codes (``ga.fail_rates.FailureMarks``), screened host side only.

    python experiments/online_round16.py VARIANT SEEDS [--budget 20000] [--set key=value ...]
                                         [--param key=value ...]
    python experiments/online_round16.py default 1-16                       # = ehw sim --no-rate-mirror
    python experiments/online_round16.py marks 1-16 --param decay=0.98      # forget old marks
    python experiments/online_round16.py marks 1-16 --param w_loop=0.5      # a loop stop marks half
    python experiments/online_round16.py default 221-240                    # held out
    python experiments/online_round16.py marks 221-240 --param pool_mirror=1
    python experiments/online_round16.py --table build/experiments/round16.jsonl

A lifetime is round 15's (``experiments.online_round15.Round15``: round 14's instruments on the
main code's defaults, ``rate_mirror`` off; ``marks pool_mirror=1`` is the main code's default). The boards see only rate codes, so every variant here changes the host's
bookkeeping and nothing on a board. Variant ``marks`` (float counts, codes rounded and clipped to
0..``RATE_ONE``):

- ``decay``: before each failure is marked, every executed and failed count is multiplied by
  ``decay`` (1: the main code; 0.98: a mark counts half after ~34 failures, i.e. ~600 interactions):
  a pair's failures depend on the controller's other motions, which each download changes;
- ``w_crash``, ``w_loop``, ``w_timeout``: what one failure of that kind adds to its pairs' failed
  counts (1 each in the main code);
- ``rate_horizon``: the steps before a failure whose pairs it marks (round 15's parameter, 8);
- ``pool_mirror``: the counts of the pair's left-right mirror image (``ga.fail_rates.mirror_image``)
  are added, times ``pool_mirror``, to its own before the code is computed (round 12
  found the world's outcome frequencies nearly mirror-symmetric);
- ``w_dist``: the host fitness takes ``w_dist`` x the distance term (SPEC section 7's weight 0.1 x
  ``w_dist``): forward motions towards an obstacle pay less, now that the rates see what fails.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments.online_round8 import main as round8_main  # noqa: E402
from experiments.online_round14 import seed_table  # noqa: E402
from experiments.online_round15 import DEFAULT_PARAMS as R15_PARAMS  # noqa: E402
from experiments.online_round15 import Round15, Weighted  # noqa: E402
from ga.fail_rates import PRIOR_CODE, RATE_ONE, FailureMarks, mirror_image  # noqa: E402

DEFAULT_OUT = Path("build/experiments/round16.jsonl")
HELD_OUT = range(221, 241)  # never used to choose (201-220: round 15's report; earlier rounds' below)
VARIANTS = ("default", "marks")
R16_PARAMS = {"decay": 1.0, "w_crash": 1.0, "w_loop": 1.0, "w_timeout": 1.0, "w_dist": 1.0, "pool_mirror": 0.0}
DEFAULT_PARAMS = {**R15_PARAMS, **R16_PARAMS}


class Marks(FailureMarks):
    """Float marks: forgotten by ``decay`` at each failure, weighted by the failure's kind."""

    def __init__(self, horizon: int, decay: float, weights: dict[str, float], mirror: float = 0.0):
        super().__init__(horizon)
        self.mirror = float(mirror)
        self.executed = self.executed.astype(np.float64)
        self.failed = self.failed.astype(np.float64)
        self.decay, self.weights = float(decay), weights
        self.reason = "crash"  # set by the run before each failure is marked

    def failure(self) -> None:
        if self.decay != 1.0:
            self.executed *= self.decay
            self.failed *= self.decay
        w = self.weights[self.reason]
        for s, a in set(self.pending[-self.horizon:]):
            self.failed[s, a] += w
        self.pending.clear()

    def codes(self) -> np.ndarray:
        failed, executed = self.failed, self.executed
        if self.mirror:
            failed = failed + self.mirror * mirror_image(failed)
            executed = executed + self.mirror * mirror_image(executed)
        rate = (RATE_ONE * failed + PRIOR_CODE) / (executed + 1)
        return np.clip(np.floor(rate + 0.5), 0, RATE_ONE).astype(np.uint8)


class Round16(Round15):
    """Round 15's lifetime (variant ``default``: the main code) with ``marks``."""

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        if self.variant == "marks" and self.config.fail_rates:
            prm = self.params
            weights = {"crash": float(prm["w_crash"]), "loop": float(prm["w_loop"]),
                       "timeout": float(prm["w_timeout"])}
            self.marks = Marks(int(prm["rate_horizon"]), float(prm["decay"]), weights, float(prm["pool_mirror"]))
            if float(prm["w_dist"]) != 1.0:
                self.evaluator = Weighted(self.evaluator, float(prm["w_dist"]), "distance")

    def learn(self, reason, *a, **k):
        if isinstance(self.marks, Marks):
            self.marks.reason = reason
        return super().learn(reason, *a, **k)


def table(path: Path) -> str:
    """The screening seeds (1-24), then this round's held-out seeds on their own."""
    return "\n\n".join(seed_table(path, seeds) for seeds in (range(1, 25), HELD_OUT))


def main(argv=None) -> int:
    return round8_main(argv, cls=Round16, defaults=DEFAULT_PARAMS, variants=VARIANTS, default_out=DEFAULT_OUT,
                       description=__doc__, table_of=table)


if __name__ == "__main__":
    raise SystemExit(main())
