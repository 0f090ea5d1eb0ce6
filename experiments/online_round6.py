"""Round 6 of the on-line search (docs/online.md, "Round 6"): host-side variants of the learning
phase, screened on a few seeds, one lifetime at a time.

    python experiments/online_round6.py VARIANT SEEDS [--budget 20000] [--set key=value ...]
    python experiments/online_round6.py closest 1-5
    python experiments/online_round6.py --table build/experiments/round6.jsonl   # the Markdown table

A variant is the current ``cosim.online.run.OnlineRun`` (the defaults of ``OnlineConfig``, or the
``--set`` fields) with one host-side hook changed: which individual is downloaded, what the GA is
told. Variants that were adopted became ``OnlineConfig`` options; the others live only here.
Each lifetime appends one JSON line (figures, phase reasons, interactions lost in failed
segments) to ``--out``; a (variant, seed, budget, settings) already there is not run again.
"""

from __future__ import annotations

import argparse
import bisect
import json
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from cosim import online as online_mod  # noqa: E402
from cosim.online.run import OnlineConfig, OnlineRun, make_run  # noqa: E402
from ga.motions import OBSTACLE_MASK  # noqa: E402
from ga.truth_table import truth_tables  # noqa: E402

DEFAULT_OUT = Path("build/experiments/round6.jsonl")


def _closest_factory(run: OnlineRun, inject: bool):
    """A choose_download that, among the individuals tied with the choice of the default rule (and
    escaping the blamed motion when the default escaped), takes the one whose truth table differs
    from the running controller's in the least visited states."""
    base = online_mod.choose_download

    def choose(pop, fitness, blamed=None, reflex=True):
        i, escaped = base(pop, fitness, blamed, reflex)
        if run.best_rows is not None:
            tables = truth_tables(pop, reflex=reflex)
            ties = fitness == fitness[i]
            if blamed is not None and escaped:
                ties &= tables[:, blamed[0]] != blamed[1]
            index = np.flatnonzero(ties)
            if len(index) > 1:
                current = truth_tables(run.best_rows[None], reflex=reflex)[0]
                cost = ((tables[index] != current) * run.visits).sum(axis=1)
                i = int(index[np.argmin(cost)])
        if inject:
            run.inject = pop[i].copy()
        return i, escaped

    return choose


class Variant(OnlineRun):
    variant = "default"

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self.visits = np.zeros(256, dtype=np.int64)
        self.inject = None
        self.cycles: list[tuple] = []
        self.cycle_vetoes = 0
        self.cycles_target = 0

    def step(self, motion, record=True):
        self.visits[self.state] += 1
        return super().step(motion, record)

    def blame_table(self) -> np.ndarray:
        """(256, 8): how often each obstacle (state, motion) was blamed for a loop or time-out."""
        table = np.zeros((256, 8), dtype=np.int64)
        for p in self.phases:
            if p["reason"] in ("timeout", "loop") and p["state"] & OBSTACLE_MASK:
                table[p["state"], p["motion"]] += 1
        return table

    def remember_cycle(self) -> None:
        """After a loop stop: the obstacle (state, motion) pairs of the last cycle back to the
        current state (the smallest p with pairs[-p] in it), kept for the lifetime."""
        w, now = list(self.track.pairs), self.track.state
        for p in range(2, min(len(w), 40) + 1):
            if w[-p][0] == now:
                sig = tuple(sorted({(s, a) for s, a in w[-p:] if s & OBSTACLE_MASK}))
                if sig and sig not in self.cycles:
                    self.cycles.append(sig)
                return

    def cycle_choice(self, base):
        def choose(pop, fitness, blamed=None, reflex=True):
            i, escaped = base(pop, fitness, blamed, reflex)
            if not self.cycles:
                return i, escaped
            tables = truth_tables(pop, reflex=reflex)
            repro = np.zeros(len(pop), dtype=np.int64)
            for sig in self.cycles:
                st = np.array([s for s, _ in sig]); mo = np.array([a for _, a in sig])
                repro += (tables[:, st] == mo).all(axis=1)
            if repro[i] == repro.min():
                return i, escaped
            ok = np.flatnonzero(repro == repro.min())
            self.cycle_vetoes += 1
            return int(ok[np.argmax(fitness[ok])]), escaped
        return choose

    def learn(self, *args, **kwargs):
        v = self.variant
        saved = online_mod.choose_download, online_mod.model_fitness, self.evaluator
        if v.startswith("cyclemem"):
            if v == "cyclemem_leg" and self.targets != self.cycles_target:
                self.cycles, self.cycles_target = [], self.targets
            if args[0] == "loop":
                self.remember_cycle()
            online_mod.choose_download = self.cycle_choice(saved[0])
        if v.startswith("closest"):
            online_mod.choose_download = _closest_factory(self, inject=v.endswith("inject"))
        if v.startswith("tabu"):
            blame = self.blame_table()
            if v == "tabu_bool":
                blame = (blame > 0).astype(np.int64)
            board, last = self.evaluator, {}

            class Spy:
                def evaluate(self_, pop):
                    last["pop"] = pop
                    return board.evaluate(pop)

            def fitness(counts, n_states):
                # lexicographic tie-break under the SPEC fitness: its smallest step is 0.1 / N
                tables = truth_tables(last["pop"], reflex=self.config.reflex)
                score = blame[np.arange(256)[None, :], tables].sum(axis=1)
                return saved[1](counts, n_states) - 0.05 / max(n_states, 1) * score / (score.max() + 1)

            self.evaluator = Spy()
            online_mod.model_fitness = fitness
        try:
            super().learn(*args, **kwargs)
        finally:
            online_mod.choose_download, online_mod.model_fitness, self.evaluator = saved
        if self.inject is not None:  # keep the downloaded controller in the next population
            self.ga._population[-1] = self.inject
            self.inject = None


