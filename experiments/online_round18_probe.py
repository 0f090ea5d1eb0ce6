"""Round 18's fitness probe (docs/online.md, "Round 18"): which fitness ranks controllers as the real
world does? Records, during a default lifetime, what each learning phase's fitness could see and
how well the candidates really do, so that fitness rules can be compared off-line.

    python experiments/online_round18_probe.py collect SEEDS [--every 2] [--repeats 6]
    python experiments/online_round18_probe.py score [--seeds 1-4]         # the table

``collect``: the main code's lifetime before this round (``ehw sim --progress-weight 0``; the
recording changes nothing in it); after every
``every``-th failure's learning phase it saves the board's world model, the host's failure counts,
the state set S, and candidates with their real-world quality: the download, the hand-written
baseline, the 12 fittest distinct controllers of the population, 8 mixes (the download with the
baseline's motion in a random quarter, half, three quarters of the obstacle states of S) and 8
mutants (the download with 3 obstacle states of S given a random motion). Quality = the mean over
``repeats`` look-aheads in a copy of the world from the robot's pose, with fresh noise
(``experiments.online_round18``: to the first failure, at most 200 steps) of targets reached plus
steps survived / 400. Files: build/experiments/round18_probe/seed<N>.npz.

``score``: for each fitness rule of :data:`RULES`, per phase the Spearman rank correlation between the
rule and the quality over that phase's candidates, and the quality of the rule's choice as a share
of the best candidate's; means over the phases of the seeds.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import cosim.online.run as online_mod  # noqa: E402
from cosim.online.run import make_run  # noqa: E402
from cosim.online.config import OnlineConfig  # noqa: E402
from experiments.online_round8 import seeds_of  # noqa: E402
from experiments.online_round18 import DEFAULT_PARAMS, Round18  # noqa: E402
from ga.evaluator import evaluate_tables  # noqa: E402
from ga.evaluator import fitness as model_fitness  # noqa: E402
from ga.fail_rates import RATE_ONE, mean_gains, mirror_pooled, progress_codes, rate_codes  # noqa: E402
from ga.motions import N_MOTIONS, N_STATES, OBSTACLE_MASK  # noqa: E402
from ga.truth_table import truth_tables  # noqa: E402
from ga.world_model import WorldModel  # noqa: E402
from sim_world.baseline import baseline_table  # noqa: E402

OUT = Path("build/experiments/round18_probe")
from ga.fail_rates import PROGRESS_STEPS  # noqa: E402  (the main code's, 8)


class Recorder(Round18):
    """The default lifetime; after every ``every``-th failure's learning phase, one record."""

    every, repeats = 2, 6

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self.records: list[dict] = []
        self.failures = 0
        self.pick = np.random.default_rng(self.config.seed + 7_000_000)  # the mixes and mutants
        self.log: list[tuple[int, int, int, int]] = []  # (state, motion, reached, mm to the ball before) of each interaction
        self.fail_at: list[int] = []  # the interactions at which a failure ended a phase

    def step(self, motion, record=True):
        s, targets, before = self.state, self.targets, self.world.target_distance()
        step = super().step(motion, record)
        self.log.append((s, int(motion), int(self.targets > targets), int(round(before))))
        return step

    def learn(self, reason, steps, state, motion, detector=""):
        last = self.learn_watching(reason, steps, state, motion, detector)
        if reason in online_mod.FAILURES:
            self.fail_at.append(self.interactions)
            self.failures += 1
            if self.failures % self.every == 0:
                self.record(last["pop"], last["fit"])

    def candidates(self, population: np.ndarray, fitness: np.ndarray) -> np.ndarray:
        reflex = self.config.reflex
        download = truth_tables(self.best_rows[None], reflex=reflex)[0]
        base = baseline_table()
        tables = truth_tables(population, reflex=reflex)
        out, seen = [download, base], {download.tobytes(), base.tobytes()}
        for i in np.argsort(-fitness, kind="stable").tolist():
            if len(out) >= 14:
                break
            if tables[i].tobytes() not in seen:
                seen.add(tables[i].tobytes())
                out.append(tables[i])
        states = self.mirror.states
        obstacle = states[(states & OBSTACLE_MASK) != 0]
        for share in (0.25, 0.5, 0.75, 0.25, 0.5, 0.75, 0.25, 0.5):
            mix = download.copy()
            chosen = obstacle[self.pick.random(len(obstacle)) < share]
            mix[chosen] = base[chosen]
            out.append(mix)
        for _ in range(8):
            mutant = download.copy()
            chosen = self.pick.choice(obstacle, size=min(3, len(obstacle)), replace=False)
            mutant[chosen] = self.pick.integers(0, N_MOTIONS, size=len(chosen))
            out.append(mutant)
        return np.stack(out).astype(np.uint8)

    def record(self, population: np.ndarray, fitness: np.ndarray) -> None:
        tables = self.candidates(population, fitness)
        self.params["oracle_noise"] = self.repeats
        quality = np.array([self.score(t) for t in tables])  # (K, 3): targets, -closest, steps
        self.params["oracle_noise"] = 0
        model = self.evaluator.model
        self.records.append({
            "time": self.interactions, "state": self.state, "states": self.mirror.states.copy(), "tables": tables,
            "targets": quality[:, 0], "steps": quality[:, 2],
            "valid": model.valid.copy(), "crash": model.crash.copy(), "next": model.next_state.copy(),
            "failed": self.marks.failed.copy(), "executed": self.marks.executed.copy(),
            "visits": self.marks.executed.sum(axis=1),
        })


