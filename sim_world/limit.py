"""The limit (issue 40): the fewest interactions any controller could need on the course.

An omniscient planner knows the arena, the ball and the robot's pose exactly (noise-free) and
searches, leg by leg, over the 8 motions of SPEC section 4 (magnitudes from ``ga.motions``, the
one home of the motion table) for the fewest interactions from the leg's start pose to the target
disc without a crash. The legs are those of ``sim_world.course.Course``: the arena's start, then
the relocation positions in their order; a leg's end pose does not matter (the next leg starts at
its own position), so the course's limit is the sum of the legs' limits.

The search: A* over the motion lattice, one interaction per edge.

* **Poses.** Every motion turns by 0 or +-22.5 degrees, so a leg's headings are exactly the 16
  multiples of 22.5 degrees from its start heading (index k). Positions are continuous; the
  search keeps one representative pose per (position cell of ``cell_mm``, k): the first one
  found with the fewest interactions (a "hybrid A*"). Its pose is exact (no snapping), so each
  path is a real motion sequence; the cell only decides which poses count as the same. Refining
  the cell changes the count by under 1 % (docs/limit.md says how it was measured).
* **Motions** move as ``World.step`` does: half the turn, the translation along that heading,
  the other half. A crash is ``World.bumper_hits``'s rule: centre samples every
  ``BUMPER_SAMPLE_MM`` along the translation, nearest obstacle or wall closer than the robot's
  radius; evaluated here for many poses at once (:class:`Geometry`), with the world's shortcut
  (no test when the start pose is farther than radius + step from everything).
* **Heuristic** (admissible, a lower bound on the motions still needed): every motion moves the
  centre by at most one step, so h = ceil(lower bound of the path length to the target disc /
  step). The bound is the larger of the straight-line distance and a grid geodesic around the
  obstacles (Dijkstra over ``HEURISTIC_CELL_MM`` cells, shrunk by its worst-case grid error);
  ``heuristic="euclid"`` uses the straight line alone (slower, the check that the geodesic one
  does not cut off a shorter path: docs/limit.md).

Every reported path is replayed in :class:`sim_world.world.World` (:func:`replay_leg`) and must
reach the target with no crash; :func:`plan_course` raises if one does not.
"""

from __future__ import annotations

import heapq
import math
import time
from dataclasses import dataclass, field

import numpy as np

from ga.motions import MOTION_ROTATION_DEG, MOTION_TRANSLATION_MM, N_MOTIONS, STEP_MM, TURN_DEG
from sim_world.arena import ROBOT_RADIUS_MM, Arena, Pose, clearance_grid
from sim_world.course import DEFAULT_MAX_LEG_STEPS, Course
from sim_world.geometry import edges
from sim_world.world import BUMPER_SAMPLE_MM, World

# Bumped whenever a change of the search can change a count (caches of limits key on it).
PLANNER_VERSION = 2
N_HEADINGS = round(360.0 / TURN_DEG)  # 16: every heading a leg can take
DEFAULT_CELL_MM = 5.0  # the position cell of the search (docs/limit.md: 2.5 mm changes the total by < 1 %)
MIN_CELL_MM = 1.0
HEURISTIC_CELL_MM = 20.0  # the geodesic heuristic's grid
HEURISTICS = ("geodesic", "euclid")
# An 8-connected grid path is at most this factor longer than the straight segment it follows
# (1 / cos(22.5 degrees)), so grid distances are divided by it to stay a lower bound.
_OCTILE_EXCESS = 1.0 / math.cos(math.radians(22.5))
_CRASH_LIMIT = ROBOT_RADIUS_MM - 1e-6  # World.bumper_hits: closer than the radius is a crash
_NO_G = np.iinfo(np.int16).max
_ROTATION = np.radians(MOTION_ROTATION_DEG.astype(float))
_TRANSLATION = MOTION_TRANSLATION_MM.astype(float)
_TURN_STEPS = np.rint(MOTION_ROTATION_DEG / TURN_DEG).astype(np.int64)  # heading index change


