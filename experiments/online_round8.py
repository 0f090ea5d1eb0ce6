"""Round 8 of the on-line search (docs/online.md, "Round 8"): *when* a learning phase starts and
which controller it leaves on the robot, screened on a few seeds, one lifetime at a time.

    python experiments/online_round8.py VARIANT SEEDS [--budget 20000] [--set key=value ...]
                                        [--param key=value ...]
    python experiments/online_round8.py default 1-8 --param first2=1
    python experiments/online_round8.py --table build/experiments/round8.jsonl   # the Markdown table

A lifetime is round 7's (``experiments.online_round7.Round7``: the current ``OnlineRun`` with its
instrumentation; VARIANT is one of round 7's) with these host-side parameters (``--param``; 0 = off,
the defaults' behaviour):

- ``first2`` = K: the cycle stop waits for a second round of the cycle for the first K loop stops
  of a leg, one round after (K = 1 is round 7's ``leg2``; a large K is ``loop_cycles=2``);
- ``at_target`` = 1: a learning phase also at each target reached (before the last one): no
  failure, no escape, no interaction; the robot goes on with the downloaded controller;
- ``every`` = K: a learning phase also after K steps of an execution phase without failure;
- ``keep`` = 1: after such a phase (``at_target``, ``every``), the running controller stays unless
  the new best is strictly fitter than it on the same model (the board evaluates it once more);
- ``blame``: the (state, motion) a cycle stop is blamed on (the escape avoids it): ``leg`` (this
  script's default: rounds 1-7's rule, the leg's most frequent obstacle pair), ``cycle_now`` (the
  cycle's first obstacle pair from the robot's state on: the main code's default ``loop_blame``
  "cycle" since this round), ``cycle_freq`` (the cycle's obstacle pair most frequent in the leg).

The learning phases that no failure started get the reasons ``target`` and ``periodic`` in the
phase records; the board and its counts are untouched.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from cosim.online.failures import Cycles, blame  # noqa: E402
from cosim.online.run import OnlineConfig, make_run  # noqa: E402
from experiments.online_round6 import lost, seeds_of  # noqa: E402
from experiments.online_round7 import DEFAULT_PARAMS as R7_PARAMS  # noqa: E402
from experiments.online_round7 import (  # noqa: E402
    VARIANTS, AdaptiveCycles, Round7, key_of, parse_kv, rows_by_variant, seed_cells)
from ga.evaluator import fitness as model_fitness  # noqa: E402
from ga.motions import OBSTACLE_MASK  # noqa: E402

DEFAULT_OUT = Path("build/experiments/round8.jsonl")
R8_PARAMS = {"first2": 0, "at_target": 0, "every": 0, "keep": 0, "blame": "leg"}
BLAMES = ("leg", "cycle_now", "cycle_freq")
DEFAULT_PARAMS = {**R7_PARAMS, **R8_PARAMS}


class Round8(Round7):
    """Round 7's lifetime with the phase-start and keep parameters of this round."""

    fail_rates = False  # OnlineConfig.fail_rates of run_one (round 15 made it the default)
    rate_mirror = False  # OnlineConfig.rate_mirror of run_one (round 16 made it the default)
    progress_weight = 0.0  # OnlineConfig.progress_weight of run_one (round 18 made 3.0 the default)

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self.leg_loops = 0  # loop stops on the current leg
        self.leg_of_loops = -1  # the targets reached when leg_loops was counted
        self.kept = 0  # phases after which the running controller stayed
        first2 = int(self.params["first2"])
        if first2:
            self.detectors = [AdaptiveCycles(lambda: self.loops_this_leg() >= first2, self.config.loop_radius_mm)
                              if isinstance(d, Cycles) else d for d in self.detectors]

    def extra_figures(self) -> dict:
        """More figures for the JSON line (a later round's instrumentation)."""
        return {}

    def loops_this_leg(self) -> int:
        return self.leg_loops if self.leg_of_loops == self.targets else 0

    def extra_stop(self, steps: int, at_target: bool) -> str:
        """The extra phase starts: at a target (``at_target``), every K execution steps (``every``)."""
        if at_target:
            return "target" if self.params["at_target"] else ""
        every = int(self.params["every"])
        return "periodic" if every and steps % every == 0 else ""

    def blamed(self, detector) -> tuple[int, int]:
        """The (state, motion) the stop is blamed on: ``blame`` = leg (the defaults: the most
        frequent obstacle pair of the leg's recent pairs), or, for a cycle stop, a pair of the
        cycle that stopped the leg: cycle_now (the robot's current state's pair when it has an
        obstacle bit, else the cycle's next obstacle pair), cycle_freq (the cycle's obstacle pair
        most frequent among the leg's recent pairs)."""
        rule = self.params["blame"]
        cycle = detected_cycle(self.track, self.config.loop_radius_mm) if detector.name == "cycles" else []
        if rule == "leg" or not cycle:
            return blame(self.track.pairs)
        obstacle = [p for p in cycle if p[0] & OBSTACLE_MASK]
        if rule == "cycle_now":
            return obstacle[0]
        counts = Counter(self.track.pairs)
        return max(obstacle, key=lambda p: counts[p])  # ties: the first from the current state

    def learn(self, reason, steps, state, motion, detector=""):
        if reason == "loop":
            self.leg_loops = self.loops_this_leg() + 1
            self.leg_of_loops = self.targets
        running = None if self.best_rows is None else self.best_rows.copy()
        super().learn(reason, steps, state, motion, detector)
        if reason in ("target", "periodic") and self.params["keep"] and running is not None:
            if not np.array_equal(running, self.best_rows):
                n = self.mirror.n_states
                both = np.stack([running, self.best_rows])
                fit = model_fitness(self.evaluator.evaluate(both), n)
                if fit[1] <= fit[0]:
                    self.best_rows = running
                    self.controller.load(running)
                    self.phases[-1]["kept"] = True
                    self.kept += 1


