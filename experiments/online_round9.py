"""Round 9 of the on-line search (docs/online.md, "Round 9"): when a learning phase starts, with
round 8's cycle blame, and a loop weighted by how likely the robot's own outcomes make it.

    python experiments/online_round9.py VARIANT SEEDS [--budget 20000] [--set key=value ...]
                                        [--param key=value ...]
    python experiments/online_round9.py default 1-8 --set loop_cycles=2
    python experiments/online_round9.py default 1-8 --param two_if='"surprise"'
    python experiments/online_round9.py likely 1-8
    python experiments/online_round9.py --table build/experiments/round9.jsonl   # the Markdown table

A lifetime is round 8's (``experiments.online_round8.Round8``, itself round 7's instrumented
``OnlineRun``), with the cycle stop blamed like today's default (``blame`` "cycle_now", the main
code's ``loop_blame`` "cycle"), so ``default`` with no parameter is ``ehw sim``'s lifetime. New here:

- ``two_if`` = "surprise": the cycle stop waits for a second round of a cycle only when one of its
  pairs went, in this round, elsewhere than the model's entry said (a loop the noise made, which
  the noise may undo); a cycle the model held (every pair confirmed, or untried) stops after one
  round;
- variant ``likely``: a loop weighted by how likely the robot's own outcomes make it. The host
  keeps the last ``history`` outcomes of each (state, motion) (round 7's ``resample`` kept the
  same); for each controller and each obstacle state s of S it computes the probability of a
  2-cycle s -> s2 -> s (s2 != s) under those outcomes as frequencies (2-cycles were 273 of seed
  1's 343 cycle stops in round 8), and ``w_likely`` / N times their sum is subtracted from the
  SPEC fitness (host side; the board's counts untouched). This is a change of SPEC section 7's
  fitness, measured here in the reference backend only;
- variant ``crashvote``: the learning phase sees the board's model except that a crash entry whose
  (state, motion) went through without a crash in at least ``safe_share`` of its executions holds
  its latest non-crash outcome (SPEC section 7 keeps a crash for ever: under the sensor noise a
  motion that is safe nearly always is then never chosen again). A change of SPEC section 7's
  model update, measured here in the reference backend only (the host evaluates the phase's
  fitness on that model; the board's counts are the SPEC's and unused).

Instrumentation (every variant; ``baseline`` in the JSON line): the hand-written reactive
baseline (``sim_world.baseline``, 4,229.5 interactions on seeds 101-120 without learning) is
scored with the SPEC fitness on the model of every learning phase, beside the downloaded
controller; and at each cycle stop, the cycle's obstacle pairs are compared with the baseline's
motion in their states.
"""

from __future__ import annotations

import sys
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from cosim.online.failures import Cycles  # noqa: E402
from experiments.online_round7 import AdaptiveCycles  # noqa: E402
from experiments.online_round7 import VARIANTS as R7_VARIANTS  # noqa: E402
from experiments.online_round8 import DEFAULT_PARAMS as R8_PARAMS  # noqa: E402
from experiments.online_round6 import cell  # noqa: E402
from experiments.online_round7 import rows_by_variant  # noqa: E402
from experiments.online_round8 import Round8, detected_cycle  # noqa: E402
from experiments.online_round8 import main as round8_main  # noqa: E402
from ga.evaluator import evaluate_tables, fitness as spec_fitness  # noqa: E402
from ga.motions import N_MOTIONS, N_STATES, OBSTACLE_MASK  # noqa: E402
from ga.truth_table import truth_tables  # noqa: E402
from sim_world.baseline import baseline_table  # noqa: E402

DEFAULT_OUT = Path("build/experiments/round9.jsonl")
VARIANTS = (*R7_VARIANTS, "likely", "crashvote")
R9_PARAMS = {"blame": "cycle_now", "two_if": "", "w_likely": 0.4, "safe_share": 0.8}
DEFAULT_PARAMS = {**R8_PARAMS, **R9_PARAMS}
TWO_IF = ("", "surprise")


def two_cycle_odds(tables: np.ndarray, outcomes: np.ndarray, states: np.ndarray,
                   back: np.ndarray | None = None) -> np.ndarray:
    """(P, len(states)): for each controller (truth tables (P, 256)) and each of ``states``, the
    probability of going s -> s2 -> s with s2 != s when each (state, motion) goes to one of its
    kept ``outcomes`` (256, 8, H; -1 = none) with their frequencies. A (state, motion) with no
    kept outcome adds nothing. ``back``: ``back_shares(outcomes)``, computed here if not given
    (round 10: it replaces a (P, len(states), H, H) gather, with the same values to the bit)."""
    pop = tables.shape[0]
    rows = np.arange(pop)[:, None, None]
    kept = (outcomes >= 0).sum(axis=2)  # (256, 8)
    o1 = outcomes[states[None, :], tables[:, states]]  # (P, n, H)
    n1 = kept[states[None, :], tables[:, states]]  # (P, n)
    away = (o1 >= 0) & (o1 != states[None, :, None])
    s2 = np.where(o1 >= 0, o1, 0)
    a2 = tables[rows, s2]  # (P, n, H)
    if back is None:
        back = back_shares(outcomes)
    return (away * back[s2, a2, states[None, :, None]]).sum(axis=2) / np.maximum(n1, 1)


