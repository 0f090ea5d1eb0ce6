"""The arena as data: size, convex obstacles, the ball, the start pose and the 64 relocation poses.

An arena is a JSON file in ``sim_world/arenas/`` (SPEC section 5: "the layout, seeds and positions
are data, not code"). Units are millimetres; headings are written in degrees in the file and held
in radians in :class:`Arena`. The origin is the lower-left corner, y up, heading 0 = +x,
counter-clockwise positive, so the "upper-left corner" has small x and large y.

File format::

    {
      "name": "default",
      "size_mm": 4000,                    # side L of the square arena
      "ball": [2000, 2000],               # the target, at the centre
      "ball_radius_mm": 100,              # the ball itself (obstacles must not touch it)
      "target_radius_mm": 200,            # reached when the robot centre is this close
      "start": [350, 3650, -45],          # x, y, heading in degrees
      "obstacles": [
        {"name": "hexagon", "polygon": [[x, y], ...]},        # convex, any orientation
        {"name": "disc", "circle": [x, y], "radius": 260}
      ],
      "positions": [[x, y, heading_deg], ...]                 # exactly 64, in visiting order
    }

:func:`load_arena` validates everything and raises :class:`ArenaError` naming the bad item.
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from base.errors import UserError
from sim_world.geometry import (
    Point,
    edges,
    inside_convex,
    is_convex,
    is_simple,
    point_segment_distance,
    polygon_area2,
    segments_intersect,
)

ARENA_DIR = Path(__file__).resolve().parent / "arenas"
DEFAULT_ARENA = "default"

ROBOT_RADIUS_MM = 125.0  # SPEC section 4: a disc of 25 cm diameter
N_POSITIONS = 64  # SPEC section 5
# A relocation pose (and the start) must leave this much free space between the robot's rim and
# any obstacle or wall, so the robot never starts touching something.
POSE_CLEARANCE_MM = 25.0
# The reachability check (every relocation position and the start must reach the ball's target
# disc through free space): a flood fill over a grid of robot-centre cells this wide.
REACH_CELL_MM = 20.0  # at least; larger arenas use 1/400 of their side
MAX_SIZE_MM = 20_000.0  # 20 m: the robot's 5 cm steps make larger arenas meaningless here


def _arena_names() -> tuple[str, ...]:
    return tuple(sorted(p.stem for p in ARENA_DIR.glob("*.json")))


class ArenaError(UserError, ValueError):
    """An arena file that cannot be used; the message names the offending item."""



@dataclass(frozen=True)
class Obstacle:
    """A convex obstacle: a polygon (counter-clockwise vertices) or a circle."""

    name: str
    vertices: tuple[Point, ...] = ()  # polygon, counter-clockwise
    centre: Point | None = None  # circle
    radius: float = 0.0

    @property
    def is_circle(self) -> bool:
        return self.centre is not None

    def distance_to_point(self, p: Point) -> float:
        """Distance from p to the obstacle (0 inside it)."""
        if self.is_circle:
            return max(0.0, math.dist(p, self.centre) - self.radius)
        verts = list(self.vertices)
        if inside_convex(p, verts):
            return 0.0
        return min(point_segment_distance(p, a, b) for a, b in edges(verts))

    def distance_to(self, other: "Obstacle") -> float:
        """Gap between two convex obstacles (0 when they touch or overlap)."""
        if self.is_circle and other.is_circle:
            return max(0.0, math.dist(self.centre, other.centre) - self.radius - other.radius)
        if self.is_circle:
            return other.distance_to(self)
        if other.is_circle:
            return max(0.0, self.distance_to_point(other.centre) - other.radius)
        a, b = list(self.vertices), list(other.vertices)
        if any(inside_convex(p, b) for p in a) or any(inside_convex(p, a) for p in b):
            return 0.0
        for p, q in edges(a):
            for r, s in edges(b):
                if segments_intersect(p, q, r, s):
                    return 0.0
        return min(
            min(point_segment_distance(p, r, s) for p in a for r, s in edges(b)),
            min(point_segment_distance(p, r, s) for p in b for r, s in edges(a)),
        )

    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax)."""
        if self.is_circle:
            (x, y), r = self.centre, self.radius
            return x - r, y - r, x + r, y + r
        xs = [v[0] for v in self.vertices]
        ys = [v[1] for v in self.vertices]
        return min(xs), min(ys), max(xs), max(ys)

    def min_vertex_angle_deg(self) -> float:
        """The sharpest interior angle of a polygon (180 for a circle)."""
        if self.is_circle:
            return 180.0
        v = list(self.vertices)
        n = len(v)
        best = 180.0
        for i in range(n):
            a, b, c = v[i - 1], v[i], v[(i + 1) % n]
            u = (a[0] - b[0], a[1] - b[1])
            w = (c[0] - b[0], c[1] - b[1])
            cos = (u[0] * w[0] + u[1] * w[1]) / (math.hypot(*u) * math.hypot(*w))
            best = min(best, math.degrees(math.acos(max(-1.0, min(1.0, cos)))))
        return best

    def to_json(self) -> dict:
        if self.is_circle:
            return {"name": self.name, "circle": list(self.centre), "radius": self.radius}
        return {"name": self.name, "polygon": [list(v) for v in self.vertices]}