def detected_cycle(track, radius_mm: float) -> list:
    """The (state, motion) pairs of the cycle ``cosim.online.failures.Cycles`` (one round) finds, in
    order from the current state; [] if none."""
    probe = Cycles(1, radius_mm)
    return probe.cycle if probe.observe(track) else []


def run_one(variant: str, seed: int, budget: int, settings: dict, params: dict, cls=None,
            defaults: dict | None = None) -> dict:
    """One lifetime of ``cls`` (Round8, or a later round's subclass with its ``defaults``)."""
    cls, defaults = cls or Round8, defaults or DEFAULT_PARAMS
    # rounds 8-14 predate round 15's default fail_rates (their classes say False; --set overrides)
    config = OnlineConfig(seed=seed, max_interactions=budget, **{"fail_rates": cls.fail_rates,
                                                                      "rate_mirror": cls.rate_mirror,
                                                                      "progress_weight": cls.progress_weight, **settings})
    base = make_run(config)
    cls.variant, cls.params = variant, {**defaults, **params}
    run = cls(config, base.controller, base.evaluator)
    t0, c0 = time.perf_counter(), time.process_time()
    run.run()
    s = run.summary()
    classes = Counter(run.classes)
    classes.update(f"{c}_in_free_space" for c, st in zip(run.classes, run.pre) if not st & OBSTACLE_MASK)
    failures = [p for p in run.phases if p["reason"] not in ("target", "periodic")]
    return {"variant": variant, "seed": seed, "budget": budget, "settings": settings, "params": params,
            "targets": s["targets_reached"], "interactions": s["interactions"],
            "generations": s["generations"], "world_states": s["world_states"],
            "transitions": s["transitions"], "phases": len(run.phases), "failures": len(failures),
            "reasons": dict(Counter(p["reason"] for p in run.phases)),
            "lost": lost(failures, run.target_log), "kept": run.kept,
            "first_leg": run.target_log[0]["interactions"] if run.target_log else run.interactions,
            "per_16": per_block(run.target_log, run.interactions),
            "legs": legs(run.target_log, run.interactions),
            "leg_failures": leg_failures(failures, len(run.target_log)),
            "steps": dict(classes), "failure_classes": dict(run.failure_classes),
            "download_trace": dict(run.download_trace), **run.extra_figures(),
            "wall_s": round(time.perf_counter() - t0, 1), "cpu_s": round(time.process_time() - c0, 1)}