def collect(seed: int, every: int, repeats: int, budget: int = 20_000, out: Path = OUT) -> Path:
    config = OnlineConfig(seed=seed, max_interactions=budget, progress_weight=0.0)  # the lifetimes before round 18
    base = make_run(config)
    Recorder.variant, Recorder.params = "default", dict(DEFAULT_PARAMS)
    Recorder.every, Recorder.repeats = every, repeats
    run = Recorder(config, base.controller, base.evaluator)
    run.run()
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"seed{seed}.npz"
    recs = run.records
    arrays = {key: np.array([r[key] for r in recs]) for key in recs[0] if key != "states"}
    arrays["states"] = np.array([np.isin(np.arange(N_STATES), r["states"]) for r in recs])
    np.savez_compressed(path, interactions=run.interactions, log=np.array(run.log, dtype=np.int32),
                        fail_at=np.array(run.fail_at, dtype=np.int64), **arrays)
    print(f"seed {seed}: {run.interactions} interactions, {len(recs)} records -> {path}", flush=True)
    return path


# -- fitness rules, scored off-line ---------------------------------------------------------------


def spec_counts(rec: dict, tables: np.ndarray, codes: np.ndarray | None):
    model = WorldModel()
    model.valid[:], model.crash[:], model.next_state[:] = rec["valid"], rec["crash"], rec["next"]
    model.in_set[:] = rec["states"]  # S as the run had it
    return evaluate_tables(tables, model, "forward", codes)


def rule_default(rec, tables, **k):
    codes = rate_codes(mirror_pooled(rec["failed"]), mirror_pooled(rec["executed"]))
    return model_fitness(spec_counts(rec, tables, codes), int(rec["states"].sum()))


def terms(rec, tables, prior=None):
    """(crashes, loops, distance, fails, N) with the mirror-pooled codes (prior: PRIOR_CODE or given)."""
    f, e = mirror_pooled(rec["failed"]).astype(float), mirror_pooled(rec["executed"]).astype(float)
    codes = rate_codes(mirror_pooled(rec["failed"]), mirror_pooled(rec["executed"]))
    c = spec_counts(rec, tables, codes)
    fails = c.fails.astype(float)
    if prior is not None:
        rates = (f + prior) / (e + 1)
        states = np.flatnonzero(rec["states"] & ((np.arange(N_STATES) & OBSTACLE_MASK) != 0))
        fails = RATE_ONE * rates[states[None, :], tables[:, states]].sum(axis=1)
    return c.crashes, c.loops, c.distance, fails, int(rec["states"].sum())


def weighted(wc=0.5, wl=0.4, wd=0.1, wf=0.5, prior=None):
    def rule(rec, tables):
        c, l, d, f, n = terms(rec, tables, prior)
        return -wc * c / n - wl * l / n + wd * d / (n * 50) - wf * f / (n * RATE_ONE)
    return rule


