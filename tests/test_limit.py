"""The limit (issue 40): the omniscient planner's counts, its replay in the world, and the
reactive bound's search (sim_world.limit, sim_world.reactive_limit, ``ehw limit``)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from ga.motions import Motion
from sim_world.arena import arena_from_dict, load_arena
from sim_world.baseline import baseline_table
from sim_world.limit import Geometry, StepBound, course_starts, plan_leg, plan_legs, replay_leg
from sim_world.reactive_limit import drive_leg, search_table
from sim_world.world import World

START = [300.0, 600.0, 0.0]
POST = {"name": "post", "polygon": [[460.0, 580.0], [500.0, 580.0], [500.0, 620.0], [460.0, 620.0]]}


def tiny_arena(obstacles=(), start=START):
    """1.2 m square, the ball 500 mm ahead of the start, a target radius of 150 mm."""
    return arena_from_dict({"name": "tiny", "size_mm": 1200.0, "ball": [800.0, 600.0], "ball_radius_mm": 50.0,
                            "target_radius_mm": 150.0, "start": list(start), "obstacles": list(obstacles),
                            "positions": [list(start)] * 64})


def exact_reachable(arena, start, depth: int) -> bool:
    """Can any crash-free motion sequence of at most ``depth`` motions reach the target? Breadth-
    first over the exact poses of the world itself (no cells: poses equal to 1e-6 merge), pruned by
    the straight-line bound only."""
    world, bound = World(arena), StepBound(arena, "euclid")
    frontier = {None: tuple(start)}
    for d in range(1, depth + 1):
        nxt = {}
        for pose in frontier.values():
            for m in range(8):
                world.place(pose)
                out = world.step(m)
                if out.crashed:
                    continue
                if out.reached:
                    return True
                x, y, h = world.pose
                if d + int(bound.steps(np.array([x]), np.array([y]))[0]) <= depth:
                    nxt.setdefault((round(x, 6), round(y, 6), round(h, 9)), (x, y, h))
        frontier = nxt
    return False


def test_free_space_facing_the_ball_is_straight_ahead():
    # 500 mm to the ball, reached within 150 mm: 350 mm at 50 mm a motion is 7 motions at least,
    # and seven forward motions do it; facing away, seven backward ones.
    arena = tiny_arena()
    ahead = plan_leg(arena, (300.0, 600.0, 0.0))
    assert ahead.interactions == 7
    assert ahead.motions == [Motion.FORWARD] * 7
    away = plan_leg(arena, (300.0, 600.0, math.pi))
    assert away.interactions == 7
    assert away.motions == [Motion.BACKWARD] * 7


def test_a_post_in_the_way_costs_the_shortest_detour():
    # A 40 mm post 160 mm ahead: the first forward motion crashes (35 mm of room for 50), so the
    # robot must go round it. The planner's 12 is the exact optimum: the world's own poses, searched
    # exhaustively, reach the target in 12 motions and never in 11.
    arena = tiny_arena([POST])
    world = World(arena)
    world.place(START)
    assert world.step(Motion.FORWARD).crashed
    plan = plan_leg(arena, START)
    assert plan.interactions == 12
    assert replay_leg(World(arena), START, plan.motions) == (True, "")
    assert exact_reachable(arena, START, 12)
    assert not exact_reachable(arena, START, 11)


def test_replay_catches_a_crash_and_a_miss():
    arena = tiny_arena([POST])
    ok, why = replay_leg(World(arena), START, [Motion.FORWARD] * 7)
    assert not ok and "crashes" in why
    ok, why = replay_leg(World(arena), START, [Motion.TURN_LEFT] * 3)
    assert not ok and "not reached" in why


def test_geometry_agrees_with_the_world_bumper():
    arena = load_arena("default")
    geometry, world = Geometry(arena), World(arena)
    rng = np.random.default_rng(3)
    x0, y0 = rng.uniform(100, 3900, 400), rng.uniform(100, 3900, 400)
    heading = rng.uniform(-math.pi, math.pi, 400)
    x1, y1 = x0 + 50 * np.cos(heading), y0 + 50 * np.sin(heading)
    hits = geometry.crashes(x0, y0, x1, y1)
    expected = [world.bumper_hits(*p) for p in zip(x0, y0, x1, y1)]
    assert hits.tolist() == expected
    assert 20 < sum(expected) < 380  # both kinds are tested
    clear = geometry.clearance(x0, y0)
    assert np.allclose(clear.clip(0), [arena.clearance(p) for p in zip(x0, y0)], atol=1e-9)


def test_planned_legs_replay_without_crash_and_beat_the_baseline():
    # Legs of the default arena, at a coarse cell to stay fast: every path is replayed in the world
    # (plan_legs raises on a failing one; here again by hand), and no leg needs more interactions
    # than the reactive baseline (which knows less) or fewer than the straight-line bound.
    arena = load_arena("default")
    legs = [0, 3, 9, 31]
    plans = list(plan_legs(arena, legs, cell_mm=20.0))
    world = World(arena)
    bound = StepBound(arena, "euclid")
    table = baseline_table()
    for i, plan in zip(legs, plans):
        assert plan.motions, i
        assert replay_leg(world, plan.start, plan.motions) == (True, ""), i
        base = drive_leg(world, table, course_starts(arena)[i], 500)
        assert base.reached and plan.interactions <= base.interactions, i
        x, y, _ = plan.start
        assert plan.interactions >= bound.steps(np.array([x]), np.array([y]))[0], i


def test_reactive_search_mends_the_baseline_and_stays_above_the_limit():
    # The baseline crashes into the post on every leg of the tiny arena; the search, scoring every
    # change in the exact world, finds a table that reaches the ball on all 64 legs, with the
    # reflex untouched, and no faster than the planner's 12 motions a leg.
    from ga.motions import REFLEX_TABLE

    arena = tiny_arena([POST])
    assert not drive_leg(World(arena), baseline_table(), START, 200).reached
    found = search_table(arena, 3.0, np.random.default_rng(0), max_leg_steps=200)
    assert found.failed_legs == 0
    assert found.interactions >= 64 * 12
    assert found.interactions == sum(drive_leg(World(arena), found.table, p, 200).interactions
                                     for p in course_starts(arena))
    reflex = REFLEX_TABLE >= 0
    assert np.array_equal(found.table[reflex], REFLEX_TABLE[reflex])


def test_ehw_limit_writes_the_tables(tmp_path, capsys):
    from cosim.cli.main import main

    path = tmp_path / "tiny.json"
    path.write_text(json.dumps(tiny_arena([POST]).to_json()))
    assert main(["limit", "--arena", str(path), "--cell", "20", "--refine", "--out", str(tmp_path / "run"),
                 "--quiet"]) == 0
    report = json.loads((tmp_path / "run" / "limit.json").read_text())
    tiny = report["arenas"]["tiny"]
    assert tiny["total_interactions"] == 64 * 12
    assert [leg["interactions"] for leg in tiny["per_leg"]] == [12] * 64
    assert tiny["refined"]["cell_mm"] == 10.0 and tiny["refined"]["change"] == 0
    assert (tmp_path / "run" / "limit_tiny.png").exists()
    assert "| tiny | 768 |" in capsys.readouterr().out


@pytest.mark.parametrize("argv, message", [(["--cell", "0.5"], "--cell"), (["--reactive", "-1"], "--reactive"),
                                           (["--arena", "no_such_arena"], "no arena")])
def test_ehw_limit_user_errors(argv, message, capsys, tmp_path):
    from cosim.cli.main import main

    assert main(["limit", "--out", str(tmp_path / "run"), *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error:") and message in err and "Traceback" not in err


def test_compare_shows_each_median_over_the_limit(tmp_path, monkeypatch):
    # The limit of an arena file is planned once and then read from the comparison's cache; the
    # table gets a column of median / limit and the plot a line at the limit.
    from cosim.compare import limit as compare_limit
    from cosim.compare.report import add_limit, build_report, markdown, write_plot
    from cosim.compare.sweep import Cache

    path = tmp_path / "tiny.json"
    path.write_text(json.dumps(tiny_arena([POST]).to_json()))
    cache = Cache(tmp_path / "cache")
    first = compare_limit.course_limit(str(path), cache, cell_mm=10.0)
    assert first["interactions"] == 64 * 12 and first["per_leg"] == [12] * 64

    def refuse(*args, **kwargs):
        raise AssertionError("planned again: the cache was not used")

    monkeypatch.setattr(compare_limit, "plan_course", refuse)
    assert compare_limit.course_limit(str(path), cache, cell_mm=10.0) == first
    lifetime = {"interactions": 1536, "targets_reached": 64, "crashes": 2,
                "target_interactions": list(range(24, 1537, 24))}
    report = add_limit(build_report({"baseline": {1: lifetime}}, "tiny", [1]), first)
    assert report["methods"]["baseline"]["median_over_limit"] == 2.0
    text = markdown(report)
    assert "| reactive baseline | 1/1 | 1,536 | 1,536-1,536 | 2.0 |" in text
    assert "| the limit (omniscient planner, noise-free) | yes | 768 | - | 1.0 |" in text
    write_plot(report, tmp_path / "compare.png")
    assert (tmp_path / "compare.png").stat().st_size > 10_000
