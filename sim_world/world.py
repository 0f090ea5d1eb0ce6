"""The robot world: a pymunk space holding the arena, a 25 cm disc robot, its IR sensors and camera.

SPEC sections 4-6. One :meth:`World.step` is one *interaction*: execute one of the 8 motions, let the
bumper decide whether it crashed (then the pose is restored), and sense the new world state.

How the physics engine is used (a measured choice, see docs/world.md):

* The obstacles and the four border walls are static pymunk shapes in one :class:`pymunk.Space`.
* The robot is a kinematic pymunk body with a circle shape (the bumper). A motion moves it
  kinematically: half the turn, the translation along the new heading, the other half of the turn
  (the midpoint rule for a differential-drive arc). A disc turning in place sweeps nothing, so the
  bumper test is the translation's swept disc, checked with ``point_query_nearest`` at centre
  samples 5 mm apart (at most 0.025 mm from the exact swept capsule; no tunnelling, no solver
  jitter). Stepping a
  dynamic body through the solver would cost ~10x more per motion and gives a pose that depends on
  contact resolution; the paper's robot simply stops and is put back.
* The 10 IR sensors are ``segment_query_first`` rays from the rim out to 30 cm; one
  ``point_query_nearest`` first tells whether anything is within reach at all (the common case in
  free space costs one query instead of ten) and also how far the robot may move without a bumper
  test.
* Noise-free, the obstacle bits of a pose never change, so they are cached by pose.
* The camera also gives a range to the ball (SPEC section 4, :func:`camera_range`): one reading
  per sensed pose, ``Step.range_mm`` and :meth:`World.camera_range`, drawn from the camera's own
  generator (derived from the world's seed), so it never shifts the motor or IR noise. It never
  enters the 8 state bits; it is what the host may learn progress from. The exact distance
  (``Step.distance_mm``, :meth:`World.target_distance`) is for figures only.
* The two hot queries call Chipmunk's C functions through pymunk's cffi handle (as pymunk's own
  wrappers do) with one reused result struct; see ``_bind_queries``.
"""

from __future__ import annotations

import functools
import math
import operator
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pymunk

from ga.motions import (
    MOTION_ROTATION_DEG,
    MOTION_TRANSLATION_MM,
    N_MOTIONS,
    OBSTACLE_BITS,
    SECTOR_SHIFT,
    X_BACK,
    X_FRONT,
    X_FRONT_LEFT,
    X_FRONT_RIGHT,
    X_LEFT,
    X_RIGHT,
    Sector,
)
from sim_world.arena import ROBOT_RADIUS_MM, Arena, Pose, load_arena

IR_RANGE_MM = 300.0  # SPEC section 4: an IR bit is set by an obstacle closer than 30 cm to the rim
# The 10 IR sensors: (angle from heading in degrees, counter-clockwise positive; the bit it sets).
IR_SENSORS: tuple[tuple[float, int], ...] = (
    (0.0, X_FRONT),
    (25.0, X_FRONT),
    (-25.0, X_FRONT),
    (55.0, X_FRONT_LEFT),
    (-55.0, X_FRONT_RIGHT),
    (90.0, X_LEFT),
    (135.0, X_LEFT),
    (-90.0, X_RIGHT),
    (-135.0, X_RIGHT),
    (180.0, X_BACK),
)
N_IR = len(IR_SENSORS)
# IR sensor mask (bit k = sensor k sees something) -> the six obstacle bits.
_MASK_TO_BITS = tuple(
    functools.reduce(operator.or_, (1 << bit for k, (_, bit) in enumerate(IR_SENSORS) if mask >> k & 1), 0)
    for mask in range(1 << N_IR)
)
SENSOR_REACH_MM = ROBOT_RADIUS_MM + IR_RANGE_MM  # from the robot's centre
SECTOR_HALF_WIDTH_DEG = 45.0  # front = -45..+45 degrees (SPEC section 4)
# The camera's range estimate (SPEC section 4): r = true range x (1 + e), e ~ N(0, sd), 10 mm steps.
CAMERA_RANGE_SD = 0.10  # the "real" world's relative error (DEFAULT_NOISE.range_sd)
CAMERA_RANGE_STEP_MM = 10.0
# The camera's generator: the world seed's SeedSequence, spawn key extended by this word, so its
# draws are a stream of their own (adding or dropping range readings moves no other noise).
_CAMERA_STREAM = 0x63616D  # "cam"

# Motion magnitudes, from the single source of truth in ga.motions.
_TRANSLATION = tuple(float(t) for t in MOTION_TRANSLATION_MM)
_ROTATION = tuple(math.radians(float(r)) for r in MOTION_ROTATION_DEG)

