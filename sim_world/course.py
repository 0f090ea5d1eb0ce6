"""Drive a controller (a 256-entry motion table) through the course of 64 legs (SPEC sections 5, 7).

The robot starts at the arena's start pose. Each time it reaches the target it is relocated: after
the k-th target (k = 1, 2, ...) to ``arena.positions[(k - 1) % 64]``. The run stops at the
``n_targets``-th target, at a crash (when ``stop_on_crash``), or when a leg exceeds
``max_leg_steps`` interactions (a time-out: the robot is stuck in a loop).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sim_world.arena import N_POSITIONS
from sim_world.world import World

# The leg step limit. The reactive baseline (sim_world.baseline) needs at most ~170 interactions
# for a leg of the default arena, noise-free or at DEFAULT_NOISE; the paper's robot, at 5 cm a
# step, crosses the 4 m arena in 80 steps. 500 leaves a good controller ~3x the baseline's worst
# leg, while a robot caught in a loop is stopped before it wastes much (SPEC section 11: leg
# time-outs dominate the interaction count).
DEFAULT_MAX_LEG_STEPS = 500


@dataclass
class CourseResult:
    targets_reached: int = 0
    steps: int = 0  # interactions used by the whole run
    crashed: bool = False  # the run ended with a crash (only when stop_on_crash)
    timed_out: bool = False  # the run ended because a leg exceeded max_leg_steps
    final_distance_mm: float = 0.0
    crashes: int = 0  # crashes met (> 1 only when not stop_on_crash)
    leg_steps: list[int] = field(default_factory=list)  # interactions of every finished leg
    states: set[int] = field(default_factory=set)
    transitions: set[tuple[int, int, int, bool]] = field(default_factory=set)
    trajectory: list[tuple[float, float, float, str]] = field(default_factory=list)


def run_course(
    world: World,
    table,
    max_leg_steps: int = DEFAULT_MAX_LEG_STEPS,
    n_targets: int = N_POSITIONS,
    start: str | int = "start",
    stop_on_crash: bool = True,
    record: bool = False,
) -> CourseResult:
    """Run the motion table ``table`` ((256,) ints, reflex already applied) through the course.

    ``start`` is "start" (the arena's start pose), "here" (the world's current pose) or a
    relocation index i (begin at ``positions[i]``; the next relocation is then positions[i + 1]).
    """
    if max_leg_steps < 1:
        raise ValueError(f"max_leg_steps must be >= 1, got {max_leg_steps!r}")
    motions = [int(m) for m in np.asarray(table).reshape(-1)]
    if len(motions) != 256 or not all(0 <= m < 8 for m in motions):
        raise ValueError(f"table must hold 256 motions in 0..7, got shape {np.shape(table)}")
    if start == "start":
        world.reset_to_start()
        next_pos = 0
    elif start == "here":
        next_pos = 0
    else:
        world.relocate(int(start))
        next_pos = int(start) + 1
    res = CourseResult()
    states, transitions = res.states, res.transitions
    traj = res.trajectory
    n_positions = len(world.arena.positions)
    step = world.step
    s = world.state()
    states.add(s)
    if record:
        x, y, h = world.pose
        traj.append((x, y, h, ""))
    leg = 0
    steps = 0
    while res.targets_reached < n_targets:
        if leg >= max_leg_steps:
            res.timed_out = True
            break
        a = motions[s]
        out = step(a)
        steps += 1
        leg += 1
        s2 = out.state
        transitions.add((s, a, s2, out.crashed))
        states.add(s2)
        if record:
            x, y, h = world.pose
            traj.append((x, y, h, "crash" if out.crashed else ("target" if out.reached else "")))
        if out.crashed:
            res.crashes += 1
            if stop_on_crash:
                res.crashed = True
                break
        if out.reached:
            res.targets_reached += 1
            res.leg_steps.append(leg)
            leg = 0
            if res.targets_reached >= n_targets:
                break
            s2 = world.relocate(next_pos % n_positions)
            next_pos += 1
            states.add(s2)
            if record:
                x, y, h = world.pose
                traj.append((x, y, h, "relocate"))
        s = s2
    res.steps = steps
    res.final_distance_mm = world.target_distance()
    return res
