"""The pymunk world: sensor bits at hand-placed poses, motions, the bumper, noise, faults, determinism,
and the reflex no-deadlock property (SPEC section 11)."""

from __future__ import annotations

import math

import numpy as np
import pymunk
import pytest

from ga.motions import (
    MOTION_ROTATION_DEG,
    MOTION_TRANSLATION_MM,
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
    make_state,
)
from sim_world.arena import ROBOT_RADIUS_MM, load_arena
from sim_world.world import DEFAULT_NOISE, SENSOR_REACH_MM, Fault, Noise, World

PI = math.pi


@pytest.fixture(scope="module")
def empty():
    return load_arena("empty")


def bits(*names: int) -> int:
    return sum(1 << b for b in names)


@pytest.mark.parametrize(
    "pose, expected",
    [
        # In the middle of nowhere: no obstacle; the ball (2000, 2000) in each sector in turn.
        ((1000, 2000, 0.0), make_state(0, Sector.FRONT)),
        ((1000, 2000, PI / 2), make_state(0, Sector.RIGHT)),
        ((1000, 2000, -PI / 2), make_state(0, Sector.LEFT)),
        ((1000, 2000, PI), make_state(0, Sector.BACK)),
        # The left wall 300 mm ahead (175 mm from the rim): the three front rays see it; the
        # +-55 rays reach it only 523 mm from the centre, beyond their 425 mm. Ball behind.
        ((300, 2000, PI), make_state(bits(X_FRONT), Sector.BACK)),
        # The right wall 350 mm behind: only the 180-degree ray (the 135s need 495 mm).
        ((3650, 2000, PI), make_state(bits(X_BACK), Sector.FRONT)),
        # The bottom wall 300 mm to the right of a robot heading +x: -90, -135 (x4) and -55 (x2).
        ((2000, 300, 0.0), make_state(bits(X_RIGHT, X_FRONT_RIGHT), Sector.LEFT)),
        # The top wall on the left of a robot heading +x: +90, +135 (x3) and +55 (x1).
        ((2000, 3700, 0.0), make_state(bits(X_LEFT, X_FRONT_LEFT), Sector.RIGHT)),
    ],
)
def test_sensor_bits_at_hand_placed_poses(empty, pose, expected):
    world = World(empty)
    assert world.place(pose) == expected
    assert world.state() == expected


def test_obstacle_seen_and_not_seen():
    """A box in one_obstacle: seen by the front rays just within range, not just beyond it."""
    arena = load_arena("one_obstacle")
    world = World(arena)
    box = arena.obstacles[0]
    # the box's lowest vertex; approach it from straight below, heading up
    vx, vy = min(box.vertices, key=lambda v: v[1])
    world.place((vx, vy - SENSOR_REACH_MM + 5, PI / 2))
    assert world.state() & OBSTACLE_MASK == bits(X_FRONT)
    world.place((vx, vy - SENSOR_REACH_MM - 5, PI / 2))
    assert world.state() & OBSTACLE_MASK == 0


@pytest.mark.parametrize("motion", list(Motion))
def test_each_motion_effect(empty, motion):
    world = World(empty)
    x0, y0, h0 = 2000.0, 1000.0, 0.3
    world.place((x0, y0, h0))
    out = world.step(motion)
    t = float(MOTION_TRANSLATION_MM[motion])
    r = math.radians(float(MOTION_ROTATION_DEG[motion]))
    # the midpoint rule: half the turn, the translation, the other half
    hm = h0 + r / 2
    x, y, h = world.pose
    assert not out.crashed
    assert x == pytest.approx(x0 + t * math.cos(hm))
    assert y == pytest.approx(y0 + t * math.sin(hm))
    assert h == pytest.approx(h0 + r)
    assert world.interactions == 1
    assert out.distance_mm == pytest.approx(math.hypot(2000 - x, 2000 - y))
    assert out.state == world.state()


