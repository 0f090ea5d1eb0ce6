"""Round 17 of the on-line search (docs/online.md, "Round 17"): more evidence per rate code, and
where the rate term weighs, screened host side only (the boards see only rate codes).

    python experiments/online_round17.py VARIANT SEEDS [--budget 20000] [--set key=value ...]
                                         [--param key=value ...]
    python experiments/online_round17.py default 1-16                       # = ehw sim
    python experiments/online_round17.py pool 1-16 --param pool_back=1      # + the x5-flipped state
    python experiments/online_round17.py pool 1-16 --param visit_gamma=0.5  # busy states weigh more
    python experiments/online_round17.py --table build/experiments/round17.jsonl

A lifetime is round 16's (``experiments.online_round16.Round16``: round 14's instruments) on the main
code's defaults, mirror pooling on (``default`` is ``ehw sim``'s lifetime). Variant ``pool``: the
main code's mirror-pooled counts (``ga.fail_rates.mirror_pooled``), then

- ``pool_back``, ``pool_side``, ``pool_sector``: each pair's counts plus, times that weight, those
  of the same motion in the obstacle states one flipped bit away: the back bit x5; the side bits
  x3 and x4 (each); the other three target sectors (each). Side and back sensors flicker as the
  robot runs along a wall, so neighbouring states often need the same motion;
- ``visit_gamma``: each state's codes times (its visits / the mean visits of the obstacle states
  visited) ** ``visit_gamma``, clipped to 0..255: the rate term weighs where the robot spends its
  steps (0: every state of S once, the main code);
- ``mark_cycle`` = 1: a cycle stop marks the pairs of the cycle that stopped the leg
  (``cosim.online.failures.Cycles``), not the last ``HORIZON`` pairs (the approach to the cycle did not
  loop); ``crash_horizon`` = K > 0: a crash marks only its last K pairs (0: ``HORIZON``);
- ``credit`` = c: when a leg reaches its target, each of its last ``HORIZON`` pairs counts c extra
  executions without failure (they got the robot there); ``prior_code`` (round 15's parameter):
  the code of a pair never executed, 25 in the main code;

codes rounded and clipped to 0..``RATE_ONE`` before the visit weight.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments.online_round8 import main as round8_main  # noqa: E402
from experiments.online_round14 import seed_table  # noqa: E402
from experiments.online_round16 import DEFAULT_PARAMS as R16_PARAMS  # noqa: E402
from experiments.online_round16 import Round16  # noqa: E402
from ga.fail_rates import RATE_ONE, FailureMarks, mirror_pooled  # noqa: E402
from ga.motions import N_STATES, OBSTACLE_MASK, SECTOR_SHIFT, X_BACK, X_LEFT, X_RIGHT  # noqa: E402

DEFAULT_OUT = Path("build/experiments/round17.jsonl")
HELD_OUT = range(241, 281)  # never used by any round (241-260, then 261-280)
VARIANTS = ("default", "pool")
R17_PARAMS = {"pool_back": 0.0, "pool_side": 0.0, "pool_sector": 0.0, "visit_gamma": 0.0, "mark_cycle": 0, "crash_horizon": 0, "credit": 0.0}
DEFAULT_PARAMS = {**R16_PARAMS, **R17_PARAMS}
_STATES = np.arange(N_STATES)
_OBSTACLE = (_STATES & OBSTACLE_MASK) != 0


def neighbours(params: dict) -> list[tuple[np.ndarray, float]]:
    """(state permutation, weight) for each flipped bit pattern the parameters pool."""
    flips = [(1 << X_BACK, params["pool_back"])]
    flips += [(1 << bit, params["pool_side"]) for bit in (X_LEFT, X_RIGHT)]
    flips += [(k << SECTOR_SHIFT, params["pool_sector"]) for k in (1, 2, 3)]
    return [(_STATES ^ mask, float(w)) for mask, w in flips if float(w)]


class Marks(FailureMarks):
    """The main code's marks (mirror pooled), pooled further over neighbouring states."""

    def __init__(self, params: dict):
        super().__init__(mirror=True)
        self.pool = neighbours(params)
        self.gamma = float(params["visit_gamma"])
        self.mark_cycle, self.crash_horizon = int(params["mark_cycle"]), int(params["crash_horizon"])
        self.cycle, self.reason = [], "crash"  # set by the run before each failure is marked
        self.credit, self.prior = float(params["credit"]), int(params["prior_code"])
        self.executed = self.executed.astype(np.float64)

    def executed_pair(self, state: int, motion: int, reached: bool, *distances) -> None:
        if reached and self.credit:
            for s, a in set(self.pending[-(self.horizon - 1):] + [(int(state), int(motion))]):
                self.executed[s, a] += self.credit
        super().executed_pair(state, motion, reached, *distances)

    def failure(self) -> None:
        if self.mark_cycle and self.cycle:
            marked = set(self.cycle)
        else:
            k = self.crash_horizon if self.reason == "crash" and self.crash_horizon else self.horizon
            marked = set(self.pending[-k:])
        for s, a in marked:
            self.failed[s, a] += 1
        self.pending.clear()

    def codes(self) -> np.ndarray:
        failed, executed = mirror_pooled(self.failed).astype(float), mirror_pooled(self.executed).astype(float)
        f, e = failed.copy(), executed.copy()
        for perm, w in self.pool:
            keep = (_OBSTACLE[perm] & _OBSTACLE)[:, None]  # only obstacle states lend and borrow
            f += w * keep * failed[perm]
            e += w * keep * executed[perm]
        codes = np.clip(np.floor((RATE_ONE * f + self.prior) / (e + 1) + 0.5), 0, RATE_ONE)
        if self.gamma:
            visits = self.executed.sum(axis=1).astype(float)
            busy = visits[_OBSTACLE & (visits > 0)]
            scale = (visits / busy.mean()) ** self.gamma if busy.size else np.ones(N_STATES)
            codes = np.clip(np.floor(codes * scale[:, None] + 0.5), 0, 255)
        return codes.astype(np.uint8)


class Round17(Round16):
    """Round 16's lifetime on the main code's defaults (mirror pooling) with ``pool``."""

    rate_mirror = True  # the main code's default since round 16

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        if self.variant == "pool" and self.config.fail_rates:
            self.marks = Marks(self.params)

    def learn(self, reason, steps, state, motion, detector=""):
        if isinstance(self.marks, Marks):
            cycles = [d for d in self.detectors if d.name == "cycles"]
            self.marks.cycle = cycles[0].cycle if reason == "loop" and detector == "cycles" and cycles else []
            self.marks.reason = reason
        return super().learn(reason, steps, state, motion, detector)


def table(path: Path) -> str:
    """The screening seeds (1-24), then this round's held-out seeds (241-280) on their own."""
    return "\n\n".join(seed_table(path, seeds) for seeds in (range(1, 25), HELD_OUT))


def main(argv=None) -> int:
    return round8_main(argv, cls=Round17, defaults=DEFAULT_PARAMS, variants=VARIANTS, default_out=DEFAULT_OUT,
                       description=__doc__, table_of=table)


if __name__ == "__main__":
    raise SystemExit(main())
