"""A hand-written reactive controller: the arena's fairness proof and every experiment's baseline.

In the paper's spirit (section 5): the reflex in free space, and near an obstacle "turn clockwise
around the obstacle until the way to the target is free". Expressed as a 256-entry truth table
over the world state, so it runs exactly like an evolved controller (``run_course``).

How it was made: the rules of :func:`baseline_motion` were written by hand; alone they reach the
target on most legs but fall into a few reactive loops and crash now and then under noise. Then,
in two rounds, single entries were changed: a seeded local search (:func:`tune_table`, over every
leg of ``TUNING_RUNS``, keeping a change that adds neither failed legs nor interactions) and
changes by hand from the failed legs of noise seeds 0..99. What the second round found
(docs/world.md): every failure under noise was a crash; backward motions (the first search had put
some in) crash into what the three rear rays miss, so the search no longer proposes them; and
with only x0 set, going round the obstacle while moving forward turned into it about as often
as away (x0 merges the 0 and +-25 degree rays, so it does not say on which side the obstacle
lies): there the robot now backs off while turning left (target front or right). Last,
:func:`revert_to_rules` put back every rule that cost nothing. ``TUNED_TABLE`` is the shipped baseline;
``rules_table()`` is the hand-written starting point.

``python -m sim_world.baseline`` runs it through the 64 legs noise-free and at DEFAULT_NOISE,
prints targets, interactions, crashes and time-outs, and writes results/baseline.json and
results/baseline_trajectory.png. ``--tune SECONDS`` continues the search from the shipped table;
``--seeds 50 --first-seed 100`` checks it on noise seeds it was never tuned on.
"""

from __future__ import annotations

import argparse
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
from sim_world.course import DEFAULT_MAX_LEG_STEPS, Course, run_course
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


def rules_table() -> np.ndarray:
    """The hand-written rules as a (256,) uint8 motion table (the reflex included)."""
    return np.array([baseline_motion(s) for s in range(N_STATES)], dtype=np.uint8)


# The shipped baseline: the rules above with the motion of 16 states changed (by the local search
# `tune_table` over every leg of TUNING_RUNS, and by hand; see the module docstring). One digit per
# state 0..255, the motion code (0 F, 1 B, 2 L, 3 R, 4 FL, 5 FR, 6 BL, 7 BR); state = obstacle bits
# x0..x5 + 64 * sector, so each line of 64 digits is one target sector (front, left, back, right).
# The reflex states (obstacle bits 0) are never changed.
TUNED_TABLE = (
    "0653424204534242005342420453424202534242005342420553424202534242"
    "2253424242534242225342422253424222034242025342422253424222534242"
    "2253424220534242225342422255424222534242525342422253424222534242"
    "3653424234334242045342420553424202534242355342420253424242534242"
)


def baseline_table() -> np.ndarray:
    """The baseline controller as a (256,) uint8 motion table (the reflex included)."""
    if not TUNED_TABLE:
        return rules_table()
    table = np.array([int(c) for c in TUNED_TABLE], dtype=np.uint8)
    assert len(table) == N_STATES
    reflex = REFLEX_TABLE >= 0
    assert np.array_equal(table[reflex], REFLEX_TABLE[reflex])
    return table


# The motions the search may put in a table: backward motions are left out. Behind the robot only
# three rays look (135, 180, -135 degrees), and 9 of the 26 failed legs of the round-1 table (noise
# seeds 0..99) were backward motions into an obstacle the rear rays missed.
SEARCH_MOTIONS = (Motion.FORWARD, Motion.TURN_LEFT, Motion.TURN_RIGHT, Motion.FORWARD_LEFT, Motion.FORWARD_RIGHT)
# A failed noise-free leg is a deterministic loop or crash, met again on every run: it weighs as
# much as this many failed noisy legs.
NOISE_FREE_WEIGHT = 10
# The front-only states (x0 alone, any sector): set by hand (BACKWARD_LEFT with the target front or
# right, TURN_LEFT, the rule, with it left or behind) and kept out of the search.
FRONT_ONLY_STATES = frozenset((1 << X_FRONT) | sector << SECTOR_SHIFT for sector in range(4))


