"""The model-free fitness of the off-line experiment (paper section 5.1, SPEC section 7).

Each controller drives the noise-free world from the arena's start pose (the upper-left corner)
through the fixed sequence of 64 relocation poses, until it crashes, a leg exceeds
``max_leg_steps``, or it has reached ``n_targets`` targets (the off-line runner drives it:
``cosim.offline.run.evaluate``). Then

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
