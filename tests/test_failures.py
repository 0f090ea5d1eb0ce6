"""The failure detectors of the execution phase (cosim.online.failures) and the download choice
(cosim.online.download), each on hand-made step sequences through its public interface."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.online.download import choose_download
from cosim.online.failures import Cycles, LegTimeout, NoProgress, Reentries, Repeats, Track, blame, blame_cycle
from ga.operators import random_population
from ga.truth_table import truth_tables

FAR = 1000.0  # the ball's distance (mm) when the robot gets no closer


def drive(detector, steps, start: int = 0, maxlen: int = 64):
    """Feed ``steps`` = [(motion, next_state[, distance])] to a fresh Track and ``detector``;
    return the 1-based steps at which it fired."""
    track = Track(maxlen)
    track.state = start
    detector.reset()
    fired = []
    for k, step in enumerate(steps, 1):
        motion, nxt, dist = (*step, FAR)[:3]
        track.step(track.state, motion, nxt, False, False, dist)
        if detector.observe(track):
            fired.append(k)
    return fired


# -- the track ---------------------------------------------------------------------------------------


def test_track_dead_reckons_the_commanded_motions_and_ignores_crashes():
    track = Track(8)
    for motion in (0, 2, 4, 1):  # forward, turn left, forward-left, backward
        track.step(2, motion, 2, False, False, FAR)
    track.step(2, 0, 2, True, False, FAR)  # a crash does not move the robot
    h = math.radians(22.5)
    x = 50 + 50 * math.cos(h + h / 2) - 50 * math.cos(2 * h)
    y = 50 * math.sin(h + h / 2) - 50 * math.sin(2 * h)
    assert track.odometry == pytest.approx([x, y, 2 * h])
    assert len(track.pairs) == len(track.places) == 5 and track.places[-1] == track.places[-2]


def test_track_closest_approach_and_new_legs():
    track = Track(8)
    for dist, closer in [(900, True), (950, False), (950, False), (800, True), (800, False)]:
        track.step(1, 0, 1, False, False, dist)
        assert track.closer is closer
    assert (track.closest, track.since_closer) == (800, 1)
    track.step(1, 0, 5, False, True, 100.0)  # a target: the pairs go, the closest approach restarts
    assert len(track.pairs) == 0 and (track.closest, track.since_closer, track.state) == (100.0, 0, 5)
    track.new_phase()
    assert track.closest == math.inf


def test_track_entered_means_into_an_obstacle_state_from_another_without_progress():
    track = Track(8)
    track.step(64, 0, 65, False, False, FAR)  # the first step is a new closest approach
    assert not track.entered
    track.step(65, 0, 1, False, False, FAR)
    assert track.entered  # 1 has an obstacle bit
    track.step(1, 0, 1, False, False, FAR)
    assert not track.entered  # stayed
    track.step(1, 0, 64, False, False, FAR)
    assert not track.entered  # no obstacle bit


# -- the detectors ----------------------------------------------------------------------------------


def test_leg_timeout_counts_the_steps_since_reset():
    timeout = LegTimeout(3)
    assert drive(timeout, [(0, 64)] * 5) == [3, 4, 5]
    assert timeout.steps == 5
    timeout.reset()
    assert timeout.steps == 0


def test_no_progress_fires_after_the_window_without_a_closer_step():
    steps = [(0, 64, 900.0)] + [(0, 64, 950.0)] * 4 + [(0, 64, 850.0)] + [(0, 64, 900.0)] * 3
    assert drive(NoProgress(3), steps) == [4, 5, 9]


@pytest.mark.parametrize("motions, radius, fires", [((2, 3), 60.0, [6, 7, 8]), ((0, 0), 60.0, []),
                                                    ((0, 0), 0.0, [6, 7, 8])])
def test_reentries_count_entries_back_at_the_same_place(motions, radius, fires):
    """Entering states 1 and 2 in turn: turning left and right in place is a loop (the third entry
    into 1, step 6); moving on 50 mm a step is not, unless the odometry check is off."""
    steps = [(motions[k % 2], (2, 1)[k % 2]) for k in range(8)]
    assert drive(Reentries(3, radius), steps, start=1) == fires


def test_reentries_forget_at_a_closer_step():
    steps = [(2, 2), (3, 1), (2, 2), (3, 1, 500.0), (2, 2), (3, 1), (2, 2), (3, 1)]
    assert drive(Reentries(3), steps, start=1) == []  # 2 entries, progress, 2 entries
    assert drive(Reentries(2), steps, start=1) == [7, 8]


@pytest.mark.parametrize("cycle, radius, fires", [([(4, 1), (5, 2)], 0.0, True), ([(4, 1), (5, 2)], 60.0, False),
                                                   ([(2, 1), (3, 2)], 60.0, True)])
def test_repeats_fire_on_a_repeated_cycle_that_goes_nowhere(cycle, radius, fires):
    """A 2-pair cycle repeated: forward-left, forward-right zigzags 100 mm on per round (no loop with
    the odometry check); turning left and right stays in place (a loop)."""
    hits = drive(Repeats(2, radius), [(0, 2)] + cycle * 3, start=2)
    assert bool(hits) is fires
    assert drive(Repeats(2), [(0, 2)] + [(4, 1), (4, 2), (6, 1)] * 2, start=2) == []  # no 2-cycle
    assert drive(Repeats(2), [(0, 2)] + [(0, 2)] * 6, start=2) == []  # one pair is no cycle


@pytest.mark.parametrize("rounds, motions, fires_at", [(1, (2, 3), 3), (2, (2, 3), 5), (1, (0, 0), None)])
def test_cycles_fire_once_the_robot_went_round_a_simple_cycle(rounds, motions, fires_at):
    """States 1 -> 2 -> 1 -> ... (the ball never closer): turning in place closes the cycle after
    ``rounds`` rounds (the first step only sets the closest approach); moving on 50 mm a step is
    no loop by odometry."""
    steps = [(motions[k % 2], (2, 1)[k % 2]) for k in range(10)]
    hits = drive(Cycles(rounds, 60.0), steps, start=1)
    assert (hits[0] if hits else None) == fires_at


def test_cycles_need_distinct_states_with_an_obstacle_bit():
    assert drive(Cycles(1), [(2, 64), (3, 128), (2, 64), (3, 128)], start=128) == []  # no obstacle bit
    assert drive(Cycles(1), [(2, 64), (3, 129), (2, 64), (3, 129)], start=129) == [3, 4]
    assert drive(Cycles(1), [(2, 1), (3, 1), (2, 1), (3, 1)], start=1) == []  # 1 -> 1 is no 2-cycle


def test_cycles_by_odometry_alone_ignore_a_lucky_range_reading():
    """Turning in place 1 -> 2 -> 1 -> 2, while the camera's noisy range reads the ball closer at
    every step: after the approach, no cycle (each reading resets the count); by odometry alone
    the robot went round without moving, and it fires."""
    steps = [(2, 2, 990.0), (3, 1, 980.0), (2, 2, 970.0), (3, 1, 960.0), (2, 2, 950.0)]
    assert drive(Cycles(1, 60.0), steps, start=1) == []
    assert drive(Cycles(1, 60.0, after_approach=False), steps, start=1) == [2, 3, 4, 5]


def test_a_cycle_stop_is_blamed_inside_its_cycle():
    """A leg that went three times through (3, 2), then round the cycle 64 -> 1 -> 64: the leg's
    most frequent pair (``blame``, rounds 1-7) is outside the loop; ``blame_cycle`` puts the stop
    on the cycle's first pair, from the state the robot is in, in an obstacle state (round 8)."""
    track, cycles = Track(64), Cycles(1)
    track.state = 3
    fired = []
    for motion, nxt in [(2, 3), (2, 3), (2, 3), (2, 64), (3, 1), (4, 64), (3, 1)]:
        track.step(track.state, motion, nxt, False, False, FAR)
        fired.append(cycles.observe(track))
        if fired[-1]:
            break
    assert fired == [False] * 5 + [True]  # back in 64 after (64, 3), (1, 4)
    assert cycles.cycle == [(64, 3), (1, 4)]
    assert blame(track.pairs) == (3, 2) and blame_cycle(cycles.cycle) == (1, 4)
    assert blame_cycle([(1, 4), (64, 3)]) == (1, 4)  # the robot in an obstacle state: its own pair
    cycles.reset()
    assert cycles.cycle == []


