"""The model-free fitness (SPEC section 7) on hand-made controllers in simple arenas."""

import numpy as np
import pytest

from cosim.offline.run import evaluate
from ga.genome import N_ROWS
from ga.model_free import max_run_steps, model_free_fitness
from ga.motions import Motion
from sim_world.world import World

LEG = 200


def _genome(*rows):
    """A genome from (literals, output) pairs; literals as {input: 1 (x_i) or 0 (NOT x_i)}."""
    words = np.zeros(N_ROWS, dtype=np.uint32)
    for r, (literals, output) in enumerate(rows):
        word = output << 16
        for i, value in literals.items():
            word |= 1 << (2 * i + (0 if value else 1))
        words[r] = word
    return words


# Steer by the target sector only, whatever the obstacles: left/back -> turn left, right -> turn
# right, front -> no row fires -> motion 0 (forward).
SECTOR_ONLY = _genome(
    ({6: 1, 7: 0}, Motion.TURN_LEFT),
    ({6: 0, 7: 1}, Motion.TURN_LEFT),
    ({6: 1, 7: 1}, Motion.TURN_RIGHT),
)
ALWAYS_BACKWARD = _genome(({}, Motion.BACKWARD))  # a row with no literal fires in every state
ALWAYS_TURN_LEFT = _genome(({}, Motion.TURN_LEFT))


def test_formula():
    assert model_free_fitness(3, 0.0, 4000.0, 0, 100) == 4.0
    assert model_free_fitness(0, 4000.0, 4000.0, 100, 100) == 0.0
    assert model_free_fitness(5, 1000.0, 4000.0, 25, 100) == pytest.approx(5 + 0.5 * 0.75 + 0.5 * 0.75)
    assert model_free_fitness(0, 9000.0, 4000.0, 500, 100) == 0.0  # ratios clipped to [0, 1]
    assert max_run_steps(150) == 64 * 150
    with pytest.raises(ValueError, match="-1"):
        model_free_fitness(0, 0.0, -1.0, 0, 10)


def test_sector_steering_reaches_every_target_in_the_empty_arena():
    world = World("empty")
    ev = evaluate(world, SECTOR_ONLY, LEG)
    assert ev.targets_reached == 64 and not ev.crashed and not ev.timed_out
    assert ev.final_distance_mm <= world.arena.target_radius_mm
    expected = 64 + 0.5 * (1 - ev.final_distance_mm / 4000) + 0.5 * (1 - ev.steps / (64 * LEG))
    assert ev.fitness == pytest.approx(expected)
    assert world.interactions == ev.steps  # every motion counted
    assert {t[0] for t in ev.transitions} <= ev.states
    assert all(t[1] == 0 for t in ev.transitions if t[0] >> 6 == 0)  # sector front: forward


def test_fewer_targets_when_the_run_is_shorter():
    world = World("empty")
    few = evaluate(world, SECTOR_ONLY, LEG, n_targets=3)
    assert few.targets_reached == 3 and 3 < few.fitness < 4


def test_backward_crashes_into_the_corner():
    world = World("empty")
    ev = evaluate(world, ALWAYS_BACKWARD, LEG)
    assert ev.crashed and ev.targets_reached == 0 and not ev.timed_out
    assert ev.fitness == pytest.approx(
        0.5 * (1 - ev.final_distance_mm / 4000) + 0.5 * (1 - ev.steps / (64 * LEG))
    )
    assert any(t[3] for t in ev.transitions)  # the crash is a transition met


def test_turning_in_place_times_out():
    world = World("empty")
    ev = evaluate(world, ALWAYS_TURN_LEFT, LEG, reflex=False)
    assert ev.timed_out and not ev.crashed and ev.steps == LEG and ev.targets_reached == 0
    assert len(ev.states) <= 16  # one place, 16 headings
    assert ev.fitness == pytest.approx(0.5 * (1 - ev.final_distance_mm / 4000) + 0.5 * (1 - 1 / 64))


def test_evaluation_is_deterministic_and_world_reusable():
    shared = World("one_obstacle")
    a = evaluate(shared, SECTOR_ONLY, LEG)
    evaluate(shared, ALWAYS_BACKWARD, LEG)
    b = evaluate(shared, SECTOR_ONLY, LEG)
    c = evaluate(World("one_obstacle"), SECTOR_ONLY, LEG)
    assert a == b == c
