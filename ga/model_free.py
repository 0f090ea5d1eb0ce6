"""The model-free fitness of the off-line experiment (paper section 5.1, SPEC section 7).

Each controller drives the noise-free world from the arena's start pose (the upper-left corner)
through the fixed sequence of 64 relocation poses (`sim_world.course.run_course`, the truth table
taken with the reflex), until it crashes, a leg exceeds ``max_leg_steps``, or it has reached
``n_targets`` targets. Then

    fitness = R1 + 0.5 (1 - D / L) + 0.5 (1 - steps / MaxSteps)

- R1 = targets reached (0..64);
- D = the robot's final distance to the target (centre to ball, mm), L = the arena's side (mm);
  D / L is clipped to [0, 1] (never binding in the shipped arenas: the ball is inside, so D < L sqrt 2,
  and with the ball at the centre D <= L / sqrt 2);
- steps = the interactions of the run (every motion executed, crashed ones included);
- MaxSteps = the run's step budget, ``n_targets * max_leg_steps`` (the most steps a run can take,
  since a leg ends after ``max_leg_steps``), so steps / MaxSteps is in [0, 1].

R2 + R3 < 1 = one more target, so fitness ranks first by targets, then (equally weighted) by
distance left and steps used: the paper's "equal contribution" of the two.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ga.genome import validate_rows
from ga.truth_table import truth_tables

N_TARGETS = 64


def max_run_steps(max_leg_steps: int, n_targets: int = N_TARGETS) -> int:
    """MaxSteps of the fitness: the step budget of one run."""
    return int(n_targets) * int(max_leg_steps)


def model_free_fitness(
    targets_reached: int, final_distance_mm: float, arena_size_mm: float, steps: int, max_steps: int
) -> float:
    """R1 + 0.5 (1 - D/L) + 0.5 (1 - steps/MaxSteps), both ratios clipped to [0, 1]."""
    if arena_size_mm <= 0 or max_steps <= 0:
        raise ValueError(f"arena size and MaxSteps must be positive, got {arena_size_mm!r}, {max_steps!r}")
    d = min(max(final_distance_mm / arena_size_mm, 0.0), 1.0)
    s = min(max(steps / max_steps, 0.0), 1.0)
    return float(targets_reached) + 0.5 * (1.0 - d) + 0.5 * (1.0 - s)


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
    """Drive ``world`` (a `sim_world.world.World`) with one genome and score it."""
    from sim_world.course import run_course  # the world is imported lazily: ga/ stays light

    rows = validate_rows(rows)
    if rows.ndim != 1:
        raise ValueError(f"evaluate takes one genome of shape (50,), got {rows.shape!r}")
    table = truth_tables(rows, reflex=reflex)
    res = run_course(world, table, max_leg_steps, n_targets=n_targets)
    # After a crash the pose is restored, so the state now is the one whose motion crashed; after
    # a time-out it is a state of the loop the robot was caught in.
    failed = res.crashed or res.timed_out
    fitness = model_free_fitness(
        res.targets_reached, res.final_distance_mm, world.arena.size_mm, res.steps,
        max_run_steps(max_leg_steps, n_targets),
    )
    return Evaluation(
        fitness=fitness,
        targets_reached=int(res.targets_reached),
        steps=int(res.steps),
        crashed=bool(res.crashed),
        timed_out=bool(res.timed_out),
        final_distance_mm=float(res.final_distance_mm),
        states=frozenset(int(s) for s in res.states),
        transitions=frozenset(tuple(int(v) for v in t) for t in res.transitions),
        failure_state=int(world.state()) if failed else None,
    )


def fitness_vector(evaluations) -> np.ndarray:
    """The fitness of a list of evaluations, as the GA's tell() takes it."""
    return np.array([e.fitness for e in evaluations], dtype=float)