def back_shares(outcomes: np.ndarray) -> np.ndarray:
    """(256, 8, 256): the share of each next state among the kept ``outcomes`` of each
    (state, motion) (0 where none kept)."""
    kept = (outcomes >= 0).sum(axis=2)
    cells = (np.arange(N_STATES * N_MOTIONS) * N_STATES).reshape(N_STATES, N_MOTIONS, 1)
    counts = np.bincount((cells + outcomes)[outcomes >= 0], minlength=N_STATES * N_MOTIONS * N_STATES)
    return counts.reshape(N_STATES, N_MOTIONS, N_STATES) / np.maximum(kept, 1)[:, :, None]


class Round9(Round8):
    """Round 8's lifetime with this round's phase-start rule, penalty and instrumentation."""

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self.base_table = baseline_table()
        self.base_log: Counter = Counter()
        self.loop_motions: Counter = Counter()  # cycle-stop obstacle pairs: "same" motion as the baseline or "other"
        if self.params["two_if"] not in TWO_IF:
            raise ValueError(f"--param two_if must be one of {TWO_IF!r}, got {self.params['two_if']!r}")
        if self.params["two_if"] == "surprise":
            self.detectors = [self._surprise_cycles() if isinstance(d, Cycles) else d for d in self.detectors]
        self._outcomes_at = self._voted_at = self._back_at = -1
        self.tally = np.zeros((N_STATES, N_MOTIONS, 2), dtype=np.int64)  # (s, a): crashes, not

    def _surprise_cycles(self) -> AdaptiveCycles:
        detector = AdaptiveCycles(None, self.config.loop_radius_mm)
        # one round is enough when no pair of that round was a surprise
        detector.known = lambda: "surprise" not in self.classes[-len(detector.one.cycle):]
        return detector

    def step(self, motion, record=True):
        s = self.state
        step = super().step(motion, record)
        self.tally[s, motion, 0 if step.crashed else 1] += 1
        return step

    def outcomes(self) -> np.ndarray:
        """The kept outcomes (round 7's ``history``) as (256, 8, H), -1 where none."""
        if self._outcomes_at != self.interactions:
            h = int(self.params["history"])
            out = np.full((N_STATES, N_MOTIONS, h), -1, dtype=np.int64)
            for (s, a), kept in self.history.items():
                out[s, a, :len(kept)] = kept
            self._outcomes, self._outcomes_at = out, self.interactions
        return self._outcomes

    def back_shares(self) -> np.ndarray:
        """``back_shares`` of the kept outcomes, once per interaction count."""
        if self._back_at != self.interactions:
            self._back, self._back_at = back_shares(self.outcomes()), self.interactions
        return self._back

    def voted_model(self):
        """The model a ``crashvote`` phase sees: the board's, except that a crash entry whose pair
        went through without a crash in at least ``safe_share`` of its executions holds its
        latest non-crash outcome instead."""
        if self._voted_at != self.interactions:
            m = self.mirror.copy()
            safe = self.tally[..., 1] / np.maximum(self.tally.sum(axis=2), 1)
            for s, a in zip(*np.nonzero(m.valid & m.crash & (safe >= float(self.params["safe_share"])))):
                m.crash[s, a] = False
                m.next_state[s, a] = self.history[(int(s), int(a))][-1]
            self._voted, self._voted_at = m, self.interactions
        return self._voted

    def vote_penalty(self, tables: np.ndarray, n: int) -> np.ndarray:
        """The SPEC fitness on the board's model minus that on the voted model (``crashvote``)."""
        rule = self.config.distance_rule
        return (spec_fitness(evaluate_tables(tables, self.mirror, rule), n)
                - spec_fitness(evaluate_tables(tables, self.voted_model(), rule), n))

    def penalty(self, pop: np.ndarray, n: int) -> np.ndarray:
        if self.variant == "crashvote":  # the SPEC fitness on the voted model instead of the board's
            return self.vote_penalty(truth_tables(pop, reflex=self.config.reflex), n)
        if self.variant != "likely":
            return super().penalty(pop, n)
        return self.likely_penalty(truth_tables(pop, reflex=self.config.reflex), n)

    def likely_penalty(self, tables: np.ndarray, n: int) -> np.ndarray:
        """``w_likely`` / N times the 2-cycle odds summed over the obstacle states of S."""
        states = self.mirror.states
        states = states[(states & OBSTACLE_MASK) != 0].astype(np.int64)
        odds = two_cycle_odds(tables.astype(np.int64), self.outcomes(), states, self.back_shares())
        return float(self.params["w_likely"]) * odds.sum(axis=1) / n

    def learn(self, reason, steps, state, motion, detector=""):
        cycle = detected_cycle(self.track, self.config.loop_radius_mm) if detector == "cycles" else []
        for s, a in cycle:
            if s & OBSTACLE_MASK:
                self.loop_motions["same" if a == self.base_table[s] else "other"] += 1
        super().learn(reason, steps, state, motion, detector)
        if self.best_rows is None or not self.mirror.n_states:
            return
        n = self.mirror.n_states
        both = np.stack([truth_tables(self.best_rows[None], reflex=self.config.reflex)[0], self.base_table])
        counts = evaluate_tables(both, self.mirror, self.config.distance_rule)
        fit = spec_fitness(counts, n)
        log = self.base_log
        log["phases"] += 1
        log["baseline_below"] += int(fit[1] < fit[0])
        log["baseline_equal"] += int(fit[1] == fit[0])
        log["best_loops"] += int(counts.loops[0])
        log["baseline_loops"] += int(counts.loops[1])
        log["best_crashes"] += int(counts.crashes[0])
        log["baseline_crashes"] += int(counts.crashes[1])

    def extra_figures(self) -> dict:
        crash = self.mirror.crash & self.mirror.valid
        safe = self.tally[..., 1] / np.maximum(self.tally.sum(axis=2), 1)
        base = np.zeros_like(crash)
        base[np.arange(N_STATES), self.base_table] = True
        entries = {"crash_entries": int(crash.sum()),
                   "crash_entries_safe_half": int((crash & (safe >= 0.5)).sum()),
                   "crash_entries_safe_80": int((crash & (safe >= 0.8)).sum()),
                   "baseline_crash_entries": int((crash & base).sum()),
                   "baseline_crash_entries_safe_half": int((crash & base & (safe >= 0.5)).sum())}
        return {"baseline": {**self.base_log, **{f"cycle_pairs_{k}": v for k, v in self.loop_motions.items()}},
                "crash_entries": entries}


