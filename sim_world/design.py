"""How the shipped arenas were made: obstacle layout by hand, relocation poses by a seeded procedure.

``python -m sim_world.design`` rewrites ``sim_world/arenas/*.json``. The JSON files are the source of
truth (the world loads them, not this module); this module documents and reproduces them.

Relocation poses: candidate points on a 50 mm grid whose clearance leaves the robot at least
``POSITION_MARGIN_MM`` to spare, outside the target radius by ``MIN_BALL_DISTANCE_MM``; 64 are
picked by farthest-point sampling (spread evenly over the free space), given a heading from a seeded
generator (multiples of 22.5 degrees), then ordered easy -> hard for shaping by a difficulty score:
the straight-line distance to the ball, plus a penalty when an obstacle (inflated by the robot
radius) blocks the straight line, plus a smaller one when the ball is not in the front sector.
"""

from __future__ import annotations

import math

import numpy as np

from sim_world.arena import (
    ARENA_DIR,
    N_POSITIONS,
    ROBOT_RADIUS_MM,
    Arena,
    arena_from_dict,
    save_arena,
)
from sim_world.geometry import point_segment_distance

SIZE_MM = 4000.0
BALL = (2000.0, 2000.0)
BALL_RADIUS_MM = 100.0
TARGET_RADIUS_MM = 200.0
START_DEG = -45.0  # facing the ball from the upper-left corner
START = (350.0, 3650.0)
POSITION_MARGIN_MM = 150.0  # free space around the robot at a relocation pose
MIN_BALL_DISTANCE_MM = 700.0
DESIGN_SEED = 1998


def regular_polygon(cx: float, cy: float, circumradius: float, n: int, rotation_deg: float = 0.0):
    rot = math.radians(rotation_deg)
    return [
        [round(cx + circumradius * math.cos(rot + 2 * math.pi * k / n), 1),
         round(cy + circumradius * math.sin(rot + 2 * math.pi * k / n), 1)]
        for k in range(n)
    ]


def ellipse(cx: float, cy: float, a: float, b: float, n: int):
    return [[round(cx + a * math.cos(2 * math.pi * k / n), 1), round(cy + b * math.sin(2 * math.pi * k / n), 1)] for k in range(n)]


def rectangle(cx: float, cy: float, width: float, height: float, rotation_deg: float = 0.0):
    rot = math.radians(rotation_deg)
    c, s = math.cos(rot), math.sin(rot)
    corners = [(-width / 2, -height / 2), (width / 2, -height / 2), (width / 2, height / 2), (-width / 2, height / 2)]
    return [[round(cx + u * c - v * s, 1), round(cy + u * s + v * c, 1)] for u, v in corners]


# The default arena's 9 obstacles: a ring of 8 around the ball plus one (the heptagon) between the
# ball and the lower-left corner, every one a different convex shape with no interior angle under
# 90 degrees (sharp corners hide between the IR rays). The centres came from a small max-min
# search over bounding circles: every gap, obstacle to obstacle and obstacle to wall, is >= 595 mm
# (2.4 robot diameters), each obstacle is >= 500 mm from the ball and clear of the start corner.
# Narrower gaps (440-580 mm) made the noisy reactive baseline crash (docs/world.md).
DEFAULT_OBSTACLES = [
    {"name": "hexagon", "polygon": regular_polygon(795, 795, 190, 6, 0)},
    {"name": "ellipse", "polygon": ellipse(2165, 860, 260, 150, 20)},
    {"name": "square", "polygon": rectangle(3200, 1035, 280, 280, 30)},
    {"name": "bar_vertical", "polygon": rectangle(3105, 2105, 180, 520, 0)},
    {"name": "disc", "circle": [3195, 3190], "radius": 210},
    {"name": "bar_horizontal", "polygon": rectangle(2185, 2800, 520, 180, 0)},
    {"name": "pentagon", "polygon": regular_polygon(1175, 3195, 210, 5, 90)},
    {"name": "octagon", "polygon": regular_polygon(790, 2275, 190, 8, 22.5)},
    {"name": "heptagon", "polygon": regular_polygon(1390, 1535, 170, 7, 45)},
]


