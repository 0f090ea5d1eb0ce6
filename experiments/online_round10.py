"""Round 10 of the on-line search (docs/online.md, "Round 10"): the normative-model direction of
round 9 (a loop and a crash weighted by the robot's own outcomes), made cheap and combined.

    python experiments/online_round10.py VARIANT SEEDS [--budget 20000] [--set key=value ...]
                                         [--param key=value ...]
    python experiments/online_round10.py likely 1-8                 # round 9's likely (now cheaper)
    python experiments/online_round10.py likely 1-8 --param cycles=3
    python experiments/online_round10.py likely 1-8 --param vote=1
    python experiments/online_round10.py likely 1-8 --param cycles=3 --param replace=1
    python experiments/online_round10.py crashfreq 1-8
    python experiments/online_round10.py --table build/experiments/round10.jsonl   # against round 9's defaults

A lifetime is round 9's (``experiments.online_round9.Round9``: round 8's with the cycle blame of
today's defaults, round 7's instrumentation, the baseline scored in every phase). New here, all
host side, changes of SPEC section 7's fitness measured in the reference backend only:

- variant ``likely``: round 9's penalty (``w_likely`` / N times the probability, summed over the
  obstacle states s of S, of a 2-cycle s -> s2 -> s under the robot's kept outcomes as
  frequencies), which round 9's ``two_cycle_odds`` now computes from a per-phase table of the
  outcome shares instead of a (P, |S|, H, H) gather, to the bit (same lifetimes). ``cycles`` = 3:
  the 3-cycles s -> s2 -> s3 -> s (distinct states) as well, listed once per learning phase with
  their per-motion factors (``likely_cycles``), so a generation costs a gather and a product over
  (P, cycles). ``vote`` = 1: round 9's ``crashvote`` model as well (a crash entry of a pair that
  went through in at least ``safe_share`` of its executions holds its latest non-crash outcome
  for the phase). ``replace`` = 1: the likely cycles replace the SPEC's loop term (its count of
  the one-outcome model's loops is given back) instead of being subtracted on top of it.
  ``crashfreq`` = 1: the crash term as below;
- variant ``crashfreq``: the SPEC crash term #{s in S : the entry of (s, T(s)) is a crash} becomes
  the expected crashes, the sum over s in S of the crash share of (s, T(s)) in the robot's
  executions of it (``w_crashfreq`` = 0.5, the SPEC weight, over N); the model (and so the traces
  and loops) unchanged.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments.online_round8 import main as round8_main  # noqa: E402
from experiments.online_round9 import DEFAULT_PARAMS as R9_PARAMS  # noqa: E402
from experiments.online_round9 import Round9  # noqa: E402
from experiments.online_round9 import table as round9_table  # noqa: E402
from ga.motions import N_MOTIONS, OBSTACLE_MASK  # noqa: E402
from ga.evaluator import evaluate_tables, fitness as spec_fitness  # noqa: E402
from ga.truth_table import truth_tables  # noqa: E402

DEFAULT_OUT = Path("build/experiments/round10.jsonl")
REFERENCE = Path("build/experiments/round9.jsonl")  # its ``default`` rows: today's defaults
VARIANTS = ("default", "likely", "crashfreq")
R10_PARAMS = {"cycles": 2, "replace": 0, "vote": 0, "crashfreq": 0, "w_crashfreq": 0.5}
DEFAULT_PARAMS = {**R9_PARAMS, **R10_PARAMS}


def likely_cycles(shares: np.ndarray, starts, length: int) -> tuple[np.ndarray, np.ndarray]:
    """The cycles of ``length`` distinct states from each of ``starts`` that the kept outcomes
    allow (each step to a state other than its own): their states (C, length) and per-motion
    factors (C, length, 8), factor i = the share of the step from state i to state i + 1."""
    reach = shares.sum(axis=1) > 0
    np.fill_diagonal(reach, False)
    succ = [np.flatnonzero(row) for row in reach]
    found = []

    def walk(path):
        if len(path) == length:
            if reach[path[-1], path[0]]:
                found.append(tuple(path))
            return
        for nxt in succ[path[-1]]:
            if nxt not in path:
                walk([*path, int(nxt)])

    for s in starts:
        walk([int(s)])
    states = np.array(found, dtype=np.int64).reshape(-1, length)
    factors = shares[states, :, np.roll(states, -1, axis=1)]  # (C, length, 8)
    return states, factors


def cycle_odds(tables: np.ndarray, states: np.ndarray, factors: np.ndarray) -> np.ndarray:
    """(P,): for each controller (truth tables (P, 256)) the summed probability of the cycles
    (``likely_cycles``) under its motions."""
    c, length = states.shape
    if not c:
        return np.zeros(tables.shape[0])
    motions = tables[:, states].astype(np.int64)  # (P, C, length)
    base = (np.arange(c * length) * N_MOTIONS).reshape(c, length)
    return factors.ravel()[base + motions].prod(axis=2).sum(axis=1)


class Round10(Round9):
    """Round 9's lifetime with this round's penalties."""

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self._cycles_at = -1

    def cycles(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """The cycle lists of lengths 3..``cycles`` of the current outcomes (the 2-cycles are
        round 9's ``likely_penalty``)."""
        if self._cycles_at != self.interactions:
            states = self.mirror.states
            starts = states[(states & OBSTACLE_MASK) != 0]
            shares = self.back_shares()
            self._cycles = [likely_cycles(shares, starts, k) for k in range(3, int(self.params["cycles"]) + 1)]
            self._cycles_at = self.interactions
        return self._cycles

    def crash_shares(self) -> np.ndarray:
        """(256, 8): the crash share of each (state, motion) in the robot's executions of it."""
        return self.tally[..., 0] / np.maximum(self.tally.sum(axis=2), 1)

    def penalty(self, pop: np.ndarray, n: int) -> np.ndarray:
        if self.variant not in ("likely", "crashfreq"):
            return super().penalty(pop, n)
        return self.penalty_of(truth_tables(pop, reflex=self.config.reflex), n)

    def penalty_of(self, tables: np.ndarray, n: int) -> np.ndarray:
        """This round's penalty of truth tables (P, 256)."""
        prm = self.params
        pen = np.zeros(len(tables))
        if self.variant == "likely":
            pen += self.likely_penalty(tables, n)  # round 9's 2-cycles, to the bit
            for states, factors in self.cycles():
                pen += float(prm["w_likely"]) * cycle_odds(tables, states, factors) / n
            if prm["replace"]:  # the likely cycles instead of the SPEC's one-outcome loops, not on top
                loops = evaluate_tables(tables, self.mirror, self.config.distance_rule).loops
                pen -= float(prm["w_likely"]) * loops / n
            if prm["vote"]:
                pen += self.vote_penalty(tables, n)
        if self.variant == "crashfreq" or prm["crashfreq"]:
            s = self.mirror.states.astype(np.int64)
            chosen = tables[:, s]
            entries = (self.mirror.valid & self.mirror.crash)[s[None, :], chosen].sum(axis=1)
            expected = self.crash_shares()[s[None, :], chosen].sum(axis=1)
            pen += float(prm["w_crashfreq"]) * (expected - entries) / n
        return pen

    def learn(self, reason, steps, state, motion, detector=""):
        super().learn(reason, steps, state, motion, detector)
        if self.variant == "default" or self.best_rows is None or not self.mirror.n_states:
            return
        # round 9's instrumentation with this round's fitness: is the baseline still below the download?
        n = self.mirror.n_states
        both = np.stack([truth_tables(self.best_rows[None], reflex=self.config.reflex)[0], self.base_table])
        fit = spec_fitness(evaluate_tables(both, self.mirror, self.config.distance_rule), n) - self.penalty_of(both, n)
        self.base_log["baseline_below_penalised"] += int(fit[1] < fit[0])


def table(path: Path) -> str:
    """Round 9's screening table, against round 9's ``default`` rows (REFERENCE)."""
    return round9_table(path, reference=REFERENCE if REFERENCE.exists() else None)


def main(argv=None) -> int:
    return round8_main(argv, cls=Round10, defaults=DEFAULT_PARAMS, variants=VARIANTS, default_out=DEFAULT_OUT,
                       description=__doc__, table_of=table)


if __name__ == "__main__":
    raise SystemExit(main())
