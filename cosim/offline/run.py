"""The off-line model-free experiment (paper section 5.1, Fig. 5 and 6).

A GA (population 20, tournament 5, elitism) evolves controllers in the noise-free world: every
individual of every generation drives the robot from the start pose through the 64 relocation
poses (:func:`evaluate`, scored by `ga.model_free.model_free_fitness`). The run stops when the best individual reaches the target 64
times, or at a generation cap. Then the best controller is "downloaded to the real robot": it
drives the noisy world (`sim_world.world.DEFAULT_NOISE`) and we count the targets it reaches
before its first crash (20 noise seeds). With ``noisy=NoisyStage(trials=K)`` (``--noisy-trials``;
none in `run_offline`) the GA goes on in the noisy world once the noise-free best reaches every
target (`cosim.offline.noisy`, docs/research-log.md, off-line round 3), or from the first generation with
``--noisy-from-start`` (round 5). ``ehw offline`` runs the latter by default (round 6:
`cosim.offline.noisy.ROBUST_STAGE`, leg limit 200); the paper's method is
``--config experiments/offline_paper.toml``.

    ehw offline --seed 1 [--generations-cap G] [--workers W] [--resume]
                [--out results/model_free] [--arena NAME] [--max-leg-steps N] [--config FILE]

Design:
- Evaluation is a pure function of (genome, arena, step limits): the world is noise-free and its
  pose cache is exact. So a process pool gives exactly the serial result (`executor.map` keeps the
  order; the sets of states and transitions are unions, order-free), and no RNG is shared.
- After every generation the GA state (genomes, RNG state), the counters, the sets met and the
  history go to ``<out>/checkpoint.json`` atomically (`base.checkpoint`). ``--resume`` reloads
  it and continues; the run then ends exactly as an uninterrupted one (test_offline checks it).
  Wall time is the sum over the sessions of a run.
- Outputs in ``<out>``: summary.json, history.json, fig5_trajectory.png,
  fig6_best_per_generation.png.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import multiprocessing
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from base.checkpoint import load_checkpoint, save_checkpoint
from base.files import atomic_write_json
from cosim.offline.noisy import (ROBUST_MAX_LEG_STEPS, TRANSFER_TRIALS, NoisyStage, Records, add_noisy_arguments,
                                 load_arena_arg, transfer)
from cosim.offline.stage import best_entry, final_step, fresh_stage_state, stage_over, stage_step, stage_summary
from cosim.offline.report import plot_results, seeds_table  # noqa: F401 (seeds_table: the API)
from cosim.paper import PAPER_OFFLINE as PAPER
from ga.evolution import GAConfig, GeneticAlgorithm
from ga.genome import validate_rows
from ga.model_free import N_TARGETS, max_run_steps, model_free_fitness
from ga.truth_table import truth_tables
from sim_world.course import run_course

KIND = "model_free"
DEFAULT_OUT = Path("results/model_free")
DEFAULT_ARENA = "default"
DEFAULT_GENERATIONS_CAP = 3000
# Step limit of one leg of the paper's noise-free method: see docs/offline.md for the measurements
# behind it. (`ehw offline` runs the noisy stage by default, at ROBUST_MAX_LEG_STEPS.)
DEFAULT_MAX_LEG_STEPS = 150
# run_offline's noisy stage: none, the paper's method (cosim.offline.noisy; docs/offline.md, issue 17).
DEFAULT_NOISY = NoisyStage()

def default_ga_config(**overrides) -> GAConfig:
    """Paper section 5.1: population 20, tournament 5, elitism 1; our operator rates, plus the
    directed mutation at 0.3 writing an 8-literal term (the failure state alone). See the
    ablation in docs/offline.md."""
    return GAConfig(**{"population": 20, "tournament": 5, "elitism": 1, "directed_rate": 0.3,
                       "directed_literals": 8, **overrides})


# -- Evaluation (also run in worker processes: module-level functions, one world per process) ----

@dataclass(frozen=True)
class Evaluation:
    """One controller's model-free run: its fitness and what the run met."""

    fitness: float
    targets_reached: int
    steps: int  # interactions
    crashed: bool
    timed_out: bool
    final_distance_mm: float
    states: frozenset  # world states met
    transitions: frozenset  # (state, motion, next state, crashed) met
    failure_state: int | None = None  # the state the run ended in, if it crashed or got stuck