def _blocked(arena: Arena, p) -> bool:
    """True when the straight line from p to the ball passes an obstacle inflated by the robot."""
    for ob in arena.obstacles:
        if ob.is_circle:
            d = point_segment_distance(ob.centre, p, arena.ball) - ob.radius
        else:
            # sample the line: obstacles are small and this runs once
            d = min(
                ob.distance_to_point((p[0] + t * (arena.ball[0] - p[0]), p[1] + t * (arena.ball[1] - p[1])))
                for t in np.linspace(0.0, 1.0, 60)
            )
        if d < ROBOT_RADIUS_MM:
            return True
    return False


def spread_positions(arena: Arena, seed: int = DESIGN_SEED, n: int = N_POSITIONS):
    """n relocation poses spread evenly over the free space, ordered easy -> hard."""
    rng = np.random.default_rng(seed)
    grid = np.arange(50.0, arena.size_mm, 50.0)
    cands = [
        (float(x), float(y))
        for x in grid
        for y in grid
        if arena.is_free((x, y), POSITION_MARGIN_MM) and math.dist((x, y), arena.ball) >= MIN_BALL_DISTANCE_MM
    ]
    pts = np.array(cands)
    # Farthest-point sampling from the candidate nearest the start corner.
    chosen = [int(np.argmin(np.hypot(pts[:, 0] - arena.start[0], pts[:, 1] - arena.start[1])))]
    dist = np.hypot(pts[:, 0] - pts[chosen[0], 0], pts[:, 1] - pts[chosen[0], 1])
    while len(chosen) < n:
        i = int(np.argmax(dist))
        chosen.append(i)
        dist = np.minimum(dist, np.hypot(pts[:, 0] - pts[i, 0], pts[:, 1] - pts[i, 1]))
    poses = []
    for i in chosen:
        x, y = pts[i]
        heading = float(rng.integers(0, 16)) * 22.5 - 180.0
        to_ball = math.degrees(math.atan2(arena.ball[1] - y, arena.ball[0] - x))
        off = abs((to_ball - heading + 180.0) % 360.0 - 180.0)
        score = math.dist((x, y), arena.ball) + (1500.0 if _blocked(arena, (x, y)) else 0.0) + 2.0 * off
        poses.append((score, [float(x), float(y), heading]))
    poses.sort(key=lambda sp: sp[0])
    return [p for _, p in poses]


def _base(name: str, obstacles: list[dict]) -> dict:
    return {
        "name": name,
        "size_mm": SIZE_MM,
        "ball": list(BALL),
        "ball_radius_mm": BALL_RADIUS_MM,
        "target_radius_mm": TARGET_RADIUS_MM,
        "start": [START[0], START[1], START_DEG],
        "obstacles": obstacles,
        "positions": [],
    }


def design(name: str, obstacles: list[dict]) -> Arena:
    data = _base(name, obstacles)
    # Validate the layout with placeholder positions, then spread the real ones.
    data["positions"] = [data["start"]] * N_POSITIONS
    draft = arena_from_dict(data)
    data["positions"] = spread_positions(draft)
    return arena_from_dict(data)


ARENA_DESIGNS = {
    "default": DEFAULT_OBSTACLES,
    # The paper's real-world test: one obstacle between the start corner and the ball.
    "one_obstacle": [{"name": "box", "polygon": rectangle(1300, 2700, 500, 500, 45)}],
    "empty": [],
}


def main() -> None:
    for name, obstacles in ARENA_DESIGNS.items():
        arena = design(name, obstacles)
        path = ARENA_DIR / f"{name}.json"
        save_arena(arena, path)
        gaps = [a.distance_to(b) for i, a in enumerate(arena.obstacles) for b in arena.obstacles[i + 1 :]]
        walls = [min(ob.bounds()[0], ob.bounds()[1], SIZE_MM - ob.bounds()[2], SIZE_MM - ob.bounds()[3]) for ob in arena.obstacles]
        print(f"{path}: {len(arena.obstacles)} obstacles, min gap {min(gaps, default=0):.0f} mm, "
              f"min wall gap {min(walls, default=0):.0f} mm, {len(arena.positions)} positions")


if __name__ == "__main__":
    main()
