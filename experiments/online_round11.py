"""Round 11 of the on-line search (docs/online.md, "Round 11"): a revised distance term of the
model-based fitness (SPEC section 7), the term that round 10 found ranks the hand-written baseline
below the downloaded controller.

    python experiments/online_round11.py VARIANT SEEDS [--budget 20000] [--set key=value ...]
                                         [--param key=value ...]
    python experiments/online_round11.py distance 1-8 --param untried=1
    python experiments/online_round11.py distance 1-8 --param obstacle_any=1
    python experiments/online_round11.py distance 1-8 --param w_distance=0
    python experiments/online_round11.py --table build/experiments/round11.jsonl   # against the defaults

A lifetime is round 10's (``experiments.online_round10.Round10``, so ``default`` is ``ehw sim``'s
lifetime). New here, host side, a change of SPEC section 7's fitness measured in the reference
backend only: variant ``distance`` replaces the SPEC distance term 0.1 distance / (N max(dist))
by ``w_distance`` D / (N max(dist)), where D sums over the states s of S a credit for the
controller's motion a = T(s) (each state is tested once, so this is also what the SPEC trace
accumulates when every visited state earns its credit; ``trace_distance`` is that trace form):

- the entry (s, a) is known and not a crash: dist[a] (the SPEC), or max(dist) when
  ``obstacle_any`` = 1 and s has an obstacle bit (any known safe motion near an obstacle, turns
  in place included, earns the full step);
- the entry is unknown (trace stop (i)): ``untried`` x that same credit (the SPEC: 0);
- a crash: 0 (the SPEC);
- ``away`` = 1: in an obstacle state, a known entry earns its credit only when its next state has
  fewer obstacle bits than s (the motion takes the robot away from the obstacle); an untried
  entry is credited as above.

With ``untried`` = 0, ``obstacle_any`` = 0, ``away`` = 0 and ``w_distance`` = 0.1 the fitness is the SPEC's to
the bit (the host's correction is exactly 0), so the lifetime is ``default``'s.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments.online_round8 import main as round8_main  # noqa: E402
from experiments.online_round9 import table as round9_table  # noqa: E402
from experiments.online_round10 import DEFAULT_PARAMS as R10_PARAMS  # noqa: E402
from experiments.online_round10 import VARIANTS as R10_VARIANTS  # noqa: E402
from experiments.online_round10 import Round10  # noqa: E402
from ga.evaluator import W_DISTANCE  # noqa: E402
from ga.motions import MAX_MOTION_DISTANCE_MM, N_STATES, OBSTACLE_MASK, motion_distances  # noqa: E402
from ga.world_model import WorldModel  # noqa: E402

DEFAULT_OUT = Path("build/experiments/round11.jsonl")
# their ``default`` rows: today's defaults (round 9's: seeds 1-16, round 10's: 17-24)
REFERENCES = (Path("build/experiments/round9.jsonl"), Path("build/experiments/round10.jsonl"))
VARIANTS = (*R10_VARIANTS, "distance")
HELD_OUT = range(141, 161)  # never used to choose (101-120 reported rounds 8-10's defaults)
R11_PARAMS = {"untried": 0.0, "obstacle_any": 0, "w_distance": W_DISTANCE, "away": 0}
DEFAULT_PARAMS = {**R10_PARAMS, **R11_PARAMS}


def obstacle_bits(states) -> np.ndarray:
    """The number of obstacle bits set in each of ``states``."""
    bits = np.asarray(states, dtype=np.int64) & OBSTACLE_MASK
    return sum((bits >> i) & 1 for i in range(OBSTACLE_MASK.bit_length()))


def credits(model: WorldModel, rule: str, untried: float = 0.0, obstacle_any: bool = False,
            away: bool = False) -> np.ndarray:
    """(256, 8) float: the distance credit of each (state, motion) entry of ``model`` (module
    docstring); ``rule`` is SPEC section 7's dist[a] (``ga.motions.DISTANCE_RULES``)."""
    dist = np.broadcast_to(motion_distances(rule).astype(np.float64), (N_STATES, len(motion_distances(rule))))
    obstacle = (np.arange(N_STATES) & OBSTACLE_MASK) != 0
    if obstacle_any:
        dist = np.where(obstacle[:, None], float(MAX_MOTION_DISTANCE_MM), dist)
    known_safe = model.valid & ~model.crash
    if away:
        fewer = obstacle_bits(model.next_state) < obstacle_bits(np.arange(N_STATES))[:, None]
        known_safe = known_safe & (fewer | ~obstacle[:, None])
    return np.where(known_safe, dist, np.where(model.valid, 0.0, float(untried) * dist))


