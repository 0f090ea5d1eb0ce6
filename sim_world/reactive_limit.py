"""The second bound of issue 40: the best controller that sees only the 8 sensor bits.

A controller of the paper's kind is a fixed mapping from the 256 world states to the 8 motions
(the reflex in the four obstacle-free states, SPEC section 6, unless ``reflex=False``). This
module searches for the one that needs the fewest interactions on the course, with full knowledge
of the world: every candidate is scored by driving it through the course's legs in the exact,
noise-free world (each leg from its own start pose, a leg time-out of ``max_leg_steps``).

The search is a seeded local search started from the hand-written baseline
(``sim_world.baseline``): change the motion of one visited state to another motion, and keep the
change when it does not raise the cost (hill climbing with neutral moves), or, with
``temperature`` T0 > 0, by simulated annealing (a change that raises the cost by D is kept with
probability exp(-D / T), T falling linearly from T0 to 0 over the budget; the best table seen is
returned). A leg's cost is its interactions when it reaches the target, else the time-out plus
its final distance to the ball in steps (so a failing leg still tells which change brings the
robot closer, as the distance term of the paper's fitness does). Scoring is exact and fast because
the world is deterministic: a state's motion matters only to the legs that visit that state, so
a change re-drives only those legs (the others keep their count). What it finds is an upper
bound on the best such controller (a local search proves no optimum); the omniscient planner
(``sim_world.limit``) is the bound below every controller.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ga.motions import N_MOTIONS, N_STATES, REFLEX_TABLE, STEP_MM
from sim_world.arena import Arena, Pose
from sim_world.baseline import baseline_table
from sim_world.course import DEFAULT_MAX_LEG_STEPS
from sim_world.limit import course_starts
from sim_world.world import World


@dataclass
class _Leg:
    reached: bool
    interactions: int
    visited: frozenset  # the states whose motion was executed on the leg
    cost: float  # interactions when reached; else the time-out plus the distance left, in steps


def drive_leg(world: World, table, start: Pose, max_leg_steps: int) -> _Leg:
    """One leg of ``table`` (256 motions) from ``start``, until the target, a crash or the time-out."""
    s = world.place(start)
    visited = set()
    n = 0
    while n < max_leg_steps:
        n += 1
        visited.add(s)
        out = world.step(int(table[s]))
        if out.reached:
            return _Leg(True, n, frozenset(visited), float(n))
        if out.crashed:
            break
        s = out.state
    return _Leg(False, n, frozenset(visited), max_leg_steps + world.target_distance() / STEP_MM)


@dataclass
class TableSearch:
    """The best table found, its score and how it was found."""

    table: np.ndarray
    failed_legs: int
    interactions: int  # every leg's interactions (a failed leg counts its time-out or crash step)
    leg_interactions: list[int]
    evaluations: int  # candidate changes scored
    accepted: int
    seconds: float
    interrupted: bool = False

    @property
    def table_text(self) -> str:
        return "".join(str(int(m)) for m in self.table)

    def to_json(self) -> dict:
        return {"failed_legs": self.failed_legs, "interactions": self.interactions,
                "per_leg": self.leg_interactions, "evaluations": self.evaluations, "accepted": self.accepted,
                "seconds": round(self.seconds, 1), "interrupted": self.interrupted, "table": self.table_text}


def search_table(arena: Arena, seconds: float, rng: np.random.Generator, table=None, reflex: bool = True,
                 max_leg_steps: int = DEFAULT_MAX_LEG_STEPS, temperature: float = 0.0,
                 progress=None) -> TableSearch:
    """Local search for the table with the fewest (failed legs, interactions) on ``arena``'s course.

    ``table``: the start (default: the baseline); ``reflex``: keep the reflex states fixed;
    ``temperature``: see the module docstring (0: hill climbing).
    ``progress(elapsed_s, failed, interactions)`` is called after each new best table. Ctrl-C
    ends the search early with the best table so far (``interrupted``).
    """
    world = World(arena)
    starts = course_starts(arena)
    table = np.array(baseline_table() if table is None else table, dtype=np.uint8)
    if table.shape != (N_STATES,):
        raise ValueError(f"a table holds {N_STATES} motions, got shape {table.shape}")
    frozen = REFLEX_TABLE >= 0 if reflex else np.zeros(N_STATES, dtype=bool)
    legs = [drive_leg(world, table, p, max_leg_steps) for p in starts]
    cost = sum(leg.cost for leg in legs)
    best = (cost, table, list(legs))
    t0 = time.perf_counter()
    evaluations = accepted = 0
    interrupted = False
    try:
        while time.perf_counter() - t0 < seconds:
            # Only a state some leg visits can change a count.
            visited = sorted({s for leg in legs for s in leg.visited if not frozen[s]})
            if not visited:
                break
            state = visited[rng.integers(len(visited))]
            motion = int(rng.integers(N_MOTIONS - 1))
            motion += motion >= table[state]  # any motion but the current one
            cand = table.copy()
            cand[state] = motion
            evaluations += 1
            heat = temperature * max(0.0, 1.0 - (time.perf_counter() - t0) / seconds)
            # the worst cost change still kept (for the annealing: drawn before the legs are driven)
            room = -heat * np.log(1.0 - rng.random()) if heat > 0 else 0.0
            affected = [i for i, leg in enumerate(legs) if state in leg.visited]
            gain_left = sum(legs[i].cost - 1 for i in affected)  # a leg costs at least 1 motion
            new_cost, redone = cost, {}
            for i in affected:
                redone[i] = drive_leg(world, cand, starts[i], max_leg_steps)
                new_cost += redone[i].cost - legs[i].cost
                gain_left -= legs[i].cost - 1
                if new_cost - gain_left - cost > room + 1e-9:
                    break  # even the best outcome of the legs left would not keep the change
            if new_cost - cost <= room + 1e-9:
                table, cost = cand, new_cost
                for i, leg in redone.items():
                    legs[i] = leg
                accepted += 1
                if cost < best[0] - 1e-9:
                    best = (cost, table, list(legs))
                    if progress is not None:
                        progress(time.perf_counter() - t0, sum(not leg.reached for leg in legs),
                                 sum(leg.interactions for leg in legs))
    except KeyboardInterrupt:
        interrupted = True
    _, table, legs = best
    return TableSearch(table, sum(not leg.reached for leg in legs), sum(leg.interactions for leg in legs),
                       [leg.interactions for leg in legs], evaluations, accepted, time.perf_counter() - t0, interrupted)
