"""The on-line run's learning phase on the learning board (``--ga hardware``, SPEC section 12).

With the host GA (``--ga host``, the default) a learning phase is ``cosim.online.run.OnlineRun._learn``:
the NumPy GA breeds, the evaluator board evaluates every population. With ``--ga hardware`` the
learning board (``cosim.boards.interfaces.LearningBoard``) does both on the chip and only the download comes
back: ``learn_on_chip`` is that phase. It keeps the default on-line options' behaviour: after a
time-out or loop in an obstacle state the download is the fittest individual whose motion in the
blamed state differs from the failed one (the escape, computed on the chip). With
``--fail-rates`` the host writes the changed rate codes to the board before the phase
(``cosim.online.run``) and the engine's score loses the fail count F, as the host GA's fitness does;
without, the board keeps ``PRIOR_CODE`` everywhere, F is the same for every child and the
selection is that of the three SPEC terms (the record's fitness then leaves F out).
"""

from __future__ import annotations

import numpy as np

from ga.evaluator import EvalResult, fitness
from ga.motions import OBSTACLE_MASK


def hardware_ga_config(config):
    """The learning engine's parameters from an OnlineConfig."""
    from ga.hardware_ga import HardwareGAConfig

    return HardwareGAConfig(population=config.population, tournament=config.tournament,
                            lanes=config.lanes, crossover_rate=config.crossover_rate,
                            literal_rate=config.literal_rate, output_rate=config.output_rate,
                            switch_rate=config.switch_rate, replace_rate=config.replace_rate)


def hardware_seed(seed: int) -> int:
    """The engine's 32-bit seed for the run's seed (its own stream: the host GA's is untouched)."""
    return int(np.random.SeedSequence([int(seed), 14]).generate_state(1)[0])


def check_learning_backend(config, backend: str) -> None:
    """Refuse ``--ga hardware`` on a backend without a learning board (a user error)."""
    from cosim.boards.interfaces import BackendUnavailable
    from cosim.boards.registry import LEARNING_BACKENDS

    if config.ga == "hardware" and backend not in LEARNING_BACKENDS:
        raise BackendUnavailable(f"--ga hardware runs on --backend {', '.join(LEARNING_BACKENDS)} (no "
                                 f"{backend} learning board yet)")


def phase_avoid(config, reason: str, state: int, motion: int):
    """The learn's ``avoid`` of a phase: (state, motion) after a time-out or loop in an obstacle
    state (the escape), else None."""
    if config.escape and reason in ("timeout", "loop") and state & OBSTACLE_MASK:
        return int(state), int(motion)
    return None


def learn_on_chip(run, record: dict, reason: str, state: int, motion: int) -> dict:
    """One learning phase on ``run.evaluator`` (a LearningBoard); returns the phase record."""
    cfg = run.config
    result = run.evaluator.learn(cfg.generations_per_phase, phase_avoid(cfg, reason, state, motion))
    run.generations += cfg.generations_per_phase
    run.genetic_operations += cfg.generations_per_phase * cfg.population
    run.best_rows = result.rows.copy()
    run.controller.load(result.rows)
    fails = result.fails if cfg.fail_rates else 0  # SPEC section 7's three terms without --fail-rates
    counts = EvalResult(*(np.array([v]) for v in (result.crashes, result.loops, result.distance, fails)))
    new_motion = int(run.controller.motion(state))
    record.update({
        "best_fitness": round(float(fitness(counts, run.mirror.n_states)[0]), 6),
        "best_crashes": result.crashes, "best_loops": result.loops, "best_distance": result.distance,
        "best_fails": fails,
        "new_motion": new_motion, "changed": new_motion != int(motion),
        "engine_cycles": result.cycles,
    })
    if result.escaped:
        record["escaped"] = True
    return record
