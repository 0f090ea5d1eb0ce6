"""Arena files: the shipped arenas load, and every validation error names the offending item."""

from __future__ import annotations

import copy
import json
import math

import pytest

from sim_world.arena import (
    ARENA_DIR,
    ARENAS,
    N_POSITIONS,
    ROBOT_RADIUS_MM,
    ArenaError,
    arena_from_dict,
    load_arena,
    save_arena,
)


@pytest.fixture
def empty_data() -> dict:
    return json.loads((ARENA_DIR / "empty.json").read_text())


def test_shipped_arenas_load():
    assert {"default", "one_obstacle", "empty"} <= set(ARENAS)
    for name in ARENAS:
        arena = load_arena(name)
        assert len(arena.positions) == N_POSITIONS
        assert arena.name == name


def test_default_arena_layout():
    """SPEC section 5: ~4 m square, 9 convex obstacles of different shapes, ball at the centre,
    start upper-left, obstacles far enough apart for the 25 cm robot to pass comfortably."""
    arena = load_arena()
    assert arena.size_mm == 4000
    assert arena.ball == (2000, 2000)
    assert len(arena.obstacles) == 9
    assert len({ob.name for ob in arena.obstacles}) == 9
    x, y, _ = arena.start
    assert x < arena.size_mm / 4 and y > 3 * arena.size_mm / 4
    for i, a in enumerate(arena.obstacles):
        x0, y0, x1, y1 = a.bounds()
        assert min(x0, y0, arena.size_mm - x1, arena.size_mm - y1) >= 590, a.name
        assert a.min_vertex_angle_deg() >= 89.9, a.name
        for b in arena.obstacles[i + 1 :]:
            assert a.distance_to(b) >= 2.35 * 2 * ROBOT_RADIUS_MM, (a.name, b.name)  # >= 587 mm


def test_positions_spread_over_the_arena():
    arena = load_arena()
    xs = [p[0] for p in arena.positions]
    ys = [p[1] for p in arena.positions]
    # every quadrant holds a fair share of the 64 poses
    for qx in (0, 1):
        for qy in (0, 1):
            n = sum((x >= 2000) == qx and (y >= 2000) == qy for x, y in zip(xs, ys))
            assert 10 <= n <= 22, (qx, qy, n)
    # the first legs are easier (closer) than the last ones
    d = [((x - 2000) ** 2 + (y - 2000) ** 2) ** 0.5 for x, y in zip(xs, ys)]
    assert sum(d[:16]) < sum(d[-16:])


def test_round_trip(tmp_path):
    arena = load_arena()
    path = tmp_path / "copy.json"
    save_arena(arena, path)
    again = load_arena(path)
    assert again.obstacles == arena.obstacles
    assert [v for p in again.positions for v in p] == pytest.approx([v for p in arena.positions for v in p])


def _with(data: dict, **changes) -> dict:
    data = copy.deepcopy(data)
    data.update(changes)
    return data


BOX = {"name": "box", "polygon": [[1000, 1000], [1400, 1000], [1400, 1400], [1000, 1400]]}


@pytest.mark.parametrize(
    "mutate, message",
    [
        (lambda d: _with(d, obstacles=[BOX, {"name": "disc", "circle": [1450, 1200], "radius": 100}]), "'box' and 'disc' overlap"),
        (lambda d: _with(d, obstacles=[BOX, dict(BOX, name="box2", polygon=[[1300, 1300], [1700, 1300], [1700, 1700], [1300, 1700]])]), "overlap"),
        (lambda d: _with(d, obstacles=[{"name": "on_ball", "circle": [2100, 2000], "radius": 50}]), "overlaps the ball"),
        (lambda d: _with(d, obstacles=[{"name": "outside", "polygon": [[3900, 100], [4100, 100], [4100, 300], [3900, 300]]}]), "'outside'"),
        (lambda d: _with(d, obstacles=[{"name": "bent", "polygon": [[1000, 1000], [1400, 1000], [1200, 1100], [1400, 1400], [1000, 1400]]}]), "not convex"),
        (lambda d: _with(d, obstacles=[{"name": "flat", "polygon": [[0, 0], [1, 1], [2, 2]]}]), "no area"),
        (lambda d: _with(d, obstacles=[{"name": "neg", "circle": [1000, 1000], "radius": -1}]), "radius must be positive"),
        (lambda d: _with(d, obstacles=[{"name": "what"}]), "needs 'polygon' or 'circle'"),
        (lambda d: _with(d, obstacles=[BOX, dict(BOX, polygon=[[3000, 3000], [3100, 3000], [3100, 3100]])]), "used 2 times"),
        (lambda d: _with(d, obstacles=[BOX], positions=[[1200, 1200, 0]] + d["positions"][1:]), "position 0 at (1200, 1200) is inside obstacle 'box'"),
        (lambda d: _with(d, obstacles=[BOX], positions=d["positions"][:5] + [[1500, 1200, 0]] + d["positions"][6:]), "position 5 at (1500, 1200) is 100 mm from obstacle 'box'"),
        (lambda d: _with(d, positions=d["positions"][:63]), "exactly 64 relocation positions, got 63"),
        (lambda d: _with(d, positions=d["positions"] + [[1000, 1000, 0]]), "got 65"),
        (lambda d: _with(d, positions=d["positions"][:7] + [[100, 2000, 0]] + d["positions"][8:]), "position 7 at (100, 2000) is outside the arena or closer"),
        (lambda d: _with(d, start=[3950, 3950, 0]), "start at (3950, 3950)"),
        (lambda d: _with(d, start=[1, 2]), "start must be [x, y, heading_deg]"),
        (lambda d: _with(d, ball=[5000, 2000]), "ball at"),
        (lambda d: _with(d, size_mm="big"), "size_mm must be a finite number"),
        (lambda d: {k: v for k, v in d.items() if k != "positions"}, "lacks the key 'positions'"),
    ],
)
def test_validation_errors(empty_data, mutate, message):
    with pytest.raises(ArenaError) as info:
        arena_from_dict(mutate(empty_data))
    assert message in str(info.value)