def evaluate(world, rows, max_leg_steps: int, n_targets: int = N_TARGETS, reflex: bool = True) -> Evaluation:
    """Drive ``world`` (a `sim_world.world.World`) with one genome through the course and score it
    (`ga.model_free.model_free_fitness`)."""
    rows = validate_rows(rows)
    if rows.ndim != 1:
        raise ValueError(f"evaluate takes one genome of shape (50,), got {rows.shape!r}")
    res = run_course(world, truth_tables(rows, reflex=reflex), max_leg_steps, n_targets=n_targets)
    # After a crash the pose is restored, so the state now is the one whose motion crashed; after
    # a time-out it is a state of the loop the robot was caught in.
    failed = res.crashed or res.timed_out
    fitness = model_free_fitness(res.targets_reached, res.final_distance_mm, world.arena.size_mm,
                                 res.steps, max_run_steps(max_leg_steps, n_targets))
    return Evaluation(
        fitness=fitness, targets_reached=int(res.targets_reached), steps=int(res.steps),
        crashed=bool(res.crashed), timed_out=bool(res.timed_out),
        final_distance_mm=float(res.final_distance_mm),
        states=frozenset(int(s) for s in res.states),
        transitions=frozenset(tuple(int(v) for v in t) for t in res.transitions),
        failure_state=int(world.state()) if failed else None,
    )


_WORLDS: dict = {}


def _world(arena: str):
    from sim_world.world import World

    world = _WORLDS.get(arena)
    if world is None:
        world = _WORLDS[arena] = World(load_arena_arg(arena))
    return world


def _evaluate_one(task) -> Evaluation:
    arena, max_leg_steps, n_targets, rows = task
    return evaluate(_world(arena), rows, max_leg_steps, n_targets)


class Evaluator:
    """Evaluates a population serially (``workers`` <= 1) or over a process pool, same result."""

    def __init__(self, arena: str, max_leg_steps: int, n_targets: int = N_TARGETS, workers: int = 1,
                 cache_size: int = 4096):
        self.cache_size = cache_size  # truth tables remembered (about 200 generations of 20)
        self.arena, self.max_leg_steps, self.n_targets = arena, max_leg_steps, n_targets
        self.workers = max(int(workers), 1)
        self._pool = None
        self._cache: dict[bytes, Evaluation] = {}
        self.simulated_steps = 0
        if self.workers > 1:
            # spawn: workers import only what they need, no fork of a threaded parent.
            ctx = multiprocessing.get_context("spawn")
            self._pool = ProcessPoolExecutor(max_workers=self.workers, mp_context=ctx)

    def __call__(self, pop: np.ndarray) -> list[Evaluation]:
        """One Evaluation per genome, in order.

        A run depends on the genome only through its truth table (reflex included), and the
        world is deterministic, so a genome whose table was evaluated recently (the elite, a
        child whose mutations hit only off rows) gets that stored Evaluation back instead of
        being driven again: the same result, and `interactions` still counts it (paper: every
        individual of every generation). ``simulated_steps`` counts what was really driven.
        """
        keys = [t.tobytes() for t in truth_tables(pop, reflex=True)]
        todo = {}
        for key, rows in zip(keys, pop):
            if key not in self._cache and key not in todo:
                todo[key] = rows
        tasks = [(self.arena, self.max_leg_steps, self.n_targets, rows) for rows in todo.values()]
        if self._pool is None:
            fresh = [_evaluate_one(t) for t in tasks]
        else:
            fresh = list(self._pool.map(_evaluate_one, tasks))
        found = {key: self._cache[key] for key in keys if key in self._cache}
        found.update(zip(todo, fresh))
        if len(self._cache) + len(fresh) > self.cache_size:
            self._cache.clear()
        self._cache.update(zip(todo, fresh))
        self.simulated_steps += sum(e.steps for e in fresh)
        return [found[key] for key in keys]

    def map(self, fn, tasks) -> list:
        """``fn`` over ``tasks``, in order: serially or over the pool (the noisy stage's runs)."""
        if self._pool is None:
            return [fn(t) for t in tasks]
        return list(self._pool.map(fn, tasks))

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)
            self._pool = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


# -- The run -------------------------------------------------------------------------------------


def _arena_digest(arena: str) -> str:
    data = json.dumps(load_arena_arg(arena).to_json(), sort_keys=True)
    return hashlib.sha256(data.encode()).hexdigest()[:16]


def run_config(seed: int, arena: str, max_leg_steps: int, n_targets: int, ga_config: GAConfig,
               noisy: NoisyStage | None = None) -> dict:
    """The parameters that define a run: a checkpoint resumes only under the same ones."""
    config = {
        "seed": int(seed),
        "arena": str(arena),
        "arena_sha256_16": _arena_digest(arena),
        "max_leg_steps": int(max_leg_steps),
        "n_targets": int(n_targets),
        "ga": ga_config.to_dict(),
    }
    if noisy is not None and noisy.trials:
        config["noisy_stage"] = noisy.to_dict()
    return config


def _fresh_state(ga: GeneticAlgorithm) -> dict:
    return {
        "ga": ga.state_dict(),
        "interactions": 0,
        "simulated_interactions": 0,
        "world_states": [],
        "transitions": [],
        "history": [],
        "best": None,
        "wall_time_s": 0.0,
        "stage": 1,  # 2: the noisy stage (cosim.offline.noisy)
        "noisy": fresh_stage_state(),
    }