Pose = tuple[float, float, float]  # x mm, y mm, heading rad


@dataclass(frozen=True)
class Arena:
    """A validated arena. Build one with :func:`load_arena` or :func:`arena_from_dict`."""

    name: str
    size_mm: float
    ball: Point
    ball_radius_mm: float
    target_radius_mm: float
    start: Pose
    obstacles: tuple[Obstacle, ...]
    positions: tuple[Pose, ...]
    source: str = field(default="", compare=False)

    def wall_distance(self, p: Point) -> float:
        """Distance from p to the nearest border wall."""
        return min(p[0], p[1], self.size_mm - p[0], self.size_mm - p[1])

    def clearance(self, p: Point) -> float:
        """Distance from p to the nearest obstacle or wall (0 inside an obstacle)."""
        d = self.wall_distance(p)
        for ob in self.obstacles:
            d = min(d, ob.distance_to_point(p))
        return d

    def is_free(self, p: Point, margin: float = 0.0) -> bool:
        """True when a robot centred at p fits with ``margin`` mm to spare."""
        return self.clearance(p) >= ROBOT_RADIUS_MM + margin

    def to_json(self) -> dict:
        deg = math.degrees
        return {
            "name": self.name,
            "size_mm": self.size_mm,
            "ball": list(self.ball),
            "ball_radius_mm": self.ball_radius_mm,
            "target_radius_mm": self.target_radius_mm,
            "start": [self.start[0], self.start[1], round(deg(self.start[2]), 6)],
            "obstacles": [ob.to_json() for ob in self.obstacles],
            "positions": [[x, y, round(deg(h), 6)] for x, y, h in self.positions],
        }


# ---------------------------------------------------------------------------------------------
# Parsing and validation.