class Geometry:
    """The arena's obstacles and border walls as arrays: the clearance of many points at once."""

    def __init__(self, arena: Arena):
        self.arena = arena
        starts, ends, self._poly_first = [], [], []
        for ob in arena.obstacles:
            if ob.is_circle:
                continue
            self._poly_first.append(len(starts))
            for a, b in edges(list(ob.vertices)):
                starts.append(a)
                ends.append(b)
        n_poly_edges = len(starts)
        L = arena.size_mm
        corners = [(0.0, 0.0), (L, 0.0), (L, L), (0.0, L)]
        for a, b in zip(corners, corners[1:] + corners[:1]):  # the border, as pymunk segments
            starts.append(a)
            ends.append(b)
        self._a = np.array(starts, dtype=float)
        self._d = np.array(ends, dtype=float) - self._a
        self._len2 = (self._d ** 2).sum(axis=1)
        self._n_poly_edges = n_poly_edges
        circles = [(*ob.centre, ob.radius) for ob in arena.obstacles if ob.is_circle]
        self._circles = np.array(circles, dtype=float).reshape(-1, 3)

    def clearance(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Distance (mm) from each point to the nearest obstacle or wall; 0 inside a polygon."""
        x = np.asarray(x, dtype=float)[:, None]
        y = np.asarray(y, dtype=float)[:, None]
        rx, ry = x - self._a[:, 0], y - self._a[:, 1]
        dx, dy = self._d[:, 0], self._d[:, 1]
        t = np.clip((rx * dx + ry * dy) / self._len2, 0.0, 1.0)
        dist = np.hypot(rx - t * dx, ry - t * dy).min(axis=1)
        if self._poly_first:
            cross = (dx * ry - dy * rx)[:, :self._n_poly_edges]
            inside = (np.minimum.reduceat(cross, self._poly_first, axis=1) > 0).any(axis=1)
            dist[inside] = 0.0
        for cx, cy, r in self._circles:
            dist = np.minimum(dist, np.hypot(x[:, 0] - cx, y[:, 0] - cy) - r)
        return dist

    def crashes(self, x0, y0, x1, y1) -> np.ndarray:
        """For each translation (x0, y0) -> (x1, y1): does the bumper hit something (the samples of
        ``World.bumper_hits``)?"""
        n_samples = np.maximum(1, np.ceil(np.hypot(x1 - x0, y1 - y0) / BUMPER_SAMPLE_MM)).astype(np.int64)
        hit = np.zeros(len(x0), dtype=bool)
        for n in np.unique(n_samples):
            rows = np.flatnonzero(n_samples == n)
            i = np.arange(1, n + 1, dtype=float)
            dx, dy = (x1[rows] - x0[rows]) / n, (y1[rows] - y0[rows]) / n
            px = x0[rows, None] + i * dx[:, None]
            py = y0[rows, None] + i * dy[:, None]
            clear = self.clearance(px.ravel(), py.ravel()).reshape(len(rows), n)
            hit[rows] = (clear < _CRASH_LIMIT).any(axis=1)
        return hit


class StepBound:
    """A lower bound on the motions from a position to the target disc (the A* heuristic)."""

    def __init__(self, arena: Arena, kind: str = "geodesic", cell_mm: float = HEURISTIC_CELL_MM):
        if kind not in HEURISTICS:
            raise ValueError(f"heuristic must be one of {HEURISTICS}, got {kind!r}")
        self.kind = kind
        self.ball = np.array(arena.ball, dtype=float)
        self.target_r = arena.target_radius_mm
        self.cell = cell_mm
        self._grid = _geodesic_grid(arena, cell_mm) if kind == "geodesic" else None

    def steps(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        length = np.hypot(x - self.ball[0], y - self.ball[1]) - self.target_r
        if self._grid is not None:
            n = self._grid.shape[0]
            i = np.clip((x // self.cell).astype(np.int64), 0, n - 1)
            j = np.clip((y // self.cell).astype(np.int64), 0, n - 1)
            # A path from a point of cell c has length >= (grid distance of c - 2 cells) / excess:
            # one cell diagonal for leaving the cell's centre, one for entering the goal cell.
            length = np.maximum(length, (self._grid[i, j] - 2 * math.sqrt(2) * self.cell) / _OCTILE_EXCESS)
        return np.maximum(0, np.ceil(length / STEP_MM - 1e-9)).astype(np.int64)


def _geodesic_grid(arena: Arena, cell: float) -> np.ndarray:
    """Octile Dijkstra distance (mm) from the cells that may hold a goal point, through every cell
    a robot centre may occupy (clearance at the cell centre >= radius - half a diagonal, so no
    free point lies in a blocked cell); inf where none leads."""
    xs, ys, clear = clearance_grid(arena, cell)
    half_diag = cell / math.sqrt(2)
    free = clear >= ROBOT_RADIUS_MM - half_diag
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    goal = free & (np.hypot(gx - arena.ball[0], gy - arena.ball[1]) <= arena.target_radius_mm + half_diag)
    dist = np.full(free.shape, np.inf)
    heap = [(0.0, int(i), int(j)) for i, j in zip(*np.nonzero(goal))]
    for _, i, j in heap:
        dist[i, j] = 0.0
    n = free.shape[0]
    moves = [(di, dj, cell * math.hypot(di, dj)) for di in (-1, 0, 1) for dj in (-1, 0, 1) if di or dj]
    while heap:
        d, i, j = heapq.heappop(heap)
        if d > dist[i, j]:
            continue
        for di, dj, w in moves:
            a, b = i + di, j + dj
            if 0 <= a < n and 0 <= b < n and free[a, b] and d + w < dist[a, b]:
                dist[a, b] = d + w
                heapq.heappush(heap, (d + w, a, b))
    return dist


@dataclass
class LegPlan:
    """The fewest interactions of one leg and a motion sequence that achieves them."""

    start: Pose
    motions: list[int]  # empty when no path was found within max_steps
    expanded: int  # poses the search expanded
    seconds: float

    @property
    def interactions(self) -> int | None:
        return len(self.motions) if self.motions else None


class _Nodes:
    """The search's poses, in growing arrays: position, heading index, interactions, parent, motion."""

    FIELDS = (("x", float), ("y", float), ("k", np.int64), ("g", np.int64), ("parent", np.int64),
              ("motion", np.int8), ("clear", float))

    def __init__(self, capacity: int = 1 << 14):
        self.n = 0
        for name, dtype in self.FIELDS:
            setattr(self, name, np.empty(capacity, dtype=dtype))

    def add(self, **values) -> np.ndarray:
        m = len(values["x"])
        if self.n + m > len(self.x):
            size = max(2 * len(self.x), self.n + m)
            for name, dtype in self.FIELDS:
                grown = np.empty(size, dtype=dtype)
                grown[:self.n] = getattr(self, name)[:self.n]
                setattr(self, name, grown)
        ids = np.arange(self.n, self.n + m)
        for name, _ in self.FIELDS:
            getattr(self, name)[ids] = values[name]
        self.n += m
        return ids

    def path(self, node: int) -> list[int]:
        motions = []
        while self.parent[node] >= 0:
            motions.append(int(self.motion[node]))
            node = int(self.parent[node])
        return motions[::-1]


def plan_leg(arena: Arena, start: Pose, cell_mm: float = DEFAULT_CELL_MM,
             max_steps: int = DEFAULT_MAX_LEG_STEPS, geometry: Geometry | None = None,
             bound: StepBound | None = None) -> LegPlan:
    """A* from ``start`` to the target disc: the fewest crash-free motions (see the module docstring)."""
    if not cell_mm >= MIN_CELL_MM:
        raise ValueError(f"cell_mm must be at least {MIN_CELL_MM}, got {cell_mm!r}")
    t0 = time.perf_counter()
    geometry = geometry or Geometry(arena)
    bound = bound or StepBound(arena)
    x0, y0, h0 = (float(v) for v in start)
    headings = h0 + np.arange(N_HEADINGS) * math.radians(TURN_DEG)
    mid = headings[:, None] + 0.5 * _ROTATION[None, :]  # (16, 8): the translation's heading
    step_x, step_y = _TRANSLATION * np.cos(mid), _TRANSLATION * np.sin(mid)
    next_k = (np.arange(N_HEADINGS)[:, None] + _TURN_STEPS[None, :]) % N_HEADINGS
    moves = _TRANSLATION != 0
    n_cells = int(math.ceil(arena.size_mm / cell_mm)) + 1
    best_g = np.full(n_cells * n_cells * N_HEADINGS, _NO_G, dtype=np.int16)
    bx, by = arena.ball
    reach2 = arena.target_radius_mm ** 2
    far = ROBOT_RADIUS_MM + STEP_MM + 1e-6  # World.step's shortcut: nothing within reach

    def cells(x, y, k):
        return ((x // cell_mm).astype(np.int64) * n_cells + (y // cell_mm).astype(np.int64)) * N_HEADINGS + k

    nodes = _Nodes()
    first = nodes.add(x=[x0], y=[y0], k=[0], g=[0], parent=[-1], motion=[-1],
                      clear=geometry.clearance([x0], [y0]))
    best_g[cells(np.array([x0]), np.array([y0]), np.array([0]))] = 0
    buckets: dict[int, list[np.ndarray]] = {int(bound.steps(np.array([x0]), np.array([y0]))[0]): [first]}
    solution, solution_g, expanded = None, max_steps + 1, 0
    while buckets:
        f = min(buckets)
        if f >= solution_g:
            break
        ids = np.concatenate(buckets.pop(f))
        ids = ids[nodes.g[ids] == best_g[cells(nodes.x[ids], nodes.y[ids], nodes.k[ids])]]  # not superseded
        if not len(ids):
            continue
        expanded += len(ids)
        g = nodes.g[ids] + 1
        if g.min() > max_steps:
            continue
        k = nodes.k[ids]
        # every (node, motion) pair, flattened node-major
        parent = np.repeat(ids, N_MOTIONS)
        motion = np.tile(np.arange(N_MOTIONS), len(ids))
        kk = np.repeat(k, N_MOTIONS)
        px, py = nodes.x[parent], nodes.y[parent]
        x1 = px + step_x[kk, motion]
        y1 = py + step_y[kk, motion]
        k1 = next_k[kk, motion]
        g1 = np.repeat(g, N_MOTIONS)
        key = cells(x1, y1, k1)
        # a pose in the target disc ends the leg: it needs no cell of its own
        at_target = (x1 - bx) ** 2 + (y1 - by) ** 2 <= reach2
        keep = (g1 <= max_steps) & ((g1 < best_g[key]) | at_target)
        test = keep & moves[motion] & (nodes.clear[parent] <= far)
        if test.any():
            rows = np.flatnonzero(test)
            keep[rows[geometry.crashes(px[rows], py[rows], x1[rows], y1[rows])]] = False
        rows = np.flatnonzero(keep)
        if not len(rows):
            continue
        reached = at_target[rows]
        if reached.any():
            hits = rows[reached]
            best = hits[np.argmin(g1[hits])]
            if g1[best] < solution_g:
                solution_g, solution = int(g1[best]), (int(parent[best]), int(motion[best]))
            rows = rows[~reached]
        # one candidate per cell: the fewest interactions, then the first generated
        order = rows[np.lexsort((g1[rows], key[rows]))]
        _, first_of = np.unique(key[order], return_index=True)
        rows = order[first_of]
        if not len(rows):
            continue
        best_g[key[rows]] = g1[rows]
        new = nodes.add(x=x1[rows], y=y1[rows], k=k1[rows], g=g1[rows], parent=parent[rows],
                        motion=motion[rows], clear=geometry.clearance(x1[rows], y1[rows]))
        f1 = g1[rows] + bound.steps(x1[rows], y1[rows])
        for value in np.unique(f1):
            if value < solution_g:
                buckets.setdefault(int(value), []).append(new[f1 == value])
    motions = [] if solution is None else nodes.path(solution[0]) + [solution[1]]
    return LegPlan(tuple(start), motions, expanded, time.perf_counter() - t0)


def replay_leg(world: World, start: Pose, motions) -> tuple[bool, str]:
    """Drive ``motions`` from ``start`` in ``world``: (True, "") when no motion crashes and the
    target is reached by the last one and not before; else (False, what went wrong)."""
    world.place(start)
    for i, motion in enumerate(motions):
        out = world.step(int(motion))
        if out.crashed:
            return False, f"motion {i} ({int(motion)}) crashes at {world.pose}"
        if out.reached and i < len(motions) - 1:
            return False, f"the target is reached after {i + 1} of {len(motions)} motions"
    if not motions or not world.target_reached():
        return False, "the target is not reached"
    return True, ""


def course_starts(arena: Arena) -> list[Pose]:
    """The start pose of each of the course's legs (SPEC section 5, ``Course``)."""
    course = Course.of(arena)
    return [arena.start] + [arena.positions[course.position_after(t)] for t in range(1, course.n_positions)]


@dataclass
class CoursePlan:
    """The limit of one arena: per leg the fewest interactions, and their total."""

    arena: str
    cell_mm: float
    heuristic: str
    legs: list[LegPlan] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def total(self) -> int | None:
        counts = [leg.interactions for leg in self.legs]
        return None if None in counts else sum(counts)

    def to_json(self) -> dict:
        return {
            "arena": self.arena, "cell_mm": self.cell_mm, "heuristic": self.heuristic,
            "total_interactions": self.total, "legs": len(self.legs), "seconds": round(self.seconds, 2),
            "per_leg": [{"leg": i, "start": [round(v, 6) for v in leg.start], "interactions": leg.interactions,
                         "expanded": leg.expanded, "seconds": round(leg.seconds, 3),
                         "motions": "".join(map(str, leg.motions))} for i, leg in enumerate(self.legs)],
        }


class ReplayError(RuntimeError):
    """A planned path that crashes or misses the target when replayed in the world (a bug)."""


def plan_legs(arena: Arena, legs, cell_mm: float = DEFAULT_CELL_MM, heuristic: str = "geodesic",
              max_steps: int = DEFAULT_MAX_LEG_STEPS):
    """Plan the legs with these indices of the arena's course, each replayed in a noise-free world
    (a generator of LegPlans, in the order of ``legs``)."""
    starts = course_starts(arena)
    geometry, bound, world = Geometry(arena), StepBound(arena, heuristic), World(arena)
    for i in legs:
        plan = plan_leg(arena, starts[i], cell_mm, max_steps, geometry, bound)
        ok, why = replay_leg(world, plan.start, plan.motions)
        if plan.motions and not ok:
            raise ReplayError(f"leg {i} of arena {arena.name!r}: the planned path fails in the world: {why}")
        yield plan


def plan_course(arena: Arena, cell_mm: float = DEFAULT_CELL_MM, heuristic: str = "geodesic",
                max_steps: int = DEFAULT_MAX_LEG_STEPS, progress=None) -> CoursePlan:
    """Every leg of the course (``progress``: called with each finished LegPlan)."""
    t0 = time.perf_counter()
    plan = CoursePlan(arena.name, cell_mm, heuristic)
    for leg in plan_legs(arena, range(len(course_starts(arena))), cell_mm, heuristic, max_steps):
        plan.legs.append(leg)
        if progress is not None:
            progress(leg)
    plan.seconds = time.perf_counter() - t0
    return plan