def test_blame_is_the_most_frequent_obstacle_pair_else_the_last():
    assert blame([(64, 0), (1, 2), (3, 4), (1, 2), (64, 0), (64, 0)]) == (1, 2)
    assert blame([(3, 4), (1, 2)]) == (3, 4)  # ties: the first seen
    assert blame([(64, 0), (65, 1)]) == (65, 1)


# -- the download -----------------------------------------------------------------------------------


def test_download_is_the_fittest_or_the_fittest_escaping_the_blamed_motion():
    pop = random_population(np.random.default_rng(3), 12)
    fitness = np.linspace(0.1, 0.9, 12)[::-1].copy()  # individual 0 is the fittest
    assert choose_download(pop, fitness) == (0, False)
    motions = truth_tables(pop)[:, 5]
    index, escaped = choose_download(pop, fitness, (5, int(motions[0])))
    others = np.flatnonzero(motions != motions[0])
    assert escaped and index == others[0] and motions[index] != motions[0]
    # the fittest already avoids the blamed motion: no escape needed
    other = next(m for m in range(8) if m != motions[0])
    assert choose_download(pop, fitness, (5, other)) == (0, False)
    # nobody avoids it: the fittest
    same = np.repeat(pop[:1], 12, axis=0)
    assert choose_download(same, fitness, (5, int(motions[0]))) == (0, False)
