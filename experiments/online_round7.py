"""Round 7 of the on-line search (docs/online.md, "Round 7"): why the failures happen, and
host-side fitness terms that score a controller on the robot's own situation, screened on a few
seeds, one lifetime at a time.

    python experiments/online_round7.py VARIANT SEEDS [--budget 20000] [--set key=value ...]
                                        [--param key=value ...]
    python experiments/online_round7.py default 1-8
    python experiments/online_round7.py --table build/experiments/round7.jsonl   # the Markdown table

A variant is the current ``cosim.online.run.OnlineRun`` (the defaults of ``OnlineConfig``, or the
``--set`` fields) with the learning phase's fitness changed on the host side: the board's counts
(crashes, loops, distance; SPEC section 7) are untouched, and the host subtracts a penalty it
computes from its mirror of the world model (the same entries the board holds) and the
population's truth tables. Variants:

- ``default``: the SPEC fitness (instrumentation only);
- ``reach``: *multi-start traces of the robot's situation*: each controller is traced in the
  model from the state the robot stands in and from the states of the last ``starts`` failures;
  a trace that ends in a cycle of the model (or a crash) costs ``w_cycle`` (``w_crash``) / N each;
- ``unknown``: every state of S visited at least ``min_visits`` times where the controller's
  motion has never been tried costs ``w_unknown`` / N (the robot prefers what it knows);
- ``reach_unknown``: both;
- ``resample``: *several models from the robot's own outcomes*: the host keeps the last
  ``history`` outcomes of each (state, motion); each learning phase draws ``samples`` - 1 models
  in which every non-crash entry holds one of its kept outcomes (drawn at random, a generator of
  its own), and a controller's fitness is the ``agg`` (mean or min) of its SPEC fitness on the
  board's model and on those. On a board this is the host re-sending observations of outcomes the
  robot met (``observe``), evaluating, and sending the latest ones back; here the reference
  evaluator is called on the drawn models directly;
- ``adaptive``: *when a phase starts*: the one-round cycle stop (``loop_cycles`` 1) waits for a
  second round of a cycle unless the cycle runs through an obstacle (state, motion) of a loop the
  robot was stopped in before in its lifetime (a new loop may dissolve in the noise, a known one
  is cut after one round);
- ``leg2``: *when a phase starts*: two rounds for the first loop stop of a leg, one round for the
  later ones of the same leg.

Each lifetime appends one JSON line (figures, phase reasons, the failure classes below) to
``--out``; a (variant, seed, budget, settings, params) already there is not run again.

Failure classes (instrumentation): each executed (state, motion) is *novel* (not in the model
before), *confirmed* (the model held this outcome) or a *surprise* (the model held another). A
crash is classed by its pair; a loop stop by the pairs of its cycle (*predicted* when all were
confirmed, i.e. the model held the loop before the robot ran it). ``download_trace`` counts how
the downloaded controller's trace from the robot's state ends in the model at each download
(unknown, crash, cycle, free-space stop, tested).
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

from cosim import online as online_mod  # noqa: E402
from cosim.online.failures import Cycles  # noqa: E402
from cosim.online.run import OnlineConfig, OnlineRun, make_run  # noqa: E402
from experiments.online_round6 import cell, lost, seeds_of  # noqa: E402
from ga.motions import OBSTACLE_MASK  # noqa: E402
from ga.truth_table import truth_tables  # noqa: E402

DEFAULT_OUT = Path("build/experiments/round7.jsonl")
VARIANTS = ("default", "reach", "unknown", "reach_unknown", "resample", "adaptive", "leg2")
DEFAULT_PARAMS = {"starts": 4, "w_cycle": 1.0, "w_crash": 1.0, "w_unknown": 0.05, "min_visits": 3,
                  "horizon": 0, "samples": 4, "history": 8, "agg": "mean"}
ENDS = ("unknown", "crash", "cycle", "free", "long")


def trace_ends(tables: np.ndarray, model, starts: np.ndarray, horizon: int) -> np.ndarray:
    """How each controller's trace in ``model`` from each start state ends: (P, K) codes into
    ENDS. A trace follows the model's entries (as the SPEC pseudo-code does, without the
    'already tested' stop): unknown entry, crash, a free-space self-transition, or back into a
    state of this trace (a cycle); ``long`` if none within ``horizon`` steps (0: |S| + 1)."""
    pop, k = tables.shape[0], len(starts)
    valid, crash, nxt = model.valid, model.crash, model.next_state.astype(np.int64)
    s = np.broadcast_to(np.asarray(starts, dtype=np.int64), (pop, k)).copy()
    end = np.full((pop, k), ENDS.index("long"), dtype=np.int8)
    alive = np.ones((pop, k), dtype=bool)
    seen = np.zeros((pop, k, 256), dtype=bool)
    rows = np.arange(pop)[:, None]
    steps = horizon or model.n_states + 1
    for _ in range(steps):
        if not alive.any():
            break
        seen[rows, np.arange(k)[None, :], s] |= alive
        a = tables[rows, s]
        known, crashed = valid[s, a], crash[s, a]
        s2 = nxt[s, a]
        for code, hit in (("unknown", ~known), ("crash", known & crashed),
                          ("free", known & ~crashed & (s2 == s) & ((s & OBSTACLE_MASK) == 0))):
            hit &= alive
            end[hit] = ENDS.index(code)
            alive &= ~hit
        loop = alive & seen[rows, np.arange(k)[None, :], s2]
        end[loop] = ENDS.index("cycle")
        alive &= ~loop
        s = np.where(alive, s2, s)
    return end


def cycle_pairs(track) -> list:
    """The (state, motion) pairs of the shortest simple cycle (2-8 pairs) back to the current
    state, as ``cosim.online.failures.Cycles`` finds it; [] if none."""
    w, now = list(track.pairs), track.state
    for p in range(2, min(len(w), 8) + 1):
        if w[-p][0] == now and len({s for s, _ in w[-p:]}) == p:
            return w[-p:]
    return []


class AdaptiveCycles:
    """``Cycles`` with two rounds, or one round when the cycle holds an obstacle pair of
    ``known`` (the pairs of the earlier loop stops)."""

    name, reason = "cycles", "loop"

    def __init__(self, known, radius_mm: float):
        self.known, self.one, self.two = known, Cycles(1, radius_mm), Cycles(2, radius_mm)

    def reset(self) -> None:
        pass

    def observe(self, track) -> bool:
        if self.two.observe(track):
            return True
        if not self.one.observe(track):
            return False
        if callable(self.known):  # leg2: one round once the leg has had a loop stop
            return self.known()
        return any(s & OBSTACLE_MASK and (s, a) in self.known for s, a in cycle_pairs(track))


class Round7(OnlineRun):
    variant = "default"
    params = DEFAULT_PARAMS

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self.visits = np.zeros(256, dtype=np.int64)
        self.classes: list[str] = []  # per interaction: novel / confirmed / surprise
        self.pre: list[int] = []  # the state each motion was taken in
        self.failure_states: list[int] = []
        self.failure_classes: Counter = Counter()
        self.download_trace: Counter = Counter()
        self.penalised = 0  # learning phases in which the penalty changed the download
        self.history: dict[tuple[int, int], list[int]] = {}
        self.sample_rng = np.random.default_rng([self.config.seed, 7])
        self.loop_pairs: set = set()
        self.loop_leg = -1  # the targets reached at the last loop stop
        if self.variant in ("adaptive", "leg2"):
            known = self.loop_pairs if self.variant == "adaptive" else (lambda: self.loop_leg == self.targets)
            self.detectors = [AdaptiveCycles(known, self.config.loop_radius_mm)
                              if isinstance(d, Cycles) else d for d in self.detectors]

    def step(self, motion, record=True):
        s, m = self.state, self.mirror
        known = bool(m.valid[s, motion])
        before = (bool(m.crash[s, motion]), int(m.next_state[s, motion]))
        self.visits[s] += 1
        self.pre.append(s)
        step = super().step(motion, record)
        outcome = (bool(step.crashed), s if step.crashed else int(step.state))
        if not step.crashed:  # the outcome the board's model was sent
            kept = self.history.setdefault((s, int(motion)), [])
            kept.append(int(step.state))
            del kept[:-int(self.params["history"])]
        self.classes.append("novel" if not known else "confirmed" if before == outcome else "surprise")
        return step

    def classify(self, reason: str, steps: int) -> None:
        if reason == "crash":
            self.failure_classes["crash_" + self.classes[-1]] += 1
            return
        if reason != "loop":
            self.failure_classes[reason] += 1
            return
        now = self.state
        w = self.pre[-steps:]
        for p in range(2, min(len(w), 8) + 1):
            if w[-p] == now:
                cyc = self.classes[-p:]
                kind = ("predicted" if all(c == "confirmed" for c in cyc)
                        else "novel" if "novel" in cyc else "surprise")
                self.failure_classes["loop_" + kind] += 1
                return
        self.failure_classes["loop_other"] += 1

    def penalty(self, pop: np.ndarray, n: int) -> np.ndarray:
        v, prm = self.variant, self.params
        tables = truth_tables(pop, reflex=self.config.reflex)
        pen = np.zeros(len(pop))
        if v.startswith("reach"):
            starts = np.array([self.state] + self.failure_states[-int(prm["starts"]):], dtype=np.int64)
            end = trace_ends(tables, self.mirror, starts, int(prm["horizon"]))
            pen += (prm["w_cycle"] * (end == ENDS.index("cycle")).sum(axis=1)
                    + prm["w_crash"] * (end == ENDS.index("crash")).sum(axis=1)) / n
        if v.endswith("unknown"):
            states = np.flatnonzero(self.visits >= prm["min_visits"])
            unknown = ~self.mirror.valid[states[None, :], tables[:, states]]
            # the reflex states are not the controller's to choose
            unknown &= (states & OBSTACLE_MASK)[None, :] != 0
            pen += prm["w_unknown"] * unknown.sum(axis=1) / n
        return pen

    def drawn_models(self) -> list:
        """``samples`` - 1 copies of the model, each non-crash entry set to one kept outcome."""
        models = []
        for _ in range(int(self.params["samples"]) - 1):
            m = self.mirror.copy()
            for (s, a), kept in self.history.items():
                if len(kept) > 1 and not m.crash[s, a]:
                    m.next_state[s, a] = kept[int(self.sample_rng.integers(len(kept)))]
            models.append(m)
        return models

    def learn(self, reason, steps, state, motion, detector=""):
        self.classify(reason, steps)
        if reason == "loop":
            self.loop_pairs.update(cycle_pairs(self.track))
            self.loop_leg = self.targets
        if self.variant == "resample":
            from ga.evaluator import evaluate_tables, fitness as spec_fitness

            models = self.drawn_models()
        else:
            models = []
        saved_fitness, saved_board = online_mod.model_fitness, self.evaluator
        if self.variant != "default":
            board, last, run = self.evaluator, {}, self

            class Spy:  # keeps the population the board evaluated, for the host's penalty
                def evaluate(self_, pop):
                    last["pop"] = pop
                    return board.evaluate(pop)

                def __getattr__(self_, name):
                    return getattr(board, name)

            def fitness(counts, n_states):
                base = saved_fitness(counts, n_states)
                if models:
                    tables = truth_tables(last["pop"], reflex=run.config.reflex)
                    each = [base] + [spec_fitness(evaluate_tables(tables, m, run.config.distance_rule), n_states)
                                     for m in models]
                    base = np.min(each, axis=0) if run.params["agg"] == "min" else np.mean(each, axis=0)
                    pen = np.zeros(len(base))
                else:
                    pen = run.penalty(last["pop"], max(n_states, 1))
                last["changed"] = int(np.argmax(base)) != int(np.argmax(base - pen))
                return base - pen

            self.evaluator = Spy()
            online_mod.model_fitness = fitness
        try:
            super().learn(reason, steps, state, motion, detector)
        finally:
            online_mod.model_fitness, self.evaluator = saved_fitness, saved_board
        if self.variant != "default" and last.get("changed"):
            self.penalised += 1
        self.failure_states.append(int(state))
        if self.best_rows is not None:
            table = truth_tables(self.best_rows[None], reflex=self.config.reflex)
            end = trace_ends(table, self.mirror, np.array([self.state]), 0)[0, 0]
            self.download_trace[ENDS[end]] += 1


def run_one(variant: str, seed: int, budget: int, settings: dict, params: dict) -> dict:
    # blamed like rounds 1-7 unless --set loop_blame=... (round 8 changed the default), SPEC
    # section 7's fitness unless --set fail_rates=true (round 15 changed the default)
    config = OnlineConfig(seed=seed, max_interactions=budget,
                          **{"loop_blame": "leg", "fail_rates": False, **settings})
    base = make_run(config)
    Round7.variant, Round7.params = variant, {**DEFAULT_PARAMS, **params}
    run = Round7(config, base.controller, base.evaluator)
    t0, c0 = time.perf_counter(), time.process_time()
    run.run()
    s = run.summary()
    classes = Counter(run.classes)
    classes.update(f"{c}_in_free_space" for c, st in zip(run.classes, run.pre) if not st & OBSTACLE_MASK)
    return {"variant": variant, "seed": seed, "budget": budget, "settings": settings, "params": params,
            "targets": s["targets_reached"], "interactions": s["interactions"],
            "generations": s["generations"], "world_states": s["world_states"],
            "transitions": s["transitions"], "phases": len(run.phases),
            "reasons": dict(Counter(p["reason"] for p in run.phases)),
            "lost": lost(run.phases, run.target_log),
            "first_leg": run.target_log[0]["interactions"] if run.target_log else run.interactions,
            "steps": dict(classes), "failure_classes": dict(run.failure_classes),
            "download_trace": dict(run.download_trace), "penalised": run.penalised,
            "wall_s": round(time.perf_counter() - t0, 1), "cpu_s": round(time.process_time() - c0, 1)}


def key_of(r: dict) -> str:
    return (r["variant"] + "".join(f" {k}={v}" for k, v in sorted(r["settings"].items()))
            + "".join(f" {k}={v}" for k, v in sorted(r.get("params", {}).items())))


def rows_by_variant(path: Path) -> dict[str, list[dict]]:
    """The JSON lines of ``path`` grouped by variant and settings (``key_of``), each group in
    seed order (a seed run twice: its last line)."""
    rows: dict[str, dict[int, dict]] = {}
    for line in path.read_text().splitlines():
        r = json.loads(line)
        rows.setdefault(key_of(r), {})[r["seed"]] = r
    return {key: [by_seed[s] for s in sorted(by_seed)] for key, by_seed in rows.items()}


def seed_cells(rs: list[dict]) -> tuple[str, str]:
    """The per-seed cell and the median (a lifetime short of 64 targets counts as a stall)."""
    cells = ", ".join(f"{r['seed']}: {cell(r)}" for r in rs)
    med = float(np.median([r["interactions"] if r["targets"] >= 64 else 10 ** 9 for r in rs]))
    return cells, (f"{med:,.0f}" if med < 10 ** 9 else "stall")


def table(path: Path) -> str:
    out = ["| variant | per seed (seed: interactions to 64, or targets @ budget) | median | learning phases |",
           "|---|---|---|---|"]
    for key, rs in rows_by_variant(path).items():
        cells, median = seed_cells(rs)
        out.append(f"| {key} | {cells} | {median} | {', '.join(str(r['phases']) for r in rs)} |")
    return "\n".join(out)


def parse_kv(items) -> dict:
    return {k: json.loads(v) for k, _, v in (kv.partition("=") for kv in items)}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("variant", nargs="?", choices=VARIANTS)
    p.add_argument("seeds", nargs="?")
    p.add_argument("--budget", type=int, default=20_000)
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="an OnlineConfig field")
    p.add_argument("--param", action="append", default=[], metavar="KEY=VALUE",
                   help=f"a variant parameter ({', '.join(DEFAULT_PARAMS)})")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT)
    p.add_argument("--table", type=Path)
    a = p.parse_args(argv)
    if a.table:
        print(table(a.table))
        return 0
    if not a.variant or not a.seeds:
        p.error("VARIANT and SEEDS are needed (or --table)")
    settings, params = parse_kv(a.set), parse_kv(a.param)
    unknown = set(params) - set(DEFAULT_PARAMS)
    if unknown:
        p.error(f"unknown --param {sorted(unknown)[0]!r}")
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
        r = run_one(a.variant, seed, a.budget, settings, params)
        with a.out.open("a") as f:
            f.write(json.dumps(r) + "\n")
        print(json.dumps(r), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