def test_crash_restores_pose(empty):
    world = World(empty)
    # 160 mm from the left wall facing it: 35 mm between rim and wall, a 50 mm step hits.
    world.place((160.0, 2000.0, PI))
    before = world.pose
    out = world.step(Motion.FORWARD)
    assert out.crashed and world.pose == before and world.crashes == 1
    # backing into it crashes too; turning in place never does
    world.place((160.0, 2000.0, 0.0))
    assert world.step(Motion.BACKWARD).crashed
    for m in (Motion.TURN_LEFT, Motion.TURN_RIGHT):
        assert not world.step(m).crashed
    # 200 mm away: 75 mm of room, the step fits
    world.place((200.0, 2000.0, PI))
    out = world.step(Motion.FORWARD)
    assert not out.crashed and world.pose[0] == pytest.approx(150.0)


def test_robot_touching_a_wall_can_leave_it(empty):
    world = World(empty)
    world.place((ROBOT_RADIUS_MM, 2000.0, 0.0))
    assert not world.step(Motion.FORWARD).crashed
    world.place((ROBOT_RADIUS_MM, 2000.0, PI))
    assert world.step(Motion.FORWARD).crashed


def test_bumper_catches_a_corner_between_start_and_end():
    """The swept disc: a thin obstacle crossed by the motion but clear of both end poses."""
    arena = load_arena("empty")
    world = World(arena)
    post = pymunk.Segment(world.space.static_body, (1000, 1123.5), (1000, 1500), 0)
    world.space.add(post)
    world.place((975.0, 1000.0, 0.0))  # from x 975 to 1025: the disc passes under the post's end
    assert world.step(Motion.FORWARD).crashed


def test_target_reached(empty):
    world = World(empty)
    world.place((2000.0, 2000.0 - 240.0, PI / 2))
    out = world.step(Motion.FORWARD)
    assert out.reached and out.distance_mm == pytest.approx(190.0)
    assert world.target_reached()


def test_determinism_same_seed_same_trajectory():
    rng = np.random.default_rng(3)
    motions = rng.integers(0, 8, size=400).tolist()

    def trajectory(seed):
        world = World(load_arena(), noise=DEFAULT_NOISE, seed=seed)
        out = []
        for m in motions:
            s = world.step(m)
            out.append((world.pose, s))
        return out

    assert trajectory(11) == trajectory(11)
    assert trajectory(11) != trajectory(12)


def test_noise_free_by_default_is_exact():
    w1, w2 = World(load_arena()), World(load_arena(), seed=5)
    for m in [0, 0, 2, 0, 5, 5, 1, 7]:
        assert w1.step(m) == w2.step(m)
    assert w1.pose == w2.pose


def test_motor_noise(empty):
    world = World(empty, noise=Noise(translation_sd=0.1, rotation_sd_deg=3.0), seed=1)
    dists, turns = [], []
    for _ in range(300):
        world.place((2000.0, 1000.0, 0.0))
        world.step(Motion.FORWARD)
        x, y, h = world.pose
        dists.append(math.hypot(x - 2000, y - 1000))
        turns.append(math.degrees(h))
    assert np.mean(dists) == pytest.approx(50, abs=1.5)
    assert np.std(dists) == pytest.approx(5, rel=0.25)
    assert np.std(turns) == pytest.approx(3, rel=0.25)


def test_ir_false_positives_and_negatives(empty):
    always_on = World(empty, noise=Noise(ir_false_positive=1.0), seed=0)
    always_on.place((2000.0, 2000.0 - 500, PI / 2))
    assert always_on.state() & OBSTACLE_MASK == OBSTACLE_MASK
    blind = World(empty, noise=Noise(ir_false_negative=1.0), seed=0)
    blind.place((300.0, 2000.0, PI))  # wall ahead, but every sensor fails
    assert blind.state() & OBSTACLE_MASK == 0
    some = World(empty, noise=Noise(ir_false_negative=0.3), seed=0)
    seen = []
    for _ in range(400):
        some.place((300.0, 2000.0, PI))  # three front rays see the wall
        seen.append(some.state() & 1)
    # the front bit is lost only when all three rays fail: 0.3 ** 3 = 2.7 %
    assert 0.95 < np.mean(seen) < 0.995