def table(path: Path, reference: Path | tuple[Path, ...] | None = None, seeds=None) -> str:
    """The screening table: per seed, the median, and against the ``default`` row (no setting, no
    parameter: today's defaults; also those of ``reference`` when given, one file or several, for a
    later round's reuse of earlier rounds' rows) on the seeds both ran: how many lifetimes were
    shorter and the geometric mean of the per-seed ratios (a run out of budget counts as the budget).
    ``seeds``: only the rows of the seeds it holds (e.g. the held-out ones)."""
    rows = {key: kept for key, rs in rows_by_variant(path).items()
            if (kept := [r for r in rs if seeds is None or r["seed"] in seeds])}

    def value(r):
        return r["interactions"] if r["targets"] >= 64 else r["budget"]

    ref = {}
    for p in (reference,) if isinstance(reference, Path) else reference or ():
        ref.update({r["seed"]: r for r in rows_by_variant(p).get("default", [])})
    ref.update({r["seed"]: r for r in rows.get("default", [])})
    out = ["| variant | per seed (seed: interactions to 64, or targets @ budget) | median | against the defaults: shorter, ratio | failures | CPU-s |",
           "|---|---|---|---|---|---|"]
    for key, rs in rows.items():
        by_seed = {r["seed"]: r for r in rs}
        cells = ", ".join(f"{r['seed']}: {cell(r)}" for r in rs)
        med = f"{float(np.median([value(r) for r in rs])):,.0f}"
        both = [s for s in by_seed if s in ref]
        if key == "default" or not both:
            versus = ""
        else:
            ratios = [value(by_seed[s]) / value(ref[s]) for s in both]
            versus = (f"{sum(x < 1 for x in ratios)} of {len(both)}, "
                      f"{float(np.exp(np.mean(np.log(ratios)))):.2f}")
        fails = ", ".join(str(r["failures"]) for r in rs)
        cpu = f"{min(r['cpu_s'] for r in rs):.0f}-{max(r['cpu_s'] for r in rs):.0f}"
        out.append(f"| {key} | {cells} | {med} | {versus} | {fails} | {cpu} |")
    return "\n".join(out)


def main(argv=None) -> int:
    return round8_main(argv, cls=Round9, defaults=DEFAULT_PARAMS, variants=VARIANTS, default_out=DEFAULT_OUT,
                       description=__doc__, table_of=table)


if __name__ == "__main__":
    raise SystemExit(main())