_TWO_PI = 2.0 * math.pi
_QUERY_FILTER = pymunk.ShapeFilter()
BUMPER_SAMPLE_MM = 5.0  # bumper test: centre samples along a translation (see World.bumper_hits)
# Poses whose noise-free IR readings are remembered (~350 bytes each); the cache is cleared
# when full. With motor noise no pose repeats, so such worlds do not cache at all.
_CACHE_LIMIT = 250_000


def _wrap(angle: float) -> float:
    """Angle wrapped to [-pi, pi)."""
    return (angle + math.pi) % _TWO_PI - math.pi


@dataclass(frozen=True)
class Noise:
    """Real-world imperfections (SPEC section 7, on-line method). All zero means noise-free.

    translation_sd: relative standard deviation of a motion's translation (0.1 = 10 % of 5 cm).
    rotation_sd_deg: standard deviation in degrees added to the heading change of every motion
        (wheel slip; a straight motion drifts too).
    ir_false_negative: probability that an IR sensor which sees an obstacle reports nothing.
    ir_false_positive: probability that an IR sensor which sees nothing reports an obstacle.

    range_sd: relative standard deviation e of the camera's range estimate (:func:`camera_range`).
    """

    translation_sd: float = 0.0
    rotation_sd_deg: float = 0.0
    ir_false_negative: float = 0.0
    ir_false_positive: float = 0.0
    range_sd: float = 0.0

    def __post_init__(self):
        for name in ("translation_sd", "rotation_sd_deg", "range_sd"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"Noise.{name} must be >= 0, got {getattr(self, name)!r}")
        for name in ("ir_false_negative", "ir_false_positive"):
            if not 0 <= getattr(self, name) <= 1:
                raise ValueError(f"Noise.{name} must be a probability, got {getattr(self, name)!r}")

    @property
    def is_zero(self) -> bool:
        return not (self.translation_sd or self.rotation_sd_deg or self.ir_false_negative or self.ir_false_positive
                    or self.range_sd)


# The "real world" of the on-line experiment: a few percent of motor error, rare IR errors, and
# the camera's range estimate within about 10 %.
DEFAULT_NOISE = Noise(translation_sd=0.1, rotation_sd_deg=3.0, ir_false_negative=0.02, ir_false_positive=0.005,
                      range_sd=CAMERA_RANGE_SD)


def camera_range(true_mm: float, sd: float = 0.0, e: float = 0.0) -> float:
    """The camera's range estimate (SPEC section 4): ``true_mm x (1 + sd e)`` for a standard
    normal draw ``e`` (from the world's camera generator), quantised to ``CAMERA_RANGE_STEP_MM``
    and never negative. ``sd`` 0: the true range, quantised."""
    r = true_mm * (1.0 + sd * e) if sd else true_mm
    return max(0.0, round(r / CAMERA_RANGE_STEP_MM) * CAMERA_RANGE_STEP_MM)


@dataclass(frozen=True)
class Fault:
    """From interaction ``at_step`` on (0 = from the start), IR bit ``bit`` (0..5) reads ``value``.

    ``Fault(at_step=5000, bit=X_LEFT)`` is the paper's blinded sensor: the left bit stuck at 0.
    """

    at_step: int
    bit: int
    value: int = 0

    def __post_init__(self):
        if not (isinstance(self.at_step, int) and self.at_step >= 0):
            raise ValueError(f"Fault.at_step must be an int >= 0, got {self.at_step!r}")
        if self.bit not in range(OBSTACLE_BITS):
            raise ValueError(f"Fault.bit must be an IR bit 0..{OBSTACLE_BITS - 1}, got {self.bit!r}")
        if self.value not in (0, 1):
            raise ValueError(f"Fault.value must be 0 or 1, got {self.value!r}")


class Step(NamedTuple):
    """The outcome of one interaction."""

    state: int  # the world state observed after the motion
    crashed: bool  # the bumper hit something; the pose was restored to before the motion
    reached: bool  # the robot's centre is within the target radius of the ball
    distance_mm: float  # exact distance from the robot's centre to the ball after the motion (figures only)
    range_mm: float  # the camera's range estimate after the motion (camera_range): what the host senses