def test_fault_blinds_a_bit_from_a_given_step(empty):
    world = World(empty, faults=[Fault(at_step=3, bit=X_FRONT)])
    world.place((450.0, 2000.0, PI))  # facing the left wall
    seen = []
    for _ in range(6):
        s = world.step(Motion.FORWARD)
        seen.append(s.state & 1)
    # after steps 1, 2 the wall is 400, 350 mm from the centre (seen); from the 3rd interaction
    # on the bit reads 0
    assert seen == [1, 1, 0, 0, 0, 0]
    stuck = World(empty, faults=[Fault(at_step=0, bit=X_BACK, value=1)])
    assert stuck.place((2000.0, 2000.0, 0.0)) & OBSTACLE_MASK == bits(X_BACK)
    with pytest.raises(ValueError, match="IR bit"):
        Fault(at_step=0, bit=6)


def test_rejects_bad_motion(empty):
    with pytest.raises(ValueError, match="motion must be in 0..7, got 8"):
        World(empty).step(8)


def _near_obstacle_poses(world: World, n: int, rng, gap_mm: float = 60.0):
    """n random poses whose rim is within gap_mm of an obstacle or wall (where a step can crash)."""
    L = world.arena.size_mm
    flt = pymunk.ShapeFilter()
    out = []
    while len(out) < n:
        x, y = rng.uniform(0, L, 2)
        q = world.space.point_query_nearest((float(x), float(y)), ROBOT_RADIUS_MM + gap_mm, flt)
        if q is not None and q.distance >= ROBOT_RADIUS_MM:
            out.append((float(x), float(y), float(rng.uniform(-PI, PI))))
    return out


@pytest.mark.parametrize("arena_name", ["default", "one_obstacle"])
@pytest.mark.parametrize("gap_mm", [60.0, 250.0])
def test_reflex_cannot_crash(arena_name, gap_mm):
    """SPEC section 11, reflex deadlock: wherever no obstacle bit is set the reflex motion (forward,
    or a turn in place) does not hit anything, so the fixed reflex never repeats a crash. Sampled
    where it matters: poses whose rim is within ``gap_mm`` of an obstacle or wall. (Within 60 mm,
    where a 50 mm step could reach something, some IR bit is always set: the reflex never even
    applies there; the wider band exercises the reflex motions themselves.)"""
    world = World(load_arena(arena_name))
    rng = np.random.default_rng(2026)
    free = 0
    for pose in _near_obstacle_poses(world, 4000, rng, gap_mm):
        s = world.place(pose)
        if s & OBSTACLE_MASK:
            continue
        free += 1
        out = world.step(int(REFLEX_TABLE[s]))
        assert not out.crashed, f"reflex crash at pose {pose}, state {s:08b}"
    if gap_mm > 200:
        assert free > 20  # the reflex was exercised near obstacles


def test_state_sector_bits(empty):
    world = World(empty)
    for heading, sector in [(0.0, 0), (PI / 2, 3), (PI, 2), (-PI / 2, 1)]:
        s = world.place((1000.0, 2000.0, heading))
        assert s >> SECTOR_SHIFT == sector


def test_cache_gives_the_same_states():
    rng = np.random.default_rng(9)
    motions = rng.integers(0, 8, size=600).tolist()
    runs = []
    for cache in (True, False):
        world = World(load_arena(), cache=cache)
        runs.append([world.step(m) for m in motions] + [world.step(m) for m in motions])
    assert runs[0] == runs[1]


def test_course_runner_records_and_counts():
    from sim_world.baseline import baseline_table
    from sim_world.course import run_course

    world = World(load_arena())
    res = run_course(world, baseline_table(), 500, n_targets=3, record=True)
    assert res.targets_reached == 3 and res.steps == sum(res.leg_steps) == world.interactions
    events = [e for *_, e in res.trajectory]
    assert events.count("target") == 3 and events.count("relocate") == 2
    assert set(events) <= {"", "crash", "target", "relocate"}
    assert len(res.trajectory) == res.steps + 1 + 2
    assert all(len(t) == 4 for t in res.transitions)
    # a leg limit of 1 times out at once; a table driving into a wall crashes
    assert run_course(world, baseline_table(), 1).timed_out
    world.place((300.0, 2000.0, math.pi))
    crash = run_course(world, np.zeros(256, dtype=np.uint8), 500, start="here")
    assert crash.crashed and crash.targets_reached == 0


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"translation_sd": -0.1}, "translation_sd must be >= 0"),
        ({"rotation_sd_deg": float("nan")}, "rotation_sd_deg must be >= 0"),
        ({"ir_false_negative": 1.5}, "ir_false_negative must be a probability"),
        ({"ir_false_positive": -0.1}, "ir_false_positive must be a probability"),
    ],
)
def test_noise_validation(kwargs, message):
    with pytest.raises(ValueError, match=message):
        Noise(**kwargs)


