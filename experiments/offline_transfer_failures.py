"""Why the best off-line controller fails in the noisy world: one line per failed transfer run.

    python experiments/offline_transfer_failures.py results/model_free/summary.json [--trials 20] [--first-seed 900000]
                                                    [--max-leg-steps L] [--all-legs]

For each noise seed the best controller of the summary drives the noisy world (DEFAULT_NOISE)
through the course until its first crash or leg time-out (as `cosim.offline.run.transfer`). For the
failing step it prints: the target count, the leg's step, the state sensed (and the state a
noise-free sensor would have given at that pose: a difference is an IR false negative/positive),
the motion, and the clearance (mm from the bumper to the nearest obstacle) before the motion.
Then a tally of the failing (state, motion) pairs, the legs where runs failed, and how many
failures followed a sensing error.

``--all-legs``: a failure ends only its leg (the robot goes on to the next leg's pose, as the
noisy stage of `cosim.offline.noisy` drives), so every run tries all 64 legs and the tally counts
every failure mode of the controller, not only the first of each run; it also prints the failure
rate per leg, from which P(64 clean legs) = (1 - rate)^64 follows.
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
             noise=DEFAULT_NOISE, all_legs: bool = False) -> list[dict]:
    """One dict per noisy run (the first failure's fields); with ``all_legs`` also "failures",
    every failed leg's fields, the run going on at the next leg after each."""
    table = truth_tables(rows_from_hex(genome_hex), reflex=True)
    clean = World(load_arena(arena))
    out = []
    for i in range(trials):
        world = World(load_arena(arena), noise=noise, seed=first_seed + i)
        course = Course.of(world)
        world.reset_to_start()
        s, targets, leg, steps = world.state(), 0, 0, 0
        failures = []
        while targets + len(failures) < 64:
            if leg >= max_leg_steps:
                failures.append({"kind": "time-out", "state": s, "target_index": targets + len(failures)})
                if not all_legs:
                    break
                leg = 0
                s = course.relocate(world, targets + len(failures))
                continue
            pose = world.pose
            true_state = clean.place(pose)
            clearance = clean._nearest_query((pose[0], pose[1]), 10_000) - ROBOT_RADIUS_MM
            a = int(table[s])
            step = world.step(a)
            steps += 1
            leg += 1
            if step.crashed:
                failures.append({"kind": "crash", "state": s, "true_state": true_state, "motion": a,
                                 "clearance_mm": round(clearance, 1), "target_index": targets + len(failures),
                                 "leg_step": leg})
                if not all_legs:
                    break
            if step.crashed or step.reached:
                targets += int(not step.crashed)
                leg = 0
                if targets + len(failures) < 64:
                    course.relocate(world, targets + len(failures))
            s = world.state()
        first = {k: v for k, v in (failures[0] if failures else {"kind": "none"}).items() if k != "target_index"}
        row = {"seed": first_seed + i, "targets": targets, "steps": steps, "leg_step": leg, **first}
        if all_legs:
            row["failures"] = failures
        out.append(row)
    return out


def main(argv=None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("summary", type=Path)
    p.add_argument("--trials", type=int, default=20)
    p.add_argument("--first-seed", type=int, default=900_000)
    p.add_argument("--max-leg-steps", type=int, default=None,
                   help="the leg time-out of the noisy runs (default: the evolution's, from the summary)")
    p.add_argument("--all-legs", action="store_true",
                   help="a failure ends only its leg: tally every failure of the 64 legs of each run")
    args = p.parse_args(argv)
    summary = json.loads(args.summary.read_text())
    cfg = summary["config"]
    rows = diagnose(summary["best_genome"], cfg["arena"], args.max_leg_steps or cfg["max_leg_steps"],
                    args.trials, args.first_seed, all_legs=args.all_legs)
    for r in rows:
        print(json.dumps({k: v for k, v in r.items() if k != "failures"}))
    if args.all_legs:
        every = [f for r in rows for f in r["failures"]]
        rate = len(every) / (64 * len(rows))
        print(f"all legs: {len(every)} failed legs of {64 * len(rows)} (rate {rate:.4f} a leg, "
              f"(1 - rate)^64 = {(1 - rate) ** 64:.3f}); runs with no failed leg: "
              f"{sum(not r['failures'] for r in rows)} of {len(rows)}")
        print("  every failure (kind, state, motion):",
              Counter((f["kind"], f["state"], f.get("motion")) for f in every).most_common(12))
        print("  every failure, leg index:", Counter(f["target_index"] for f in every).most_common(12))
        crashes = [f for f in every if f["kind"] == "crash"]
        print(f"  crashes after a sensing error: {sum(f['state'] != f['true_state'] for f in crashes)} of "
              f"{len(crashes)}; clearance before the crash (mm): "
              f"{sorted(f['clearance_mm'] for f in crashes)}")
    fails = [r for r in rows if r["kind"] != "none"]
    print(f"reached 64: {sum(r['kind'] == 'none' for r in rows)} of {len(rows)}")
    print("failing (kind, state, motion):", Counter((r["kind"], r["state"], r.get("motion")) for r in fails).most_common(8))
    print("failing target index:", Counter(r["targets"] for r in fails).most_common(8))
    crashes = [r for r in fails if r["kind"] == "crash"]
    print(f"crashes after a sensing error: {sum(r['state'] != r['true_state'] for r in crashes)} of {len(crashes)}")


if __name__ == "__main__":
    main()
