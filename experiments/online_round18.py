"""Round 18 of the on-line search (docs/online.md, "Round 18"): how much a perfect download rule
could save. An *instrument*, not a method: the oracle looks into the world's future.

    python experiments/online_round18.py VARIANT SEEDS [--budget 20000] [--set key=value ...]
                                         [--param key=value ...]
    python experiments/online_round18.py default 1-16                        # = ehw sim --progress-weight 0
    python experiments/online_round18.py oracle 1-16 --param oracle_k=16     # the bound
    python experiments/online_round18.py --table build/experiments/round18.jsonl

A lifetime is round 17's (``experiments.online_round17.Round17``) on the main code's defaults before
this round (``progress_weight`` 0; variant ``progress_codes`` with ``progress_w=3`` is the main code's
default since).
Variant ``oracle``: after each learning phase's generations, the ``oracle_k`` fittest distinct
controllers of the population (by the model fitness, the download rule's own candidates; with
``oracle_keep`` = 1 the running controller as well) are each run ahead in a copy of the real
world, from the robot's exact pose and with the world's own future noise, under the same failure
detectors, for at most ``oracle_h`` steps or until the first failure; the one that reaches the most
targets, then comes closest to the ball, then survives longest, is downloaded. Those look-ahead
steps are **not** interactions (the real robot never makes them): the lifetime says how few
interactions a download rule that ranked the GA's candidates perfectly would need, so whether the
remaining distance to issue 17's goal lies in the ranking (the model and fitness) or in the
candidates and the phase structure. ``oracle_k`` = 1 with ``oracle_keep`` = 1 asks only whether
keeping the running controller would have been better than the download.
"""

from __future__ import annotations

import copy
import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import cosim.online.run as online_mod  # noqa: E402
from experiments.online_round8 import main as round8_main  # noqa: E402
from experiments.online_round14 import seed_table  # noqa: E402
from experiments.online_round17 import DEFAULT_PARAMS as R17_PARAMS  # noqa: E402
from experiments.online_round17 import Round17  # noqa: E402
from ga.fail_rates import RATE_ONE, W_FAIL, FailureMarks, mean_gains, mirror_pooled  # noqa: E402
from ga.motions import MAX_MOTION_DISTANCE_MM, N_MOTIONS, N_STATES, OBSTACLE_MASK  # noqa: E402
from ga.truth_table import truth_tables  # noqa: E402
from sim_world.world import World  # noqa: E402

DEFAULT_OUT = Path("build/experiments/round18.jsonl")
HELD_OUT = range(281, 301)  # never used by any round
VARIANTS = ("default", "oracle", "progress", "progress_codes")
R18_PARAMS = {"oracle_k": 16, "oracle_h": 200, "oracle_keep": 0, "oracle_noise": 0, "probe": 0,
              "progress_w": 10.0, "progress_h": 8}
DEFAULT_PARAMS = {**R17_PARAMS, **R18_PARAMS}


def clone_world(world: World, scratch: World) -> World:
    """``scratch`` (a world on the same arena) made the same world as ``world``: pose, sensing,
    counters and the noise generator's state and buffers (so the same future noise)."""
    physics = set(World._PHYSICS) | {"_cache"}
    state = {k: v for k, v in world.__dict__.items() if k not in physics}
    state["rng"] = copy.deepcopy(world.rng)
    state["_uniforms"], state["_normals"] = list(world._uniforms), list(world._normals)
    scratch.__dict__.update(state)
    return scratch


class ProgressBoard:
    """The evaluator board, with the ``progress`` term added to the distance count on the host:
    w times the summed mean gains of the controller's motions in the obstacle states of S, in
    units of h forward steps per state (the fitness's distance term has weight 0.1 per 50 mm)."""

    def __init__(self, board, run: "Round18"):
        self._board, self._run = board, run

    def __getattr__(self, name):
        return getattr(self._board, name)

    def evaluate(self, population):
        counts = self._board.evaluate(population)
        run = self._run
        w, h = float(run.params["progress_w"]), int(run.params["progress_h"])
        tables = truth_tables(population, reflex=run.config.reflex)
        states = run.mirror.states
        states = states[(states & OBSTACLE_MASK) != 0]
        total = run.mean_gains()[states[None, :], tables[:, states]].sum(axis=1)
        extra = 10.0 * w * total / h  # 0.1 extra / (N 50) = w total / (N 50 h)
        return dataclasses.replace(counts, distance=np.asarray(counts.distance) + extra)


class ProgressMarks(FailureMarks):
    """The main code's marks (mirror pooled) whose codes also carry the progress deficit, so every
    board sums it with no change: code = failure code + round(1.25 w (best mean gain of the state -
    the pair's mean gain)), clipped to 0..RATE_ONE (1.25 w code units per mm is the weight of
    ``ProgressBoard`` with h = 8: W_FAIL code / (N RATE_ONE) = w mm / (N 50 h))."""

    def __init__(self, run: "Round18"):
        super().__init__(mirror=True)
        self.run = run

    def codes(self) -> np.ndarray:
        codes = super().codes().astype(float)
        mean = self.run.mean_gains()
        w, h = float(self.run.params["progress_w"]), int(self.run.params["progress_h"])
        per_mm = w * RATE_ONE / (W_FAIL * MAX_MOTION_DISTANCE_MM * h)  # 1.25 w for h = 8
        deficit = mean.max(axis=1, keepdims=True) - mean
        return np.clip(np.floor(codes + per_mm * deficit + 0.5), 0, RATE_ONE).astype(np.uint8)