def test_unknown_arena_name():
    with pytest.raises(ArenaError, match="no arena 'nowhere'"):
        load_arena("nowhere")


def test_bad_json(tmp_path):
    path = tmp_path / "bad.json"
    path.write_text("{not json")
    with pytest.raises(ArenaError, match="not valid JSON"):
        load_arena(path)


# -- issue 15: arena files that made results meaningless are refused ------------------------------

STAR = [[2000 + 400 * math.cos(math.radians(90 + 144 * k)), 1000 + 400 * math.sin(math.radians(90 + 144 * k))]
        for k in range(5)]  # a pentagram: turns one way at every vertex, goes round twice


def _walled_ball(d: dict, lo=1650, hi=2350) -> dict:
    """Four bars boxing the ball in (gaps of 60 mm at the corners: too narrow for the robot)."""
    t = 60  # a box round the ball, walls 60 mm thick
    bars = [[[lo, lo], [hi, lo], [hi, lo + t], [lo, lo + t]],
            [[lo, hi - t], [hi, hi - t], [hi, hi], [lo, hi]],
            [[lo, lo + 2 * t], [lo + t, lo + 2 * t], [lo + t, hi - 2 * t], [lo, hi - 2 * t]],
            [[hi - t, lo + 2 * t], [hi, lo + 2 * t], [hi, hi - 2 * t], [hi - t, hi - 2 * t]]]
    return _with(d, obstacles=[{"name": f"bar{i}", "polygon": b} for i, b in enumerate(bars)])


@pytest.mark.parametrize(
    "mutate, message",
    [
        (lambda d: _with(d, target_radius_mm=3000), "target_radius_mm 3000 covers half"),
        (lambda d: _with(d, target_radius_mm=1500), "within the target radius"),  # 64 targets in 64 steps
        (lambda d: _with(d, ball_radius_mm=-100), "ball_radius_mm must be positive"),
        (lambda d: _with(d, ball_radius_mm=0), "ball_radius_mm must be positive"),
        (lambda d: _with(d, size_mm=1e9), "size_mm must exceed"),
        (lambda d: _with(d, obstacles=[{"name": "bowtie", "polygon": [[1000, 1000], [1400, 1400], [1400, 1000], [1000, 1400]]}]),
         "'bowtie'"),
        (lambda d: _with(d, obstacles=[{"name": "star", "polygon": STAR}]), "'star'"),
        (lambda d: _with(d, obstacles=[{"name": "twice", "polygon": [[1000, 1000], [1400, 1000], [1400, 1400], [1400, 1000]]}]),
         "not simple"),
        (_walled_ball, "start at (350, 3650) cannot reach the ball"),
        (lambda d: _walled_ball(d, 1835, 2165), "the ball at (2000, 2000) cannot be reached"),  # no room
    ],
)
def test_meaningless_arenas_are_refused(empty_data, mutate, message):
    with pytest.raises(ArenaError) as info:
        arena_from_dict(mutate(empty_data))
    assert message in str(info.value)


def test_a_position_walled_off_from_the_ball_is_refused(empty_data):
    # A closed room round position 2 (the one farthest from the others; the ball stays reachable).
    x, y, _ = empty_data["positions"][2]
    room = [[[x - 280, y - 280], [x + 280, y - 280], [x + 280, y - 220], [x - 280, y - 220]],
            [[x - 280, y + 220], [x + 280, y + 220], [x + 280, y + 280], [x - 280, y + 280]],
            [[x - 280, y - 200], [x - 220, y - 200], [x - 220, y + 200], [x - 280, y + 200]],
            [[x + 220, y - 200], [x + 280, y - 200], [x + 280, y + 200], [x + 220, y + 200]]]
    data = _with(empty_data, obstacles=[{"name": f"wall{i}", "polygon": b} for i, b in enumerate(room)])
    with pytest.raises(ArenaError, match=r"position 2 at \(2550, 1500\) cannot reach the ball"):
        arena_from_dict(data)
    # The same room with a door the robot fits through (280 mm) is fine.
    room[3] = [[x + 220, y - 200], [x + 280, y - 200], [x + 280, y - 60], [x + 220, y - 60]]
    arena_from_dict(_with(empty_data, obstacles=[{"name": f"wall{i}", "polygon": b} for i, b in enumerate(room)]))


def test_the_shipped_arenas_pass_the_reachability_check():
    from sim_world.arena import _reachable_grid

    for name in ARENAS:
        xs, reached = _reachable_grid(load_arena(name))
        assert 0.3 < reached.mean() < 1.0, name  # most of the floor, never the walls' margins