def _number(value, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ArenaError(f"{what} must be a finite number, got {value!r}")
    return float(value)


def _point(value, what: str) -> Point:
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ArenaError(f"{what} must be [x, y], got {value!r}")
    return _number(value[0], what), _number(value[1], what)


def _pose(value, what: str) -> Pose:
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise ArenaError(f"{what} must be [x, y, heading_deg], got {value!r}")
    x, y, h = (_number(v, what) for v in value)
    return x, y, math.radians(h)


def _obstacle(item, index: int) -> Obstacle:
    if not isinstance(item, dict):
        raise ArenaError(f"obstacle {index} must be an object, got {item!r}")
    name = str(item.get("name", f"obstacle {index}"))
    label = f"obstacle {index} ({name!r})"
    if "circle" in item:
        centre = _point(item["circle"], f"{label} circle centre")
        radius = _number(item.get("radius"), f"{label} radius")
        if radius <= 0:
            raise ArenaError(f"{label} radius must be positive, got {radius!r}")
        return Obstacle(name=name, centre=centre, radius=radius)
    if "polygon" in item:
        raw = item["polygon"]
        if not isinstance(raw, list) or len(raw) < 3:
            raise ArenaError(f"{label} polygon needs at least 3 vertices, got {raw!r}")
        verts = [_point(v, f"{label} vertex {i}") for i, v in enumerate(raw)]
        if not is_simple(verts):
            raise ArenaError(f"{label} polygon is not simple (its edges cross, or a vertex repeats): {raw!r}")
        area2 = polygon_area2(verts)
        if abs(area2) < 1e-6:
            raise ArenaError(f"{label} polygon has no area: {raw!r}")
        if area2 < 0:
            verts.reverse()  # hold every polygon counter-clockwise
        if not is_convex(verts):
            raise ArenaError(f"{label} polygon is not convex (no horseshoes, SPEC section 5): {raw!r}")
        return Obstacle(name=name, vertices=tuple(verts))
    raise ArenaError(f"{label} needs 'polygon' or 'circle', got keys {sorted(item)!r}")


def _check_pose(arena_partial: Arena, pose: Pose, what: str) -> None:
    x, y, _ = pose
    need = ROBOT_RADIUS_MM + POSE_CLEARANCE_MM
    if arena_partial.wall_distance((x, y)) < need:
        raise ArenaError(
            f"{what} at ({x:g}, {y:g}) is outside the arena or closer than {need:g} mm to a wall"
        )
    for ob in arena_partial.obstacles:
        d = ob.distance_to_point((x, y))
        if d == 0:
            raise ArenaError(f"{what} at ({x:g}, {y:g}) is inside obstacle {ob.name!r}")
        if d < need:
            raise ArenaError(
                f"{what} at ({x:g}, {y:g}) is {d:.0f} mm from obstacle {ob.name!r}: too close "
                f"for the {2 * ROBOT_RADIUS_MM:g} mm robot (need {need:g} mm)"
            )


def arena_from_dict(data: dict, source: str = "") -> Arena:
    """Build and validate an arena from the JSON structure described in the module docstring."""
    if not isinstance(data, dict):
        raise ArenaError(f"an arena must be a JSON object, got {type(data).__name__}")
    for key in ("size_mm", "ball", "target_radius_mm", "start", "obstacles", "positions"):
        if key not in data:
            raise ArenaError(f"arena {source or data.get('name', '?')!r} lacks the key {key!r}")
    name = str(data.get("name", Path(source).stem if source else "arena"))
    size = _number(data["size_mm"], "size_mm")
    if not 4 * ROBOT_RADIUS_MM < size <= MAX_SIZE_MM:
        raise ArenaError(f"size_mm must exceed {4 * ROBOT_RADIUS_MM:g} and be at most {MAX_SIZE_MM:g}, got {size!r}")
    ball = _point(data["ball"], "ball")
    ball_radius = _number(data.get("ball_radius_mm", 100.0), "ball_radius_mm")
    if ball_radius <= 0:
        raise ArenaError(f"ball_radius_mm must be positive, got {ball_radius!r}")
    target_radius = _number(data["target_radius_mm"], "target_radius_mm")
    if target_radius <= 0:
        raise ArenaError(f"target_radius_mm must be positive, got {target_radius!r}")
    if target_radius >= size / 2:
        raise ArenaError(f"target_radius_mm {target_radius:g} covers half the {size:g} mm arena or more")
    if not (0 < ball[0] < size and 0 < ball[1] < size):
        raise ArenaError(f"ball at {ball!r} is outside the {size:g} mm arena")
    if not isinstance(data["obstacles"], list):
        raise ArenaError(f"obstacles must be a list, got {data['obstacles']!r}")
    obstacles = tuple(_obstacle(item, i) for i, item in enumerate(data["obstacles"]))

    names = [ob.name for ob in obstacles]
    for ob in obstacles:
        if names.count(ob.name) > 1:
            raise ArenaError(f"obstacle name {ob.name!r} is used {names.count(ob.name)} times")
        x0, y0, x1, y1 = ob.bounds()
        if x0 < 0 or y0 < 0 or x1 > size or y1 > size:
            raise ArenaError(
                f"obstacle {ob.name!r} (bounds {x0:g}..{x1:g} x {y0:g}..{y1:g}) lies outside the "
                f"{size:g} mm arena"
            )
        if ob.distance_to_point(ball) < ball_radius:
            raise ArenaError(f"obstacle {ob.name!r} overlaps the ball at {ball!r}")
    for i, a in enumerate(obstacles):
        for b in obstacles[i + 1 :]:
            if a.distance_to(b) <= 0:
                raise ArenaError(f"obstacles {a.name!r} and {b.name!r} overlap")

    if not isinstance(data["positions"], list):
        raise ArenaError(f"positions must be a list, got {data['positions']!r}")
    if len(data["positions"]) != N_POSITIONS:
        raise ArenaError(
            f"an arena needs exactly {N_POSITIONS} relocation positions, got {len(data['positions'])}"
        )
    start = _pose(data["start"], "start")
    positions = tuple(_pose(p, f"position {i}") for i, p in enumerate(data["positions"]))
    arena = Arena(
        name=name,
        size_mm=size,
        ball=ball,
        ball_radius_mm=ball_radius,
        target_radius_mm=target_radius,
        start=start,
        obstacles=obstacles,
        positions=positions,
        source=source,
    )
    _check_pose(arena, start, "start")
    for i, pose in enumerate(positions):
        _check_pose(arena, pose, f"position {i}")
    _check_target(arena)
    _check_reachable(arena)
    return arena


def _check_target(arena: Arena) -> None:
    """A leg must start outside the target disc, by at least the robot's radius: else the robot
    "reaches" the ball without moving (a target radius covering the positions makes 64 targets
    in 64 interactions)."""
    need = arena.target_radius_mm + ROBOT_RADIUS_MM
    for what, (x, y, _) in [("start", arena.start)] + [(f"position {i}", p) for i, p in enumerate(arena.positions)]:
        d = math.dist((x, y), arena.ball)
        if d < need:
            raise ArenaError(
                f"{what} at ({x:g}, {y:g}) is {d:.0f} mm from the ball: within the target radius "
                f"({arena.target_radius_mm:g} mm) plus the robot's radius ({ROBOT_RADIUS_MM:g} mm), "
                "so the leg needs no motion")


def clearance_grid(arena: Arena, cell: float = REACH_CELL_MM) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(xs, ys, clearance)``: cell centres and, per cell, the distance to the nearest obstacle
    or wall (0 inside an obstacle), as :meth:`Arena.clearance` but for the whole grid at once."""
    xs = np.arange(cell / 2, arena.size_mm, cell)
    gx, gy = np.meshgrid(xs, xs, indexing="ij")
    clear = np.minimum.reduce([gx, gy, arena.size_mm - gx, arena.size_mm - gy])
    for ob in arena.obstacles:
        if ob.is_circle:
            d = np.maximum(0.0, np.hypot(gx - ob.centre[0], gy - ob.centre[1]) - ob.radius)
        else:
            d = np.full(gx.shape, np.inf)
            inside = np.ones(gx.shape, bool)
            for (ax, ay), (bx, by) in edges(list(ob.vertices)):
                dx, dy = bx - ax, by - ay
                t = np.clip(((gx - ax) * dx + (gy - ay) * dy) / (dx * dx + dy * dy), 0.0, 1.0)
                d = np.minimum(d, np.hypot(gx - ax - t * dx, gy - ay - t * dy))
                inside &= dx * (gy - ay) - dy * (gx - ax) > 0
            d[inside] = 0.0
        clear = np.minimum(clear, d)
    return xs, xs, clear


def _flood(free: np.ndarray, seeds: np.ndarray) -> np.ndarray:
    """4-connected flood fill of ``free`` from ``seeds`` (boolean grids of one shape)."""
    reached = seeds & free
    while True:
        grown = reached.copy()
        grown[1:, :] |= reached[:-1, :]
        grown[:-1, :] |= reached[1:, :]
        grown[:, 1:] |= reached[:, :-1]
        grown[:, :-1] |= reached[:, 1:]
        grown &= free
        if (grown == reached).all():
            return reached
        reached = grown


@functools.lru_cache(maxsize=16)
def _reachable_grid(arena: Arena) -> tuple[np.ndarray, np.ndarray]:
    cell = max(REACH_CELL_MM, arena.size_mm / 400)
    xs, ys, clear = clearance_grid(arena, cell)
    # A cell is free when the robot fits there; the slack of most of a cell keeps a gap the
    # robot just fits through from falling between two grid lines.
    free = clear >= ROBOT_RADIUS_MM - 0.75 * cell
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    goal = np.hypot(gx - arena.ball[0], gy - arena.ball[1]) <= arena.target_radius_mm
    if not (goal & free).any():
        raise ArenaError(
            f"the ball at ({arena.ball[0]:g}, {arena.ball[1]:g}) cannot be reached: no point within "
            f"the target radius ({arena.target_radius_mm:g} mm) has room for the "
            f"{2 * ROBOT_RADIUS_MM:g} mm robot")
    return xs, _flood(free, goal)


def _check_reachable(arena: Arena) -> None:
    """Every relocation position (and the start) reaches the target disc through free space."""
    xs, reached = _reachable_grid(arena)
    cell = xs[1] - xs[0]
    last = len(xs) - 1
    for what, (x, y, _) in [("start", arena.start)] + [(f"position {i}", p) for i, p in enumerate(arena.positions)]:
        i, j = min(last, int(x // cell)), min(last, int(y // cell))
        if not reached[i, j]:
            raise ArenaError(
                f"{what} at ({x:g}, {y:g}) cannot reach the ball: obstacles and walls leave no "
                f"free path for the {2 * ROBOT_RADIUS_MM:g} mm robot")


def load_arena(name_or_path: str | Path = DEFAULT_ARENA) -> Arena:
    """Load and validate an arena: a shipped name (see :data:`ARENAS`) or a path to a JSON file."""
    path = Path(name_or_path)
    if isinstance(name_or_path, str) and name_or_path in _arena_names():
        path = ARENA_DIR / f"{name_or_path}.json"
    elif not path.exists():
        raise ArenaError(f"no arena {str(name_or_path)!r}: not a file, and not one of {_arena_names()}")
    try:
        data = json.loads(path.read_bytes().decode())
    except OSError as exc:
        raise ArenaError(f"cannot read arena file {str(path)!r}: {exc.strerror or exc}") from None
    except (ValueError, RecursionError) as exc:  # JSONDecodeError, UnicodeDecodeError
        raise ArenaError(f"arena file {str(path)!r} is not valid JSON: {exc}") from None
    try:
        return arena_from_dict(data, source=str(path))
    except ArenaError as exc:  # the message names the field; the line names the file too
        if str(path) in str(exc):
            raise
        raise ArenaError(f"arena file {str(path)!r}: {exc}") from None


def save_arena(arena: Arena, path: Path) -> None:
    """Write an arena as JSON (one obstacle or position per line, for readable diffs)."""
    data = arena.to_json()
    lines = ["{"]
    for key in ("name", "size_mm", "ball", "ball_radius_mm", "target_radius_mm", "start"):
        lines.append(f'  "{key}": {json.dumps(data[key])},')
    lines.append('  "obstacles": [')
    lines.append(",\n".join(f"    {json.dumps(o)}" for o in data["obstacles"]))
    lines.append("  ],")
    lines.append('  "positions": [')
    lines.append(",\n".join(f"    {json.dumps(p)}" for p in data["positions"]))
    lines.append("  ]")
    lines.append("}")
    Path(path).write_text("\n".join(lines) + "\n")


ARENAS: tuple[str, ...] = _arena_names()