def per_block(target_log, interactions: int, block: int = 16) -> list[int]:
    """Interactions spent on each block of ``block`` targets (the last one may be short)."""
    marks = [0] + [t["interactions"] for t in target_log if t["target"] % block == 0]
    if not target_log or target_log[-1]["target"] % block:
        marks.append(interactions)
    return [b - a for a, b in zip(marks, marks[1:])]


def legs(target_log, interactions: int) -> list[int]:
    """Interactions spent on each leg (the last one unfinished if the budget ran out)."""
    marks = [0] + [t["interactions"] for t in target_log]
    if interactions > marks[-1]:
        marks.append(interactions)
    return [b - a for a, b in zip(marks, marks[1:])]


def leg_failures(failures, n_legs: int) -> list[int]:
    """Learning phases started by a failure on each leg."""
    counts = Counter(p["targets"] for p in failures)
    return [counts.get(i, 0) for i in range(max(n_legs, max(counts, default=0)) + 1)]


def table(path: Path) -> str:
    out = ["| variant | per seed (seed: interactions to 64, or targets @ budget) | median | failures | CPU-s |",
           "|---|---|---|---|---|"]
    for key, rs in rows_by_variant(path).items():
        cells, median = seed_cells(rs)
        fails = ", ".join(str(r.get("failures", r["phases"])) for r in rs)
        cpu = f"{min(r['cpu_s'] for r in rs):.0f}-{max(r['cpu_s'] for r in rs):.0f}"
        out.append(f"| {key} | {cells} | {median} | {fails} | {cpu} |")
    return "\n".join(out)


def main(argv=None, cls=None, defaults: dict | None = None, variants=VARIANTS, default_out: Path = DEFAULT_OUT,
         description: str = __doc__, table_of=None) -> int:
    """The command line (a later round passes its subclass, parameters, variants and output)."""
    defaults = defaults or DEFAULT_PARAMS
    p = argparse.ArgumentParser(description=description.splitlines()[0])
    p.add_argument("variant", nargs="?", choices=variants)
    p.add_argument("seeds", nargs="?")
    p.add_argument("--budget", type=int, default=20_000)
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="an OnlineConfig field")
    p.add_argument("--param", action="append", default=[], metavar="KEY=VALUE",
                   help=f"a parameter ({', '.join(defaults)})")
    p.add_argument("--out", type=Path, default=default_out)
    p.add_argument("--table", type=Path)
    a = p.parse_args(argv)
    if a.table:
        print((table_of or table)(a.table))
        return 0
    if not a.variant or not a.seeds:
        p.error("VARIANT and SEEDS are needed (or --table)")
    settings, params = parse_kv(a.set), parse_kv(a.param)
    unknown = set(params) - set(defaults)
    if unknown:
        p.error(f"unknown --param {sorted(unknown)[0]!r}")
    if params.get("blame", defaults["blame"]) not in BLAMES:
        p.error(f"--param blame must be one of {', '.join(BLAMES)}")
    a.out.parent.mkdir(parents=True, exist_ok=True)
    done = set()
    if a.out.exists():
        for line in a.out.read_text().splitlines():
            r = json.loads(line)
            done.add((key_of(r), r["seed"], r["budget"]))
    for seed in seeds_of(a.seeds):
        probe = {"variant": a.variant, "settings": settings, "params": params}
        if (key_of(probe), seed, a.budget) in done:
            continue
        r = run_one(a.variant, seed, a.budget, settings, params, cls, defaults)
        with a.out.open("a") as f:
            f.write(json.dumps(r) + "\n")
        print(json.dumps(r), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