def _run_leg(world: World, tab, leg: int, max_leg_steps: int):
    """One leg from ``leg`` (-1: the start pose). Returns (reached, interactions, the last
    obstacle states met)."""
    s = world.reset_to_start() if leg < 0 else world.relocate(leg)
    seen = []
    for n in range(1, max_leg_steps + 1):
        if s & OBSTACLE_MASK:
            seen.append(s)
        out = world.step(int(tab[s]))
        if out.crashed:
            return False, n, seen[-12:]
        if out.reached:
            return True, n, seen[-12:]
        s = out.state
    return False, max_leg_steps, seen[-12:]


def evaluate_legs(table, runs, max_leg_steps: int = DEFAULT_MAX_LEG_STEPS, limit=None):
    """Every leg of every run in ``runs`` ((arena name, noise or None, seed) triples), each leg
    started afresh from its own pose, one World per run (its noise stream runs on across legs).

    Returns (cost, interactions, failures): cost counts failed legs, a noise-free one
    NOISE_FREE_WEIGHT times; failures lists the last obstacle states of each failed leg. Stops
    early once cost exceeds ``limit``.
    """
    arenas = {}
    cost, steps, fails = 0, 0, []
    for name, noise, seed in runs:
        arena = arenas.get(name) or arenas.setdefault(name, load_arena(name))
        world = World(arena, noise=noise, seed=seed)
        weight = 1 if noise is not None else NOISE_FREE_WEIGHT
        course = Course.of(arena)
        for target in range(course.n_positions):  # the leg after the target-th (0: from the start)
            leg = course.position_after(target) if target else -1
            reached, n, seen = _run_leg(world, table, leg, max_leg_steps)
            steps += n
            if not reached:
                cost += weight
                fails.append(seen)
                if limit is not None and cost > limit:
                    return cost, steps, fails
    return cost, steps, fails


def tune_table(table: np.ndarray, runs, seconds: float, rng: np.random.Generator,
               max_leg_steps: int = DEFAULT_MAX_LEG_STEPS, frozen=(), motions=SEARCH_MOTIONS,
               log=print) -> np.ndarray:
    """Local search: set one non-reflex state, mostly one met near the end of a failed leg, to one
    of ``motions``; keep the change when (cost, interactions) of :func:`evaluate_legs` over
    ``runs`` does not get worse. States in ``frozen`` keep their motion. Returns the new table."""
    order = sorted(runs, key=lambda r: r[1] is not None)  # noise-free runs first: cheap rejects
    best = evaluate_legs(table, order, max_leg_steps)
    log(f"start: cost {best[0]}, {best[1]} interactions")
    t0 = time.perf_counter()
    all_states = [s for s in range(N_STATES) if s & OBSTACLE_MASK and s not in frozen]
    while all_states and time.perf_counter() - t0 < seconds:
        failed = [[s for s in f if s not in frozen] for f in best[2]]
        failed = [f for f in failed if f]
        candidates = failed[rng.integers(len(failed))] if failed and rng.random() < 0.8 else all_states
        state = candidates[rng.integers(len(candidates))]
        motion = motions[rng.integers(len(motions))]
        if table[state] == motion:
            continue
        cand = table.copy()
        cand[state] = motion
        res = evaluate_legs(cand, order, max_leg_steps, limit=best[0])
        if res[:2] <= best[:2]:
            table, best = cand, res
            log(f"{time.perf_counter() - t0:6.0f} s: cost {best[0]}, {best[1]} interactions")
    log(f"final: cost {best[0]}, {best[1]} interactions")
    return table


