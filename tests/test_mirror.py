"""The robot's left-right mirror (ga.motions: MIRROR_STATE, MIRROR_MOTION, MIRROR_SECTOR)."""

from __future__ import annotations

import numpy as np

from ga.motions import (
    MIRROR_MOTION, MIRROR_SECTOR, MIRROR_STATE, MOTION_ROTATION_DEG, MOTION_TRANSLATION_MM, N_MOTIONS,
    N_STATES, REFLEX_TABLE, SECTOR_SHIFT, X_BACK, X_FRONT, X_FRONT_LEFT, X_FRONT_RIGHT, X_LEFT, X_RIGHT,
    Motion, Sector, make_state, mirror_state,
)
from sim_world.world import IR_SENSORS


def test_the_mirror_is_an_involution_on_states_motions_and_sectors():
    assert MIRROR_STATE[MIRROR_STATE].tolist() == list(range(N_STATES))
    assert MIRROR_MOTION[MIRROR_MOTION].tolist() == list(range(N_MOTIONS))
    assert MIRROR_SECTOR[MIRROR_SECTOR].tolist() == [0, 1, 2, 3]
    assert sorted(MIRROR_STATE.tolist()) == list(range(N_STATES))  # a permutation


def test_the_mirror_codes():
    assert MIRROR_SECTOR.tolist() == [Sector.FRONT, Sector.RIGHT, Sector.BACK, Sector.LEFT]
    assert MIRROR_MOTION.tolist() == [0, 1, 3, 2, 5, 4, 7, 6]
    assert MIRROR_MOTION[Motion.FORWARD_LEFT] == Motion.FORWARD_RIGHT
    assert MIRROR_MOTION[Motion.BACKWARD_RIGHT] == Motion.BACKWARD_LEFT
    pairs = {X_FRONT: X_FRONT, X_BACK: X_BACK, X_FRONT_LEFT: X_FRONT_RIGHT, X_FRONT_RIGHT: X_FRONT_LEFT,
             X_LEFT: X_RIGHT, X_RIGHT: X_LEFT}
    for bit, image in pairs.items():
        for sector in range(4):
            assert mirror_state(make_state(1 << bit, sector)) == make_state(1 << image, int(MIRROR_SECTOR[sector]))
    s = make_state((1 << X_FRONT) | (1 << X_FRONT_LEFT) | (1 << X_RIGHT), Sector.LEFT)
    assert MIRROR_STATE[s] == make_state((1 << X_FRONT) | (1 << X_FRONT_RIGHT) | (1 << X_LEFT), Sector.RIGHT)
    # the symmetric states: x1 = x2, x3 = x4, target front or back
    fixed = np.flatnonzero(MIRROR_STATE == np.arange(N_STATES))
    assert len(fixed) == 32 and all((s >> SECTOR_SHIFT) in (Sector.FRONT, Sector.BACK) for s in fixed)


def test_the_mirror_is_the_world_s_geometry():
    """What makes a mirrored observation evidence: the sensors and the motions are symmetric."""
    image = {X_FRONT: X_FRONT, X_BACK: X_BACK, X_FRONT_LEFT: X_FRONT_RIGHT, X_FRONT_RIGHT: X_FRONT_LEFT,
             X_LEFT: X_RIGHT, X_RIGHT: X_LEFT}
    sensors = {(angle % 360.0, bit) for angle, bit in IR_SENSORS}
    assert {(-angle % 360.0, image[bit]) for angle, bit in sensors} == sensors
    assert MOTION_TRANSLATION_MM[MIRROR_MOTION].tolist() == MOTION_TRANSLATION_MM.tolist()
    assert MOTION_ROTATION_DEG[MIRROR_MOTION].tolist() == (-MOTION_ROTATION_DEG).tolist()


def test_the_reflex_is_symmetric_except_for_the_target_behind():
    reflex = np.flatnonzero(REFLEX_TABLE >= 0)
    for s in reflex:
        m = MIRROR_STATE[s]
        assert REFLEX_TABLE[m] >= 0  # the reflex states map to reflex states
        if (s >> SECTOR_SHIFT) != Sector.BACK:
            assert REFLEX_TABLE[m] == MIRROR_MOTION[REFLEX_TABLE[s]]
        else:  # it always turns left with the target behind
            assert REFLEX_TABLE[m] == REFLEX_TABLE[s] == Motion.TURN_LEFT