VARIANTS = ("default", "closest", "closest_inject", "tabu", "tabu_bool", "cyclemem", "cyclemem_leg")


def lost(phases, target_log) -> int:
    """Interactions in failed segments: from the later of the last target and the last failure
    up to each failure."""
    tints = [t["interactions"] for t in target_log]
    total, prev = 0, 0
    for p in phases:
        i = p["interactions"]
        k = bisect.bisect_right(tints, i) - 1
        total += i - max(prev, tints[k] if k >= 0 else 0)
        prev = i
    return total


def run_one(variant: str, seed: int, budget: int, settings: dict) -> dict:
    # blamed like rounds 1-7 unless --set loop_blame=... (round 8 changed the default), SPEC
    # section 7's fitness unless --set fail_rates=true (round 15 changed the default)
    config = OnlineConfig(seed=seed, max_interactions=budget,
                          **{"loop_blame": "leg", "fail_rates": False, **settings})
    run = make_run(config)
    v = Variant(config, run.controller, run.evaluator)
    v.variant = variant
    t0 = time.perf_counter()
    v.run()
    s = v.summary()
    first = v.target_log[0]["interactions"] if v.target_log else v.interactions
    return {"variant": variant, "seed": seed, "budget": budget, "settings": settings,
            "targets": s["targets_reached"], "interactions": s["interactions"],
            "generations": s["generations"], "world_states": s["world_states"],
            "transitions": s["transitions"], "phases": len(v.phases),
            "reasons": dict(Counter(p["reason"] for p in v.phases)),
            "lost": lost(v.phases, v.target_log), "first_leg": first,
            "wall_s": round(time.perf_counter() - t0, 1),
            "cycles_remembered": len(v.cycles), "cycle_vetoes": v.cycle_vetoes}


def seeds_of(text: str) -> list[int]:
    out = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += list(range(int(a), int(b or a) + 1))
    return out


def cell(r: dict) -> str:
    return f"{r['interactions']:,}" if r["targets"] >= 64 else f"**{r['targets']} @ {r['budget'] // 1000}k**"


def table(path: Path) -> str:
    rows: dict[str, dict[int, dict]] = {}
    for line in path.read_text().splitlines():
        r = json.loads(line)
        key = r["variant"] + "".join(f" {k}={v}" for k, v in sorted(r["settings"].items()))
        rows.setdefault(key, {})[r["seed"]] = r
    out = ["| variant | per seed (seed: interactions to 64, or targets @ budget) | lost in failed segments | learning phases |",
           "|---|---|---|---|"]
    for key, by_seed in rows.items():
        seeds = sorted(by_seed)
        rs = [by_seed[s] for s in seeds]
        cells = ", ".join(f"{r['seed']}: {cell(r)}" for r in rs)
        lost_ = ", ".join(f"{r['lost']:,}" for r in rs)
        phases = ", ".join(str(r["phases"]) for r in rs)
        out.append(f"| {key} | {cells} | {lost_} | {phases} |")
    return "\n".join(out)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("variant", nargs="?", choices=VARIANTS)
    p.add_argument("seeds", nargs="?")
    p.add_argument("--budget", type=int, default=20_000)
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT)
    p.add_argument("--table", type=Path)
    a = p.parse_args(argv)
    if a.table:
        print(table(a.table))
        return 0
    if not a.variant or not a.seeds:
        p.error("VARIANT and SEEDS are needed (or --table)")
    settings = {}
    for kv in a.set:
        k, _, v = kv.partition("=")
        settings[k] = json.loads(v)
    a.out.parent.mkdir(parents=True, exist_ok=True)
    done = set()
    if a.out.exists():
        for line in a.out.read_text().splitlines():
            r = json.loads(line)
            done.add((r["variant"], r["seed"], r["budget"], json.dumps(r["settings"], sort_keys=True)))
    for seed in seeds_of(a.seeds):
        if (a.variant, seed, a.budget, json.dumps(settings, sort_keys=True)) in done:
            continue
        r = run_one(a.variant, seed, a.budget, settings)
        with a.out.open("a") as f:
            f.write(json.dumps(r) + "\n")
        print(json.dumps(r), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
