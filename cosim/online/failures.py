"""Failure detection of the execution phase (SPEC section 7): when does a leg stop for learning?

A crash ends the execution phase at once. Besides, the phase ends when one of these detectors
fires (checked after every step that neither crashed nor reached the target, in this order):

- :class:`LegTimeout`: ``max_leg_steps`` steps on one leg since the phase began (reason
  ``timeout``);
- :class:`NoProgress`: no new closest approach to the ball for ``window`` steps (a real-world
  loop the world model cannot see; reason ``loop``, detector ``window``);
- :class:`Reentries`: ``k`` entries into one obstacle state since the last new closest approach,
  each counted only among the earlier entries within ``radius_mm`` by odometry (an oscillation
  in place, docs/research-log.md, on-line round 3);
- :class:`Repeats`: the last pairs are ``k`` repetitions of one cycle of 2..6 (state, motion)
  pairs that brought the robot less than ``radius_mm`` on;
- :class:`Cycles`: the robot has gone ``k`` times round one simple cycle of 2..8 states back to
  the state it is in now, within ``radius_mm`` (round 5).

Every detector has the same small protocol (:class:`FailureDetector`): ``reset()`` at the start of
an execution phase and of every leg, and ``observe(track) -> bool`` after every step, True when
the phase should end there. They read what the loop has seen from one :class:`Track` (the recent
(state, motion) pairs, the odometry, the closest approach), which the loop updates once a step;
the loop composes them as a list, as Gymnasium stacks its ``TimeLimit`` and other wrappers.
:func:`blame` names the (state, motion) a time-out or loop is put on; :func:`blame_cycle` the one a
cycle stop is put on (a pair of the cycle that stopped the leg).
"""

from __future__ import annotations

import math
from collections import Counter, deque
from typing import Protocol

from ga.motions import MOTION_ROTATION_DEG, MOTION_TRANSLATION_MM, OBSTACLE_MASK


class Track:
    """What the execution phase has seen, as the detectors read it.

    - ``pairs``: the recent (state, motion) pairs (at most ``maxlen``; emptied at every target,
      kept across execution phases of one leg);
    - ``places``: the odometry position (x, y) after each of them: the commanded motions
      dead-reckoned from the start of the lifetime (crashed motions do not move it);
    - ``state``: the state the robot is in now;
    - ``closest`` / ``since_closer``: the closest approach to the ball since the phase began or
      the last target, and the steps since it; ``closer``: the last step made a new one (judged
      on the camera's range estimate, SPEC section 4, never the exact distance);
    - ``entered``: the last step, not a new closest approach, entered an obstacle state from
      another state.
    """

    def __init__(self, maxlen: int):
        self.pairs: deque[tuple[int, int]] = deque(maxlen=maxlen)
        self.places: deque[tuple[float, float]] = deque(maxlen=maxlen)
        self.odometry = [0.0, 0.0, 0.0]  # x, y (mm), heading (rad)
        self.state = 0
        self.closest = float("inf")
        self.since_closer = 0
        self.closer = False
        self.entered = False

    def new_phase(self) -> None:
        """An execution phase begins: the closest approach is forgotten (the pairs are kept)."""
        self.closest, self.since_closer = float("inf"), 0

    def step(self, state: int, motion: int, next_state: int, crashed: bool, reached: bool,
             range_mm: float) -> None:
        """One interaction: ``motion`` in ``state`` led to ``next_state`` (after a target: the
        state at the relocation position), where the camera read ``range_mm`` to the ball."""
        self.pairs.append((state, motion))
        if not crashed:
            x, y, heading = self.odometry
            turn = math.radians(float(MOTION_ROTATION_DEG[motion]))
            move = float(MOTION_TRANSLATION_MM[motion])
            self.odometry = [x + move * math.cos(heading + turn / 2),
                             y + move * math.sin(heading + turn / 2), heading + turn]
        self.places.append((self.odometry[0], self.odometry[1]))
        self.state = next_state
        if reached:  # a new leg
            self.pairs.clear()
            self.places.clear()
            self.new_phase()
        self.closer = range_mm < self.closest - 1e-9
        if self.closer:
            self.closest, self.since_closer = range_mm, 0
        else:
            self.since_closer += 1
        self.entered = not self.closer and next_state != state and bool(next_state & OBSTACLE_MASK)

    def moved(self, since: int) -> float:
        """Odometry distance (mm) from the position ``since`` steps ago (-since indexes places)
        to the position now."""
        (x0, y0), (x1, y1) = self.places[since], self.places[-1]
        return math.hypot(x1 - x0, y1 - y0)


class FailureDetector(Protocol):
    """One reason to end an execution phase before a crash."""

    name: str  # recorded in the phase record ("detector") for loops
    reason: str  # "timeout" or "loop"

    def reset(self) -> None:
        """An execution phase or a leg begins."""

    def observe(self, track: Track) -> bool:
        """After one step (``track`` already updated): True to end the phase here."""


class LegTimeout:
    """``max_steps`` steps on one leg since the execution phase began. ``steps`` is the count."""

    name, reason = "timeout", "timeout"

    def __init__(self, max_steps: int):
        self.max_steps = max_steps
        self.steps = 0

    def reset(self) -> None:
        self.steps = 0

    def observe(self, track: Track) -> bool:
        self.steps += 1
        return self.steps >= self.max_steps


