"""Sensor bits, motions and the reflex: the contracts of SPEC sections 4 and 6.

Every part of the project (reference model, HDL, world, evaluator) imports these names; none
re-types them.
"""

from __future__ import annotations

import enum

import numpy as np

N_INPUTS = 8  # n: sensor bits x0..x7
N_OUTPUTS = 3  # m: motion bits y0..y2
N_STATES = 1 << N_INPUTS  # 256 world states
N_MOTIONS = 1 << N_OUTPUTS  # 8 motions

# Input bits (SPEC section 4). x0..x5 are obstacle bits, x6 + 2*x7 is the target sector.
X_FRONT, X_FRONT_LEFT, X_FRONT_RIGHT, X_LEFT, X_RIGHT, X_BACK = range(6)
OBSTACLE_BITS = 6
OBSTACLE_MASK = (1 << OBSTACLE_BITS) - 1  # 0b00111111
SECTOR_SHIFT = 6


class Sector(enum.IntEnum):
    """Target sector seen by the camera, code x6 + 2*x7."""

    FRONT = 0  # -45..+45 degrees
    LEFT = 1
    BACK = 2
    RIGHT = 3


class Motion(enum.IntEnum):
    """Motion code y0 + 2*y1 + 4*y2 (SPEC section 4)."""

    FORWARD = 0
    BACKWARD = 1
    TURN_LEFT = 2
    TURN_RIGHT = 3
    FORWARD_LEFT = 4
    FORWARD_RIGHT = 5
    BACKWARD_LEFT = 6
    BACKWARD_RIGHT = 7


# Starting magnitudes (SPEC section 4): translation in mm (signed, + is forward) and rotation in
# degrees (+ is counter-clockwise, i.e. left) for each motion code.
STEP_MM = 50
TURN_DEG = 22.5
MOTION_TRANSLATION_MM = np.array([STEP_MM, -STEP_MM, 0, 0, STEP_MM, STEP_MM, -STEP_MM, -STEP_MM])
MOTION_ROTATION_DEG = np.array([0.0, 0.0, TURN_DEG, -TURN_DEG, TURN_DEG, -TURN_DEG, TURN_DEG, -TURN_DEG])

# The distance covered by each motion, integer mm (dist[a] under the "covered" rule, below).
MOTION_DISTANCE_MM = np.abs(MOTION_TRANSLATION_MM).astype(np.int64)
MAX_MOTION_DISTANCE_MM = int(MOTION_DISTANCE_MM.max())

# Which motions the fitness's distance term rewards. "forward" is SPEC section 7's dist[a]: the
# forward translation of the motion, so a backward step covers 0 like a turn. "covered" (the
# paper's first reading, an option) counts every translation, backward ones too: it pays a
# backward-turn 50 mm where a turn in place gets 0, and the looping back-off-and-return it
# favours is what most on-line interactions were lost to (docs/research-log.md, on-line round 5). The maximum
# (forward, 50 mm) is the same for both, so the fitness keeps its scale.
DISTANCE_RULES = ("covered", "forward")
DEFAULT_DISTANCE_RULE = "forward"


def motion_distances(rule: str = DEFAULT_DISTANCE_RULE) -> np.ndarray:
    """dist[a] (int64, (8,), mm) of the model-based fitness under ``rule`` (see DISTANCE_RULES)."""
    if rule == "covered":
        return MOTION_DISTANCE_MM.copy()
    if rule == "forward":
        return np.maximum(MOTION_TRANSLATION_MM, 0).astype(np.int64)
    raise ValueError(f"distance rule must be one of {DISTANCE_RULES}, got {rule!r}")

# The reflex (SPEC section 6): the motion taken when no obstacle bit is set, by target sector.
REFLEX_MOTION = np.array(
    [Motion.FORWARD, Motion.TURN_LEFT, Motion.TURN_LEFT, Motion.TURN_RIGHT], dtype=np.uint8
)  # indexed by Sector: front, left, back, right


def make_state(obstacles: int, sector: int) -> int:
    """Pack six obstacle bits and a sector code into an 8-bit world state."""
    if not 0 <= obstacles <= OBSTACLE_MASK:
        raise ValueError(f"obstacle bits must be in 0..{OBSTACLE_MASK}, got {obstacles!r}")
    if not 0 <= sector <= 3:
        raise ValueError(f"sector must be in 0..3, got {sector!r}")
    return obstacles | (sector << SECTOR_SHIFT)


# States where the reflex overrides the controller (4 of them, one per sector), and their motions.
REFLEX_STATES = np.array([make_state(0, s) for s in range(4)], dtype=np.int64)
# A 256-entry table: reflex motion where the reflex applies, -1 elsewhere.
REFLEX_TABLE = np.full(N_STATES, -1, dtype=np.int16)
REFLEX_TABLE[REFLEX_STATES] = REFLEX_MOTION


# The robot's left-right mirror symmetry (SPEC section 4: the sensor angles and the motion set are
# symmetric about the heading). The mirror image of a state swaps front-left/front-right and
# left/right obstacle bits and the left/right target sectors; that of a motion swaps each left
# turn with its right one. Every outcome the robot observes, (s, a) -> s2 or a crash, is therefore
# evidence of (m(s), m(a)) -> m(s2) (docs/research-log.md, on-line round 12). The reflex is not symmetric: with
# the target behind it turns left in both mirror images (REFLEX_TABLE), so the mirror is a
# statement about the world, not about the controller.
MIRROR_SECTOR = np.array([Sector.FRONT, Sector.RIGHT, Sector.BACK, Sector.LEFT], dtype=np.uint8)
MIRROR_MOTION = np.array([
    Motion.FORWARD, Motion.BACKWARD, Motion.TURN_RIGHT, Motion.TURN_LEFT,
    Motion.FORWARD_RIGHT, Motion.FORWARD_LEFT, Motion.BACKWARD_RIGHT, Motion.BACKWARD_LEFT,
], dtype=np.uint8)
_MIRROR_BIT = (X_FRONT, X_FRONT_RIGHT, X_FRONT_LEFT, X_RIGHT, X_LEFT, X_BACK)  # bit i goes to _MIRROR_BIT[i]


def mirror_state(state: int) -> int:
    """The mirror image of an 8-bit world state (obstacle bits and sector swapped left/right)."""
    if not 0 <= state < N_STATES:
        raise ValueError(f"a world state is in 0..{N_STATES - 1}, got {state!r}")
    obstacles = sum(((state >> i) & 1) << j for i, j in enumerate(_MIRROR_BIT))
    return make_state(obstacles, int(MIRROR_SECTOR[state >> SECTOR_SHIFT]))


MIRROR_STATE = np.array([mirror_state(s) for s in range(N_STATES)], dtype=np.uint8)