def marks_at(rec, horizon: int = 8, window: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(failed, executed) (256, 8) float from the lifetime's log up to the record's time: the
    main code's marks (``window`` = 0), or each execution's mark less the share of marked steps
    among the ``window`` steps before and after it (what the place and time made likely), plus
    the lifetime's mean share (so the counts stay rates)."""
    log, t = rec["log"][: int(rec["time"])], int(rec["time"])
    fails = set(int(f) for f in rec["fail_at"] if f <= t)
    marked = np.zeros(len(log))
    pending: list[int] = []
    for i, (s, a, reached, _) in enumerate(log):
        pending.append(i)
        if reached:
            pending.clear()
        if i + 1 in fails:
            seen = set()
            for j in reversed(pending[-horizon:]):
                if (log[j][0], log[j][1]) not in seen:
                    seen.add((log[j][0], log[j][1]))
                    marked[j] = 1
            pending.clear()
    value = marked
    if window:
        csum = np.concatenate([[0.0], np.cumsum(marked)])
        lo = np.clip(np.arange(len(log)) - window, 0, len(log))
        hi = np.clip(np.arange(len(log)) + window + 1, 0, len(log))
        local = (csum[hi] - csum[lo]) / (hi - lo)
        value = marked - local + marked.mean()
    failed = np.zeros((N_STATES, N_MOTIONS))
    executed = np.zeros((N_STATES, N_MOTIONS))
    np.add.at(failed, (log[:, 0], log[:, 1]), value)
    np.add.at(executed, (log[:, 0], log[:, 1]), 1)
    return failed, executed


def with_marks(horizon: int = 8, window: int = 0, prior: float = 0.1, w: float = 0.5):
    """The default rule with the rate codes computed by :func:`marks_at` (float rates)."""
    def rule(rec, tables):
        f, e = marks_at(rec, horizon, window)
        rates = np.clip((mirror_pooled(f) + prior) / (mirror_pooled(e) + 1), 0, 1)
        c = spec_counts(rec, tables, None)
        n = int(rec["states"].sum())
        states = np.flatnonzero(rec["states"] & ((np.arange(N_STATES) & OBSTACLE_MASK) != 0))
        fails = rates[states[None, :], tables[:, states]].sum(axis=1)
        return (-0.5 * c.crashes / n - 0.4 * c.loops / n + 0.1 * c.distance / (n * 50) - w * fails / n)
    return rule


def with_distance(dvec, obstacle_dvec=None, wd: float = 0.1, wf: float = 0.5, known_only: bool = True):
    """The default rule with dist[a] = ``dvec`` (mm, 8 motions), in obstacle states ``obstacle_dvec``;
    ``known_only`` = False: credited also where the model does not know the pair."""
    dvec = np.asarray(dvec, float)
    odvec = dvec if obstacle_dvec is None else np.asarray(obstacle_dvec, float)

    def rule(rec, tables):
        codes = rate_codes(mirror_pooled(rec["failed"]), mirror_pooled(rec["executed"]))
        c = spec_counts(rec, tables, codes)
        n = int(rec["states"].sum())
        states = np.flatnonzero(rec["states"])
        motions = tables[:, states]
        obstacle = ((states & OBSTACLE_MASK) != 0)[None, :]
        credit = np.where(obstacle, odvec[motions], dvec[motions])
        ok = ~rec["crash"][states[None, :], motions]
        if known_only:
            ok &= rec["valid"][states[None, :], motions]
        dist = (credit * ok).sum(axis=1)
        return -0.5 * c.crashes / n - 0.4 * c.loops / n + wd * dist / (n * 50) - wf * c.fails / (n * RATE_ONE)
    return rule


FORWARD = [50, 0, 0, 0, 50, 50, 0, 0]
def gains_at(rec, horizon: int) -> tuple[np.ndarray, np.ndarray]:
    """(summed gain, count) (256, 8) from the log up to the record's time: for each execution, the
    distance to the ball it had less the distance ``horizon`` steps later (the whole distance when
    the leg reaches the ball before); executions whose horizon is not over yet are left out."""
    t = int(rec["time"])
    log = rec["log"][:t]
    dist = log[:, 3].astype(float)
    reached = log[:, 2].astype(bool)
    gain = np.full(t, np.nan)
    # the next target at or after each step
    nxt = np.full(t + 1, np.iinfo(np.int64).max)
    for i in range(t - 1, -1, -1):
        nxt[i] = i if reached[i] else nxt[i + 1]
    for i in range(t):
        if nxt[i] < i + horizon:
            gain[i] = dist[i]
        elif i + horizon < t:
            gain[i] = dist[i] - dist[i + horizon]
    ok = ~np.isnan(gain)
    g = np.zeros((N_STATES, N_MOTIONS))
    n = np.zeros((N_STATES, N_MOTIONS))
    np.add.at(g, (log[ok, 0], log[ok, 1]), gain[ok])
    np.add.at(n, (log[ok, 0], log[ok, 1]), 1)
    return g, n


def with_return(horizon: int, w: float | None = None, prior: str = "mean"):
    """``w`` None: the mean gain alone; else the default rule plus w times it (per state of S, in
    units of ``horizon`` forward steps). Untried pairs: the mean gain of all (``prior`` mean) or 0."""
    def rule(rec, tables):
        g, n = gains_at(rec, horizon)
        g, n = mirror_pooled(g), mirror_pooled(n)
        mean = mean_gains(g, n) if prior == "mean" else np.where(n > 0, g / np.maximum(n, 1), 0.0)
        states = np.flatnonzero(rec["states"] & ((np.arange(N_STATES) & OBSTACLE_MASK) != 0))
        total = mean[states[None, :], tables[:, states]].sum(axis=1)
        if w is None:
            return total
        return rule_default(rec, tables) + w * total / (int(rec["states"].sum()) * 50 * horizon)
    return rule


def with_main_progress(weight: float):
    """The main code's codes with ``progress_weight`` = weight (``ga.fail_rates.progress_codes``)."""
    def rule(rec, tables):
        g, n = gains_at(rec, PROGRESS_STEPS)
        base = rate_codes(mirror_pooled(rec["failed"]), mirror_pooled(rec["executed"]))
        codes = progress_codes(base, mirror_pooled(g), mirror_pooled(n), weight)
        return model_fitness(spec_counts(rec, tables, codes), int(rec["states"].sum()))
    return rule


RULES = {
    "main code, progress_weight 3": with_main_progress(3.0),
    "main code, progress_weight 1": with_main_progress(1.0),
    "default + 3 return 8": with_return(8, 3.0),
    "default + 10 return 8": with_return(8, 10.0),
    "return 8 alone": with_return(8),
    "return 16 alone": with_return(16),
    "return 32 alone": with_return(32),
    "return 64 alone": with_return(64),
    "return 32 alone, untried 0": with_return(32, prior="zero"),
    "default + 1 return 32": with_return(32, 1.0),
    "default + 3 return 32": with_return(32, 3.0),
    "distance rule re-done (= default)": with_distance(FORWARD),
    "turns in obstacle states 25": with_distance(FORWARD, [50, 0, 25, 25, 50, 50, 0, 0]),
    "turns in obstacle states 50": with_distance(FORWARD, [50, 0, 50, 50, 50, 50, 0, 0]),
    "obstacle states: no distance": with_distance(FORWARD, [0] * 8),
    "obstacle states: only forward-turns": with_distance(FORWARD, [0, 0, 0, 0, 50, 50, 0, 0]),
    "distance for unknown pairs too": with_distance(FORWARD, known_only=False),
    "marks from the log (= default)": with_marks(),
    "context-adjusted marks, window 25": with_marks(window=25),
    "context-adjusted marks, window 100": with_marks(window=100),
    "context-adjusted marks, window 25, w 1": with_marks(window=25, w=1.0),
    "default (SPEC + mirror-pooled rates)": rule_default,
    "SPEC three terms": weighted(wf=0),
    "rates only": weighted(0, 0, 0, 0.5),
    "distance only": weighted(0, 0, 0.1, 0),
    "crashes + loops only": weighted(wd=0, wf=0),
    "no distance": weighted(wd=0),
    "rates x2": weighted(wf=1.0),
    "prior 0.3": weighted(prior=0.3),
    "prior 0.5": weighted(prior=0.5),
}


def score(seeds, only: str = "", folder: Path = OUT) -> str:
    rows = []
    for name, rule in RULES.items():
        if only not in name:
            continue
        corr, share, picks_base = [], [], 0
        for seed in seeds:
            data = np.load(folder / f"seed{seed}.npz")
            n = len(data["targets"])
            for i in range(n):
                rec = {k: data[k][i] for k in data.files if k not in ("interactions", "log", "fail_at")}
                rec["log"], rec["fail_at"] = data["log"], data["fail_at"]
                quality = rec["targets"] + rec["steps"] / 400.0
                value = rule(rec, rec["tables"])
                corr.append(spearman(value, quality))
                choice = int(np.argmax(value))
                share.append(quality[choice] / max(quality.max(), 1e-9))
                picks_base += int(choice == 1)
        rows.append(f"| {name} | {np.nanmean(corr):.3f} | {np.mean(share):.3f} | {picks_base}/{len(share)} |")
    head = "| rule | mean Spearman (rule, quality) | chosen quality / best | picks the baseline |\n|---|---|---|---|"
    return "\n".join([head, *rows])


def spearman(a, b) -> float:
    ra, rb = rank(np.asarray(a, float)), rank(np.asarray(b, float))
    if ra.std() == 0 or rb.std() == 0:
        return float("nan")
    return float(np.corrcoef(ra, rb)[0, 1])


def rank(x: np.ndarray) -> np.ndarray:
    """Ranks with ties averaged."""
    order = np.argsort(x, kind="stable")
    r = np.empty(len(x))
    r[order] = np.arange(len(x))
    for v in np.unique(x):
        same = x == v
        r[same] = r[same].mean()
    return r


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("mode", choices=("collect", "score"))
    p.add_argument("seeds", nargs="?", default="1-4")
    p.add_argument("--every", type=int, default=2)
    p.add_argument("--repeats", type=int, default=6)
    p.add_argument("--rules", default="", help="score only the rules whose name holds this")
    a = p.parse_args(argv)
    if a.mode == "collect":
        for seed in seeds_of(a.seeds):
            collect(seed, a.every, a.repeats)
    else:
        print(score(seeds_of(a.seeds), a.rules))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
