"""Drive a controller (a 256-entry motion table) through the course of 64 legs (SPEC sections 5, 7).

The robot starts at the arena's start pose. Each time it reaches the target it is relocated: after
the k-th target (k = 1, 2, ...) to ``arena.positions[(k - 1) % 64]`` (``Course``, the one place this
rule is written: the on-line and off-line runs, the baseline and the Gymnasium env use it). The run stops at the
``n_targets``-th target, at a crash (when ``stop_on_crash``), or when a leg exceeds
``max_leg_steps`` interactions (a time-out: the robot is stuck in a loop).

With ``skip_failed_legs`` a crash or a time-out ends only its leg: the leg counts as failed and the
robot goes on to the next leg's pose as after a target, so a run tries all ``n_targets`` legs (or
stops at ``max_failures`` failed legs). The off-line method's noisy stage scores controllers so
(``cosim.offline.noisy``): the clean legs of one run vary less than the targets before a first
crash.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ga.motions import X_BACK, X_LEFT, X_RIGHT, Motion
from sim_world.arena import N_POSITIONS, Arena
from sim_world.world import World

# The leg step limit. The reactive baseline (sim_world.baseline) needs at most ~170 interactions
# for a leg of the default arena, noise-free or at DEFAULT_NOISE; the paper's robot, at 5 cm a
# step, crosses the 4 m arena in 80 steps. 500 leaves a good controller ~3x the baseline's worst
# leg, while a robot caught in a loop is stopped before it wastes much (SPEC section 11: leg
# time-outs dominate the interaction count).
DEFAULT_MAX_LEG_STEPS = 500
_BACKWARD = frozenset((Motion.BACKWARD, Motion.BACKWARD_LEFT, Motion.BACKWARD_RIGHT))
_SIDE_OR_BACK = (1 << X_LEFT) | (1 << X_RIGHT) | (1 << X_BACK)


@dataclass(frozen=True)
class Course:
    """The relocation course of SPEC section 5: the arena's positions, always in the same order.

    After the k-th target (k = 1, 2, ...) the robot goes to position ``(first + k - 1) % n_positions``;
    ``first`` = 0 for a lifetime that starts at the arena's start pose, i for one that starts at
    ``positions[i - 1]`` (the next relocation is then ``positions[i]``).
    """

    n_positions: int = N_POSITIONS
    first: int = 0

    def __post_init__(self):
        if self.n_positions < 1:
            raise ValueError(f"a course needs at least one position, got n_positions={self.n_positions!r}")
        if not 0 <= self.first < self.n_positions:
            raise ValueError(f"first must be in 0..{self.n_positions - 1}, got {self.first!r}")

    @classmethod
    def of(cls, arena_or_world: Arena | World, first: int = 0) -> "Course":
        """The course of an arena (or of a world's arena)."""
        arena = getattr(arena_or_world, "arena", arena_or_world)
        return cls(len(arena.positions), first % len(arena.positions))

    def position_after(self, target: int) -> int:
        """Index of the relocation position after the ``target``-th target (1-based)."""
        if target < 1:
            raise ValueError(f"target counts from 1, got {target!r}")
        return (self.first + target - 1) % self.n_positions

    def relocate(self, world: World, target: int) -> int:
        """Relocate ``world`` after its ``target``-th target; returns the new world state."""
        return world.relocate(self.position_after(target))


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
    failed_legs: int = 0  # legs ended by a crash or a time-out (only with skip_failed_legs)
    failure_states: list[int] = field(default_factory=list)  # the state each failed leg ended in
    near_misses: int = 0  # motions that ended with the bumper closer than near_miss_mm to an obstacle
    obstacle_backs: int = 0  # backward motions executed with an obstacle beside or behind (count_backs)


def run_course(
    world: World,
    table,
    max_leg_steps: int = DEFAULT_MAX_LEG_STEPS,
    n_targets: int = N_POSITIONS,
    start: str | int = "start",
    stop_on_crash: bool = True,
    record: bool = False,
    skip_failed_legs: bool = False,
    max_failures: int | None = None,
    leg_noise_seed=None,
    near_miss_mm: float = 0.0,
    count_backs: bool = False,
) -> CourseResult:
    """Run the motion table ``table`` ((256,) ints, reflex already applied) through the course.

    ``start`` is "start" (the arena's start pose), "here" (the world's current pose) or a
    relocation index i (begin at ``positions[i]``; the next relocation is then positions[i + 1]).
    ``skip_failed_legs`` (see the module docstring): ``n_targets`` legs are tried, a crash or a
    time-out fails its leg, and the run ends at ``max_failures`` failed legs (None: never early);
    ``targets_reached`` counts the clean legs. ``leg_noise_seed`` (a function of the leg index
    0, 1, ...): the world's noise generator is re-seeded with its value before each leg's start
    pose is sensed, so a leg's noise does not depend on what earlier legs drew (common random
    numbers per leg: two controllers that drive a leg alike meet the same noise there).
    ``near_miss_mm`` > 0: count the motions (crashed ones excluded) after which the bumper is
    closer than this to an obstacle (``near_misses``; docs/research-log.md, off-line round 5). ``count_backs``:
    count the backward motions executed with an obstacle beside or behind (x3, x4 or x5 set;
    ``obstacle_backs``).
    """
    if max_leg_steps < 1:
        raise ValueError(f"max_leg_steps must be >= 1, got {max_leg_steps!r}")
    motions = [int(m) for m in np.asarray(table).reshape(-1)]
    if len(motions) != 256 or not all(0 <= m < 8 for m in motions):
        raise ValueError(f"table must hold 256 motions in 0..7, got shape {np.shape(table)}")
    if leg_noise_seed is not None:
        world.reset(leg_noise_seed(0))
    if start == "start":
        world.reset_to_start()
        course = Course.of(world)
    elif start == "here":
        course = Course.of(world)
    else:
        world.relocate(int(start))
        course = Course.of(world, first=int(start) + 1)
    res = CourseResult()
    states, transitions = res.states, res.transitions
    traj = res.trajectory
    step = world.step
    s = world.state()
    states.add(s)
    if record:
        x, y, h = world.pose
        traj.append((x, y, h, ""))
    leg = 0
    steps = 0
    while res.targets_reached + res.failed_legs < n_targets:
        failed = leg >= max_leg_steps
        if failed and not skip_failed_legs:
            res.timed_out = True
            break
        if not failed:
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
            if count_backs and a in _BACKWARD and s & _SIDE_OR_BACK:
                res.obstacle_backs += 1
            if near_miss_mm and not out.crashed and world.bumper_clearance < near_miss_mm:
                res.near_misses += 1
            if out.crashed:
                res.crashes += 1
                if skip_failed_legs:
                    failed = True
                elif stop_on_crash:
                    res.crashed = True
                    break
        if failed:  # only with skip_failed_legs: the leg ends here, the next one starts
            res.failed_legs += 1
            res.failure_states.append(s)
            if max_failures is not None and res.failed_legs >= max_failures:
                break
        elif out.reached:
            res.targets_reached += 1
            res.leg_steps.append(leg)
        if failed or out.reached:
            leg = 0
            done = res.targets_reached + res.failed_legs
            if done >= n_targets:
                break
            if leg_noise_seed is not None:
                world.reset(leg_noise_seed(done))
            s2 = course.relocate(world, done)
            states.add(s2)
            if record:
                x, y, h = world.pose
                traj.append((x, y, h, "relocate"))
        s = s2
    res.steps = steps
    res.final_distance_mm = world.target_distance()
    return res
