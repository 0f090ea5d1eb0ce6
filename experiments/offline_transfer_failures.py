"""Why the best off-line controller fails in the noisy world: one line per failed transfer run.

    python experiments/offline_transfer_failures.py results/model_free/summary.json [--trials 20] [--first-seed 900000]

For each noise seed the best controller of the summary drives the noisy world (DEFAULT_NOISE)
through the course until its first crash or leg time-out (as `cosim.offline.transfer`). For the
failing step it prints: the target count, the leg's step, the state sensed (and the state a
noise-free sensor would have given at that pose: a difference is an IR false negative/positive),
the motion, and the clearance (mm from the bumper to the nearest obstacle) before the motion.
Then a tally of the failing (state, motion) pairs, the legs where runs failed, and how many
failures followed a sensing error.
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path

from ga.genome import rows_from_hex
from ga.truth_table import truth_tables
from sim_world.arena import load_arena
from sim_world.course import Course
from sim_world.world import DEFAULT_NOISE, ROBOT_RADIUS_MM, World


def diagnose(genome_hex: str, arena: str, max_leg_steps: int, trials: int, first_seed: int,
             noise=DEFAULT_NOISE) -> list[dict]:
    table = truth_tables(rows_from_hex(genome_hex), reflex=True)
    clean = World(load_arena(arena))
    out = []
    for i in range(trials):
        world = World(load_arena(arena), noise=noise, seed=first_seed + i)
        course = Course.of(world)
        world.reset_to_start()
        s, targets, leg, steps = world.state(), 0, 0, 0
        failure = None
        while targets < 64:
            if leg >= max_leg_steps:
                failure = {"kind": "time-out", "state": s}
                break
            pose = world.pose
            true_state = clean.place(pose)
            clearance = clean._nearest_query((pose[0], pose[1]), 10_000) - ROBOT_RADIUS_MM
            a = int(table[s])
            step = world.step(a)
            steps += 1
            leg += 1
            if step.crashed:
                failure = {"kind": "crash", "state": s, "true_state": true_state, "motion": a,
                           "clearance_mm": round(clearance, 1)}
                break
            if step.reached:
                targets += 1
                leg = 0
                if targets < 64:
                    course.relocate(world, targets)
            s = world.state()
        out.append({"seed": first_seed + i, "targets": targets, "steps": steps, "leg_step": leg,
                    **(failure or {"kind": "none"})})
    return out


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("summary", type=Path)
    p.add_argument("--trials", type=int, default=20)
    p.add_argument("--first-seed", type=int, default=900_000)
    p.add_argument("--max-leg-steps", type=int, default=None,
                   help="the leg time-out of the noisy runs (default: the evolution's, from the summary)")
    args = p.parse_args(argv)
    summary = json.loads(args.summary.read_text())
    cfg = summary["config"]
    rows = diagnose(summary["best_genome"], cfg["arena"], args.max_leg_steps or cfg["max_leg_steps"],
                    args.trials, args.first_seed)
    for r in rows:
        print(json.dumps(r))
    fails = [r for r in rows if r["kind"] != "none"]
    print(f"reached 64: {sum(r['kind'] == 'none' for r in rows)} of {len(rows)}")
    print("failing (kind, state, motion):", Counter((r["kind"], r["state"], r.get("motion")) for r in fails).most_common(8))
    print("failing target index:", Counter(r["targets"] for r in fails).most_common(8))
    crashes = [r for r in fails if r["kind"] == "crash"]
    print(f"crashes after a sensing error: {sum(r['state'] != r['true_state'] for r in crashes)} of {len(crashes)}")


if __name__ == "__main__":
    main()
