"""One robot lifetime of a tabular learner under the paper's protocol (the on-line method's).

* **World**: ``sim_world.world.World`` at ``DEFAULT_NOISE`` (the "real" world of the on-line
  run), the same arena, noise seeded as the on-line run seeds it (``seeds``: the first child of
  ``SeedSequence(seed)`` for the world, the second for the learner's ``numpy`` Generator).
* **Course**: the robot starts at the arena's start pose; after the k-th target it is relocated
  to the next position of the course (``sim_world.course.Course``), as in the on-line run.
* **Reflex** (SPEC section 6, the paper's bias, for every method): in the four obstacle-free
  states the reflex motion is taken; the learner is not asked there, and those states allow only
  that motion in its table (their value is the reflex motion's).
* **Counting**: every motion executed is one interaction, exploration included; a crash restores
  the pose (the world's bumper) and the lifetime goes on; the lifetime stops at ``n_targets``
  (64) targets or at ``max_interactions`` (100,000, the on-line run's cap).
* **Learning**: one ``observe`` per interaction; reaching the target ends the task for the
  backup (``done``: the relocation is not the action's doing).

Rewards (the constants are the Gymnasium env's, ``sim_world.gym_env``, one source for both):

* ``unshaped``: ``TARGET_REWARD`` (+10) on reaching the target, ``CRASH_REWARD`` (-5) on a
  crash, minus ``STEP_COST`` (0.01) on every interaction. It uses only what the robot senses
  (its bumper, its target camera at the target) and the interaction count.
* ``shaped``: the same plus ``PROGRESS_SCALE`` (10 per metre) times the progress towards the ball
  in this step, measured by the camera's range estimate (``Step.range_mm``, SPEC section 4: the
  true range within about 10 %, in 10 mm steps), the same signal the on-line method learns its
  progress from; never the simulator's exact distance. It is the Gymnasium env's own reward.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from ga.motions import N_MOTIONS, N_STATES, REFLEX_TABLE
from peers.tabular import LearnerConfig, make_learner, tuned_config
from sim_world.arena import N_POSITIONS
from sim_world.course import Course
from sim_world.gym_env import CRASH_REWARD, PROGRESS_SCALE, STEP_COST, TARGET_REWARD
from sim_world.world import DEFAULT_NOISE, World

SHAPINGS = ("shaped", "unshaped")
MAX_INTERACTIONS = 100_000  # as the on-line run's cap (OnlineConfig.max_interactions)


def seeds(seed: int) -> tuple[int, np.random.Generator]:
    """The world's noise seed and the learner's generator for run ``seed``: the on-line run's
    scheme (``cosim.online.run``: ``SeedSequence(seed).spawn(2)``, world first), so the world of
    seed k draws its noise from the same stream in every method."""
    world_seq, learner_seq = np.random.SeedSequence(seed).spawn(2)
    return int(world_seq.generate_state(1)[0]), np.random.default_rng(learner_seq)


def allowed_actions(reflex: bool = True) -> list[list[int]]:
    """Per world state the motions a learner may choose: the reflex motion alone in the four
    obstacle-free states (with ``reflex``), all eight elsewhere."""
    every = list(range(N_MOTIONS))
    return [[int(REFLEX_TABLE[s])] if reflex and REFLEX_TABLE[s] >= 0 else every for s in range(N_STATES)]


def run_lifetime(method: str, seed: int, *, shaping: str = "shaped", config: LearnerConfig | None = None,
                 arena: str = "default", n_targets: int = N_POSITIONS,
                 max_interactions: int = MAX_INTERACTIONS, reflex: bool = True) -> dict:
    """One lifetime of the tabular learner ``method`` (``peers.tabular.LEARNERS``); the figures
    as a dict (interactions, targets_reached, crashes, the interactions at each target, ...)."""
    if shaping not in SHAPINGS:
        raise ValueError(f"shaping must be one of {SHAPINGS}, got {shaping!r}")
    if max_interactions < 1:
        raise ValueError(f"max_interactions must be >= 1, got {max_interactions!r}")
    config = config or tuned_config(method, shaping)
    cpu0 = time.process_time()
    world_seed, rng = seeds(seed)
    world = World(arena, noise=DEFAULT_NOISE, seed=world_seed)
    course = Course.of(world)
    learner = make_learner(method, allowed_actions(reflex), config, rng)
    shaped = shaping == "shaped"
    progress_per_mm = PROGRESS_SCALE / 1000.0
    act, observe, step = learner.act, learner.observe, world.step
    s = world.reset_to_start()
    d = world.camera_range()  # the camera's estimate, never the exact distance
    targets = crashes = interactions = 0
    at_target: list[int] = []  # interactions when each target was reached
    states = {s}
    pairs: set[tuple[int, int]] = set()
    while targets < n_targets and interactions < max_interactions:
        a = act(s)
        out = step(a)
        interactions += 1
        pairs.add((s, a))
        states.add(out.state)
        if out.crashed:
            crashes += 1
            r = CRASH_REWARD - STEP_COST
        elif out.reached:
            r = TARGET_REWARD - STEP_COST
        else:
            r = -STEP_COST + (progress_per_mm * (d - out.range_mm) if shaped else 0.0)
        observe(s, a, r, out.state, out.reached)
        if out.reached:
            targets += 1
            at_target.append(interactions)
            s = course.relocate(world, targets) if targets < n_targets else out.state
            states.add(s)
            d = world.camera_range()
        else:
            s, d = out.state, out.range_mm
    return {
        "method": f"{method}/{shaping}",
        "seed": int(seed),
        "interactions": interactions,
        "targets_reached": targets,
        "crashes": crashes,
        "world_states": len(states),
        "transitions": len(pairs),  # distinct (state, motion) pairs met, as the GA methods count
        "model_updates": learner.updates,  # Q-value updates, real and planned (planning is free)
        "target_interactions": at_target,
        "config": {"learner": dataclasses.asdict(config), "shaping": shaping, "reflex": reflex, "arena": arena, "n_targets": n_targets,
                   "max_interactions": max_interactions},
        "cpu_s": round(time.process_time() - cpu0, 3),
    }