def revert_to_rules(table: np.ndarray, runs, max_leg_steps: int = DEFAULT_MAX_LEG_STEPS,
                    slack: float = 0.002, frozen=(), log=print) -> np.ndarray:
    """Put back the rule's motion wherever that neither adds cost nor more than ``slack`` of
    interactions (the search's neutral drift), to stay close to the hand-written rules."""
    rules = rules_table()
    best = evaluate_legs(table, runs, max_leg_steps)
    for s in np.flatnonzero(rules != table):
        if s in frozen:
            continue
        cand = table.copy()
        cand[s] = rules[s]
        res = evaluate_legs(cand, runs, max_leg_steps, limit=best[0])
        if res[0] <= best[0] and res[1] <= best[1] * (1 + slack):
            table, best = cand, res
    log(f"reverted: cost {best[0]}, {best[1]} interactions, {int((rules != table).sum())} entries off the rules")
    return table


# What the shipped table was tuned on: every leg of these runs. Seeds 100.. are never used here:
# they are the held-out check (`python -m sim_world.baseline --seeds 50 --first-seed 100`).
TUNING_RUNS = (
    [("default", None, 0), ("one_obstacle", None, 0), ("empty", None, 0)]
    + [("default", DEFAULT_NOISE, s) for s in range(60)]
    + [("one_obstacle", DEFAULT_NOISE, s) for s in range(3)]
)


def run_baseline(arena="default", noise=None, seed: int = 0, max_leg_steps: int = DEFAULT_MAX_LEG_STEPS,
                 record: bool = False):
    """Run the baseline through the course of 64 legs; returns the CourseResult."""
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


def add_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    parser.add_argument("--arena", default="default", help="arena name or .json path")
    parser.add_argument("--seeds", type=int, default=5, help="noisy runs (seeds FIRST..FIRST+N-1)")
    parser.add_argument("--first-seed", type=int, default=0, metavar="FIRST",
                        help="first noisy seed (100 and up were never tuned on)")
    parser.add_argument("--max-leg-steps", type=int, default=DEFAULT_MAX_LEG_STEPS, help="step limit of one leg")
    parser.add_argument("--out", type=Path, default=Path("results"), metavar="DIR",
                        help="folder of baseline.json and baseline_trajectory.png")
    parser.add_argument("--tune", type=float, default=0.0, metavar="SECONDS",
                        help="continue the local search from the shipped table and print the new table")
    return parser


def run_from_args(args) -> int:
    from base.files import atomic_write_json

    if args.tune:
        table = tune_table(baseline_table(), TUNING_RUNS, args.tune, np.random.default_rng(0), args.max_leg_steps,
                           frozen=FRONT_ONLY_STATES)
        table = revert_to_rules(table, TUNING_RUNS, args.max_leg_steps, frozen=FRONT_ONLY_STATES)
        print("".join(str(int(m)) for m in table))
        return 0
    args.out.mkdir(parents=True, exist_ok=True)
    report = {"arena": args.arena, "max_leg_steps": args.max_leg_steps, "noise": DEFAULT_NOISE.__dict__}
    t0 = time.perf_counter()
    clean = run_baseline(args.arena, None, 0, args.max_leg_steps, record=True)
    report["noise_free"] = _summary(clean)
    print(f"noise-free: {_summary(clean)}")
    noisy = []
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        res = run_baseline(args.arena, DEFAULT_NOISE, seed, args.max_leg_steps)
        noisy.append({"seed": seed, **_summary(res)})
        print(f"noisy seed {seed}: {noisy[-1]}")
    report["noisy"] = noisy
    full = sum(r["targets"] == N_POSITIONS for r in noisy)
    print(f"noisy: {full} of {len(noisy)} runs reach all {N_POSITIONS} targets")
    report["seconds"] = round(time.perf_counter() - t0, 2)
    atomic_write_json(args.out / "baseline.json", report, indent=2)
    from sim_world.render import plot_trajectory

    png = args.out / "baseline_trajectory.png"
    plot_trajectory(load_arena(args.arena), clean.trajectory, png,
                    title=f"reactive baseline, noise-free: {clean.targets_reached} targets, {clean.steps} interactions")
    print(f"wrote {args.out / 'baseline.json'} and {png}")
    return 0


if __name__ == "__main__":  # the module alone; ``ehw baseline`` adds the input checks and the lock
    import argparse

    raise SystemExit(run_from_args(add_arguments(argparse.ArgumentParser(prog="python -m sim_world.baseline")).parse_args()))