def test_zero_noise_is_noise_free():
    assert World(load_arena("empty"), noise=Noise()).noise is None


def test_pickle_round_trip_continues_identically():
    import pickle

    world = World(load_arena(), noise=DEFAULT_NOISE, seed=4)
    for m in [0, 0, 3, 0, 5]:
        world.step(m)
    copy_ = pickle.loads(pickle.dumps(world))
    motions = [0, 2, 0, 0, 4, 1, 0, 0, 7, 0] * 20
    assert [world.step(m) for m in motions] == [copy_.step(m) for m in motions]
    assert world.pose == copy_.pose


def test_no_motion_ends_inside_any_obstacle_or_wall():
    """The bumper against the arena's own geometry (not pymunk's): a random walk that hugs every
    obstacle, the disc included, never ends a motion with the robot overlapping anything."""
    arena = load_arena("default")
    world = World(arena, seed=7)
    rng = np.random.default_rng(7)
    crashes = 0
    for leg in range(40):
        world.relocate(leg % len(arena.positions))
        for _ in range(150):
            # Mostly forward, so the robot keeps running into things.
            step = world.step(int(rng.choice(8, p=[0.55, 0.05, 0.1, 0.1, 0.1, 0.1, 0.0, 0.0])))
            crashes += step.crashed
            assert arena.clearance(world.pose[:2]) >= ROBOT_RADIUS_MM - 0.05, world.pose
    assert crashes > 50  # the walk did reach the obstacles


def test_the_disc_obstacle_is_solid():
    """Regression: pymunk's capsule shape_query reported a positive distance for a capsule
    overlapping a circle, so the default arena's disc could be driven through."""
    arena = load_arena("default")
    disc = next(ob for ob in arena.obstacles if ob.is_circle)
    (cx, cy), r = disc.centre, disc.radius
    world = World(arena)
    world.place((cx - r - ROBOT_RADIUS_MM - 200.0, cy, 0.0))
    crashed = [world.step(0).crashed for _ in range(12)]
    assert crashed[:3] == [False] * 3 and crashed[-1]
    assert cx - world.pose[0] >= r + ROBOT_RADIUS_MM - 1e-6


def test_course_relocation_rule():
    """SPEC section 5: after the k-th target, position (first + k - 1) mod n, in that order."""
    import pytest

    from sim_world.arena import N_POSITIONS, load_arena
    from sim_world.course import Course

    course = Course.of(load_arena("default"))
    assert course.n_positions == N_POSITIONS
    assert [course.position_after(k) for k in (1, 2, 64, 65)] == [0, 1, 63, 0]
    later = Course.of(load_arena("default"), first=10)
    assert [later.position_after(k) for k in (1, 54, 55)] == [10, 63, 0]
    with pytest.raises(ValueError, match="target counts from 1"):
        course.position_after(0)
    with pytest.raises(ValueError, match="first must be"):
        Course(4, first=4)


def test_course_run_from_a_position_relocates_to_the_next_one():
    from sim_world.arena import load_arena
    from sim_world.baseline import baseline_table
    from sim_world.course import run_course

    world = World(load_arena("default"), noise=None)
    res = run_course(world, baseline_table(), 500, n_targets=2, start=5, record=True)
    assert res.targets_reached == 2
    relocations = [i for i, p in enumerate(res.trajectory) if p[3] == "relocate"]
    assert len(relocations) == 1
    x, y, _, _ = res.trajectory[relocations[0]]
    assert (x, y) == pytest.approx(tuple(world.arena.positions[6][:2]))