class NoProgress:
    """No new closest approach to the ball for ``window`` steps."""

    name, reason = "window", "loop"

    def __init__(self, window: int):
        self.window = window

    def reset(self) -> None:
        pass

    def observe(self, track: Track) -> bool:
        return track.since_closer >= self.window


class Reentries:
    """``k`` entries into one obstacle state since the last new closest approach; with
    ``radius_mm`` > 0 an entry counts only the earlier entries within that odometry distance."""

    name, reason = "reentries", "loop"

    def __init__(self, k: int, radius_mm: float = 0.0):
        self.k, self.radius_mm = k, radius_mm
        self.entries: Counter = Counter()  # state -> entries counted
        self.places: dict[int, list[tuple[float, float]]] = {}  # state -> odometry at its entries

    def reset(self) -> None:
        self.entries.clear()
        self.places.clear()

    def observe(self, track: Track) -> bool:
        if track.closer:
            self.reset()
        elif track.entered:
            state = track.state
            if self.radius_mm:
                x0, y0 = track.odometry[0], track.odometry[1]
                seen = self.places.setdefault(state, [])
                seen.append((x0, y0))
                self.entries[state] = sum(1 for x1, y1 in seen if math.hypot(x1 - x0, y1 - y0) <= self.radius_mm)
            else:
                self.entries[state] += 1
        return bool(self.entries) and max(self.entries.values()) >= self.k


class Repeats:
    """The last ``k * p`` pairs repeat one cycle of p pairs (2 <= p <= 6, not all one pair), all
    since the last new closest approach, and (``radius_mm`` > 0) moved the robot less than that."""

    name, reason = "repeats", "loop"

    def __init__(self, k: int, radius_mm: float = 0.0):
        self.k, self.radius_mm = k, radius_mm

    def reset(self) -> None:
        pass

    def observe(self, track: Track) -> bool:
        pairs = track.pairs
        for p in range(2, 7):
            n = self.k * p
            if n > len(pairs) or n > track.since_closer:
                break
            tail = list(pairs)[-n:]
            if all(tail[i] == tail[i % p] for i in range(n)) and len(set(tail[:p])) > 1:
                if self.radius_mm and track.moved(-n) > self.radius_mm:
                    continue  # the cycle moves the robot on: not a loop
                return True
        return False


class Cycles:
    """The robot is back in its current state after a simple cycle of p pairs (2 <= p <= 8, its
    states distinct, one with an obstacle bit), gone round ``k`` times in a row (with
    ``after_approach``: since the last new closest approach), and (``radius_mm`` > 0) by odometry
    within that distance of where the first round began. The cycle's transitions are then the
    world model's latest entries, so the model holds the loop the controller just ran
    (docs/research-log.md, on-line round 5). Without ``after_approach`` the odometry alone says the robot made
    no progress: a new closest approach by the camera's noisy range is weak evidence of one
    (docs/online.md, "Honest sensing")."""

    name, reason = "cycles", "loop"

    def __init__(self, k: int, radius_mm: float = 0.0, after_approach: bool = True):
        self.k, self.radius_mm, self.after_approach = k, radius_mm, after_approach
        self.cycle: list[tuple[int, int]] = []  # the pairs of the last round when it fired

    def reset(self) -> None:
        self.cycle = []

    def observe(self, track: Track) -> bool:
        w, now = track.pairs, track.state
        for p in range(2, 9):
            n = self.k * p
            if n > len(w) or (self.after_approach and n > track.since_closer):
                break
            if w[-p][0] != now:
                continue
            cycle = [w[i] for i in range(-p, 0)]
            states = [s for s, _ in cycle]
            if len(set(states)) < p or not any(s & OBSTACLE_MASK for s in states):
                continue
            if any(w[-p * r + i] != cycle[i] for r in range(2, self.k + 1) for i in range(p)):
                continue
            # where the first round began: the position after the pair before it (the oldest one
            # kept if the track holds no earlier pair)
            if self.radius_mm and track.moved(max(-n - 1, -len(track.places))) > self.radius_mm:
                continue
            self.cycle = cycle
            return True
        return False


def blame(pairs) -> tuple[int, int]:
    """The (state, motion) a time-out or loop is blamed on: the most frequent of the recent
    ``pairs`` in a state the controller decides (some obstacle bit set; ties: the first seen),
    else the last pair (a cycle stop with ``loop_blame`` "leg"; the leg time-out, the window, the
    re-entries and the repeats)."""
    pairs = list(pairs)
    decided = [p for p in pairs if p[0] & OBSTACLE_MASK]
    if not decided:
        return pairs[-1]
    return Counter(decided).most_common(1)[0][0]


def blame_cycle(cycle) -> tuple[int, int]:
    """The (state, motion) a cycle stop is blamed on with ``loop_blame`` "cycle" (the default,
    docs/research-log.md, on-line round 8): the first pair of the cycle, in order from the state the robot is in
    now, in a state the controller decides. The cycle starts at the current state, so when that
    state has an obstacle bit the escape changes the very next motion, inside the loop that
    stopped the leg; the leg's most frequent pair (:func:`blame`) was outside that loop in most
    cycle stops."""
    return next(p for p in cycle if p[0] & OBSTACLE_MASK)