def run_offline(
    seed: int,
    *,
    generations_cap: int = DEFAULT_GENERATIONS_CAP,
    workers: int = 1,
    resume: bool = False,
    out: Path | str = DEFAULT_OUT,
    arena: str = DEFAULT_ARENA,
    max_leg_steps: int = DEFAULT_MAX_LEG_STEPS,
    n_targets: int = N_TARGETS,
    ga_config: GAConfig | None = None,
    progress: bool = True,
    plots: bool = True,
    transfer_trials: int = TRANSFER_TRIALS,
    transfer_leg_steps: int = 0,
    on_generation: Callable[[dict], None] | None = None,
    noisy: NoisyStage | None = None,
) -> dict:
    """Run (or, with ``resume``, continue) the model-free experiment; return the summary dict.

    ``on_generation`` is called with each generation's history entry after its checkpoint is
    written (tests raise from it to interrupt a run). The summary is also written to
    ``<out>/summary.json``. ``transfer_leg_steps``: the leg limit of the transfer runs (0: the
    run's ``max_leg_steps``).
    """
    from tqdm import tqdm

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    ga_config = ga_config or default_ga_config()
    noisy = DEFAULT_NOISY if noisy is None else noisy
    config = run_config(seed, arena, max_leg_steps, n_targets, ga_config, noisy)
    ck_path = out / "checkpoint.json"
    if resume and ck_path.exists():
        state = load_checkpoint(ck_path, KIND, config)
        state.setdefault("stage", 1)  # a checkpoint written before the noisy stage existed
        state.setdefault("noisy", fresh_stage_state())
        ga = GeneticAlgorithm.from_state_dict(state["ga"], np.random.default_rng())
    else:
        ga = GeneticAlgorithm(ga_config, np.random.default_rng(seed))
        state = _fresh_state(ga)
        if noisy.trials and noisy.from_start:  # round 5: no noise-free stage
            state["stage"] = 2
            state["noisy"]["from_generation"] = ga.generation + 1  # generations count from 1
    states = set(state["world_states"])
    transitions = {tuple(t) for t in state["transitions"]}
    records = Records(state["noisy"]["records"])
    t_session = time.perf_counter()
    wall_before = state["wall_time_s"]

    def reached_all() -> bool:
        best = state["best"]
        return best is not None and best["targets_reached"] >= n_targets

    def finished() -> bool:
        return stage_over(noisy, state["noisy"], ga.generation) if noisy.trials else reached_all()

    bar = tqdm(total=generations_cap, initial=min(ga.generation, generations_cap), disable=not progress,
               desc=f"model-free seed {seed}", unit="gen", dynamic_ncols=True)
    try:
        with Evaluator(arena, max_leg_steps, n_targets, workers) as evaluator:
            while not finished() and ga.generation < generations_cap:
                pop = ga.ask()
                if state["stage"] == 2:
                    best, entry_extra = stage_step(ga, pop, evaluator, noisy, records, state, seed, arena,
                                                   max_leg_steps, n_targets, states, transitions)
                else:
                    driven = evaluator.simulated_steps
                    evals = evaluator(pop)
                    state["simulated_interactions"] += evaluator.simulated_steps - driven
                    fitness = np.array([e.fitness for e in evals], dtype=float)
                    ga.tell(fitness, failures=[e.failure_state for e in evals])
                    i = int(np.argmax(fitness))  # the same individual tell() took as best
                    best = evals[i]
                    for e in evals:
                        states |= e.states
                        transitions |= e.transitions
                    state["interactions"] += sum(e.steps for e in evals)
                    state["best"] = best_entry(pop[i], best)
                    # how the best's run ends, and the diversity (docs/offline.md, the history)
                    entry_extra = {
                        "best_end": "crash" if best.crashed else "time-out" if best.timed_out else "done",
                        "best_end_state": best.failure_state,
                        "distinct_tables": len({t.tobytes() for t in truth_tables(pop, reflex=True)}),
                        "at_best_targets": sum(e.targets_reached == best.targets_reached for e in evals),
                    }
                    if noisy.trials and best.targets_reached >= n_targets:
                        state["stage"] = 2  # the noise-free best reaches every target: go noisy
                        state["noisy"]["from_generation"] = ga.generation + 1
                        state["noisy"]["noise_free_best"] = dict(state["best"], generations=ga.generation,
                                                                 interactions=state["interactions"])
                entry = {
                    "generation": ga.generation,
                    "best_fitness": best.fitness,
                    "best_targets": best.targets_reached,
                    "best_steps": best.steps,
                    "mean_fitness": float(ga.last_fitness.mean()),
                    "interactions": state["interactions"],
                    "world_states": len(states),
                    "transitions": len({(t[0], t[1]) for t in transitions}),
                    "transition_outcomes": len(transitions),
                    **entry_extra,
                }
                state["history"].append(entry)
                state["ga"] = ga.state_dict()
                state["noisy"]["records"] = records.to_dict()
                state["world_states"] = sorted(states)
                state["transitions"] = sorted(transitions)
                state["wall_time_s"] = wall_before + time.perf_counter() - t_session
                save_checkpoint(ck_path, KIND, config, state)
                bar.update(1)
                bar.set_postfix(targets=best.targets_reached, steps=best.steps,
                                interactions=state["interactions"], refresh=False)
                if on_generation is not None:
                    on_generation(entry)
            if noisy.final_race and state["stage"] == 2 and state["noisy"].get("final_race") is None:
                final_step(evaluator, noisy, state, seed, arena, max_leg_steps, n_targets)
                save_checkpoint(ck_path, KIND, config, state)
    finally:
        bar.close()

    summary = _summary(seed, state, config, ga_config, workers, reached_all())
    if transfer_trials:
        legs = transfer_leg_steps or (noisy.trials and noisy.leg_steps) or max_leg_steps
        summary["transfer"] = transfer(summary["best_genome"], arena, legs, n_targets, seed, transfer_trials)
        first = (summary.get("noisy_stage") or {}).get("noise_free_best")
        if first:  # the noise-free stage's champion, on the same noise seeds
            first["transfer"] = transfer(first["genome"], arena, legs, n_targets, seed, transfer_trials)
    atomic_write_json(out / "history.json", state["history"])
    if plots:
        summary["figures"] = plot_results(out, state["history"], summary["best_genome"], arena,
                                          max_leg_steps, n_targets, seed)
    atomic_write_json(out / "summary.json", summary, indent=2)
    return summary


