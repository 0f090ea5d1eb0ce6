"""The robot world: interactions per second, overhead against bare pymunk queries, the baseline."""

from __future__ import annotations

import math
import time

import numpy as np
import pymunk

from ga.motions import REFLEX_TABLE
from sim_world.arena import ROBOT_RADIUS_MM, load_arena
from sim_world.world import DEFAULT_NOISE, IR_SENSORS, SENSOR_REACH_MM, World

N_STEPS = 50_000
REPEATS = 3  # best of: the machine is shared, the fastest run is the least disturbed


def _controller(rng) -> list[int]:
    """A random controller with the reflex, like an individual of the off-line GA."""
    table = rng.integers(0, 8, size=256)
    return np.where(REFLEX_TABLE >= 0, REFLEX_TABLE, table).tolist()


def _drive(world: World, n: int, seed: int = 0, record: bool = False):
    """n interactions: random reflex controllers (a new one every 200 steps or at a crash),
    relocating to the next position every 200 steps so the robot sees the whole arena."""
    rng = np.random.default_rng(seed)
    poses = []
    table = _controller(rng)
    k = 0
    t0 = time.perf_counter()
    s = world.relocate(0)
    for i in range(n):
        if record:
            poses.append(world.pose)
        out = world.step(table[s])
        s = out.state
        if out.crashed or out.reached or i % 200 == 199:
            k += 1
            table = _controller(rng)
            s = world.relocate(k % 64)
    return time.perf_counter() - t0, poses


def _bare(space: pymunk.Space, poses, direct: bool = True) -> float:
    """The same pymunk work as World.step for a list of poses with nothing around it but the
    loop: one nearest-point query, the ten IR segment queries when something is in reach, and
    the bumper's capsule shape query when the robot is near something. ``direct`` calls the
    Chipmunk functions through pymunk's cffi handle (as World does); otherwise pymunk's public
    wrappers."""
    from pymunk._chipmunk import ffi, lib

    flt = pymunk.ShapeFilter()
    body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
    sweep = pymunk.Segment(body, (0, 0), (1, 0), ROBOT_RADIUS_MM)
    angles = [math.radians(a) for a, _ in IR_SENSORS]
    r0, r1 = ROBOT_RADIUS_MM, SENSOR_REACH_MM
    shq = space.shape_query
    if direct:
        cp, seg_info, pt_info = space._space, ffi.new("cpSegmentQueryInfo *"), ffi.new("cpPointQueryInfo *")
        seg_first, pt_nearest, null = lib.cpSpaceSegmentQueryFirst, lib.cpSpacePointQueryNearest, ffi.NULL

        def pq(p):
            return None if pt_nearest(cp, p, r1, flt, pt_info) == null else pt_info.distance

        def sq(a, b):
            return seg_first(cp, a, b, 0.0, flt, seg_info) != null
    else:

        def pq(p):
            info = space.point_query_nearest(p, r1, flt)
            return None if info is None else info.distance

        def sq(a, b):
            return space.segment_query_first(a, b, 0.0, flt) is not None

    t0 = time.perf_counter()
    for x, y, h in poses:
        near = pq((x, y))
        if near is not None:
            for a in angles:
                c, s = math.cos(h + a), math.sin(h + a)
                sq((x + r0 * c, y + r0 * s), (x + r1 * c, y + r1 * s))
            if near < r0 + 50.0:
                sweep.unsafe_set_endpoints((x, y), (x + 50.0 * math.cos(h), y + 50.0 * math.sin(h)))
                shq(sweep)
    return time.perf_counter() - t0


def run() -> dict:
    arena = load_arena()
    # a fresh world each time: the cache starts empty, as for one GA run of N_STEPS interactions
    t_cached = min(_drive(World(arena), N_STEPS)[0] for _ in range(REPEATS))
    cached_first = World(arena)
    _drive(cached_first, N_STEPS)
    uncached = World(arena, cache=False)
    _, poses = _drive(uncached, N_STEPS, record=True)
    t_uncached = t_bare = t_public = t_noisy = float("inf")
    for _ in range(REPEATS):  # interleaved, so that load changes hit all alike
        t_uncached = min(t_uncached, _drive(World(arena, cache=False), N_STEPS)[0])
        t_bare = min(t_bare, _bare(uncached.space, poses))
        t_public = min(t_public, _bare(uncached.space, poses, direct=False))
        t_noisy = min(t_noisy, _drive(World(arena, noise=DEFAULT_NOISE, seed=1), N_STEPS)[0])

    from sim_world.baseline import run_baseline

    clean = run_baseline("default")
    noisy_runs = [run_baseline("default", DEFAULT_NOISE, seed) for seed in range(5)]
    return {
        "world_interactions_per_s": round(N_STEPS / t_cached),
        "world_interactions_per_s_uncached": round(N_STEPS / t_uncached),
        "world_interactions_per_s_noisy": round(N_STEPS / t_noisy),
        "world_bare_pymunk_queries_per_s": round(N_STEPS / t_bare),
        "world_bare_pymunk_public_api_per_s": round(N_STEPS / t_public),
        "world_overhead_vs_bare_pymunk": round(t_uncached / t_bare, 2),
        "world_overhead_vs_bare_pymunk_cached": round(t_cached / t_bare, 2),
        "world_cache_hit_rate": round(cached_first.cache_hits / N_STEPS, 3),
        "baseline_interactions": clean.steps,
        "baseline_targets": clean.targets_reached,
        "baseline_interactions_noisy_mean": round(float(np.mean([r.steps for r in noisy_runs])), 1),
        "baseline_noisy_failures": sum(r.targets_reached < 64 for r in noisy_runs),
    }
