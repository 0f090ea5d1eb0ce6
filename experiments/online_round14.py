"""Round 14 of the on-line search (docs/online.md, "Round 14"): where the interactions above the
hand-written controller's go (thrash legs), and the robot's own failure rates in the learning phase.

    python experiments/online_round14.py VARIANT SEEDS [--budget 20000] [--set key=value ...]
                                         [--param key=value ...]
    python experiments/online_round14.py default 1-8
    python experiments/online_round14.py failrate 1-8 --param w_fail=0.5
    python experiments/online_round14.py bandit 1-8
    python experiments/online_round14.py --table build/experiments/round14.jsonl

A lifetime is round 12's (``experiments.online_round12.Round12``, so ``default`` is ``ehw sim``'s
lifetime). New here, host side:

- *failure rates*: each executed (state, motion) is marked *failed* when a failure (crash, loop
  stop, time-out) ends its execution phase within ``horizon`` steps of it (each pair once per
  failure), else *ok* (a target reached, or more than ``horizon`` steps before the failure). The
  failure rate of a pair is (failed + ``prior`` * ``pseudo``) / (executed + ``pseudo``), ``prior``
  for a pair never executed. Unlike the world model's entries (one latest outcome, 70 % wrong in
  obstacle states, round 7) this is what the pair cost the robot, whatever the noise did.
- variant ``failrate``: ``w_fail`` / N times the summed failure rates of the controller's motions
  in the obstacle states of S is subtracted from SPEC section 7's fitness (a per-(state, motion)
  weight table, the shape of the distance term, so an evaluator board could hold it in a RAM).
- variant ``bandit``: the escape after a loop stop or time-out (``cosim.online.download``) picks, among
  the motions the population offers in the blamed state other than the blamed one, the one with
  the lowest failure rate, and downloads the fittest individual choosing it (instead of the
  fittest individual choosing any other motion). ``--param bandit=1`` adds it to ``failrate``.

The round's instrument, ``thrash``: each leg's interactions against the hand-written controller's
mean for that leg (``sim_world.baseline``, noise seeds 1-5): the excess over it, and how much of it
lies in *thrash legs* (more than twice the baseline's leg plus 30 interactions); and how many targets
each download reached before the next learning phase (``downloads``).
"""

from __future__ import annotations

import json
import statistics
import sys
from functools import lru_cache
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import cosim.online.run as online_mod  # noqa: E402
from cosim.online.download import choose_download  # noqa: E402
from experiments.online_round6 import cell  # noqa: E402
from experiments.online_round7 import rows_by_variant  # noqa: E402
from experiments.online_round8 import main as round8_main  # noqa: E402
from experiments.online_round12 import DEFAULT_PARAMS as R12_PARAMS  # noqa: E402
from experiments.online_round12 import Round12  # noqa: E402
from ga.motions import N_MOTIONS, N_STATES, OBSTACLE_MASK  # noqa: E402
from ga.truth_table import truth_tables  # noqa: E402

DEFAULT_OUT = Path("build/experiments/round14.jsonl")
VARIANTS = ("default", "failrate", "bandit")
R14_PARAMS = {"horizon": 8, "prior": 0.3, "pseudo": 1.0, "w_fail": 0.5, "bandit": 0}
DEFAULT_PARAMS = {**R12_PARAMS, **R14_PARAMS}
HELD_OUT = range(181, 201)  # never used to choose (101-120, 141-160, 161-180: earlier rounds')
BASELINE_NOISE_SEEDS = range(1, 6)
THRASH_FACTOR, THRASH_MARGIN = 2.0, 30


@lru_cache(maxsize=1)
def baseline_legs() -> tuple[float, ...]:
    """The hand-written controller's mean interactions per leg in the noisy world (noise seeds 1-5)."""
    from sim_world.baseline import run_baseline
    from sim_world.world import DEFAULT_NOISE

    runs = [run_baseline(noise=DEFAULT_NOISE, seed=s).leg_steps for s in BASELINE_NOISE_SEEDS]
    return tuple(float(np.mean([r[i] for r in runs])) for i in range(min(map(len, runs))))


def thrash(legs: list[int]) -> dict:
    """A lifetime's legs against the baseline's: the excess, and its part in thrash legs."""
    base = baseline_legs()
    pairs = list(zip(legs, base))  # an unfinished last leg is compared all the same
    excess = sum(on - b for on, b in pairs)
    bad = [i for i, (on, b) in enumerate(pairs) if on > THRASH_FACTOR * b + THRASH_MARGIN]
    return {"excess": round(excess), "thrash_legs": len(bad),
            "thrash_excess": round(sum(pairs[i][0] - pairs[i][1] for i in bad)),
            "baseline": round(sum(b for _, b in pairs))}


def failure_rates(failed: np.ndarray, executed: np.ndarray, prior: float, pseudo: float) -> np.ndarray:
    """(256, 8): (failed + prior * pseudo) / (executed + pseudo)."""
    return (failed + prior * pseudo) / (executed + pseudo)