def credited_distance(tables: np.ndarray, model: WorldModel, rule: str, untried: float = 0.0,
                      obstacle_any: bool = False, away: bool = False) -> np.ndarray:
    """(P,): D of each controller (truth tables (P, 256)): the credits of (s, T(s)) over S."""
    s = model.states.astype(np.int64)
    return credits(model, rule, untried, obstacle_any, away)[s[None, :], np.asarray(tables)[:, s]].sum(axis=1)


def trace_distance(table, model: WorldModel, rule: str, untried: float = 0.0, obstacle_any: bool = False,
                   away: bool = False) -> float:
    """D of one controller (a 256-entry truth table) by SPEC section 7's pseudo-code, each visited
    state earning its credit where the SPEC adds dist[a] (and at stop (i)): the form a trace
    evaluator (the HDL's) would take; equal to ``credited_distance``."""
    credit = credits(model, rule, untried, obstacle_any, away)
    valid, crash, nxt = model.valid, model.crash, model.next_state
    tested: set[int] = set()
    total = 0.0
    for s0 in model.states.tolist():
        if s0 in tested:
            continue
        trace: set[int] = set()
        s = s0
        while True:
            tested.add(s)
            trace.add(s)
            a = int(table[s])
            total += credit[s, a]
            if not valid[s, a] or crash[s, a]:  # (i), (ii)
                break
            s2 = int(nxt[s, a])
            if s2 == s and not s & OBSTACLE_MASK:
                break
            if s2 in trace or s2 in tested:  # (iv), (iii)
                break
            s = s2
    return total


class Round11(Round10):
    """Round 10's lifetime with this round's distance term."""

    def distance_params(self) -> tuple[float, bool, bool, float]:
        prm = self.params
        return float(prm["untried"]), bool(prm["obstacle_any"]), bool(prm["away"]), float(prm["w_distance"])

    def penalty_of(self, tables: np.ndarray, n: int) -> np.ndarray:
        if self.variant != "distance":
            return super().penalty_of(tables, n)
        untried, obstacle_any, away, w = self.distance_params()
        rule = self.config.distance_rule
        spec = credited_distance(tables, self.mirror, rule)
        revised = credited_distance(tables, self.mirror, rule, untried, obstacle_any, away)
        # the SPEC term given back, the revised one taken: exactly 0 when the rule is the SPEC's
        return (W_DISTANCE * spec - w * revised) / (n * MAX_MOTION_DISTANCE_MM)

    def penalty(self, pop: np.ndarray, n: int) -> np.ndarray:
        if self.variant != "distance":
            return super().penalty(pop, n)
        from ga.truth_table import truth_tables

        return self.penalty_of(truth_tables(pop, reflex=self.config.reflex), n)


def table(path: Path, references=REFERENCES, held_out=HELD_OUT) -> str:
    """Round 9's table, against today's defaults (the ``default`` rows of ``references`` and this
    file's own): the screening seeds (1-24), then the held-out seeds on their own."""
    reference = tuple(p for p in references if p.exists())
    return "\n\n".join([round9_table(path, reference, seeds=range(1, 25)),
                          round9_table(path, reference, seeds=held_out)])


def main(argv=None) -> int:
    return round8_main(argv, cls=Round11, defaults=DEFAULT_PARAMS, variants=VARIANTS, default_out=DEFAULT_OUT,
                       description=__doc__, table_of=table)


if __name__ == "__main__":
    raise SystemExit(main())