def build_space(arena: Arena) -> pymunk.Space:
    """A pymunk space with the arena's obstacles and border walls as static shapes."""
    space = pymunk.Space()
    body = space.static_body
    shapes = []
    for ob in arena.obstacles:
        if ob.is_circle:
            shapes.append(pymunk.Circle(body, ob.radius, offset=ob.centre))
        else:
            shapes.append(pymunk.Poly(body, list(ob.vertices)))
    L = arena.size_mm
    corners = [(0.0, 0.0), (L, 0.0), (L, L), (0.0, L)]
    for a, b in zip(corners, corners[1:] + corners[:1]):
        shapes.append(pymunk.Segment(body, a, b, 0.0))
    space.add(*shapes)
    return space


class World:
    """The simulated robot in an arena. Noise-free unless ``noise`` is given; seeded by ``seed``."""

    def __init__(self, arena: Arena | str | None = None, noise: Noise | None = None, faults=(), seed=None,
                 cache: bool = True):
        if arena is None or isinstance(arena, str):
            arena = load_arena(arena or "default")
        self.arena = arena
        self.noise = None if noise is None or noise.is_zero else noise
        self.faults = tuple(faults)
        for f in self.faults:
            if not isinstance(f, Fault):
                raise TypeError(f"faults must be Fault instances, got {f!r}")
        self._build_physics()
        self._bx, self._by = arena.ball
        self._target_r = arena.target_radius_mm
        self._ir_dirs = tuple(
            (math.radians(a), 1 << bit) for a, bit in IR_SENSORS
        )
        motor_noise = self.noise is not None and (self.noise.translation_sd or self.noise.rotation_sd_deg)
        self._cache: dict | None = {} if cache and not motor_noise else None
        self.cache_hits = 0
        self.interactions = 0
        self.crashes = 0
        self.reset(seed)
        self.reset_to_start()

    _PHYSICS = ("space", "_body", "bumper", "_ray_query", "_nearest_query")

    def _build_physics(self) -> None:
        self.space = build_space(self.arena)
        # The robot: a kinematic body and its bumper. Its pose is held in plain floats (the hot
        # path) and copied to the body by `robot_body` when someone wants to look at it.
        self._body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        self.bumper = pymunk.Circle(self._body, ROBOT_RADIUS_MM)
        self._bind_queries()

    def __getstate__(self) -> dict:
        """Pickle support (process pools): the pymunk objects are rebuilt from the arena."""
        state = self.__dict__.copy()
        for key in self._PHYSICS:
            state.pop(key, None)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._build_physics()

    def _bind_queries(self) -> None:
        """Bind the two hot queries to Chipmunk's C functions, as pymunk's own wrappers call them.

        pymunk's Python wrappers allocate a result object per call, which costs 2-3x the query
        itself (measured in docs/world.md); calling the same ``cpSpaceSegmentQueryFirst`` and
        ``cpSpacePointQueryNearest`` through pymunk's cffi handle with one reused result struct
        gives identical answers. Falls back to the public API if pymunk's internals move.
        """
        space = self.space
        try:
            from pymunk._chipmunk import ffi, lib

            cp_space = space._space
            seg_info = ffi.new("cpSegmentQueryInfo *")
            pt_info = ffi.new("cpPointQueryInfo *")
            null = ffi.NULL
            seg_first = lib.cpSpaceSegmentQueryFirst
            pt_nearest = lib.cpSpacePointQueryNearest

            def ray_hits(p0, p1) -> bool:
                return seg_first(cp_space, p0, p1, 0.0, _QUERY_FILTER, seg_info) != null

            def nearest(p, max_distance):
                if pt_nearest(cp_space, p, max_distance, _QUERY_FILTER, pt_info) == null:
                    return None
                return pt_info.distance

        except (ImportError, AttributeError):  # pragma: no cover - depends on pymunk internals

            def ray_hits(p0, p1) -> bool:
                return space.segment_query_first(p0, p1, 0.0, _QUERY_FILTER) is not None

            def nearest(p, max_distance):
                info = space.point_query_nearest(p, max_distance, _QUERY_FILTER)
                return None if info is None else info.distance

        self._ray_query = ray_hits
        self._nearest_query = nearest

    # -- seeding and placement -----------------------------------------------------------------

    def reset(self, seed=None) -> None:
        """Re-seed the noise generator and zero the interaction counters (the pose is kept)."""
        seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
        self.rng = np.random.default_rng(seq)  # the motor and IR noise (as default_rng(seed))
        self._camera_rng = np.random.default_rng(
            np.random.SeedSequence(seq.entropy, spawn_key=(*seq.spawn_key, _CAMERA_STREAM)))
        self._camera_normals: list[float] = []
        self._normals: list[float] = []
        self._uniforms: list[float] = []
        self.interactions = 0
        self.crashes = 0

    def place(self, pose: Pose) -> int:
        """Put the robot at ``pose`` = (x, y, heading); returns the world state sensed there."""
        x, y, h = (float(v) for v in pose)
        self._x, self._y, self._h = x, y, _wrap(h)
        self._state = self._sense()
        return self._state

    def reset_to_start(self) -> int:
        return self.place(self.arena.start)

    def relocate(self, i: int) -> int:
        """Move the robot to the i-th relocation pose (0..63)."""
        return self.place(self.arena.positions[i])

    @property
    def pose(self) -> Pose:
        return (self._x, self._y, self._h)

    @property
    def robot_body(self) -> pymunk.Body:
        """The robot's pymunk body, moved to the current pose."""
        self._body.position = (self._x, self._y)
        self._body.angle = self._h
        return self._body

    def state(self) -> int:
        """The 8-bit world state observed at the current pose (sampled once per pose)."""
        return self._state

    @property
    def bumper_clearance(self) -> float:
        """Distance (mm) from the bumper to the nearest obstacle at the current pose, as sensed
        (noise-free geometry); IR_RANGE_MM when nothing is within the sensors' reach."""
        return self._clearance - ROBOT_RADIUS_MM

    def target_distance(self) -> float:
        """The exact distance (mm) from the robot's centre to the ball: for figures only (what the
        robot senses of it is :meth:`camera_range`)."""
        return math.hypot(self._bx - self._x, self._by - self._y)

    def target_reached(self) -> bool:
        """The target event: the ball is within the target radius (the robot touches it)."""
        return math.hypot(self._bx - self._x, self._by - self._y) <= self._target_r

    def camera_range(self) -> float:
        """The camera's range estimate (mm) at the current pose: one reading per sensed pose
        (:func:`camera_range`; the same value until the robot is sensed again)."""
        return self._range

    # -- sensing -------------------------------------------------------------------------------

    def _rays(self, x: float, y: float, h: float) -> int:
        """A mask with bit k set when IR sensor k sees an obstacle (noise-free), plus the clearance."""
        nearest = self._nearest_query((x, y), SENSOR_REACH_MM)
        if nearest is None:
            return 0, SENSOR_REACH_MM
        query = self._ray_query
        mask = 0
        r0, r1 = ROBOT_RADIUS_MM, SENSOR_REACH_MM
        cos, sin = math.cos, math.sin
        for k, (a, _) in enumerate(self._ir_dirs):
            c, s = cos(h + a), sin(h + a)
            if query((x + r0 * c, y + r0 * s), (x + r1 * c, y + r1 * s)):
                mask |= 1 << k
        return mask, nearest

    def _ray_mask(self, x: float, y: float, h: float):
        if self._cache is None:
            return self._rays(x, y, h)
        key = (x, y, h)
        hit = self._cache.get(key)
        if hit is not None:
            self.cache_hits += 1
            return hit
        hit = self._rays(x, y, h)
        if len(self._cache) >= _CACHE_LIMIT:
            self._cache.clear()
        self._cache[key] = hit
        return hit

    def _uniform(self) -> float:
        if not self._uniforms:
            self._uniforms = self.rng.random(4096).tolist()
        return self._uniforms.pop()

    def _normal(self) -> float:
        if not self._normals:
            self._normals = self.rng.standard_normal(4096).tolist()
        return self._normals.pop()

    def _camera(self, true_mm: float) -> float:
        """One range reading of the camera at ``true_mm`` (its own generator, one draw a frame)."""
        sd = 0.0 if self.noise is None else self.noise.range_sd
        if not sd:
            return camera_range(true_mm)
        if not self._camera_normals:
            self._camera_normals = self._camera_rng.standard_normal(4096).tolist()
        return camera_range(true_mm, sd, self._camera_normals.pop())

    def _sense(self) -> int:
        """Sense the world state at the current pose: IR bits (noise, faults) and the sector; the
        camera's range reading goes to ``_range``."""
        x, y, h = self._x, self._y, self._h
        self._range = self._camera(math.hypot(self._bx - x, self._by - y))
        mask, self._clearance = self._ray_mask(x, y, h)
        noise = self.noise
        if noise is not None and (noise.ir_false_negative or noise.ir_false_positive):
            fn, fp = noise.ir_false_negative, noise.ir_false_positive
            noisy = 0
            for k in range(N_IR):
                seen = (mask >> k) & 1
                if self._uniform() < (fn if seen else fp):
                    seen ^= 1
                noisy |= seen << k
            mask = noisy
        bits = _MASK_TO_BITS[mask]
        for f in self.faults:
            if self.interactions >= f.at_step:
                bits = (bits | (1 << f.bit)) if f.value else (bits & ~(1 << f.bit))
        return bits | (self.sector() << SECTOR_SHIFT)

    def sector(self) -> int:
        """The camera's target sector (SPEC section 4): 0 front, 1 left, 2 back, 3 right."""
        rel = math.degrees(_wrap(math.atan2(self._by - self._y, self._bx - self._x) - self._h))
        if -SECTOR_HALF_WIDTH_DEG <= rel < SECTOR_HALF_WIDTH_DEG:
            return Sector.FRONT
        if SECTOR_HALF_WIDTH_DEG <= rel < 180.0 - SECTOR_HALF_WIDTH_DEG:
            return Sector.LEFT
        if -180.0 + SECTOR_HALF_WIDTH_DEG <= rel < -SECTOR_HALF_WIDTH_DEG:
            return Sector.RIGHT
        return Sector.BACK

    def ray_hits(self) -> list[tuple[float, float, float | None]]:
        """For drawing: (sensor angle rad, reach mm from centre, hit distance from centre or None)."""
        x, y, h = self._x, self._y, self._h
        out = []
        for a, _ in self._ir_dirs:
            c, s = math.cos(h + a), math.sin(h + a)
            p0 = (x + ROBOT_RADIUS_MM * c, y + ROBOT_RADIUS_MM * s)
            p1 = (x + SENSOR_REACH_MM * c, y + SENSOR_REACH_MM * s)
            info = self.space.segment_query_first(p0, p1, 0.0, _QUERY_FILTER)
            hit = None if info is None else ROBOT_RADIUS_MM + info.alpha * IR_RANGE_MM
            out.append((a, SENSOR_REACH_MM, hit))
        return out

    # -- motion --------------------------------------------------------------------------------

    def bumper_hits(self, x0: float, y0: float, x1: float, y1: float) -> bool:
        """True when the robot's disc, swept from (x0, y0) to (x1, y1), cuts into an obstacle or wall.

        The disc's centre is sampled every ``BUMPER_SAMPLE_MM`` along the path and pymunk's
        ``point_query_nearest`` gives the distance from it to the nearest obstacle surface: a
        crash when that is less than the robot's radius. Between two samples the union of the
        discs misses at most R - sqrt(R^2 - (s/2)^2) = 0.025 mm of the swept capsule. (Two exact
        alternatives fail: ``segment_query_first`` with a radius only visits shapes whose bounding
        box the bare centre line crosses, and ``shape_query`` with a capsule reports a positive
        contact distance for a capsule overlapping a circle, so a disc obstacle was not solid.)
        Touching without penetrating (distance R) is not a crash, so a robot resting against a
        wall can leave it.
        """
        n = max(1, math.ceil(math.hypot(x1 - x0, y1 - y0) / BUMPER_SAMPLE_MM))
        dx, dy = (x1 - x0) / n, (y1 - y0) / n
        limit = ROBOT_RADIUS_MM - 1e-6
        for i in range(1, n + 1):
            d = self._nearest_query((x0 + i * dx, y0 + i * dy), ROBOT_RADIUS_MM)
            if d is not None and d < limit:
                return True
        return False

    def step(self, motion: int) -> Step:
        """Execute one motion (one interaction) and sense the result."""
        if not 0 <= motion < N_MOTIONS:
            raise ValueError(f"motion must be in 0..{N_MOTIONS - 1}, got {motion!r}")
        t, r = _TRANSLATION[motion], _ROTATION[motion]
        noise = self.noise
        if noise is not None:
            if noise.translation_sd:
                t *= 1.0 + noise.translation_sd * self._normal()
            if noise.rotation_sd_deg:
                r += math.radians(noise.rotation_sd_deg) * self._normal()
        x0, y0, h0 = self._x, self._y, self._h
        hm = h0 + 0.5 * r
        crashed = False
        if t:
            x1, y1 = x0 + t * math.cos(hm), y0 + t * math.sin(hm)
            # Far from everything (clearance known from sensing) no bumper test is needed.
            if self._clearance <= ROBOT_RADIUS_MM + abs(t) + 1e-6:
                crashed = self.bumper_hits(x0, y0, x1, y1)
        else:
            x1, y1 = x0, y0
        self.interactions += 1
        if crashed:
            self.crashes += 1
        else:
            self._x, self._y, self._h = x1, y1, _wrap(h0 + r)
        self._state = self._sense()
        d = math.hypot(self._bx - self._x, self._by - self._y)
        return Step(self._state, crashed, d <= self._target_r, d, self._range)