class Round14(Round12):
    """Round 12's lifetime with this round's failure rates."""

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self.executed = np.zeros((N_STATES, N_MOTIONS), dtype=np.int64)
        self.failed = np.zeros((N_STATES, N_MOTIONS), dtype=np.int64)
        self.open_pairs: list[tuple[int, int]] = []  # this execution phase's pairs not yet judged
        self.bandit_log = {"escapes": 0, "changed_motion": 0}

    def step(self, motion, record=True):
        s = self.state
        step = super().step(motion, record)
        self.executed[s, motion] += 1
        self.open_pairs.append((s, int(motion)))
        if step.reached:
            self.open_pairs.clear()  # ok: the leg ended at its target
        return step

    def rates(self) -> np.ndarray:
        prm = self.params
        return failure_rates(self.failed, self.executed, float(prm["prior"]), float(prm["pseudo"]))

    def judge_failure(self) -> None:
        """The failure that ended this execution phase: its last ``horizon`` pairs failed."""
        tail = self.open_pairs[-int(self.params["horizon"]):]
        for s, a in set(tail):
            self.failed[s, a] += 1
        self.open_pairs.clear()

    def penalty(self, pop: np.ndarray, n: int) -> np.ndarray:
        if self.variant in ("failrate", "bandit"):
            return self.penalty_of(truth_tables(pop, reflex=self.config.reflex), n)
        return super().penalty(pop, n)

    def penalty_of(self, tables: np.ndarray, n: int) -> np.ndarray:
        if self.variant == "bandit":
            return np.zeros(len(tables))  # the SPEC fitness, to the bit
        if self.variant != "failrate":
            return super().penalty_of(tables, n)
        states = self.mirror.states
        states = states[(states & OBSTACLE_MASK) != 0].astype(np.int64)
        return float(self.params["w_fail"]) * self.rates()[states[None, :], tables[:, states]].sum(axis=1) / n

    def escape_download(self, population, fitness, blamed=None, reflex=True):
        """``bandit``: the blamed state's other motion with the lowest failure rate (see the docstring)."""
        if blamed is None:
            return choose_download(population, fitness, None, reflex)
        state, motion = blamed
        motions = truth_tables(population, reflex=reflex)[:, state]
        offered = sorted(set(motions.tolist()) - {motion})
        if not offered:
            return choose_download(population, fitness, blamed, reflex)
        rates = self.rates()[state]
        pick = min(offered, key=lambda m: (rates[m], -float(fitness[motions == m].max())))
        which = np.flatnonzero(motions == pick)
        i = int(which[np.argmax(fitness[which])])
        others = np.flatnonzero(motions != motion)  # the plain escape's choice: the fittest of these
        self.bandit_log["escapes"] += 1
        self.bandit_log["changed_motion"] += int(motions[others[np.argmax(fitness[others])]] != pick)
        return i, i != int(np.argmax(fitness))

    def learn(self, reason, steps, state, motion, detector=""):
        if reason in ("crash", "loop", "timeout"):
            self.judge_failure()
        bandit = self.variant == "bandit" or bool(self.params["bandit"])
        saved = online_mod.choose_download
        if bandit:
            online_mod.choose_download = self.escape_download
        try:
            super().learn(reason, steps, state, motion, detector)
        finally:
            online_mod.choose_download = saved

    def extra_figures(self) -> dict:
        from experiments.online_round8 import legs

        marks = [0] + [p["targets"] for p in self.phases] + [self.targets]  # the first: the random start
        gains = [b - a for a, b in zip(marks, marks[1:])]  # targets each download reached before the next phase
        return {**super().extra_figures(), "bandit": dict(self.bandit_log),
                "downloads": {"n": len(gains), "no_target": sum(g == 0 for g in gains),
                              "most_targets": max(gains, default=0)},
                "thrash": thrash(legs(self.target_log, self.interactions)),
                "failed_marks": int(self.failed.sum()), "executed": int(self.executed.sum())}


def table(path: Path) -> str:
    """The screening seeds (1-24), then the held-out seeds on their own."""
    return "\n\n".join(seed_table(path, seeds) for seeds in (range(1, 25), HELD_OUT))


def seed_table(path: Path, seeds) -> str:
    """Each variant's lifetimes on ``seeds`` against this file's ``default`` rows on the same seeds."""
    rows = {k: [r for r in rs if r["seed"] in seeds] for k, rs in rows_by_variant(path).items()}
    rows = {k: rs for k, rs in rows.items() if rs}
    default = {r["seed"]: r for r in rows.get("default", [])}
    out = ["| variant | seeds | per seed (interactions to 64, or t @ budget) | median | default's median, same seeds "
           "| shorter | ratio (geometric mean) | failures | thrash legs | excess in thrash legs | CPU-s |",
           "|---|---|---|---|---|---|---|---|---|---|---|"]

    def value(r):
        return r["interactions"] if r["targets"] >= 64 else r["budget"]

    for key, rs in rows.items():
        rs = sorted(rs, key=lambda r: r["seed"])
        seeds = [r["seed"] for r in rs]
        same = [r for r in rs if r["seed"] in default]
        ref = [value(default[r["seed"]]) for r in same]
        shorter = sum(value(r) < v for r, v in zip(same, ref))
        ratio = float(np.exp(np.mean([np.log(value(r) / v) for r, v in zip(same, ref)]))) if same else float("nan")
        th = [r.get("thrash", {}) for r in rs]
        share = sum(t.get("thrash_excess", 0) for t in th) / max(sum(t.get("excess", 0) for t in th), 1)
        out.append(
            f"| {key} | {seeds[0]}-{seeds[-1]} ({len(rs)}) | " + ", ".join(f"{r['seed']}: {cell(r)}" for r in rs)
            + f" | {statistics.median(map(value, rs)):,.1f} | {statistics.median(ref):,.1f} | {shorter}/{len(same)} "
            f"| {ratio:.2f} | {statistics.median(r['failures'] for r in rs):,.0f} "
            f"| {statistics.median(t.get('thrash_legs', 0) for t in th):.0f} | {share:.0%} "
            f"| {min(r['cpu_s'] for r in rs):.0f}-{max(r['cpu_s'] for r in rs):.0f} |")
    return "\n".join(out)


def main(argv=None) -> int:
    return round8_main(argv, cls=Round14, defaults=DEFAULT_PARAMS, variants=VARIANTS, default_out=DEFAULT_OUT,
                       description=__doc__, table_of=table)


if __name__ == "__main__":
    raise SystemExit(main())
