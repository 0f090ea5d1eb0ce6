"""A hand-written reactive controller: the arena's fairness proof and every experiment's baseline.

In the paper's spirit (section 5): the reflex in free space, and near an obstacle "turn clockwise
around the obstacle until the way to the target is free". Expressed as a 256-entry truth table
over the world state, so it runs exactly like an evolved controller (``run_course``).

``python -m sim_world.baseline`` runs it through the 64 legs noise-free and at DEFAULT_NOISE,
prints targets, interactions, crashes and time-outs, and writes results/baseline.json and
results/baseline_trajectory.png.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from ga.motions import (
    N_STATES,
    OBSTACLE_MASK,
    REFLEX_TABLE,
    SECTOR_SHIFT,
    X_BACK,
    X_FRONT,
    X_FRONT_LEFT,
    X_FRONT_RIGHT,
    X_LEFT,
    X_RIGHT,
    Motion,
    Sector,
)
from sim_world.arena import N_POSITIONS, load_arena
from sim_world.course import DEFAULT_MAX_LEG_STEPS, run_course
from sim_world.world import DEFAULT_NOISE, World


def baseline_motion(state: int) -> Motion:
    """The baseline's motion in world state ``state``.

    The robot keeps an obstacle it meets on its right and so circles it clockwise; it leaves the
    obstacle as soon as the target is not on the obstacle's side (the reflex then steers it).
    """
    bits = state & OBSTACLE_MASK
    sector = Sector((state >> SECTOR_SHIFT) & 3)
    has = lambda b: bool(bits >> b & 1)  # noqa: E731
    if bits == 0:
        return Motion(int(REFLEX_TABLE[state]))
    if has(X_FRONT):
        if has(X_FRONT_RIGHT):
            # Blocked ahead and ahead-right: turn left in place, which puts the obstacle on the
            # right (the clockwise way round).
            return Motion.TURN_LEFT
        if has(X_FRONT_LEFT):
            # Blocked ahead and ahead-left: turn right in place, away from it.
            return Motion.TURN_RIGHT
        if sector in (Sector.BACK, Sector.LEFT) or has(X_BACK):
            return Motion.TURN_LEFT
        # Something that fills only the front cone (far, or narrow), with the target beyond it:
        # go round it clockwise while moving (a pure turn would alternate with the reflex's
        # turn towards the target for ever, SPEC section 11).
        return Motion.FORWARD_LEFT
    if has(X_FRONT_RIGHT):
        # Obstacle ahead-right: veer left while moving on, keeping it beside the robot.
        return Motion.FORWARD_LEFT
    if has(X_FRONT_LEFT):
        # Obstacle ahead-left: veer right while moving on.
        return Motion.FORWARD_RIGHT
    if has(X_RIGHT):
        # Obstacle beside on the right: follow it while the target lies on its side (front/right);
        # with the target on the free side, turn towards it.
        if sector in (Sector.FRONT, Sector.RIGHT):
            return Motion.FORWARD
        return Motion.TURN_LEFT
    if has(X_LEFT):
        # Obstacle on the left only: like free space, but never turn into it.
        return Motion.TURN_RIGHT if sector in (Sector.RIGHT, Sector.BACK) else Motion.FORWARD
    # Only something behind: free space for every purpose.
    return Motion(int(REFLEX_TABLE[state & ~OBSTACLE_MASK]))


def baseline_table() -> np.ndarray:
    """The baseline controller as a (256,) uint8 motion table (the reflex included)."""
    return np.array([baseline_motion(s) for s in range(N_STATES)], dtype=np.uint8)


def run_baseline(arena="default", noise=None, seed: int = 0, max_leg_steps: int = DEFAULT_MAX_LEG_STEPS,
                 record: bool = False):
    """Run the baseline through the course; returns the CourseResult."""
    world = World(arena if not isinstance(arena, str) else load_arena(arena), noise=noise, seed=seed)
    return run_course(world, baseline_table(), max_leg_steps, n_targets=N_POSITIONS, record=record)


def _summary(res) -> dict:
    return {
        "targets": res.targets_reached,
        "interactions": res.steps,
        "crashed": res.crashed,
        "timed_out": res.timed_out,
        "max_leg_steps_used": max(res.leg_steps, default=0),
        "states": len(res.states),
        "transitions": len(res.transitions),
    }


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--arena", default="default")
    parser.add_argument("--seeds", type=int, default=5, help="noisy runs (seeds 0..N-1)")
    parser.add_argument("--max-leg-steps", type=int, default=DEFAULT_MAX_LEG_STEPS)
    parser.add_argument("--out", type=Path, default=Path("results"))
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    report = {"arena": args.arena, "max_leg_steps": args.max_leg_steps, "noise": DEFAULT_NOISE.__dict__}
    t0 = time.perf_counter()
    clean = run_baseline(args.arena, None, 0, args.max_leg_steps, record=True)
    report["noise_free"] = _summary(clean)
    print(f"noise-free: {_summary(clean)}")
    noisy = []
    for seed in range(args.seeds):
        res = run_baseline(args.arena, DEFAULT_NOISE, seed, args.max_leg_steps)
        noisy.append(_summary(res))
        print(f"noisy seed {seed}: {noisy[-1]}")
    report["noisy"] = noisy
    report["seconds"] = round(time.perf_counter() - t0, 2)
    (args.out / "baseline.json").write_text(json.dumps(report, indent=2) + "\n")
    from sim_world.render import plot_trajectory

    png = args.out / "baseline_trajectory.png"
    plot_trajectory(load_arena(args.arena), clean.trajectory, png,
                    title=f"reactive baseline, noise-free: {clean.targets_reached} targets, {clean.steps} interactions")
    print(f"wrote {args.out / 'baseline.json'} and {png}")


if __name__ == "__main__":
    main()