def _summary(seed, state, config, ga_config: GAConfig, workers, reached_all) -> dict:
    best = state["best"] or {}
    generations = len(state["history"])
    return {
        "seed": int(seed),
        "reached_all_targets": bool(reached_all),
        "targets_reached": best.get("targets_reached", 0),
        "generations": generations,
        "genetic_operations": generations * ga_config.population,
        "interactions": state["interactions"],
        # Steps really simulated: identical truth tables are not driven twice (Evaluator).
        "simulated_interactions": state["simulated_interactions"],
        "world_states": len(state["world_states"]),
        # The paper's transitions (at most 256 x 8 = 2048): distinct (state, motion) pairs met.
        "transitions": len({(t[0], t[1]) for t in state["transitions"]}),
        # Distinct observed outcomes (state, motion, next state, crashed).
        "transition_outcomes": len(state["transitions"]),
        "best_fitness": best.get("fitness"),
        "best_steps": best.get("steps"),
        "best_genome": best.get("genome"),
        "wall_time_s": round(state["wall_time_s"], 3),
        "workers": int(workers),
        "max_run_steps": max_run_steps(config["max_leg_steps"], config["n_targets"]),
        "config": config,
        "paper": PAPER,
        **({"noisy_stage": stage_summary(state, generations)} if "noisy_stage" in config else {}),
    }


# -- Command line --------------------------------------------------------------------------------


def add_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """The off-line experiment's options (``ehw offline``; the shared --seed/--out/--resume/
    --force/--quiet/--config come from ``cosim.cli.main``)."""
    parser.add_argument("--seed", type=int, default=1, help="GA seed")
    parser.add_argument("--generations-cap", type=int, default=DEFAULT_GENERATIONS_CAP,
                        help="stop after this many generations")
    parser.add_argument("--workers", type=int, default=1, help="evaluation processes (1: serial)")
    parser.add_argument("--arena", default=DEFAULT_ARENA, help="arena name or .json path")
    parser.add_argument("--max-leg-steps", type=int, default=ROBUST_MAX_LEG_STEPS,
                        help=f"step limit of one leg (the paper's noise-free method: {DEFAULT_MAX_LEG_STEPS}, "
                             "--config experiments/offline_paper.toml)")
    add_noisy_arguments(parser)
    parser.add_argument("--transfer-trials", type=int, default=TRANSFER_TRIALS,
                        help="noisy-world runs of the final controller (noise seeds seed*1000+i)")
    parser.add_argument("--transfer-leg-steps", type=int, default=0,
                        help="leg limit of those runs (0: --max-leg-steps; the hand-written baseline needs "
                             "250: docs/research-log.md, off-line round 5)")
    parser.add_argument("--no-plots", action="store_true",
                        help="write no figures (an earlier run's figures are removed all the same)")
    parser.add_argument("--table", nargs="+", type=Path, metavar="SUMMARY",
                        help="print the Markdown table of these summary.json files and exit")
    return parser