class Round18(Round17):
    """Round 17's lifetime (the main code before this round: ``progress_weight`` 0) with the
    look-ahead download of ``oracle``, the ``probe`` and the progress variants."""

    progress_weight = 0.0  # round 18 made 3.0 the main code's default (``progress_codes`` is it)

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self.scratch = copy.copy(self.world)  # its own dict; physics rebuilt below
        self.scratch.__dict__ = dict(self.world.__dict__)
        self.scratch._build_physics()
        self.probe_log: list[dict] = []
        # progress: per (state, motion), the summed distance to the ball gained over the next
        # progress_h steps of the leg (all of it when the leg reaches the ball first), and count
        self.gain = np.zeros((N_STATES, N_MOTIONS))
        self.gain_n = np.zeros((N_STATES, N_MOTIONS))
        self.pending_gain: list[tuple[int, int, float, int]] = []
        if self.variant == "progress":
            self.evaluator = ProgressBoard(self.evaluator, self)
        if self.variant == "progress_codes" and self.config.fail_rates:
            self.marks = ProgressMarks(self)
        self.oracle_log = {"phases": 0, "changed": 0, "kept": 0, "lookahead_steps": 0, "rank": []}

    def step(self, motion, record=True):
        if self.variant not in ("progress", "progress_codes"):  # nothing reads the gains
            return super().step(motion, record)
        s, targets, before = self.state, self.targets, self.world.target_distance()
        step = super().step(motion, record)
        reached = self.targets > targets
        now = 0.0 if reached else step.distance_mm
        horizon = int(self.params["progress_h"])
        keep = []
        for ps, pa, d0, age in [*self.pending_gain, (s, int(motion), before, 0)]:
            if reached or age + 1 >= horizon:
                self.gain[ps, pa] += d0 - now
                self.gain_n[ps, pa] += 1
            else:
                keep.append((ps, pa, d0, age + 1))
        self.pending_gain = keep
        return step

    def mean_gains(self) -> np.ndarray:
        """(256, 8): each pair's mean gain, mirror pooled; a pair with none: the mean of all."""
        return mean_gains(mirror_pooled(self.gain), mirror_pooled(self.gain_n))

    def rollout(self, table: np.ndarray, noise_seed: int | None = None) -> tuple:
        """(targets, -closest distance, steps) of ``table`` run ahead from now in a world copy,
        with the world's own future noise, or with fresh noise from ``noise_seed``."""
        world = clone_world(self.world, self.scratch)
        if noise_seed is not None:
            world.rng, world._uniforms, world._normals = np.random.default_rng(noise_seed), [], []
        track = copy.deepcopy(self.track)
        track.new_phase()
        detectors = self.config.detectors()
        for d in detectors:
            d.reset()
        targets, state, closest = self.targets, self.state, float("inf")
        horizon = int(self.params["oracle_h"])
        for n in range(1, horizon + 1):
            s = state
            a = int(table[s])
            step = world.step(a)
            reached = step.reached and not step.crashed
            closest = min(closest, step.distance_mm)
            if reached:
                targets += 1
                state = self.course.relocate(world, targets)
            else:
                state = step.state
            track.step(s, a, state, step.crashed, reached, step.distance_mm)
            fired = any([d.observe(track) for d in detectors])
            if reached:
                closest = float("inf")
                for d in detectors:
                    d.reset()
                if targets >= self.config.n_targets:
                    break
                continue
            if step.crashed or fired:
                break
        self.oracle_log["lookahead_steps"] += n
        return targets - self.targets, -closest, n

    def score(self, table: np.ndarray) -> tuple:
        """The look-ahead's score of ``table``: one rollout with the world's own noise, or the mean
        of ``oracle_noise`` rollouts with fresh noise (the same seeds for every candidate)."""
        repeats = int(self.params["oracle_noise"])
        if not repeats:
            return self.rollout(table)
        base = (self.config.seed * 1_000_003 + len(self.phases)) * 64
        runs = np.array([self.rollout(table, base + r) for r in range(repeats)], dtype=float)
        return tuple(runs.mean(axis=0))

    def oracle_download(self, population, fitness, blamed=None, reflex=True):
        """The download by look-ahead (see the module docstring); returns (index, escaped) as
        ``cosim.online.download.choose_download``. Index -1: keep the running controller."""
        default, escaped = self.plain_download(population, fitness, blamed, reflex)
        tables = truth_tables(population, reflex=reflex)
        order = np.argsort(-fitness, kind="stable")
        seen, picks = set(), []
        for i in [default, *order.tolist()]:
            key = tables[i].tobytes()
            if key not in seen:
                seen.add(key)
                picks.append(int(i))
            if len(picks) >= int(self.params["oracle_k"]):
                break
        candidates = {i: tables[i] for i in picks}
        if int(self.params["oracle_keep"]) and self.best_rows is not None:
            running = truth_tables(self.best_rows[None], reflex=reflex)[0]
            if running.tobytes() not in seen:
                candidates[-1] = running
        scores = {i: self.score(table) for i, table in candidates.items()}
        best = max(scores, key=lambda i: scores[i])
        log = self.oracle_log
        log["phases"] += 1
        log["changed"] += int(best != default)
        log["kept"] += int(best == -1)
        if best != -1:
            log["rank"].append(picks.index(best))
        return best, escaped and best == default

    def probe(self, population: np.ndarray, fitness: np.ndarray) -> None:
        """``probe`` = R > 0 (variant ``default``): after the download, the model's fitness of the
        download and of the hand-written baseline, and the mean of R fresh-noise look-aheads of
        the download, the baseline and the best of the 8 fittest distinct candidates."""
        from ga.evaluator import evaluate_tables
        from ga.evaluator import fitness as model_fitness
        from sim_world.baseline import baseline_table

        reflex = self.config.reflex
        download = truth_tables(self.best_rows[None], reflex=reflex)[0]
        base = baseline_table()
        board = self.evaluator
        counts = evaluate_tables(np.stack([download, base]), board.model, self.config.distance_rule, board.rates)
        fit = model_fitness(counts, self.mirror.n_states)
        tables = truth_tables(population, reflex=reflex)
        seen, top = set(), []
        for i in np.argsort(-fitness, kind="stable").tolist():
            if tables[i].tobytes() not in seen:
                seen.add(tables[i].tobytes())
                top.append(tables[i])
            if len(top) >= 8:
                break
        saved = self.params["oracle_noise"]
        self.params["oracle_noise"] = int(self.params["probe"])
        try:
            d, b = self.score(download), self.score(base)
            best = max(self.score(tb) for tb in top)
        finally:
            self.params["oracle_noise"] = saved
        self.probe_log.append({"phase": len(self.phases), "fit_download": round(float(fit[0]), 5),
                               "fit_baseline": round(float(fit[1]), 5),
                               "baseline_terms": [int(counts.crashes[1]), int(counts.loops[1]),
                                                  int(counts.distance[1]), int(counts.fails[1])],
                               "download_terms": [int(counts.crashes[0]), int(counts.loops[0]),
                                                  int(counts.distance[0]), int(counts.fails[0])],
                               "ahead_download": [round(v, 2) for v in d], "ahead_baseline": [round(v, 2) for v in b],
                               "ahead_best8": [round(v, 2) for v in best]})

    def learn_watching(self, reason, steps, state, motion, detector="") -> dict:
        """Round 17's learning phase; returns the population and fitness the download chose from."""
        last = {}
        saved = online_mod.choose_download

        def choose(population, fitness, blamed=None, reflex=True):
            last["pop"], last["fit"] = population.copy(), fitness.copy()
            return saved(population, fitness, blamed, reflex)

        online_mod.choose_download = choose
        try:
            super().learn(reason, steps, state, motion, detector)
        finally:
            online_mod.choose_download = saved
        return last

    def learn(self, reason, steps, state, motion, detector=""):
        if self.variant != "oracle":
            if not int(self.params["probe"]):
                return super().learn(reason, steps, state, motion, detector)
            last = self.learn_watching(reason, steps, state, motion, detector)
            if reason in online_mod.FAILURES:
                self.probe(last["pop"], last["fit"])
            return None
        self.plain_download = online_mod.choose_download
        running = None if self.best_rows is None else self.best_rows.copy()

        def choose(population, fitness, blamed=None, reflex=True):
            i, escaped = self.oracle_download(population, fitness, blamed, reflex)
            if i == -1:  # keep: OnlineRun.learn indexes the population; hand it the running genome
                population[0] = running
            return max(i, 0), escaped

        online_mod.choose_download = choose
        try:
            super().learn(reason, steps, state, motion, detector)
        finally:
            online_mod.choose_download = self.plain_download

    def extra_figures(self) -> dict:
        log = dict(self.oracle_log)
        ranks = log.pop("rank")
        log["rank_hist"] = np.bincount(ranks, minlength=1).tolist() if ranks else []
        return {**super().extra_figures(), "oracle": log, **({"probe": self.probe_log} if self.probe_log else {})}


def table(path: Path) -> str:
    """The screening seeds (1-24), then this round's held-out seeds on their own."""
    return "\n\n".join(seed_table(path, seeds) for seeds in (range(1, 25), HELD_OUT))


def main(argv=None) -> int:
    return round8_main(argv, cls=Round18, defaults=DEFAULT_PARAMS, variants=VARIANTS, default_out=DEFAULT_OUT,
                       description=__doc__, table_of=table)


if __name__ == "__main__":
    raise SystemExit(main())
