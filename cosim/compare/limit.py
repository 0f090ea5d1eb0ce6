"""The limit beside the comparison (issue 40): the omniscient planner's total for the arena.

``ehw compare`` divides every method's median by it (``cosim.compare.report.add_limit``). The
plan is deterministic, so it is computed once per arena file and planner setting and kept in the
comparison's cache (``results/compare/cache/limit/``) like a lifetime.
"""

from __future__ import annotations

import hashlib
import json

from cosim.compare.sweep import Cache
from sim_world.arena import load_arena
from sim_world.course import DEFAULT_MAX_LEG_STEPS
from sim_world.limit import DEFAULT_CELL_MM, HEURISTICS, PLANNER_VERSION, plan_course


def limit_task(arena: str, cell_mm: float = DEFAULT_CELL_MM) -> dict:
    """The cache key of an arena's limit: its file's content, the planner's settings and version."""
    data = json.dumps(load_arena(arena).to_json(), sort_keys=True)
    return {"method": "limit", "seed": 0,
            "config": {"arena": arena, "arena_sha256": hashlib.sha256(data.encode()).hexdigest()[:16],
                       "cell_mm": cell_mm, "heuristic": HEURISTICS[0], "max_leg_steps": DEFAULT_MAX_LEG_STEPS,
                       "planner_version": PLANNER_VERSION}}


def course_limit(arena: str, cache: Cache, cell_mm: float = DEFAULT_CELL_MM) -> dict:
    """The limit of ``arena``'s course: {"interactions", "per_leg", "cell_mm", "seconds"} (cached)."""
    task = limit_task(arena, cell_mm)
    found = cache.get(task)
    if found is None:
        plan = plan_course(load_arena(arena), cell_mm, HEURISTICS[0], DEFAULT_MAX_LEG_STEPS)
        found = {"interactions": plan.total, "per_leg": [leg.interactions for leg in plan.legs],
                 "cell_mm": cell_mm, "seconds": round(plan.seconds, 1)}
        cache.put(task, found)
    return found
